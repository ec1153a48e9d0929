"""Figures: every title is inside the picture (none cut at the edges)."""

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
