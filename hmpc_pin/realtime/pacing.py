"""Keeping the period: waking at an absolute deadline, the real-time scheduling policy and
CPU affinity, and the tally of missed deadlines and of garbage collections run in a
cycle's slack (the loop's timing rules: :mod:`hmpc_pin.realtime.loop`).

How the loop's thread waits for a deadline :math:`D` (:class:`Waker`): it sleeps until
:math:`D - \\ell` and busy-waits the last stretch :math:`\\ell`, so that it is awake and on its
core at :math:`D`. A sleep ends late by the kernel's wake-up latency (its timer slack, 50 µs
by default for a normal thread, is set to 1 ns for the loop's thread: :func:`timer_slack`),
and more when another thread holds the core; :math:`\\ell` is chosen from the wake-ups
measured in the run itself, a running estimate of their 99th percentile (a stochastic
quantile estimate, updated in O(1) at every wake-up), bounded to half a period. Spinning
costs about :math:`(\\ell - \\text{median lateness}) \\cdot f` of a core.
"""

from __future__ import annotations

import contextlib
import ctypes
import gc
import os
import sys
import time
from collections.abc import Callable

from ..exceptions import ConfigError

__all__ = [
    "AUTO_PRIORITY",
    "GCWatch",
    "QuantileTracker",
    "Tally",
    "Waker",
    "cpu_affinity",
    "cpu_latency_limit",
    "fifo_priority",
    "memory_locked",
    "realtime_policy",
    "resolve_priority",
    "sleep_until",
    "timer_slack",
]


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


class QuantileTracker:
    """A running estimate of the ``q``-quantile of a stream (stochastic approximation:
    each sample moves the estimate up by ``q·step`` if above it, down by ``(1-q)·step``
    otherwise; it settles where a fraction ``q`` of the samples lies below), kept inside
    ``[low, high]``. O(1) per sample, no memory of the samples.

    Args:
        start: The first estimate [s].
        q: The quantile, in (0, 1).
        step: The update's size [s].
        low, high: Bounds of the estimate [s].
    """

    __slots__ = ("high", "low", "q", "step", "value")

    def __init__(self, start: float, q: float = 0.99, step: float = 2e-5, low=0.0, high=1.0):
        self.q, self.step, self.low, self.high = q, step, low, high
        self.value = min(max(start, low), high)

    def add(self, x: float) -> float:
        """Take the sample ``x``; return the new estimate."""
        v = self.value + (self.q * self.step if x > self.value else (self.q - 1.0) * self.step)
        self.value = v = self.high if v > self.high else (self.low if v < self.low else v)
        return v


class Waker:
    """Wake at absolute deadlines: sleep, then busy-wait the last stretch (module doc).

    Args:
        clock: Monotonic seconds (the loop's clock).
        period: The loop's period [s]; the stretch stays below half of it.
        spin: The stretch [s]: a number (fixed; 0 sleeps the whole wait, as
            :func:`sleep_until`), or ``None`` to choose it from the measured wake-ups.
        warm: The time [s] first reserved for the work done before a deadline
            (:meth:`until`'s ``before``), then the measured 99th percentile of that work.

    The wake-ups' lateness is measured at every sleep, whatever ``spin``: the work before
    a deadline is started early enough for that lateness and the work's own duration
    (their 99th percentiles, at most half a period together), and skipped (counted) when
    the thread woke too late for it to end by the deadline.

    Attributes:
        lead: The current stretch [s] (the wake-up lateness estimate, or ``spin``).
        late_work: Deadlines at which the work before them ended late.
        skipped_work: Deadlines whose work was skipped (no time left for it).
        spun: Total time [s] spent busy-waiting.
    """

    def __init__(
        self,
        clock: Callable[[], float],
        period: float,
        spin: float | None = None,
        warm: float = 0.0,
    ):
        self.clock, self.period = clock, period
        self.adaptive = spin is None
        self.high = high = 0.5 * period
        self._wake = QuantileTracker(min(1e-4, high), 0.99, 1e-5, 1e-5, high)
        self.lead = self._wake.value if spin is None else float(spin)
        self._work = QuantileTracker(warm, 0.99, 1e-5, 0.0, high)
        self.late_work = self.skipped_work = 0
        self.spun = 0.0

    def adapt(self, on: bool) -> None:
        """Choose the stretch from the wake-ups (``on``), or sleep the whole wait (lead 0)."""
        self.adaptive = on
        self.lead = self._wake.value if on else 0.0

    def until(self, deadline: float, before: Callable[[], None] | None = None) -> None:
        """Return when the clock has reached ``deadline`` [s] (never before it); with
        ``before``, call it first, woken early enough for it to end by the deadline
        (skipped if the thread woke too late for it)."""
        clock = self.clock
        work = self._work.value
        if before is None:
            early = self.lead
        else:
            early = min(work + max(self.lead, self._wake.value), self.high)
        target = deadline - early
        delay = target - clock()
        if delay > 0:
            time.sleep(delay)
            woke = clock()
            late = self._wake.add(woke - target)
            if self.adaptive:
                self.lead = late
        else:
            woke = clock()
        if before is not None:
            if deadline - woke >= work:
                before()
                ended = clock()
                self._work.add(ended - woke)
                if ended > deadline:
                    self.late_work += 1
            else:
                self.skipped_work += 1
        start = clock()
        while clock() < deadline:
            pass
        self.spun += clock() - start


@contextlib.contextmanager
def timer_slack(nanoseconds: int = 1):
    """Run the block with the calling thread's timer slack at ``nanoseconds`` (Linux
    ``PR_SET_TIMERSLACK``; the kernel may end a sleep up to the slack late, 50 µs by
    default), then restore the default. Elsewhere, or if refused, changes nothing."""
    prctl = None
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            prctl = ctypes.CDLL(None, use_errno=True).prctl
    if prctl is None or prctl(29, ctypes.c_ulong(nanoseconds), 0, 0, 0) != 0:
        yield
        return
    try:
        yield
    finally:
        prctl(29, ctypes.c_ulong(0), 0, 0, 0)  # 0: back to the thread's default


#: ``mlockall`` flags (Linux): the pages mapped now, and those mapped later.
MCL_CURRENT, MCL_FUTURE = 1, 2


@contextlib.contextmanager
def memory_locked(lock: bool = True):
    """Run the block with the process's memory locked in RAM (``mlockall(MCL_CURRENT |
    MCL_FUTURE)``, as ``cyclictest -m`` does), then unlock it (``munlockall``).

    A locked page is faulted in when it is mapped, not at its first touch: the records
    allocated in the block, the interpreter's and the libraries' pages are resident before
    the first cycle, and none is paged out during the run. Where it is not permitted
    (no ``CAP_IPC_LOCK`` and an ``RLIMIT_MEMLOCK`` below the process's size) or not
    available (not Linux), the block runs unlocked.

    Yields:
        The outcome, one line: ``"locked"``, ``"off"`` (``lock`` false), or
        ``"refused: <why>"``/``"unavailable: <why>"``.
    """
    if not lock:
        yield "off"
        return
    libc = None
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            libc = ctypes.CDLL(None, use_errno=True)
            libc.mlockall, libc.munlockall  # noqa: B018 (both present)
    if libc is None:
        yield f"unavailable: no mlockall on {sys.platform}"
        return
    if libc.mlockall(MCL_CURRENT | MCL_FUTURE) != 0:
        err = ctypes.get_errno()
        yield f"refused: {os.strerror(err)} (errno {err}; CAP_IPC_LOCK or a memlock limit)"
        return
    try:
        yield "locked"
    finally:
        libc.munlockall()


#: The kernel's CPU wake-up latency request (Linux PM QoS): while a process holds it open
#: with a value written, idle states slower to leave than that are not entered.
CPU_DMA_LATENCY = "/dev/cpu_dma_latency"


@contextlib.contextmanager
def cpu_latency_limit(microseconds: int | None = 0, path: str = CPU_DMA_LATENCY):
    """Run the block with the CPUs' idle-exit latency limited to ``microseconds`` (written
    to ``/dev/cpu_dma_latency`` and held open, as ``cyclictest`` does; the kernel drops the
    request when the file is closed). With 0 an idle CPU polls instead of halting: a
    sleeping thread's wake-up does not wait for the core (or, in a virtual machine, the
    virtual CPU) to come out of a halt. ``None`` changes nothing; where the file cannot be
    opened (not root, not Linux) the block runs without the limit.

    Yields:
        The outcome, one line: ``"<n> us"``, ``"off"`` (``None``) or ``"refused: <why>"``.
    """
    if microseconds is None:
        yield "off"
        return
    try:
        fd = os.open(path, os.O_WRONLY)
    except OSError as exc:
        yield f"refused: {exc.strerror} ({path})"
        return
    try:
        os.write(fd, int(microseconds).to_bytes(4, sys.byteorder, signed=True))
    except OSError as exc:
        os.close(fd)
        yield f"refused: {exc.strerror} ({path})"
        return
    try:
        yield f"{int(microseconds)} us"
    finally:
        os.close(fd)


@contextlib.contextmanager
def cpu_affinity(cpus):
    """Run the block with the calling thread on the CPUs ``cpus`` (a set of indices;
    ``None`` or empty: unchanged), then restore its affinity.

    Raises:
        ConfigError: A CPU this process may not run on.
    """
    if not cpus or not hasattr(os, "sched_setaffinity"):
        yield
        return
    old = os.sched_getaffinity(0)
    try:
        os.sched_setaffinity(0, set(cpus))
    except (OSError, ValueError) as exc:
        raise ConfigError(
            "realtime.cpus",
            f"cannot run on CPUs {sorted(cpus)} ({exc}); expected a subset of "
            f"{sorted(old)} (the CPUs this process may use), or [] for no pinning",
        ) from exc
    try:
        yield
    finally:
        os.sched_setaffinity(0, old)


#: The ``SCHED_FIFO`` priority ``priority = "auto"`` asks for: above a PREEMPT_RT kernel's
#: interrupt threads (50), below libfranka's own 99.
AUTO_PRIORITY = 80


def resolve_priority(priority: int | str) -> int:
    """The ``SCHED_FIFO`` priority ``priority`` stands for: itself (0: none), or for
    ``"auto"`` :data:`AUTO_PRIORITY` if this process may take it, else 0 (tried on the
    calling thread and undone)."""
    if priority != "auto":
        return int(priority)
    try:
        old_policy, old_param = os.sched_getscheduler(0), os.sched_getparam(0)
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(AUTO_PRIORITY))
    except (OSError, AttributeError):
        return 0
    os.sched_setscheduler(0, old_policy, old_param)
    return AUTO_PRIORITY


def realtime_policy() -> bool:
    """Whether the calling thread runs under a real-time policy (``SCHED_FIFO``/``RR``)."""
    try:
        return os.sched_getscheduler(0) in (os.SCHED_FIFO, os.SCHED_RR)
    except (OSError, AttributeError):
        return False


@contextlib.contextmanager
def fifo_priority(priority: int | str):
    """Run the block under the real-time policy ``SCHED_FIFO`` at ``priority`` (1–99),
    then restore the process's policy; ``0`` changes nothing; ``"auto"`` takes
    :data:`AUTO_PRIORITY` where this process may (root, ``CAP_SYS_NICE`` or an rtprio
    limit) and changes nothing elsewhere. Yields the priority taken (0: none).

    A FIFO thread preempts every normal one as soon as it is runnable, so the loop wakes
    on time even on a loaded machine (what libfranka asks for with ``kEnforce``). The
    loop sleeps most of each period, so it does not starve the rest of the machine (and
    the kernel keeps 5 % of each second for normal threads: ``sched_rt_runtime_us``).

    Raises:
        ConfigError: A priority 1–99 that cannot be set here (no ``CAP_SYS_NICE``/rtprio
            limit).
    """
    priority = resolve_priority(priority)
    if priority == 0:
        yield 0
        return
    try:
        old_policy, old_param = os.sched_getscheduler(0), os.sched_getparam(0)
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (OSError, AttributeError) as exc:
        raise ConfigError(
            "realtime.priority",
            f"cannot run at SCHED_FIFO priority {priority} ({exc}); run as root or grant "
            'an rtprio limit (/etc/security/limits.conf), or set priority = 0 (or "auto": '
            "a real-time priority where permitted)",
        ) from exc
    try:
        yield priority
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
