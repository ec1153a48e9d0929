"""The command line's figures, drawn beside the run in a process of their own.

Importing matplotlib and drawing a run's three per-joint figures costs a short command
several times its run. ``hmpc-pin run`` therefore starts this module as a process
(``python -m hmpc_pin.apps.figure_worker``, :func:`start`) as soon as it knows it will
draw figures. While the command imports the library, builds the experiment and runs it,
the process imports matplotlib and draws a small figure (fonts and caches loaded,
:func:`~hmpc_pin.apps.plots.warm_up`). Once the command has written the run's ``.npz``
and printed its table, it sends one job (:func:`draw`): the process reads the arrays from
that file and deals the figures in turn to one process per core it may use (itself and
children of its own: ``fork``, matplotlib stays imported); each draws its share one after
the other on one figure (:func:`hmpc_pin.apps.plots.draw_all`: the Axes and ticks made
once), each PNG written to ``<name>.part`` and renamed. The figures are the same, pixel for
pixel, as drawn in the command's process (:func:`hmpc_pin.apps.plots.draw`). This shortens
the command where a core is free; the CPU time stays that of matplotlib's import and
drawing (plus the process's own start, about 0.15 s), so a machine busy with other work
sees little change.

Only the command line does this (``hmpc-pin`` or ``python -m hmpc_pin``); the library
and ``main()`` called from Python draw in their own process. Nothing outlives the command:
the process and its children are in a process group of their own (a Ctrl-C in the
terminal reaches the command only, which then ends them, with what they had half
written), they end with the command on Linux however it ends (the parent-death signal),
and on other POSIX systems when its pipe closes (on Windows the command draws its figures
itself). A figure the process could not draw is drawn by the command itself, which then
reports what went wrong as usual.

This module imports only the standard library at its top (the command imports it before
the library).
"""

from __future__ import annotations

import atexit
import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

__all__ = ["draw", "start", "stop"]

#: The process started by :func:`start` and not yet given its job.
_worker: subprocess.Popen[bytes] | None = None


def start() -> bool:
    """Start the figure process if this process is the command line; return whether it
    runs (it is ended at the interpreter's exit if no job took it, :func:`stop`)."""
    global _worker
    from .. import _startup

    if _worker is not None or os.name != "posix" or not _startup.is_command_line():
        return _worker is not None  # elsewhere (Windows): no process groups, no fork
    try:
        _worker = subprocess.Popen(
            [sys.executable, "-m", __name__, str(os.getpid())],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            process_group=0,  # a Ctrl-C in the terminal reaches the command only
        )
    except OSError:  # no process: the command draws its figures itself
        return False
    atexit.register(stop)
    return True


def stop() -> None:
    """End the figure process and its children, if any, at once."""
    global _worker
    worker, _worker = _worker, None
    if worker is None:
        return
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(worker.pid, signal.SIGKILL)
    for pipe in (worker.stdin, worker.stdout):
        with contextlib.suppress(OSError):
            if pipe is not None:
                pipe.close()
    worker.wait()


def draw(npz: Path, figures: list[tuple[str, Path, str, str]], done: list[Path]) -> bool:
    """Have the figure process draw ``figures`` from the run saved in ``npz``.

    Args:
        npz: The run's ``.npz`` (:meth:`~hmpc_pin.sim.result.Result.save`).
        figures: ``(kind, path, title, label)`` per figure (:func:`hmpc_pin.apps.plots.draw`).
        done: Each path written is appended as it is reported (a Ctrl-C keeps the list of
            what exists).

    Returns:
        ``False`` when no figure process runs (nothing drawn); ``True`` when the job ran,
        every figure in ``done`` written (a figure missing from ``done`` was not: the
        caller draws it).
    """
    worker = _worker
    if worker is None or worker.stdin is None or worker.stdout is None:
        return False
    started = time.time()
    try:  # :func:`stop` ends the process however this ends
        job = {"npz": str(npz), "figures": [[k, str(p), t, lab] for k, p, t, lab in figures]}
        try:
            worker.stdin.write((json.dumps(job) + "\n").encode())
            worker.stdin.close()
        except OSError:  # the process is gone
            return True
        for _ in figures:  # one line per figure; none more once the process is gone
            line = worker.stdout.readline()
            if not line:
                break
            reply = json.loads(line)
            if reply.get("error") is None:
                done.append(Path(reply["path"]))
        return True
    finally:
        stop()
        for _, path, _, _ in figures:
            Path(str(path) + ".part").unlink(missing_ok=True)  # half written by a child
            # a figure renamed into place (complete) by now, its line not read yet; the
            # file clock's tick is a few milliseconds behind ``time.time()``
            path = Path(path)
            with contextlib.suppress(OSError):
                if path not in done and path.stat().st_mtime >= started - 0.05:
                    done.append(path)


# --- the figure process ---------------------------------------------------------------


def _die_with(parent: int) -> None:
    """End this process when ``parent`` ends (Linux: the parent-death signal)."""
    if sys.platform.startswith("linux"):
        import ctypes

        with contextlib.suppress(OSError, AttributeError):
            ctypes.CDLL(None).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    if os.getppid() != parent:  # it ended before the signal was set
        os._exit(0)


class _Run:
    """The arrays of a saved run that the figures draw (read without importing the
    library: :class:`~hmpc_pin.sim.result.Result` needs Pinocchio)."""

    def __init__(self, npz: str):
        import numpy as np

        with np.load(npz, allow_pickle=False) as f:
            arrays = {k: f[k] for k in f.files}
        self.meta = json.loads(str(arrays.pop("meta")))
        self.extra = {k[6:]: arrays.pop(k) for k in list(arrays) if k.startswith("extra_")}
        self.joint_names = tuple(str(s) for s in arrays.pop("joint_names"))
        self.ee_pos = self.ee_pos_ref = self.ee_quat = self.ee_quat_ref = None
        self.__dict__.update(arrays)

    @property
    def error(self):
        return self.q - self.q_ref


def _reply(path: str, error: str | None) -> None:
    """One line to the command (a single write: lines of children never interleave)."""
    os.write(1, (json.dumps({"path": path, "error": error}) + "\n").encode())


def _draw_some(run: _Run, figures: list) -> int:
    """Draw ``figures`` one after the other (:func:`hmpc_pin.apps.plots.draw_all`), one
    line to the command per figure; the number that failed (the command draws them)."""
    from . import plots

    failed = 0
    for path, exc in plots.draw_all(figures, run):
        failed += exc is not None
        _reply(str(path), None if exc is None else f"{type(exc).__name__}: {exc}"[:2000])
    return failed


def _cores() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def _groups(figures: list, cores: int) -> list[list]:
    """``figures`` dealt to at most ``cores`` groups in turn (one process each)."""
    k = max(1, min(cores, len(figures)))
    return [figures[i::k] for i in range(k)]


def _serve(parent: int) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _die_with(parent)
    from . import plots

    plots.warm_up()
    line = sys.stdin.buffer.readline()
    if not line:  # the command ended, or needs no figure
        return
    job = json.loads(line)
    run = _Run(job["npz"])
    groups = _groups(job["figures"], _cores())
    me = os.getpid()
    children = []
    for group in groups[1:]:  # the first group is drawn here, beside the others
        pid = os.fork()
        if pid == 0:
            code = 1
            try:
                _die_with(me)
                code = _draw_some(run, group)
            finally:
                os._exit(code)
        children.append(pid)
    _draw_some(run, groups[0])
    for pid in children:
        os.waitpid(pid, 0)
    os._exit(0)  # the job is done: no clean-up of matplotlib's modules to wait for


if __name__ == "__main__":
    _serve(int(sys.argv[1]))
