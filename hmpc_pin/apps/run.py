"""Run one experiment and write its files: the ``run`` command's work, shared by
``report`` (so that ``report`` does not import the command line)."""

from __future__ import annotations

import contextlib
import csv
import sys
from pathlib import Path
from typing import Any

import numpy as np

from ..exceptions import RunInterrupted, SimulationError
from ..experiment.build import Experiment
from ..experiment.config import ExperimentConfig
from ..sim.result import RESULT_ARRAYS, TASK_ARRAYS, Result

__all__ = ["PROGRESS_DELAY", "Progress", "draw_figures", "live_view", "run_one", "write_csv"]

#: A run's progress bar shows once the run has taken this long [s] (``progress=None``).
PROGRESS_DELAY = 2.0


class Progress:
    """A run's progress bar on stderr (tqdm), in control periods: ``progress(k, K)`` of
    :meth:`~hmpc_pin.experiment.build.Experiment.run` after each chunk of periods.

    Args:
        name: The bar's label.
        show: ``None``: on a terminal only, once the run has taken :data:`PROGRESS_DELAY`
            (a short run shows none); ``True``: from the start, wherever stderr goes;
            ``False``: never.

    The bar reads the count of periods only: the run is the same, bit for bit, with or
    without it.
    """

    def __init__(self, name: str, show: bool | None = None):
        self.name = name
        self.show = sys.stderr.isatty() if show is None else bool(show)
        self.delay = PROGRESS_DELAY if show is None else 0.0
        self._bar: Any = None

    def __call__(self, k: int, total: int) -> None:
        if not self.show:
            return
        if self._bar is None:
            from tqdm import tqdm

            self._bar = tqdm(
                total=total, desc=self.name, unit="step", delay=self.delay, file=sys.stderr,
                leave=False, dynamic_ncols=True,
            )  # fmt: skip
        self._bar.update(k - self._bar.n)

    def close(self) -> None:
        """Remove the bar (the table printed next starts on a clean line)."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None


def write_csv(result: Result, path: Path) -> Path:
    """Write the trajectories as CSV: ``t`` then ``<array>_<joint>`` for every array and joint.

    Arrays (in order): q, dq, tau (commanded), d, d_hat, q_ref, dq_ref, tau_applied (what
    the plant applied: tau clipped to the effort limit), in rad, rad/s and N·m; the
    columns of a prismatic joint are in m, m/s and N and say so: ``q_<joint> [m]``. Then the
    result's ``extra`` arrays by name (generalized forces, e.g. ``contact_force`` of a MuJoCo
    run with an obstacle); for a pose task then ``ee_pos_{x,y,z}``, ``ee_pos_ref_{x,y,z}``,
    ``ee_quat_{x,y,z,w}``, ``ee_quat_ref_{x,y,z,w}``.
    """
    from .metrics import UNITS, joint_units

    names = result.joint_names or tuple(f"joint{i + 1}" for i in range(result.q.shape[1]))
    which = {"q": 0, "q_ref": 0, "dq": 1, "dq_ref": 1, "tau": 2, "d": 2, "d_hat": 2}
    units = joint_units(result)
    extra = sorted(result.extra)
    header = ["t"] + [
        f"{a}_{j}" + ("" if u == UNITS["revolute"] else f" [{u[which.get(a, 2)]}]")
        for a in (*RESULT_ARRAYS[1:], *extra)
        for j, u in zip(names, units, strict=True)
    ]
    table = np.column_stack(
        [result.t]
        + [getattr(result, a) for a in RESULT_ARRAYS[1:]]
        + [result.extra[a] for a in extra]
    )
    if result.ee_pos is not None:  # pose task: the frame's position [m] and quaternion
        header += [
            f"{a}_{c}"
            for a, comps in (
                ("ee_pos", "xyz"),
                ("ee_pos_ref", "xyz"),
                ("ee_quat", "xyzw"),
                ("ee_quat_ref", "xyzw"),
            )
            for c in comps
        ]
        table = np.column_stack([table, *(getattr(result, a) for a in TASK_ARRAYS)])
    with open(path, "w", newline="", encoding="utf-8") as f:
        csv.writer(f).writerow(header)
        # the rows as csv.writer writes floats (repr, "\r\n"), 1.6x faster than writerows
        f.writelines(",".join(map(repr, row)) + "\r\n" for row in table.tolist())
    return path


def live_view(robot, speed: float, obstacle: dict | None = None):
    """A :class:`~hmpc_pin.apps.viz.LiveView` (with the MuJoCo scene's ``obstacle``, if any), or
    ``None`` with a warning if Meshcat cannot run."""
    from .viz import LiveView, VizError

    try:
        view = LiveView(robot, speed=speed, obstacle=obstacle)
    except VizError as exc:
        print(f"warning: no live view: {exc}; the run goes on and is saved", file=sys.stderr)
        return None
    print(f"Meshcat live view: open {view.url} (speed {speed:g}x)")
    return view


def _save_data(result: Result, out: Path, stem: str) -> list[Path]:
    """Write ``<stem>.npz`` and ``<stem>.csv``; a second Ctrl-C while writing leaves no
    half-written ``.npz`` (it is written to a ``.part`` file and renamed)."""
    return [result.save(out / f"{stem}.npz"), write_csv(result, out / f"{stem}.csv")]


def run_one(
    config: ExperimentConfig,
    out: Path,
    stem: str | None = None,
    viz: float | None = None,
    open_view=None,
    experiment: Experiment | None = None,
    figures: bool = True,
    progress: bool | None = False,
):
    """Run ``config``; write ``<stem>.npz``, ``<stem>.csv`` and figures to ``out``.

    Args:
        viz: Open a live view at this speed for the run (closed at its end).
        open_view: ``open_view(experiment)`` returns a live view (or ``None``) that the
            caller owns: it is animated and left open.
        experiment: The experiment of ``config`` if already built (so that bad input is
            found before the output directory is created).
        figures: Draw the figures (:func:`draw_figures`); ``False``: the caller draws
            them later (the command line prints its table first).
        progress: A progress bar on stderr (:class:`Progress`: ``None`` on a terminal
            once the run takes more than :data:`PROGRESS_DELAY`, ``True`` always,
            ``False`` never).

    Returns:
        (experiment, result, files, failure message or None).

    Raises:
        RunInterrupted: Ctrl-C; the data up to that step are written first
            (``exc.files``), no figure.
    """
    stem = stem or config.name
    if experiment is None:
        experiment = Experiment.from_config(config)
    own_view = open_view is None and viz is not None
    if open_view is None and viz is not None:  # (own_view, spelled out for the type)
        view = live_view(experiment.robot, viz, experiment.obstacle)
    else:
        view = open_view(experiment) if open_view is not None else None
    target = getattr(experiment.reference, "path", None)  # a pose task: draw its target path
    if view is not None and target is not None:
        times = np.linspace(0.0, config.simulation.duration, 3001)
        view.draw_path("target_path", target.poses(times)[0])
    failure = None
    bar = Progress(config.name, progress)
    try:
        result = experiment.run(on_step=view, progress=bar if bar.show else None)
    except SimulationError as exc:
        if exc.result is None:
            raise
        result, failure = exc.result, str(exc)
    except RunInterrupted as exc:  # Ctrl-C: keep the data, skip the figures
        exc.where = f"{exc.where} in {config.name}"
        exc.files = _save_data(exc.result, out, stem)
        raise
    finally:
        bar.close()
        if own_view and view is not None:
            view.close()
    files = _save_data(result, out, stem)
    if figures:
        with after_the_run(config.name, files):
            draw_figures(config, result, out, stem, files)
    return experiment, result, files, failure


def draw_figures(
    config: ExperimentConfig,
    result: Result,
    out: Path,
    stem: str,
    files: list[Path],
    error_label: str | None = None,
) -> list[Path]:
    """Draw the run's figures to ``out`` and append each to ``files`` as it is written (a
    Ctrl-C keeps the list of what exists): ``<stem>_tracking.png``,
    ``<stem>_disturbance.png``, for an end-effector task ``<stem>_task_space.png``, and
    with ``error_label`` ``<stem>_error.png`` (the run's |q − r| so labelled); none for a
    run of one sample.

    When the command line started its figure process
    (:mod:`~hmpc_pin.apps.figure_worker`) and ``files`` holds the run's ``.npz``, that
    process draws them, all at once; otherwise they are drawn here, one after the other
    (:func:`~hmpc_pin.apps.plots.draw_all`), matplotlib imported on first use. Either way
    the figures are the same."""
    sys.stdout.flush()  # what was printed (the command's table) shows while they are drawn
    if len(result.t) <= 1:
        return files
    from . import figure_worker

    title = config.description or config.name
    jobs = [
        ("tracking", out / f"{stem}_tracking.png", title, ""),
        ("disturbance", out / f"{stem}_disturbance.png", title, ""),
    ]
    if result.ee_pos is not None:
        jobs.append(("task_space", out / f"{stem}_task_space.png", title, ""))
    if error_label is not None:
        jobs.append(("error", out / f"{stem}_error.png", config.description, error_label))
    npz = next((f for f in files if f.suffix == ".npz"), None)
    done: list[Path] = []
    if npz is not None:
        try:
            figure_worker.draw(npz, jobs, done)
        except BaseException:  # a Ctrl-C: what was written is listed
            files.extend(done)
            raise
    missing = [job for job in jobs if job[1] not in done]  # no figure process, or it failed
    if missing:
        from . import plots

        drawn = plots.draw_all(missing, result)  # one after the other, each as plots.draw
    for _, path, _, _ in jobs:
        if path not in done:
            _, exc = next(drawn)
            if exc is not None:
                raise exc
        files.append(path)
    return files


@contextlib.contextmanager
def after_the_run(name: str, files: list):
    """A Ctrl-C while the figures (or anything after the run) are drawn says where it
    stopped and which files were already written (``exc.where``, ``exc.files``)."""
    try:
        yield
    except KeyboardInterrupt as exc:
        if not getattr(exc, "where", ""):
            exc.where = f"drawing the figures of {name}, after a complete run"  # type: ignore[attr-defined]
        if not getattr(exc, "files", ()):
            exc.files = tuple(files)  # type: ignore[attr-defined]
        raise
