"""How the real-time loop keeps its period and sets itself up: the set-up before an arm's
own clock starts, the waker (sleep, then spin a measured stretch), the running quantile
that chooses the stretch, the watchdog that does not charge the loop's own stall to the
arm, the real-time policy where permitted, the CPU affinity and the timer slack. Logic
only: no assertion on how long anything took."""

from __future__ import annotations

import gc
import os
import sys
import threading
import time

import numpy as np
import pytest

import hmpc_pin
from hmpc_pin.controllers.base import ControllerWrapper
from hmpc_pin.exceptions import ConfigError
from hmpc_pin.experiment.config import RealtimeConfig
from hmpc_pin.realtime import LoopSettings, PlantArm, RealtimeLoop, SafeTorque, SafetySettings
from hmpc_pin.realtime.pacing import (
    AUTO_PRIORITY,
    QuantileTracker,
    Waker,
    cpu_affinity,
    fifo_priority,
    realtime_policy,
    resolve_priority,
    timer_slack,
)
from hmpc_pin.sim import RK4Plant

from .test_realtime import FakeClock, P, _sine


@pytest.fixture(scope="module")
def robot():
    return hmpc_pin.load_robot("planar3")


class Counting(ControllerWrapper):
    """The wrapped controller; records its resets and steps with the arm's state then
    (``started``: whether the arm's clock had started). ``warm``: forward ``warm_up``
    (the loop then runs the set-up's dry step)."""

    def __init__(self, controller, arm, warm: bool):
        super().__init__(controller)
        self.arm, self.events = arm, []
        if warm:
            self.warm_up = controller.warm_up

    def reset(self, q0, dq0) -> None:
        self.events.append(("reset", self.arm.started, np.array(q0), np.array(dq0)))
        self.controller.reset(q0, dq0)

    def step(self, t, q, dq, reference):
        self.events.append(("step", self.arm.started, t))
        return self.controller.step(t, q, dq, reference)


class Starting:
    """A polled arm whose clock starts with :meth:`start` (as Franka's torque control):
    reading it before is an error; :meth:`start` records the collector's state then."""

    def __init__(self, arm):
        self.arm, self.nq, self.period = arm, arm.nq, arm.period
        self.started = False
        self.at_start: dict = {}

    def start(self):
        self.started = True
        self.at_start = {"frozen": gc.get_freeze_count(), "enabled": gc.isenabled()}

    def read(self):
        assert self.started, "read before the arm's clock started"
        return self.arm.read()

    def write(self, tau):
        assert self.started
        self.arm.write(tau)

    def close(self):
        self.arm.close()


class Plain(Starting):
    """The same arm with its clock running from the beginning (no ``start``)."""

    started = True

    def __init__(self, arm):
        super().__init__(arm)
        self.started = True

    start = None  # type: ignore[assignment]


def _run(robot, iface_type, warm, start, q0_given=True, duration=0.3):
    clock = FakeClock()
    q0 = _sine().sample(0.0)[0]
    arm = PlantArm(RK4Plant(robot.copy(), None, P, P), q0, clock=clock)
    iface = iface_type(arm)
    ctrl = Counting(hmpc_pin.make_controller(robot), iface, warm)
    loop = RealtimeLoop(
        iface, ctrl, _sine(), SafeTorque(robot, damping=3.0),
        LoopSettings(1.0 / P, duration, warm_up=0.0),
        SafetySettings.unlimited(3, max_misses=5, watchdog=0.005, hold=0.01),
        clock=clock, sleep=clock.sleep,
    )  # fmt: skip
    args = (q0, np.zeros(3)) if q0_given else ()
    run = loop.run(*args, start=start)
    return run, iface, ctrl, q0


def test_the_set_up_happens_before_the_arms_clock_starts(robot):
    """With ``start=True`` and the reset state given: the whole heap is frozen (a heap of
    300,000 objects made before the run is out of the collector's reach), automatic
    collection is off and the controller reset before the arm's ``start``; no step before
    it; the run equals the same run against the arm whose clock ran from the beginning."""
    heap = [[i] for i in range(300_000)]
    run, iface, ctrl, q0 = _run(robot, Starting, warm=True, start=True)
    assert iface.at_start["frozen"] >= len(heap)
    assert iface.at_start["enabled"] is False
    resets = [e for e in ctrl.events if e[0] == "reset"]
    assert len(resets) == 2 and not any(e[1] for e in resets)  # reset, dry step, reset
    np.testing.assert_array_equal(resets[-1][2], q0)
    steps = [e for e in ctrl.events if e[0] == "step"]
    assert steps and all(e[1] for e in steps)  # the dry step went to the inner controller
    assert steps[0][2] == 0.0
    plain, *_ = _run(robot, Plain, warm=False, start=False)
    assert run.complete and plain.complete
    np.testing.assert_array_equal(run.result.tau, plain.result.tau)
    np.testing.assert_array_equal(run.result.q, plain.result.q)
    assert gc.isenabled() and gc.get_freeze_count() == 0  # restored after the run
    del heap


def test_without_a_reset_state_the_controller_is_reset_at_the_first_state(robot):
    """``start=True`` without ``q0``: the heap is still frozen before the start; the
    controller is reset after it, at the first state the arm gives."""
    run, iface, ctrl, q0 = _run(robot, Starting, warm=False, start=True, q0_given=False)
    assert iface.at_start["frozen"] > 0
    resets = [e for e in ctrl.events if e[0] == "reset"]
    assert len(resets) == 1 and resets[0][1]  # after the start
    np.testing.assert_array_equal(resets[0][2], q0)
    assert run.complete


def test_the_set_ups_dry_step_changes_no_torque(robot):
    """The dry step run at set-up (then undone by a reset) leaves every torque of the run
    as without it, to the last bit."""
    warm, *_ = _run(robot, Plain, warm=True, start=False)
    cold, *_ = _run(robot, Plain, warm=False, start=False)
    np.testing.assert_array_equal(warm.result.tau, cold.result.tau)


def test_the_waker_never_returns_before_its_deadline():
    """On the clock it uses, :meth:`Waker.until` returns at or after the deadline, with a
    fixed stretch, an adaptive one and work before it; the work is called once per
    deadline, or skipped (and counted) when the deadline leaves no time for it."""
    clock = time.perf_counter
    for spin in (0.0, 2e-4, None):
        waker = Waker(clock, 1e-3, spin, warm=1e-4)
        calls: list[float] = []
        work = lambda: calls.append(clock())  # noqa: E731, B023
        start = clock()
        for k in range(1, 40):
            deadline = start + k * 1e-3
            waker.until(deadline, work if k % 2 else None)
            assert clock() >= deadline
        assert len(calls) + waker.skipped_work == 20
        assert waker.lead <= 0.5e-3
    waker = Waker(clock, 1e-3, None, warm=1e-4)
    waker.until(clock() - 1.0, lambda: pytest.fail("no time left: the work is skipped"))
    assert waker.skipped_work == 1


def test_the_adaptive_stretch_is_off_without_a_real_time_policy():
    waker = Waker(time.perf_counter, 1e-3, None)
    waker.adapt(False)
    assert waker.lead == 0.0 and not waker.adaptive
    waker.adapt(True)
    assert waker.lead > 0.0 and waker.adaptive


@pytest.mark.parametrize("q", [0.5, 0.9, 0.99])
def test_the_running_quantile_settles_at_the_quantile(q):
    """Against numpy's quantile of the same samples (exponential, scale 50 µs, as wake-up
    lateness is): within the estimator's own resolution (a few steps)."""
    rng = np.random.default_rng(7)
    x = rng.exponential(5e-5, 200_000)
    step = 2e-6
    tracker = QuantileTracker(0.0, q, step, 0.0, 1.0)
    for v in x:
        tracker.add(v)
    exact = np.quantile(x, q)
    assert tracker.value == pytest.approx(exact, abs=max(20 * step, 0.05 * exact))
    # the bounds hold
    bounded = QuantileTracker(0.0, q, 1e-3, 1e-5, 2e-5)
    for v in x[:100]:
        bounded.add(v)
        assert 1e-5 <= bounded.value <= 2e-5


def test_the_watchdog_does_not_charge_the_loops_own_stall_to_the_arm(robot):
    """A wake-up later than a period (the loop's stall) is not counted as the arm's silence;
    the same stale stamp at on-time wake-ups is."""
    clock = FakeClock(0.0)
    arm = PlantArm(RK4Plant(robot.copy(), None, P, P), np.zeros(3), clock=clock)
    loop = RealtimeLoop(
        arm, hmpc_pin.make_controller(robot), _sine(), SafeTorque(robot),
        LoopSettings(1.0 / P, 0.1), SafetySettings.unlimited(3, watchdog=0.005),
        clock=clock, sleep=clock.sleep,
    )  # fmt: skip
    loop._fresh = (1.0, 0.0)
    # woke 13 ms late (the loop's own stall): no stop, the stall is not the arm's
    assert loop._watch(1.0, 0.014, 0.005, late=0.013) is None
    assert loop._stalls == 1
    # the next on-time cycles with the same stamp: the arm's silence counts from there
    assert loop._watch(1.0, 0.018, 0.005, late=0.0) is None
    stop = loop._watch(1.0, 0.0195, 0.005, late=0.0)
    assert stop is not None and stop[0] == "watchdog"
    # a late wake-up of less than a period is charged as before
    loop._fresh = (2.0, 0.0)
    assert loop._watch(2.0, 0.0056, 0.005, late=0.0009) is not None


def test_priority_auto_takes_a_real_time_policy_only_where_permitted():
    """``"auto"``: :data:`AUTO_PRIORITY` if this process may set SCHED_FIFO (tried here
    independently), else 0; the policy is restored after the block either way."""
    before, param = os.sched_getscheduler(0), os.sched_getparam(0)
    was_realtime = realtime_policy()  # (libfranka's Robot() leaves its thread at FIFO 99)
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(AUTO_PRIORITY))
        permitted = True
        os.sched_setscheduler(0, before, param)
    except OSError:
        permitted = False
    assert os.sched_getscheduler(0) == before
    assert resolve_priority("auto") == (AUTO_PRIORITY if permitted else 0)
    assert resolve_priority(0) == 0 and resolve_priority(7) == 7
    with fifo_priority("auto") as taken:
        assert taken == (AUTO_PRIORITY if permitted else 0)
        assert realtime_policy() == (permitted or was_realtime)
    assert os.sched_getscheduler(0) == before and os.sched_getparam(0) == param


def test_the_config_takes_auto_and_cpus():
    rc = RealtimeConfig(priority="auto", spin="auto", cpus=[0])
    assert rc.priority == "auto" and rc.spin == "auto" and rc.cpus == (0,)
    assert RealtimeConfig().spin == "auto" and RealtimeConfig().priority == "auto"
    assert RealtimeConfig(priority=0).priority == 0
    assert RealtimeConfig(spin=2e-4).spin == 2e-4
    with pytest.raises(ConfigError, match="spin"):
        RealtimeConfig(spin="fast")
    with pytest.raises(ConfigError, match="priority"):
        RealtimeConfig(priority="high")
    with pytest.raises(ConfigError, match="cpus"):
        RealtimeConfig(cpus=[-1])
    with pytest.raises(ConfigError, match=r"realtime\.spin"):
        LoopSettings(1000.0, 1.0, spin="fast")


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="no CPU affinity here")
def test_cpu_affinity_pins_the_block_and_restores():
    allowed = os.sched_getaffinity(0)
    one = min(allowed)
    with cpu_affinity([one]):
        assert os.sched_getaffinity(0) == {one}
    assert os.sched_getaffinity(0) == allowed
    with cpu_affinity([]):
        assert os.sched_getaffinity(0) == allowed
    with pytest.raises(ConfigError, match=r"realtime\.cpus"), cpu_affinity([4096]):
        pass
    assert os.sched_getaffinity(0) == allowed


@pytest.mark.skipif(
    not (sys.platform.startswith("linux") and os.path.exists("/proc/self/timerslack_ns")),
    reason="Linux timer slack",
)
def test_timer_slack_is_1_ns_in_the_block_and_the_default_after():
    assert threading.current_thread() is threading.main_thread()  # /proc/self: this thread

    def slack() -> int:
        with open("/proc/self/timerslack_ns") as f:
            return int(f.read())

    # (a real-time thread has no timer slack: the kernel reports 0; this runs under the
    # normal policy, as the loop's thread does without a priority)
    policy, param = os.sched_getscheduler(0), os.sched_getparam(0)
    os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    try:
        before = slack()
        with timer_slack(1):
            assert slack() == 1
        assert slack() == before
    finally:
        os.sched_setscheduler(0, policy, param)
