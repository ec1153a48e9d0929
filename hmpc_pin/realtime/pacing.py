"""Keeping the period: sleeping to an absolute deadline, the real-time scheduling policy,
and the tally of missed deadlines and of garbage collections run in a cycle's slack (the
loop's timing rules: :mod:`hmpc_pin.realtime.loop`)."""

from __future__ import annotations

import contextlib
import gc
import os
import time
from collections.abc import Callable

from ..exceptions import ConfigError

__all__ = ["GCWatch", "Tally", "fifo_priority", "sleep_until"]


def sleep_until(
    deadline: float, clock: Callable[[], float] = time.perf_counter, spin: float = 0.0
) -> None:
    """Sleep until ``clock()`` reaches ``deadline`` [s] (returns at once if it has).

    With ``spin`` > 0 [s], sleep until ``deadline - spin`` and busy-wait the rest: the
    thread is awake and on its core at the deadline, so the kernel's wake-up latency
    (hundreds of µs at p99.9 on a shared machine) and a core waking from idle are off
    the cycle's latency, at the cost of ``spin · rate`` of a core.
    """
    delay = deadline - clock() - spin
    if delay > 0:
        time.sleep(delay)
    if spin > 0:
        while clock() < deadline:
            pass


@contextlib.contextmanager
def fifo_priority(priority: int):
    """Run the block under the real-time policy ``SCHED_FIFO`` at ``priority`` (1–99),
    then restore the process's policy; ``0`` changes nothing.

    A FIFO thread preempts every normal one as soon as it is runnable, so the loop wakes
    on time even on a loaded machine (what libfranka asks for with ``kEnforce``). The
    loop sleeps most of each period, so it does not starve the rest of the machine.

    Raises:
        ConfigError: The policy cannot be set here (no ``CAP_SYS_NICE``/rtprio limit).
    """
    if priority == 0:
        yield
        return
    try:
        old_policy, old_param = os.sched_getscheduler(0), os.sched_getparam(0)
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (OSError, AttributeError) as exc:
        raise ConfigError(
            "realtime.priority",
            f"cannot run at SCHED_FIFO priority {priority} ({exc}); run as root or grant "
            "an rtprio limit (/etc/security/limits.conf), or set priority = 0",
        ) from exc
    try:
        yield
    finally:
        os.sched_setscheduler(0, old_policy, old_param)


class GCWatch:
    """A :data:`gc.callbacks` entry: counts the collections that run and their longest
    duration [s] (the loop's own and, without GC handling, the automatic ones)."""

    def __init__(self, clock: Callable[[], float]):
        self.clock, self.count, self.longest, self._start = clock, 0, 0.0, 0.0

    def __call__(self, phase: str, info: dict) -> None:
        if phase == "start":
            self._start = self.clock()
        else:
            self.count += 1
            self.longest = max(self.longest, self.clock() - self._start)


class Tally:
    """Missed deadlines and garbage collections of a run."""

    __slots__ = (
        "consecutive",
        "gc_deferred",
        "gc_max",
        "gc_runs",
        "misses",
        "skipped",
        "th",
        "worst_run",
    )

    def __init__(self):
        self.misses = self.consecutive = self.worst_run = self.skipped = 0
        self.gc_runs = self.gc_deferred = 0
        self.gc_max = 0.0
        self.th = gc.get_threshold()

    def miss(self, max_misses: int) -> bool:
        """One missed deadline; whether the run of misses reached ``max_misses``."""
        self.misses += 1
        self.consecutive += 1
        self.worst_run = max(self.worst_run, self.consecutive)
        return self.consecutive >= max_misses

    def skip(self, skip: int, late: int, max_misses: int) -> bool:
        """``skip`` periods skipped, ``late`` of them missed; whether the run of misses
        reached ``max_misses``."""
        self.misses += late
        self.skipped += skip
        if not late:
            return False
        self.consecutive += late
        self.worst_run = max(self.worst_run, self.consecutive)
        return self.consecutive >= max_misses

    def collect(self, k: int, next_deadline: float, clock, slack: float, record) -> None:
        """Collect the generation automatic collection would, if at least ``slack`` [s]
        remains before ``next_deadline``; else defer it."""
        c0, c1, c2 = gc.get_count()
        th0, th1, th2 = self.th
        if c0 < th0:
            return
        gen = 2 if (c2 + 1 >= th2 and c1 + 1 >= th1) else (1 if c1 + 1 >= th1 else 0)
        if next_deadline - clock() < slack:
            self.gc_deferred += 1
            return
        g0 = clock()
        gc.collect(gen)
        spent = clock() - g0
        record[k] = spent
        self.gc_runs += 1
        self.gc_max = max(self.gc_max, spent)
