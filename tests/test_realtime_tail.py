"""What the loop does for its latency tail, checked by its effects (no wall-clock figures):
the memory locked during a run and unlocked after, the CPUs' idle-exit limit held, the arm
process one FIFO level below the loop, its collector frozen while it runs and restored
after."""

from __future__ import annotations

import atexit
import functools
import gc
import mmap
import os
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import hmpc_pin
from hmpc_pin.realtime import ProcessArm
from hmpc_pin.realtime.pacing import (
    AUTO_PRIORITY,
    CPU_DMA_LATENCY,
    cpu_latency_limit,
    fifo_priority,
    memory_locked,
    realtime_policy,
)
from hmpc_pin.sim import RK4Plant

from .test_realtime import P, _setup

linux = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="Linux only")


def _locked_kb() -> int:
    """VmLck of this process [kB], as the kernel reports it."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmLck:"):
            return int(line.split()[1])
    raise AssertionError("no VmLck in /proc/self/status")


def _fifo_permitted() -> bool:
    policy, param = os.sched_getscheduler(0), os.sched_getparam(0)
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(AUTO_PRIORITY))
    except OSError:
        return False
    os.sched_setscheduler(0, policy, param)
    return True


@linux
def test_memory_is_locked_in_the_block_and_unlocked_after():
    assert _locked_kb() == 0
    with memory_locked() as outcome:
        inside = _locked_kb()
        # 8 MiB newly mapped in the block (MCL_FUTURE): an anonymous mapping of its own, not
        # memory the allocator may hand back from pages already mapped (and locked)
        fresh = mmap.mmap(-1, 8 << 20)
        fresh.write(b"\1" * len(fresh))
        after_alloc = _locked_kb()
        size_kb = len(fresh) // 1024
        fresh.close()
    assert _locked_kb() == 0
    if outcome == "locked":
        # the whole process: more than this interpreter's numpy alone, and what is mapped
        # later is locked too
        assert inside > 50_000
        assert after_alloc >= inside + size_kb - 64
    else:
        assert outcome.startswith("refused") and inside == 0
    with memory_locked(False) as outcome:
        assert outcome == "off" and _locked_kb() == 0


@linux
def test_a_run_locks_memory_records_the_outcome_and_unlocks(robot):
    """Asked for (``lock_memory=True``), and by default under a real-time policy only."""
    seen = []
    for lock, fifo in ((True, False), ("auto", True)):
        if fifo and not _fifo_permitted():
            continue
        loop, _, _, _ = _setup(robot, 0.05, hook=lambda t: seen.append(_locked_kb()))
        loop.lock_memory = lock
        seen.clear()
        with fifo_priority(1 if fifo else 0):
            run = loop.run()
        assert run.complete
        outcome = run.stats["memory_lock"]
        if outcome == "locked":
            assert min(seen) > 0  # every controller step ran with the memory locked
        else:
            assert outcome.startswith("refused") and max(seen) == 0
        assert _locked_kb() == 0
    for lock in (False, "auto"):  # (this thread under normal scheduling)
        assert not realtime_policy()
        loop, _, _, _ = _setup(robot, 0.02, hook=lambda t: seen.append(_locked_kb()))
        loop.lock_memory = lock
        seen.clear()
        assert loop.run().stats["memory_lock"] == "off" and max(seen) == 0


def _holds(path: str) -> bool:
    """Whether this process has ``path`` open."""
    fds = Path("/proc/self/fd")
    return any(os.path.realpath(fd) == path for fd in fds.iterdir() if fd.exists())


@linux
def test_the_cpu_latency_request_is_held_in_the_block_and_dropped_after(tmp_path):
    permitted = os.path.exists(CPU_DMA_LATENCY) and os.access(CPU_DMA_LATENCY, os.W_OK)
    with cpu_latency_limit(0) as outcome:
        held = _holds(CPU_DMA_LATENCY)
        value = Path(CPU_DMA_LATENCY).read_bytes() if held else None
    assert not _holds(CPU_DMA_LATENCY)
    if permitted:
        assert outcome == "0 us" and held
        assert int.from_bytes(value, sys.byteorder, signed=True) == 0  # the system's limit now
    else:
        assert outcome.startswith("refused") and not held
    with cpu_latency_limit(None) as outcome:
        assert outcome == "off" and not _holds(CPU_DMA_LATENCY)
    # the request written is the value asked for, as a 32-bit integer
    target = tmp_path / "qos"
    target.write_bytes(b"")
    with cpu_latency_limit(7, path=str(target)) as outcome:
        assert outcome == "7 us"
    assert int.from_bytes(target.read_bytes(), sys.byteorder, signed=True) == 7
    with cpu_latency_limit(0, path=str(tmp_path / "none" / "qos")) as outcome:
        assert outcome.startswith("refused")


@linux
@pytest.mark.parametrize(
    ("limit", "fifo"), [(0, False), ("auto", True), ("auto", False), ("default", True)]
)
def test_a_run_records_the_cpu_latency_outcome(robot, limit, fifo):
    if fifo and not _fifo_permitted():
        pytest.skip("SCHED_FIFO not permitted here")
    seen = []
    loop, _, _, _ = _setup(robot, 0.02, hook=lambda t: seen.append(_holds(CPU_DMA_LATENCY)))
    if limit == "default":
        assert loop.cpu_latency is None  # off unless asked (the guide: stalls on a VM)
    else:
        loop.cpu_latency = limit
    with fifo_priority(1 if fifo else 0):
        run = loop.run()
    outcome = run.stats["cpu_latency"]
    if limit == "default" or (limit == "auto" and not fifo):
        assert outcome == "off" and not any(seen)
    else:
        assert seen and all(seen) == (outcome == "0 us")
        assert outcome == "0 us" or (outcome.startswith("refused") and not any(seen))
    assert not _holds(CPU_DMA_LATENCY)


# ------------------------------------------------------------ the arm process
class _GarbagePlant:
    """A planar plant that makes cyclic garbage every step, and reports its process's
    collector (enabled, frozen objects) at its first step and at the process's exit to
    ``path`` (one line each)."""

    def __init__(self, path: str):
        self.plant = RK4Plant(hmpc_pin.load_robot("planar3"), None, P, P)
        self.path, self.steps = path, 0
        self.nq, self.Ts = self.plant.nq, self.plant.Ts
        atexit.register(self._report, "exit")

    def _report(self, when: str) -> None:
        with open(self.path, "a") as f:
            f.write(f"{when} {gc.isenabled()} {gc.get_freeze_count()}\n")

    def reset(self, q0, dq0, t0=0.0):
        return self.plant.reset(q0, dq0, t0)

    def advance(self, tau):
        self.steps += 1
        if self.steps == 1:
            self._report("step")
        for _ in range(20):  # cycles only a collection frees
            a: list = []
            a.append(a)
        return self.plant.advance(tau)


def _garbage_plant(path):
    return _GarbagePlant(path)


def _run_arm(arm, seconds: float) -> None:
    """Command the arm (zero torque) for ``seconds``, so that it steps."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        arm.write(np.zeros(arm.nq))
        time.sleep(P)


@pytest.mark.parametrize("frozen", [True, False])
def test_the_arm_collects_only_in_its_slack_and_restores_its_collector(tmp_path, frozen):
    report = tmp_path / "gc.txt"
    arm = ProcessArm(functools.partial(_garbage_plant, str(report)), np.zeros(3), gc_frozen=frozen)
    try:
        _run_arm(arm, 0.5)
        during = arm.counters
    finally:
        arm.close()
    after = arm.counters
    lines = dict(line.split(" ", 1) for line in report.read_text().splitlines())
    enabled, frozen_objects = lines["step"].split()
    if frozen:
        # in the run: automatic collection off, the set-up's objects frozen ...
        assert enabled == "False" and int(frozen_objects) > 1000
        assert during["gc"] == "frozen"
        # ... and the cyclic garbage collected in the slack (20 cycles a step, 0.5 s)
        assert during["gc_collections"] > 0
        # after the loop: as before
        assert lines["exit"].split() == ["True", "0"]
        assert after["gc"] == "restored"
    else:
        assert enabled == "True" and int(frozen_objects) == 0
        assert during["gc"] == "automatic" and during["gc_collections"] == 0
    assert after["steps"] >= during["steps"] > 0


@pytest.mark.skipif(not hasattr(os, "sched_getscheduler"), reason="no POSIX scheduling")
@pytest.mark.parametrize("below", [1, 0, 200])
def test_the_arm_runs_below_the_loops_priority(below):
    if not _fifo_permitted():
        pytest.skip("SCHED_FIFO not permitted here")
    arm = ProcessArm(functools.partial(_planar, P), np.zeros(3), priority=10, below=below)
    try:
        policy = os.sched_getscheduler(arm.pid)
        priority = os.sched_getparam(arm.pid).sched_priority
    finally:
        arm.close()
    assert policy == os.SCHED_FIFO
    assert priority == max(1, 10 - below) == arm.counters["priority"]


def test_the_arm_at_normal_scheduling_stays_there():
    arm = ProcessArm(functools.partial(_planar, P), np.zeros(3), priority=0)
    try:
        policy = os.sched_getscheduler(arm.pid)
    finally:
        arm.close()
    assert policy == os.SCHED_OTHER and arm.counters["priority"] == 0


def _planar(period):
    return RK4Plant(hmpc_pin.load_robot("planar3"), None, period, period)


@pytest.fixture(scope="module")
def robot():
    return hmpc_pin.load_robot("planar3")


# ------------------------------------------------------------ reading the arm's state
def _block(n: int):
    from hmpc_pin.realtime.process_arm import _size, _views

    buf = bytearray(_size(n))
    return buf, _views(memoryview(buf), n)


def test_a_reader_waits_for_a_writer_caught_mid_write_and_takes_its_copy():
    """The writer's counter odd (mid-write) while the reader starts: the reader must
    neither return the torn copy nor give up while the writer finishes (here in another
    thread, which runs only while the reader sleeps: it holds the GIL otherwise)."""
    from hmpc_pin.realtime.process_arm import _STATE_SEQ, _read_state

    n = 3
    _, (ctl, _, state, _) = _block(n)
    state[:] = 1.0
    ctl[_STATE_SEQ] = 2  # a whole copy of ones
    out, scratch = np.full(1 + 2 * n, np.nan), np.empty(1 + 2 * n)
    assert _read_state(ctl, state, out, scratch) and (out == 1.0).all()
    ctl[_STATE_SEQ] = 3  # the writer begins ...
    state[: n + 1] = 2.0  # ... half of the new state written

    def finish():
        state[n + 1 :] = 2.0
        ctl[_STATE_SEQ] = 4

    timer = threading.Timer(0.0005, finish)
    timer.start()
    try:
        assert _read_state(ctl, state, out, scratch)
    finally:
        timer.join()
    assert (out == 2.0).all()  # the writer's whole new copy, not the torn one


def test_a_reader_gives_up_on_a_writer_gone_mid_write_keeping_the_last_whole_copy():
    from hmpc_pin.realtime.process_arm import _STATE_SEQ, _read_state

    n = 2
    _, (ctl, _, state, _) = _block(n)
    state[:] = 1.0
    ctl[_STATE_SEQ] = 2
    out, scratch = np.full(1 + 2 * n, np.nan), np.empty(1 + 2 * n)
    assert _read_state(ctl, state, out, scratch)
    ctl[_STATE_SEQ] = 5  # a writer that never finishes
    state[:2] = 7.0
    assert not _read_state(ctl, state, out, scratch)
    assert (out == 1.0).all()  # the last whole copy, never the torn one
