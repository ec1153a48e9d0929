"""Figures: every title is inside the picture (none cut at the edges); a long line is drawn
through its min/max envelope, every spike kept."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.figure import Figure

import hmpc_pin
from hmpc_pin.apps import plots

from .conftest import PLANAR3

LONG = "Paper Section 5.1: unknown Coulomb-viscous friction only (Figures 4 and 5) - baseline " \
       "without the NDO"  # fmt: skip


@pytest.fixture(scope="module")
def run():
    robot = hmpc_pin.load_robot(PLANAR3)
    result = hmpc_pin.simulate(robot, hmpc_pin.HierarchicalMPC(robot), hmpc_pin.SineReference(3),
                               duration=0.3, q0=np.ones(3))  # fmt: skip
    return robot, result


def _title_boxes(monkeypatch):
    """Record, at save time, each figure's size and its titles' extents [px]."""
    seen = []
    save = Figure.savefig

    def savefig(fig, path, **kw):
        save(fig, path, **kw)  # draws the figure: the extents below are final
        renderer = fig._get_renderer()
        texts = [fig._suptitle] if fig._suptitle is not None else []
        texts += [ax.title for ax in fig.axes if ax.get_title()]
        seen.append((fig.bbox, [t.get_window_extent(renderer) for t in texts],
                     [t.get_text() for t in texts]))  # fmt: skip

    monkeypatch.setattr(Figure, "savefig", savefig)
    return seen


@pytest.mark.parametrize("kind", ["tracking", "disturbance", "error", "cartesian"])
def test_long_titles_fit_in_the_figure(run, tmp_path, monkeypatch, kind):
    robot, result = run
    seen = _title_boxes(monkeypatch)
    path = tmp_path / f"{kind}.png"
    if kind == "tracking":
        plots.plot_tracking(result, path, LONG)
    elif kind == "disturbance":
        plots.plot_disturbance(result, path, LONG)
    elif kind == "error":
        plots.plot_error({"with NDO": result}, path, LONG)
    else:
        plots.plot_cartesian(robot, result, path, (1.2, 0.5), (2.4, 2.2), LONG)
    ((fig_box, boxes, texts),) = seen
    assert boxes and all(" ".join(t.split()) == LONG for t in texts)  # all words kept
    for box in boxes:
        assert box.x0 >= fig_box.x0 - 0.5 and box.x1 <= fig_box.x1 + 0.5, (box, fig_box)
        assert box.y0 >= fig_box.y0 - 0.5 and box.y1 <= fig_box.y1 + 0.5, (box, fig_box)


# ------------------------------------------------------------------ long lines
def test_envelope_keeps_every_spike_and_each_buckets_extremes(make_rng):
    """A long noisy line with one-sample spikes: at most MAX_POINTS samples kept, all of
    them samples of the line in time order, the first and last kept, every spike kept,
    and per bucket of the reduction (recomputed here with a loop) its min and max."""
    rng = make_rng(3)
    k = 200_003  # not a multiple of the bucket count
    t = np.linspace(0.0, 200.0, k)
    y = np.cumsum(rng.normal(size=k)) * 1e-3
    spikes = rng.choice(k, size=5, replace=False)
    y[spikes[:3]] += 50.0
    y[spikes[3:]] -= 50.0
    te, ye = plots.envelope(t, y)
    assert len(te) <= plots.MAX_POINTS
    idx = np.searchsorted(t, te)
    assert np.all(np.diff(idx) > 0) and np.array_equal(y[idx], ye)
    assert idx[0] == 0 and idx[-1] == k - 1
    assert set(spikes) <= set(idx.tolist())
    buckets = plots.MAX_POINTS // 2 - 1
    m = -(-k // buckets)
    kept = set(idx.tolist())
    for b in range(buckets):
        seg = y[b * m : (b + 1) * m]
        if len(seg):
            assert b * m + int(np.argmin(seg)) in kept and b * m + int(np.argmax(seg)) in kept


def test_envelope_leaves_short_lines_and_keeps_gaps():
    t = np.arange(10.0)
    assert plots.envelope(t, t)[1] is t  # short: unchanged
    t = np.linspace(0, 1, 50_000)
    y = np.sin(t)
    y[20_000:20_010] = np.nan  # a gap (samples missing) stays a gap
    te, ye = plots.envelope(t, y)
    assert np.isnan(ye).any() and len(te) <= plots.MAX_POINTS


def test_a_spike_of_a_long_run_is_in_the_drawn_figure(tmp_path, monkeypatch):
    """The tracking figure of a 100,000-sample run with a one-sample spike of the angle:
    the line drawn holds the spike (and at most MAX_POINTS samples)."""
    k, n = 100_000, 2
    t = np.linspace(0.0, 100.0, k)
    q = np.tile(np.sin(t)[:, None], (1, n))
    q[61_234, 1] = 7.5
    zeros = np.zeros_like(q)
    result = hmpc_pin.Result(t, q, zeros, zeros, zeros, zeros, np.sin(t)[:, None] * [1, 1],
                             zeros)  # fmt: skip
    drawn = []
    save = Figure.savefig

    def savefig(fig, path, **kw):
        drawn.extend(line.get_ydata() for ax in fig.axes for line in ax.get_lines())
        save(fig, path, **kw)

    monkeypatch.setattr(Figure, "savefig", savefig)
    plots.plot_tracking(result, tmp_path / "t.png", "spike")
    assert max(np.max(y) for y in drawn) == 7.5
    assert all(len(y) <= plots.MAX_POINTS for y in drawn)


# ------------------------------------------------------------------ log axes in plain text
@pytest.mark.parametrize(
    ("x", "label"),
    [(1e-7, "10⁻⁷"), (1e-3, "10⁻³"), (1.0, "10⁰"), (10.0, "10¹"), (1e12, "10¹²"),
     (2e-3, "2×10⁻³"), (0.5, "5×10⁻¹"), (0.0, ""), (-1.0, ""), (float("nan"), "")],
)  # fmt: skip
def test_power_labels_are_the_decades_in_superscript_digits(x, label):
    assert plots.power_label(x) == label


def test_the_error_figure_labels_its_decades_without_mathtext(run, tmp_path, monkeypatch):
    """Every y tick label of the error figure reads 10 to the power of the tick's decade
    (computed here from the tick's value), written without matplotlib's mathtext."""
    _, result = run
    labels = []
    save = Figure.savefig

    def savefig(fig, path, **kw):
        save(fig, path, **kw)  # drawn: the labels are final
        for ax in fig.axes:
            lo, hi = ax.get_ylim()
            for tick in ax.yaxis.get_major_ticks():
                if lo <= tick.get_loc() <= hi:
                    labels.append((tick.get_loc(), tick.label1.get_text()))

    monkeypatch.setattr(Figure, "savefig", savefig)
    plots.plot_error({"run": result}, tmp_path / "e.png", "error")
    assert len(labels) >= 3 * 3  # three rows, 7+ decades each
    for loc, text in labels:
        exponent = round(np.log10(loc))
        assert np.isclose(loc, 10.0**exponent)
        digits = str(exponent).translate(str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹"))
        assert text == "10" + digits and "$" not in text


# ------------------------------------------------------------------ several figures of a run
def _pixels(path) -> np.ndarray:
    from PIL import Image

    with Image.open(path) as image:
        return np.asarray(image.convert("RGBA"))


@pytest.mark.parametrize(
    "order",
    [("tracking", "disturbance", "error"), ("error", "tracking", "disturbance"),
     ("disturbance", "error", "tracking")],
)  # fmt: skip
def test_figures_drawn_one_after_the_other_are_those_drawn_alone(run, tmp_path, order):
    """draw_all draws the per-joint figures on one figure in turn: each PNG is, pixel for
    pixel, the one draw makes on a new figure, whatever came before it (a log axis, a
    title or none, another legend)."""
    _, result = run
    jobs = [(kind, tmp_path / f"all_{kind}.png", title, "with NDO")
            for kind, title in zip(order, ("a title", "", LONG), strict=True)]  # fmt: skip
    assert list(plots.draw_all(jobs, result)) == [(path, None) for _, path, _, _ in jobs]
    for kind, path, title, label in jobs:
        alone = plots.draw(kind, result, tmp_path / f"alone_{kind}.png", title, label)
        assert np.array_equal(_pixels(path), _pixels(alone)), kind


def test_figures_drawn_one_after_the_other_plot_the_runs_arrays(run, tmp_path, monkeypatch):
    """Each figure of draw_all holds, per row, exactly its own lines with the run's arrays
    (the reference and the angle; the true and estimated disturbance; |q − r| floored at
    1e-9 and the 0.01 line): nothing of the figure before it."""
    _, result = run
    drawn = []
    save = Figure.savefig

    def savefig(fig, path, **kw):
        drawn.append([[(line.get_label(), np.asarray(line.get_ydata(), float))
                       for line in ax.get_lines()] for ax in fig.axes])  # fmt: skip
        save(fig, path, **kw)

    monkeypatch.setattr(Figure, "savefig", savefig)
    kinds = ("error", "tracking", "disturbance")
    jobs = [(kind, tmp_path / f"{kind}.png", "", "with NDO") for kind in kinds]
    assert all(exc is None for _, exc in plots.draw_all(jobs, result))
    error, tracking, disturbance = drawn
    for i in range(3):
        assert [label for label, _ in tracking[i]] == ["reference r", "angle q"]
        assert np.array_equal(tracking[i][0][1], result.q_ref[:, i])
        assert np.array_equal(tracking[i][1][1], result.q[:, i])
        assert [label for label, _ in disturbance[i]] == ["true d", "NDO estimate d̂"]
        assert np.array_equal(disturbance[i][0][1], result.d[:, i])
        assert np.array_equal(disturbance[i][1][1], result.d_hat[:, i])
        assert [label for label, _ in error[i]] == ["with NDO", "0.01 rad"]
        e = np.maximum(np.abs(result.q[:, i] - result.q_ref[:, i]), 1e-9)
        assert np.array_equal(error[i][0][1], e)
        assert np.array_equal(error[i][1][1], [0.01, 0.01])


def test_a_figure_that_cannot_be_drawn_is_reported_and_the_next_is_drawn(run, tmp_path):
    _, result = run
    jobs = [("tracking", tmp_path / "t.png", "", ""), ("nonsense", tmp_path / "x.png", "", ""),
            ("disturbance", tmp_path / "d.png", "", "")]  # fmt: skip
    out = list(plots.draw_all(jobs, result))
    assert [p.name for p, _ in out] == ["t.png", "x.png", "d.png"]
    assert out[0][1] is None and out[2][1] is None
    assert isinstance(out[1][1], hmpc_pin.ConfigError) and "nonsense" in str(out[1][1])
    assert not (tmp_path / "x.png").exists()
    alone = plots.draw("disturbance", result, tmp_path / "alone.png")
    assert np.array_equal(_pixels(tmp_path / "d.png"), _pixels(alone))
