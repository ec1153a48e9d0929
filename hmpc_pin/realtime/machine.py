"""What else on the machine delays a real-time loop: other processes' real-time threads
(looked at once before a run starts) and the host's steal time (counted over a run).

A thread of another process under ``SCHED_FIFO``/``SCHED_RR`` takes a core whenever it
runs: one at or above the loop's priority is never preempted by it, and one below it
still preempts the loop's arm process (one level below the loop) and every normal thread
the run needs (the middleware's). Two real-time loops on a 2-core machine stalled each
other by about 0.1 s, enough to stop one on its consecutive misses (the real-time
tutorial, "Scheduling").

:func:`rival_warnings` words each process found as one line naming it and what to do;
``hmpc-pin realtime`` and ``hmpc-pin franka`` issue them as
:class:`~hmpc_pin.exceptions.RealtimeWarning` before the motion and go on. Nothing on the
machine is changed.

:func:`steal_time` is the time the hypervisor did not run this (virtual) machine's CPUs
while they had work: the real-time loop records it over each run (``stats["host_steal_s"]``,
printed when not zero), so that late cycles the host caused can be told from the loop's
own. Linux only (elsewhere nothing is found, and the steal time is 0).
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

__all__ = ["RealtimeRival", "realtime_rivals", "rival_warnings", "steal_time"]

#: ``/proc/<pid>/stat``'s ``flags``: a kernel thread (``PF_KTHREAD``).
PF_KTHREAD = 0x00200000
#: Scheduling policies by their number in ``/proc/<pid>/stat`` (real-time ones only).
REALTIME_POLICIES = {1: "SCHED_FIFO", 2: "SCHED_RR"}


@dataclass(frozen=True)
class RealtimeRival:
    """A thread of another process under a real-time policy.

    Attributes:
        pid: Its process. tid: The thread. name: The process's name (``comm``).
        policy: ``"SCHED_FIFO"`` or ``"SCHED_RR"``. priority: Its real-time priority 1–99.
    """

    pid: int
    tid: int
    name: str
    policy: str
    priority: int


def _stat_fields(path: Path) -> tuple[str, list[str]] | None:
    """``(comm, fields after comm)`` of a ``/proc/.../stat`` file, or ``None`` (gone)."""
    try:
        text = path.read_text()
    except OSError:
        return None
    left, right = text.find("("), text.rfind(")")
    if left < 0 or right < left:
        return None
    return text[left + 1 : right], text[right + 2 :].split()


def realtime_rivals(exclude: Iterable[int] = (), proc: Path = Path("/proc")) -> list[RealtimeRival]:
    """The user-space threads of other processes under a real-time policy.

    Kernel threads (``PF_KTHREAD``: the per-CPU ``migration``/``watchdog`` threads run at
    priority 99 on every Linux) and this process are left out, with the pids ``exclude``.

    Args:
        exclude: Further process ids to leave out (e.g. the run's own arm process).
        proc: The proc file system's mount point.

    Returns:
        The rivals, highest priority first (empty where ``/proc`` is not readable).
    """
    skip = {os.getpid(), *exclude}
    found: list[RealtimeRival] = []
    try:
        pids = [int(p.name) for p in proc.iterdir() if p.name.isdigit()]
    except OSError:
        return found
    for pid in pids:
        if pid in skip:
            continue
        try:
            tids = [int(t.name) for t in (proc / str(pid) / "task").iterdir()]
        except OSError:
            continue  # gone, or not ours to read
        for tid in tids:
            stat = _stat_fields(proc / str(pid) / "task" / str(tid) / "stat")
            # fields after comm start at stat's field 3: flags is field 9, rt_priority 40,
            # policy 41 (proc(5))
            if stat is None or len(stat[1]) < 39:
                continue
            comm, fields = stat
            flags, priority, policy = int(fields[6]), int(fields[37]), int(fields[38])
            if flags & PF_KTHREAD or policy not in REALTIME_POLICIES:
                continue
            found.append(RealtimeRival(pid, tid, comm, REALTIME_POLICIES[policy], priority))
    found.sort(key=lambda r: (-r.priority, r.pid, r.tid))
    return found


def rival_warnings(exclude: Iterable[int] = (), proc: Path = Path("/proc")) -> list[str]:
    """One line per process of :func:`realtime_rivals` (its highest-priority thread
    named), saying what it does to the run and what to do; empty when none was found."""
    by_pid: dict[int, list[RealtimeRival]] = {}
    for rival in realtime_rivals(exclude, proc):
        by_pid.setdefault(rival.pid, []).append(rival)
    lines = []
    for pid, threads in by_pid.items():
        top = threads[0]
        more = f", {len(threads)} threads" if len(threads) > 1 else ""
        lines.append(
            f"process {pid} ({top.name}) runs under {top.policy} {top.priority}{more}: "
            "it takes a core from this run whenever it runs (two real-time loops on a "
            "2-core machine stall each other by up to 0.1 s); stop it, or keep it and this "
            "run on separate CPUs (taskset, cpusets)"
        )
    return lines


def steal_time(stat: Path = Path("/proc/stat")) -> float:
    """The machine's steal time so far [s], summed over its CPUs: ``/proc/stat``'s eighth
    ``cpu`` field (clock ticks; counted by a virtual machine's kernel from the
    hypervisor's steal clock, 0 on bare metal). 0 where it is not reported."""
    try:
        with stat.open() as f:
            fields = f.readline().split()
    except OSError:
        return 0.0
    if len(fields) < 9 or fields[0] != "cpu":
        return 0.0
    return int(fields[8]) / os.sysconf("SC_CLK_TCK")
