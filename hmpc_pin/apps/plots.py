"""Figures in the paper's layout: one row per joint, time on the x axis.

Figures are built with ``matplotlib.figure.Figure`` (no pyplot, no global
backend switch), so plotting works headless and never touches the user's
matplotlib state. Every function writes a PNG and returns its path; the PNG is written to
``<name>.part`` and renamed, so an interrupted figure leaves no half-written file.

A line of more than :data:`MAX_POINTS` samples is drawn through its min/max envelope
(:func:`envelope`): per bucket of consecutive samples its lowest and highest value, in
their order, so that every spike stays visible at the figure's resolution while the
drawing no longer grows with the run's length.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter, MaxNLocator, NullLocator

from ..exceptions import ConfigError
from .metrics import joint_units

__all__ = [
    "KINDS",
    "MAX_POINTS",
    "arm_points",
    "draw",
    "draw_all",
    "envelope",
    "plot_cartesian",
    "plot_disturbance",
    "plot_error",
    "plot_overview",
    "plot_task_space",
    "plot_torques",
    "plot_tracking",
    "plot_workspace",
    "power_label",
    "tool_path",
    "warm_up",
]


#: Most points drawn per line of a time plot: 2 per bucket of :func:`envelope`, about
#: three per pixel of a 6-inch axis at the figures' 110 dpi.
MAX_POINTS = 2000

#: The figures' resolution [dots per inch].
DPI = 110

#: PNG compression (zlib level 1 of 9): files about 7 % larger than the default 6,
#: written in two thirds of the time.
_PNG = {"compress_level": 1}


def envelope(t: np.ndarray, y: np.ndarray, max_points: int = MAX_POINTS):
    """``(t, y)`` reduced to at most ``max_points`` samples that keep its extremes.

    The samples are cut into ``max_points // 2`` buckets of consecutive samples; each
    bucket keeps its lowest and its highest sample, in time order. A line drawn through
    them covers the same vertical extent at every pixel column as the full line (a
    one-sample spike stays), with the first and last samples kept. Returns the inputs
    unchanged when they are short enough.

    Args:
        t: Sample times [s], shape (K,).
        y: Values, shape (K,).
        max_points: Largest number of samples returned (at least 4).
    """
    k = len(t)
    if k <= max_points:
        return t, y
    buckets = max(max_points // 2 - 1, 1)  # 2 per bucket, and the first and last samples
    m = -(-k // buckets)  # samples per bucket; the last is padded with the last sample
    rows = np.pad(np.asarray(y), (0, m * buckets - k), mode="edge").reshape(buckets, m)
    start = np.arange(buckets) * m
    # argmin/argmax return a NaN's index in a bucket that holds one: the gap stays
    keep = np.concatenate([[0, k - 1], start + rows.argmin(axis=1), start + rows.argmax(axis=1)])
    keep = np.unique(np.minimum(keep, k - 1))
    return t[keep], y[keep]


_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def power_label(x: float, pos=None) -> str:
    """A log axis's tick label in plain text: ``10⁻³`` at a decade, ``2×10⁻³`` between.

    Matplotlib's default writes ``$10^{-3}$``, which goes through its mathtext parser
    (about a seventh of the Panda's error figure in a profile). Superscript digits of the
    figures' font give the same label without it.
    """
    if not x > 0 or not np.isfinite(x):
        return ""
    exponent = int(np.floor(np.log10(x) + 1e-9))
    mantissa = x / 10.0**exponent
    power = "10" + str(exponent).translate(_SUPERSCRIPT)
    return power if abs(mantissa - 1.0) < 1e-6 else f"{mantissa:.3g}×{power}"


def _log_y(ax) -> None:
    """A log y axis labelled in plain text (:func:`power_label`)."""
    ax.set_yscale("log")
    ax.yaxis.set_major_formatter(FuncFormatter(power_label))


def _line(ax, t, y, *args, **kwargs):
    """``ax.plot`` of ``y`` over ``t`` through its :func:`envelope`."""
    return ax.plot(*envelope(t, y), *args, **kwargs)


def _new_figure(figsize) -> Figure:
    """A figure on the Agg canvas (PNG, headless, the user's pyplot state untouched)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = Figure(figsize=figsize)
    FigureCanvasAgg(fig)
    return fig


def _save(fig, path) -> Path:
    """Write ``fig`` as a PNG to ``path`` (through ``<path>.part``, renamed when complete)."""
    path = Path(path)
    part = path.with_name(path.name + ".part")
    try:
        fig.savefig(part, format="png", dpi=DPI, pil_kwargs=_PNG)
        os.replace(part, path)
    finally:
        if part.exists():
            part.unlink()
    return path


def _rows(n: int, cols: int = 1, panels: _Panels | None = None):
    """A figure of ``n`` rows and ``cols`` columns of Axes sharing the time axis: new, or
    the one of that shape in ``panels``, cleared."""
    if panels is not None:
        return panels.take(n, cols)
    fig = _new_figure((6 * cols, 2.2 * n + 0.8))
    axes = fig.subplots(n, cols, sharex=True, squeeze=False)
    return fig, axes


class _Panels:
    """The per-joint figures of one run drawn on one :class:`~matplotlib.figure.Figure`
    per shape, one after the other (:func:`draw_all`).

    Making a row's Axes and, at its first drawing, its ticks is about half of a per-joint
    figure's time; a figure drawn on the Axes of the previous one pays for its lines,
    texts and pixels only. Between two figures the Axes are cleared of what a
    figure adds (lines, legend, limits, scale, title), so that each figure is the one a
    new Figure gives, pixel for pixel.
    """

    def __init__(self) -> None:
        self._made: dict[tuple[int, int], tuple] = {}

    def take(self, n: int, cols: int):
        made = self._made.get((n, cols))
        if made is None:
            made = self._made[(n, cols)] = _rows(n, cols)
            return made
        fig, axes = made
        fig.suptitle("")  # a figure without a title draws none
        for ax in axes.flat:
            for line in list(ax.lines):
                line.remove()
            if ax.get_legend() is not None:
                ax.get_legend().remove()
            ax.set_yscale("linear")  # its default ticks and labels, as a new Axes
            ax.set_ylabel("")
            ax.relim()  # no data: the next lines set the limits
            ax.set_autoscale_on(True)
        return made


def _wrap(title: str, fig) -> str:
    """``title`` broken into lines that fit the figure's width (about 11 characters per
    inch at the default title size), so that no title is cut at the figure's edges."""
    import textwrap

    return "\n".join(textwrap.wrap(title, width=max(20, int(9.5 * fig.get_figwidth()))))


#: Margins of the per-joint figures [in]: left (tick labels and the joint's label), right,
#: bottom (time axis), the gap between rows (shared time axis: no labels between) and
#: between columns (each column has its own labels), and one line of the title.
_MARGINS = {
    "left": 0.9,
    "right": 0.2,
    "bottom": 0.55,
    "row_gap": 0.25,
    "col_gap": 1.0,
    "top": 0.2,
    "title_line": 0.26,
}


def _fixed_layout(fig, rows: int, cols: int, title_lines: int) -> None:
    """Place the axes with :data:`_MARGINS` (what ``tight_layout`` finds for these figures,
    without the extra drawing pass it costs: half the figure's time)."""
    w, h = fig.get_size_inches()
    m = _MARGINS
    top = m["top"] + m["title_line"] * title_lines
    ax_h = (h - top - m["bottom"] - m["row_gap"] * (rows - 1)) / rows
    ax_w = (w - m["left"] - m["right"] - m["col_gap"] * (cols - 1)) / cols
    fig.subplots_adjust(
        left=m["left"] / w,
        right=1 - m["right"] / w,
        bottom=m["bottom"] / h,
        top=1 - top / h,
        hspace=m["row_gap"] / ax_h,
        wspace=m["col_gap"] / ax_w,
    )


def _finish(fig, axes, path, title):
    """Label the time axis, title and lay out ``fig``; write it to ``path`` and return the
    path, or return the figure itself when ``path`` is ``None`` (:mod:`~hmpc_pin.apps.plot`
    saves it)."""
    for ax in axes[-1]:
        ax.set_xlabel("time t [s]")
    lines = 0
    if title:
        wrapped = _wrap(title, fig)
        lines = wrapped.count("\n") + 1
        fig.suptitle(wrapped, y=1 - 0.1 / fig.get_figheight(), va="top")
    _fixed_layout(fig, len(axes), len(axes[0]), lines)
    return fig if path is None else _save(fig, path)


def _tracking(ax, result, i):
    _line(ax, result.t, result.q_ref[:, i], "k--", lw=1.2, label="reference r")
    _line(ax, result.t, result.q[:, i], "C0", lw=1.2, label="angle q")
    ax.set_ylabel(f"joint {i + 1} [{joint_units(result)[i][0]}]")
    _decorate(ax, i)


def _disturbance(ax, result, i):
    ff = result.extra.get("friction_feedforward")
    if not np.any(np.isfinite(result.d[:, i])):
        pass  # an arm does not report its disturbance (``realtime``, ``ros``): d̂ alone
    elif ff is None:
        _line(ax, result.t, result.d[:, i], "k", lw=1.2, label="true d")
    else:  # the observer estimates what the friction model fed forward leaves
        _line(ax, result.t, result.d[:, i] + ff[:, i], "k", lw=1.2, label="true d + τ_f")
    _line(ax, result.t, result.d_hat[:, i], "C3--", lw=1.2, label="NDO estimate d̂")
    ax.set_ylabel(f"joint {i + 1} [{joint_units(result)[i][2]}]")
    _decorate(ax, i)


def _decorate(ax, i: int) -> None:
    """The legend on the first row only (the same lines on every row: the figure's time
    goes into ticks and legends), four y ticks, a light grid."""
    if i == 0:
        ax.legend(loc="upper right", fontsize=8)
    ax.yaxis.set_major_locator(MaxNLocator(nbins=4))
    ax.grid(alpha=0.3)


def _per_joint(result, path, title, *drawers, panels: _Panels | None = None) -> Path:
    """One row per joint, one column per drawer ``drawer(ax, result, joint)``."""
    n = result.q.shape[1]
    fig, axes = _rows(n, len(drawers), panels)
    for i in range(n):
        for col, draw in enumerate(drawers):
            draw(axes[i, col], result, i)
    return _finish(fig, axes, path, title)


def plot_tracking(result, path, title: str = "") -> Path:
    """Reference vs joint angle, one row per joint (paper Figures 5, 7, 9)."""
    return _per_joint(result, path, title, _tracking)


def plot_disturbance(result, path, title: str = "") -> Path:
    """True vs NDO-estimated disturbance, one row per joint (paper Figures 4, 6, 8)."""
    return _per_joint(result, path, title, _disturbance)


def plot_overview(result, path, title: str = "") -> Path:
    """Both side by side: tracking (left) and disturbance estimate (right), one row per joint."""
    return _per_joint(result, path, title, _tracking, _disturbance)


def _overlay(results: dict, path, title, draw, decorate, panels=None) -> Path:
    """One row per joint; ``draw(ax, label, result, joint, color)`` for every run, then
    ``decorate(ax, joint)`` once per row."""
    n = next(iter(results.values())).q.shape[1]
    fig, axes = _rows(n, 1, panels)
    for i in range(n):
        ax = axes[i, 0]
        for k, (label, r) in enumerate(results.items()):
            draw(ax, label, r, i, f"C{k}")
        decorate(ax, i)
    return _finish(fig, axes, path, title)


def plot_error(results: dict, path, title: str = "") -> Path:
    """Tracking error |q − r| on a log scale, one row per joint, several runs overlaid.

    Args:
        results: Label → :class:`~hmpc_pin.sim.result.Result`, e.g.
            ``{"with NDO": r1, "without NDO": r2}``.
    """
    return _error(results, path, title)


def _error(results: dict, path, title: str, panels: _Panels | None = None) -> Path:

    def draw(ax, label, r, i, color):
        e = np.maximum(np.abs(r.q[:, i] - r.q_ref[:, i]), 1e-9)
        _log_y(ax)
        _line(ax, r.t, e, color, lw=1.0, label=label)

    unit = joint_units(next(iter(results.values())))

    def decorate(ax, i):
        ax.axhline(0.01, color="k", ls=":", lw=0.8, label=f"0.01 {unit[i][0]}")
        ax.set_ylabel(f"|e{i + 1}| [{unit[i][0]}]")
        ax.set_ylim(1e-7, None)
        ax.yaxis.set_minor_locator(NullLocator())  # a line per decade: 7+ decades stay
        if i == 0:  # the same lines on every row
            ax.legend(loc="upper right", fontsize=8)
        ax.grid(alpha=0.3)

    return _overlay(results, path, title, draw, decorate, panels)


def arm_points(robot, q) -> np.ndarray:
    """x–z positions of base, joints and tool at ``q`` by Pinocchio FK, shape (n+2, 2)."""
    import pinocchio as pin

    model, data = robot.model, robot.data
    pin.framesForwardKinematics(model, data, np.asarray(q, dtype=float))
    pts = [data.oMi[j].translation for j in range(1, model.njoints)]
    pts.insert(0, np.zeros(3))
    pts.append(data.oMf[model.getFrameId(robot.tool_frame)].translation)
    return np.array([[p[0], p[2]] for p in pts])


def tool_path(robot, q_traj: np.ndarray) -> np.ndarray:
    """Tool x–z position along a joint trajectory (K, n) → (K, 2)."""
    return np.array([arm_points(robot, q)[-1] for q in q_traj])


def _draw_arm(ax, robot, q, style, label=None):
    pts = arm_points(robot, q)
    ax.plot(pts[:, 0], pts[:, 1], style, lw=2.5, marker="o", ms=4, label=label)


def _finish_plane(fig, ax, path, title, legend_loc) -> Path:
    ax.set_xlabel("x [m]")
    ax.set_ylabel("z [m] (paper's y)")
    ax.set_aspect("equal")
    ax.grid(alpha=0.3)
    ax.legend(loc=legend_loc, fontsize=8)
    if title:
        ax.set_title(_wrap(title, fig))
    fig.tight_layout()
    return _save(fig, path)


def plot_workspace(robot, path, poses: dict, points: np.ndarray, title: str = "") -> Path:
    """Figure 3(b): tool positions reachable within the joint limits, arm drawn at ``poses``.

    Args:
        robot: The arm.
        poses: Label → joint configuration to draw, e.g. ``{"q = 0": np.zeros(3)}``.
        points: Reachable tool positions (m, 2) in the x–z plane.
    """
    fig = _new_figure((6.5, 6))
    ax = fig.subplots()
    ax.scatter(points[:, 0], points[:, 1], s=1, c="0.75", label="reachable tool positions")
    for k, (label, q) in enumerate(poses.items()):
        _draw_arm(ax, robot, q, f"C{k}-", label)
    return _finish_plane(fig, ax, path, title, "lower left")


def plot_cartesian(
    robot, result, path, start, goal, title: str = "", arms: int = 6, window=None
) -> Path:
    """Figure 10: the tool path in the x–z plane with start, goal and a few arm poses.

    Args:
        result: A :class:`~hmpc_pin.sim.result.Result` of the Cartesian experiment.
        start, goal: Tool (x, z) of the start and goal poses.
        arms: Number of arm poses drawn, evenly spaced in time over ``window``.
        window: (t0, t1) [s] of the motion; default the whole run.
    """
    fig = _new_figure((6.5, 6))
    ax = fig.subplots()
    ref = tool_path(robot, result.q_ref)
    act = tool_path(robot, result.q)
    t0, t1 = window if window is not None else (result.t[0], result.t[-1])
    for tk in np.linspace(t0, min(t1, result.t[-1]), arms):
        k = int(np.argmin(np.abs(result.t - tk)))
        _draw_arm(ax, robot, result.q[k], "-", None)
        ax.annotate(f"t={result.t[k]:.1f}s", arm_points(robot, result.q[k])[-1], fontsize=7)
    ax.plot(ref[:, 0], ref[:, 1], "k--", lw=1.2, label="reference tool path")
    ax.plot(act[:, 0], act[:, 1], "C3", lw=1.5, label="tool path")
    ax.plot(*start, "gs", ms=9, label=f"start ({start[0]:g}, {start[1]:g})")
    ax.plot(*goal, "r*", ms=13, label=f"goal ({goal[0]:g}, {goal[1]:g})")
    return _finish_plane(fig, ax, path, title, "lower right")


def plot_torques(results: dict, path, title: str = "", window=None) -> Path:
    """Torque τ per joint for several runs overlaid, optionally over a time ``window`` [s].

    Args:
        results: Label → :class:`~hmpc_pin.sim.result.Result`.
        window: ``(t0, t1)`` to zoom on (chattering is invisible over 10 s); ``None``: all.

    The y axis is symmetric-log (linear within ±1 N·m), so a chattering run of thousands
    of N·m and a smooth one of tens stay readable in one panel.
    """

    def draw(ax, label, r, i, color):
        sel = slice(None) if window is None else (r.t >= window[0]) & (r.t <= window[1])
        ax.step(r.t[sel], r.tau[sel, i], color, where="post", lw=1.0, label=label)

    unit = joint_units(next(iter(results.values())))

    def decorate(ax, i):
        ax.set_ylabel(f"τ{i + 1} [{unit[i][2]}] (symlog)")
        ax.set_yscale("symlog", linthresh=1.0)
        ax.legend(loc="upper right", fontsize=7)
        ax.grid(alpha=0.3)

    return _overlay(results, path, title, draw, decorate)


def plot_task_space(result, path, title: str = "", after: float = 1.0) -> Path:
    """Task-space figure of an end-effector task: the tool path and its target in 3-D,
    the position error :math:`\\|p - p^*\\|` [mm] and the orientation error
    :math:`2\\arccos|\\langle q^*, q\\rangle|` [mrad] over time (``after`` marked)."""
    from .metrics import quat_angle

    fig = _new_figure((11, 4.6))
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    ref, pos = result.ee_pos_ref, result.ee_pos
    ax3.plot(ref[:, 0], ref[:, 1], ref[:, 2], "k--", lw=1.2, label="target path")
    ax3.plot(pos[:, 0], pos[:, 1], pos[:, 2], "C0", lw=1.0, label="tool path")
    both = np.vstack([ref, pos])  # equal scales on the three axes: the true shape
    mid = (both.max(axis=0) + both.min(axis=0)) / 2
    half = max(float((both.max(axis=0) - both.min(axis=0)).max()) / 2 * 1.1, 1e-3)
    ax3.set_xlim(mid[0] - half, mid[0] + half)
    ax3.set_ylim(mid[1] - half, mid[1] + half)
    ax3.set_zlim(mid[2] - half, mid[2] + half)
    ax3.set_box_aspect((1, 1, 1))
    ax3.set_xlabel("x [m]")
    ax3.set_ylabel("y [m]")
    ax3.set_zlabel("z [m]")
    ax3.legend(loc="upper left", fontsize=8)
    ax_p = fig.add_subplot(2, 2, 2)
    ax_r = fig.add_subplot(2, 2, 4, sharex=ax_p)
    e = np.linalg.norm(pos - ref, axis=1)
    a = quat_angle(result.ee_quat_ref, result.ee_quat)
    _log_y(ax_p)
    _line(ax_p, result.t, np.maximum(e * 1e3, 1e-6), "C0", lw=1.0)
    ax_p.set_ylabel("position error [mm]")
    _log_y(ax_r)
    _line(ax_r, result.t, np.maximum(a * 1e3, 1e-6), "C3", lw=1.0)
    ax_r.set_ylabel("orientation error [mrad]")
    ax_r.set_xlabel("time t [s]")
    for ax in (ax_p, ax_r):
        ax.axvline(after, color="0.5", lw=0.8, ls=":")
        ax.grid(alpha=0.3, which="both")
    frame = result.meta.get("task", {}).get("frame", "tool")
    fig.suptitle(f"{title} — frame {frame}" if title else f"frame {frame}")
    fig.tight_layout()
    return fig if path is None else _save(fig, path)


#: The figures of a run by name (:func:`draw`): tracking, disturbance and the error
#: (one run, labelled), and the task-space figure of an end-effector task.
KINDS = ("tracking", "disturbance", "error", "task_space")


def draw(kind: str, result, path, title: str = "", label: str = "") -> Path:
    """Draw the figure ``kind`` (one of :data:`KINDS`) of ``result`` to ``path``.

    Args:
        label: The run's label in the error figure's legend (e.g. ``"with NDO"``).
    """
    return _draw(kind, result, path, title, label, None)


def _draw(kind: str, result, path, title: str, label: str, panels: _Panels | None) -> Path:
    if kind == "tracking":
        return _per_joint(result, path, title, _tracking, panels=panels)
    if kind == "disturbance":
        return _per_joint(result, path, title, _disturbance, panels=panels)
    if kind == "error":
        return _error({label: result}, path, title, panels)
    if kind == "task_space":
        return plot_task_space(result, path, title)
    raise ConfigError("figure", f"expected one of {KINDS}, got {kind!r}")


def draw_all(figures, result) -> Iterator[tuple[Path, Exception | None]]:
    """Draw several figures of ``result``, one after the other, each as :func:`draw` does.

    The per-joint figures (tracking, disturbance, error) of one run have the same rows:
    they are drawn on one figure in turn, which saves making their Axes and ticks again
    (the Panda's disturbance figure: 0.17 s of CPU after the tracking figure, 0.27 s
    alone).

    Args:
        figures: ``(kind, path, title, label)`` per figure (as :func:`draw` takes them).

    Yields:
        ``(path, None)`` per figure written, ``(path, exception)`` per figure that could
        not be drawn (the next ones are drawn on a new figure).
    """
    panels = _Panels()
    for kind, path, title, label in figures:
        try:
            _draw(kind, result, path, title, label, panels)
        except Exception as exc:  # the caller reports it; nothing half drawn is reused
            panels = _Panels()
            yield Path(path), exc
        else:
            yield Path(path), None


def warm_up() -> None:
    """Draw a small figure with text (no file): the font is loaded and matplotlib's caches
    are filled, so that the next figure pays for its own drawing only."""
    fig = _new_figure((2, 1.5))
    ax = fig.subplots()
    ax.plot([0.0, 1.0], [0.0, 1.0], "k--", label="d̂ τ")
    ax.legend(fontsize=8)
    ax.set_xlabel("time t [s]")
    fig.suptitle("warm")
    fig.canvas.draw()
