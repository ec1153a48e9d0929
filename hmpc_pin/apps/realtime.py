"""``hmpc-pin realtime``: the experiment's controller at a fixed rate against its plant
running in a separate process in wall-clock time (:mod:`hmpc_pin.realtime`).

Writes ``<stem>_realtime.npz`` (the trajectories at the controller steps, latency
statistics and the stop record in ``meta``; ``complete = False`` after a safe stop),
``<stem>_realtime_timing.npz`` (every cycle's wake-up, latency, compute time, misses)
and ``<stem>_realtime.json`` (the statistics and tracking metrics).
"""

from __future__ import annotations

import functools
import json
import math
from dataclasses import replace
from pathlib import Path

from ..experiment.build import Experiment, make_arm_plant
from ..experiment.config import ExperimentConfig
from ..experiment.inner_law import close_law, inner_law_controller, inner_law_summary
from ..experiment.realtime import realtime_parts
from ..realtime.loop import RealtimeLoop, RealtimeRun, fifo_priority
from ..realtime.pacing import cpu_affinity
from ..realtime.process_arm import ProcessArm, start_child
from .metrics import compute_metrics

__all__ = ["ArmView", "StatusLine", "run_realtime", "with_realtime"]

#: Seconds between two status lines of a running loop.
STATUS_EVERY = 5.0


def with_realtime(
    config: ExperimentConfig,
    rate=None,
    gc=None,
    priority=None,
    spin=None,
    watchdog=None,
    max_misses=None,
    inner_law=None,
) -> ExperimentConfig:
    """``config`` with ``[realtime]`` ``rate``, ``gc``, ``priority``, ``spin``,
    ``watchdog``, ``max_misses``, ``inner_law`` replaced (flags; ``None``: kept). The
    values are checked as the config file's are
    (:class:`~hmpc_pin.experiment.config.RealtimeConfig`).

    Raises:
        ConfigError: A value ``[realtime]`` refuses, named by its key.
    """
    rc = config.realtime
    pairs = (
        ("rate", rate),
        ("gc", gc),
        ("priority", priority),
        ("spin", spin),
        ("watchdog", watchdog),
        ("max_misses", max_misses),
        ("inner_law", inner_law),
    )
    changes = {k: v for k, v in pairs if v is not None}
    return replace(config, realtime=replace(rc, **changes)) if changes else config


def _positive_seconds(text: str) -> float:
    """``--watchdog``'s value: a finite time [s] > 0 (argparse exits 2 otherwise)."""
    import argparse

    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a time [s] > 0, got {text!r}")
    return value


def spin_value(text: str) -> float | str:
    """``--spin``'s value: ``auto`` or a time [s] (argparse exits 2 otherwise; the config
    checks its range)."""
    import argparse

    if text == "auto":
        return text
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected auto or a time [s], got {text!r}") from None


def priority_value(text: str) -> int | str:
    """``--priority``'s value: ``auto`` or a whole number (argparse exits 2 otherwise; the
    range is checked with the config's)."""
    import argparse

    if text == "auto":
        return text
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected auto or a whole number 0-99, got {text!r}"
        ) from None


def _positive_count(text: str) -> int:
    """``--max-misses``' value: a whole number >= 1 (argparse exits 2 otherwise)."""
    import argparse

    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text!r}")
    return value


def add_stop_options(parser) -> None:
    """``--watchdog`` and ``--max-misses``: the two safe stops a loaded machine trips,
    set for one run without editing the config (a packaged config has no copy to edit)."""
    parser.add_argument(
        "--watchdog",
        type=_positive_seconds,
        metavar="S",
        help="stop when no new state arrives for S seconds (overrides realtime.watchdog)",
    )
    parser.add_argument(
        "--max-misses",
        type=_positive_count,
        metavar="K",
        help="stop after K consecutive missed deadlines (overrides realtime.max_misses)",
    )


def format_status(p: dict, duration: float) -> str:
    """One status line from :meth:`~hmpc_pin.realtime.loop.RealtimeLoop.progress`."""
    worst = "-" if math.isnan(p["worst_us"]) else f"{p['worst_us']:.0f} us"
    error = "-" if math.isnan(p["error"]) else f"{p['error']:.2e} rad"
    return (
        f"t={p['t']:.1f} s of {duration:g} s: {p['cycles']} cycles, {p['misses']} missed "
        f"(longest run {p['longest']}), worst latency {worst} since the last line, "
        f"max |q - q_ref| {error}"
    )


class StatusLine:
    """A status line every ``every`` seconds while a loop runs, printed by a thread of
    its own from the loop's records (:meth:`~hmpc_pin.realtime.loop.RealtimeLoop.progress`):
    nothing is printed in a cycle.

    Args:
        loop: The :class:`~hmpc_pin.realtime.loop.RealtimeLoop`, started after this.
        duration: The run's length [s] (in the line).
        every: Seconds between lines.
        file: Where to print (default: stderr).
    """

    def __init__(self, loop: RealtimeLoop, duration: float, every: float = STATUS_EVERY, file=None):
        import sys
        import threading

        self.loop, self.duration, self.every = loop, duration, every
        self.file = sys.stderr if file is None else file
        self.lines = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._work, name="status_line", daemon=True)
        self._thread.start()

    def _work(self) -> None:
        while not self._stop.wait(self.every):
            p = self.loop.progress()
            if p is not None:
                print(format_status(p, self.duration), file=self.file, flush=True)
                self.lines += 1

    def close(self) -> None:
        """Stop printing (idempotent)."""
        self._stop.set()
        self._thread.join(timeout=1.0)


def _finite(x):
    """JSON-safe: NaN → None."""
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_finite(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def tracking_summary(result, after: float = 1.0) -> dict:
    """RMS and max |q − r| per joint after ``after`` [s] (the metrics of ``run``)."""
    if len(result.t) < 2 or result.t[-1] < after:
        return {}
    m = compute_metrics(result, after=after)
    return {"after": after, "rms_error": m.rms_error.tolist(), "max_error": m.max_error.tolist()}


def run_realtime(
    config: ExperimentConfig,
    out: Path,
    stem: str | None = None,
    viz=None,
    experiment: Experiment | None = None,
    ready=None,
):
    """Run ``config`` in real time against an arm process; write the files to ``out``.

    Args:
        config: The experiment (``[realtime]`` for rate and safety).
        out: Output directory (exists, writable).
        stem: File stem (default: the config's name).
        viz: ``None``, or a callable ``viz(arm, experiment)`` started beside the loop and
            returning an object with ``close()``.
        experiment: ``config`` already built (default: built here).
        ready: ``None``, or a callable ``ready()`` called once the arm process runs, just
            before the first cycle (the command line prints a line there).

    Returns:
        ``(run, files)``: the :class:`~hmpc_pin.realtime.loop.RealtimeRun` and the files.
    """
    stem = (stem or config.name) + "_realtime"
    experiment = Experiment.from_config(config) if experiment is None else experiment
    loop_settings, safety, safe = realtime_parts(experiment)
    with fifo_priority(config.realtime.priority) as priority:  # checked before the arm starts
        pass
    # the inner law of [realtime] inner_law (a threaded law's planner runs from here)
    ctrl = inner_law_controller(
        experiment, loop_settings.period, "realtime", experiment.effort_limit
    )
    try:
        parts = (loop_settings, safety, safe)
        run = _run_arm(config, experiment, ctrl, parts, priority, viz, ready)
    finally:
        close_law(ctrl)  # the planner thread joined on every way out
    return run, save_run(run, out, stem, "arm")


def _run_arm(config, experiment, ctrl, parts, priority, viz, ready) -> RealtimeRun:
    """:func:`run_realtime`'s run against the arm process (the caller closes the law)."""
    loop_settings, safety, safe = parts
    arm = ProcessArm(
        functools.partial(make_arm_plant, experiment.config),
        experiment.q0,
        experiment.dq0,
        effort_limit=experiment.effort_limit,
        priority=priority,
    )
    view = None
    try:
        if viz is not None:
            view = viz(arm, experiment)
        loop = RealtimeLoop(
            arm,
            ctrl,
            experiment.reference,
            safe,
            loop_settings,
            safety,
            joint_names=tuple(experiment.robot.joint_names),
            meta=experiment.meta(),
        )
        if ready is not None:
            ready()
        status = StatusLine(loop, loop_settings.duration)
        try:
            with fifo_priority(priority), cpu_affinity(config.realtime.cpus):
                run = loop.run(experiment.q0, experiment.dq0)
        finally:
            status.close()
        run.result.meta["arm"] = arm.counters
        run.stats["priority"] = priority
        run.stats["inner_law"] = inner_law_summary(ctrl, loop_settings.period)
        run.result.meta["engine"] = config.plant.engine
    finally:
        if view is not None:
            view.close()
        arm.close()
    return run


def save_run(run: RealtimeRun, out: Path, stem: str, meta_key: str) -> list[Path]:
    """Write a real-time run: ``<stem>.npz`` (the result), ``<stem>_timing.npz`` (every
    cycle) and ``<stem>.json`` (statistics, stop record, ``run.result.meta[meta_key]``,
    tracking metrics; NaN as null).

    Returns:
        The three files written.
    """
    files = [run.result.save(out / f"{stem}.npz"), run.save_timing(out / f"{stem}_timing.npz")]
    summary = {
        "realtime": run.stats,
        "stop": run.stop,
        meta_key: run.result.meta[meta_key],
        "tracking": tracking_summary(run.result),
    }
    path = out / f"{stem}.json"
    path.write_text(json.dumps(_finite(summary), indent=2, sort_keys=True) + "\n")
    files.append(path)
    return files


def format_tracking(run: RealtimeRun) -> str:
    """RMS and max tracking error per joint, one line each."""
    tr = tracking_summary(run.result)
    if not tr:
        return "tracking: run shorter than 1 s, no metrics"
    names = run.result.joint_names or [f"joint{i + 1}" for i in range(len(tr["rms_error"]))]
    w = max(10, *(len(x) for x in names))
    lines = [f"{'joint':<{w}} {'RMS e (t>=1s) [rad]':>20} {'max |e| [rad]':>14}"]
    for name, rms, mx in zip(names, tr["rms_error"], tr["max_error"], strict=True):
        lines.append(f"{name:<{w}} {rms:>20.3e} {mx:>14.3e}")
    return "\n".join(lines)


def _view_main(shm_name, n, robot_config, reference, fps, conn, stop) -> None:  # pragma: no cover
    """The viewer process: show the arm's published state (and the reference) in Meshcat."""
    import signal
    import time

    from ..experiment.build import load_robot_config
    from ..realtime.process_arm import StateReader
    from .viz import ARM, GHOST, LiveView, VizError

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})  # blocked by start_child
    try:
        view = LiveView(load_robot_config(robot_config), speed=math.inf)
    except VizError as exc:
        conn.send(("error", str(exc)))
        return
    conn.send(("url", view.url))
    reader = StateReader(shm_name, n)
    try:
        while not stop.is_set():
            stamp, q, _ = reader.read()
            view.show(ARM, q)
            if GHOST in view.roots:
                view.show(GHOST, reference.sample(stamp)[0])
            time.sleep(1.0 / fps)
    finally:
        reader.close()
        view.close()


class ArmView:
    """A live Meshcat view of an arm process, drawn by a third process that reads the
    arm's shared memory: the control loop does no drawing.

    Args:
        arm: The :class:`~hmpc_pin.realtime.process_arm.ProcessArm`.
        experiment: Its experiment (robot config for the meshes, reference for the ghost).
        fps: Display rate [1/s].

    Attributes:
        url: The Meshcat URL (``None`` when Meshcat could not start: a warning is printed
            and the run goes on).
    """

    def __init__(self, arm: ProcessArm, experiment: Experiment, fps: float = 30.0):
        import multiprocessing as mp
        import sys

        ctx = mp.get_context("spawn")
        self._stop = ctx.Event()
        recv, send = ctx.Pipe(duplex=False)
        self._proc = ctx.Process(
            target=_view_main,
            args=(
                arm.shm_name,
                arm.nq,
                experiment.config.robot,
                experiment.reference,
                fps,
                send,
                self._stop,
            ),
            name="hmpc-pin-view",
            daemon=True,
        )
        start_child(self._proc)
        send.close()
        self.url = None
        if recv.poll(120.0):
            kind, text = recv.recv()
            if kind == "url":
                self.url = text
                print(f"Meshcat live view: open {text}")
            else:
                print(
                    f"warning: no live view: {text}; the run goes on and is saved", file=sys.stderr
                )
        recv.close()

    def close(self) -> None:
        """Stop the viewer process (and its Meshcat server)."""
        self._stop.set()
        self._proc.join(timeout=10.0)
        if self._proc.is_alive():
            self._proc.terminate()
            self._proc.join(timeout=5.0)
