"""Edges of the real-time loop's cycle on the fake clock of ``tests/test_realtime.py``:
states the arm reports overdue or not, a burst before the first cycle, a skip past the
end, the controller grid after a long skip, the velocity bound, the watchdog's and the
reference switch's boundaries, and a stop asked while the arm is silent."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import hmpc_pin
from hmpc_pin.realtime import LoopSettings, PlantArm, RealtimeLoop, SafeTorque, SafetySettings
from hmpc_pin.sim import RK4Plant
from hmpc_pin.tasks import SineReference

from .test_realtime import FakeClock, P, Paced, Spend, _sine


@pytest.fixture(scope="module")
def robot():
    return hmpc_pin.load_robot("planar3")


class Overdue(Paced):
    """:class:`Paced` that reports how many of the states it hands over were overdue
    (``overdue_of[k]`` for state k; 0 by default: a burst after the arm's own stall)."""

    def __init__(self, *args, overdue_of=None, **kwargs):
        super().__init__(*args, **kwargs)
        self.overdue_of = dict(overdue_of or {})
        self.overdue = 0

    def wait(self, timeout):
        count = super().wait(timeout)
        self.overdue = self.overdue_of.get(self.k, 0) if count else 0
        return count


def _loop(
    robot, duration, iface_factory, *, max_misses=5, velocity=np.inf, hook=None, reference=None
):
    reference = _sine() if reference is None else reference
    clock = FakeClock()
    q0 = reference.sample(0.0)[0]
    arm = PlantArm(RK4Plant(robot.copy(), None, P, P), q0, clock=clock)
    iface = iface_factory(arm, clock)
    ctrl = Spend(hmpc_pin.make_controller(robot), clock, lambda t: 0.0, hook)
    inf = np.full(3, np.inf)
    safety = SafetySettings(-inf, inf, np.full(3, velocity), max_misses=max_misses,
                            watchdog=0.05, hold=0.01)  # fmt: skip
    loop = RealtimeLoop(iface, ctrl, reference, SafeTorque(robot, damping=3.0),
                        LoopSettings(1.0 / P, duration), safety,
                        joint_names=tuple(robot.joint_names))  # fmt: skip
    return loop, arm


def test_a_burst_after_the_arms_own_stall_is_skipped_but_no_miss(robot):
    """The arm stalls 3 periods and then delivers its states at once (none overdue): the
    loop skips them (its time keeps the arm's) without a miss; the same states reported
    overdue are misses."""
    loop, _ = _loop(robot, 0.5, lambda a, c: Overdue(a, c, extra={301: 3}))
    run = loop.run()
    assert run.complete
    assert run.stats["skipped"] == 3 and run.stats["misses"] == 0
    loop, _ = _loop(robot, 0.5, lambda a, c: Overdue(a, c, extra={301: 3}, overdue_of={304: 2}))
    run = loop.run()
    assert run.stats["skipped"] == 3 and run.stats["misses"] == 2


def test_states_waiting_before_the_first_cycle_are_not_skipped(robot):
    """Three states already waiting when the loop starts: cycle 0 answers the newest,
    nothing is skipped or missed."""
    loop, _ = _loop(robot, 0.2, lambda a, c: Paced(a, c, extra={1: 3}))
    run = loop.run()
    assert run.complete
    assert run.stats["skipped"] == 0 and run.stats["misses"] == 0
    assert run.stats["cycles_run"] == 201


def test_a_skip_past_the_end_counts_only_the_cycles_left(robot):
    """10 states unanswered at cycle 99 of a 0.1 s run (cycles 0..100): 2 cycles were left,
    2 are skipped and missed (not 10: below max_misses = 5, the run is complete)."""
    loop, _ = _loop(robot, 0.1, lambda a, c: Paced(a, c, extra={100: 10}))
    run = loop.run()
    assert run.complete
    assert run.stats["skipped"] == 2 and run.stats["misses"] == 2


def test_after_a_long_skip_the_controller_keeps_its_grid(robot):
    """25 periods skipped (none overdue) from cycle 300: the controller steps at the
    resume (cycle 325) and then on its grid of m = 10 cycles (330, 340, ...), not at
    every cycle until it has caught up."""
    loop, _ = _loop(robot, 0.5, lambda a, c: Overdue(a, c, extra={301: 25}), max_misses=100)
    run = loop.run()
    assert run.complete
    mpc = np.flatnonzero(run.timing["mpc"])
    assert 325 in mpc
    after = mpc[mpc > 325]
    assert after[0] == 330 and (after % 10 == 0).all()
    assert list(mpc[mpc < 300]) == list(range(0, 300, 10))


def test_a_joint_faster_than_its_bound_is_a_fault_naming_it(robot):
    """A velocity bound of 0.05 rad/s on every joint: the sine (joint1 at up to 1.6 rad/s)
    passes it early; the stop is a fault naming joint1's speed and its bound."""
    loop, _ = _loop(robot, 0.5, lambda a, c: Paced(a, c), velocity=0.05)
    run = loop.run()
    assert not run.complete and run.stop["cause"] == "fault"
    assert "|dq|=" in run.stop["reason"] and "beyond its bound 0.05" in run.stop["reason"]
    speed = float(run.stop["reason"].split("|dq|=")[1].split()[0])
    assert speed > 0.05


def test_a_joint_faster_than_its_bound_backwards_is_a_fault_too(robot):
    """The bound is on |dq|: the sine run backwards (every joint's velocity negative at
    first, joint1 down to -1.6 rad/s) stops on the same fault, naming a speed above it."""
    backwards = SineReference(3, amplitude=[-0.5, -0.3, -0.2], frequency=[0.5, 0.4, 0.3],
                              offset=[0.3, -0.4, 0.2])  # fmt: skip
    assert np.all(backwards.sample(0.0)[1] < 0)
    loop, _ = _loop(robot, 0.5, lambda a, c: Paced(a, c), velocity=0.05, reference=backwards)
    run = loop.run()
    assert not run.complete and run.stop["cause"] == "fault"
    speed = float(run.stop["reason"].split("|dq|=")[1].split()[0])
    assert speed > 0.05


def test_the_watchdog_allows_exactly_its_time(robot):
    """A polled arm's stamp unchanged for exactly ``watchdog`` is no stop; longer is
    (with the loop's watchdog of 50 ms given here as 5 ms)."""
    loop, _ = _loop(robot, 0.1, lambda a, c: a)
    loop._fresh = (1.0, 0.0)
    assert loop._watch(1.0, 0.005, 0.005) is None
    assert loop._fresh == (1.0, 0.0)
    stop = loop._watch(1.0, 0.0051, 0.005)
    assert stop is not None and stop[0] == "watchdog" and "(watchdog 5 ms)" in stop[1]
    assert loop._watch(1.001, 0.0051, 0.005) is None  # a new stamp: fresh again
    assert loop._fresh == (1.001, 0.0051)


def test_a_reference_is_swapped_in_at_its_time_to_rounding(robot):
    loop, _ = _loop(robot, 0.1, lambda a, c: a)
    old, new = loop.reference, SineReference(3, amplitude=[0.1, 0.1, 0.1], frequency=[1, 1, 1])
    assert loop.set_reference(new, at=0.3)
    assert loop._swap_reference(0.29, old) is old and loop.pending_reference is not None
    assert loop._swap_reference(0.3 - 5e-10, old) is not old  # 0.3 as 30 steps of 0.01
    assert loop.pending_reference is None and loop.reference is not old
    # a reference made against one no longer in use is not taken; without a base it is
    assert not loop.set_reference(new, at=0.5, base=old)
    assert loop.set_reference(new, at=0.5)


def test_a_stop_asked_while_the_arm_is_silent_is_that_stop_not_the_watchdog(robot):
    """The arm's last state is the one of the step at 0.1 s, and the stop is asked at that
    step: the loop waits in vain for the next state, and the stop is the one asked
    (Ctrl-C), not a watchdog."""
    holder = {}

    def hook(t):
        if t >= 0.1 - 1e-9:
            holder["loop"].request_stop()

    loop, _ = _loop(robot, 0.5, lambda a, c: Paced(a, c, silent_after=0.1015), hook=hook)
    holder["loop"] = loop
    run = loop.run()
    assert not run.complete and run.stop["cause"] == "interrupted"
    assert run.stop["t"] == pytest.approx(0.1, abs=1.5 * P)


# ------------------------------------------------------------ the stop sequence
class Recorder:
    """The arm, with every command written recorded (after ``mark`` is set: the stop)."""

    def __init__(self, arm, t_stop=np.inf):
        self.arm, self.t_stop = arm, t_stop
        self.nq, self.period = arm.nq, arm.period
        self.writes: list[np.ndarray] = []
        self._last = None

    def read(self):
        stamp, q, dq = self.arm.read()
        if stamp >= self.t_stop and self._last is not None:  # frozen from t_stop on
            return self._last
        self._last = (stamp, q.copy(), dq.copy())
        return stamp, q, dq

    def write(self, tau):
        self.writes.append(np.array(tau, dtype=float))
        self.arm.write(tau)

    def close(self):
        self.arm.close()


class PacedRecorder(Paced):
    """:class:`Paced` with every command written recorded."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.writes: list[np.ndarray] = []

    def write(self, tau):
        self.writes.append(np.array(tau, dtype=float))
        super().write(tau)


def _g(robot, q):
    model = robot.model
    zero = np.zeros(model.nv)
    return np.array(pin.rnea(model, model.createData(), np.asarray(q), zero, zero))


def test_a_complete_run_ends_with_the_safe_torque_then_the_held_one(robot):
    """hold = 0: after the last cycle the arm gets G(q) - D dq at the last state (the
    brake's first command), then G(q) at that position with no velocity term, and
    nothing after it."""
    from .test_realtime import _setup

    safety = SafetySettings.unlimited(3, max_misses=5, watchdog=0.005, hold=0.0)
    loop, _, _, _ = _setup(robot, 0.2, safety=safety, wrap=Recorder)
    run = loop.run()
    assert run.complete
    writes = loop.interface.writes
    assert len(writes) == 201 + 2
    q, dq = run.stats["brake"]["q"], np.asarray(loop.interface._last[2])
    np.testing.assert_allclose(writes[-2], _g(robot, q) - 3.0 * dq, atol=1e-9)
    np.testing.assert_allclose(writes[-1], _g(robot, q), atol=1e-9)
    np.testing.assert_allclose(run.stats["brake"]["held_tau"], writes[-1], atol=0)


def test_a_frozen_stamp_during_the_brake_ends_it_after_the_watchdog_not_the_hold(robot):
    """Ctrl-C at 0.3 s on a polled arm whose stamp freezes then: the brake waits one
    watchdog for a fresh state, not the whole hold, and leaves G(q) at the last position."""
    from .test_realtime import _setup

    safety = SafetySettings.unlimited(3, max_misses=5, watchdog=0.005, hold=1.0)
    holder = {}

    def hook(t):
        if t >= 0.3 - 1e-9:
            holder["loop"].request_stop()

    loop, _, _, _ = _setup(robot, 0.6, safety=safety, hook=hook,
                           wrap=lambda a: Recorder(a, t_stop=0.3))  # fmt: skip
    holder["loop"] = loop
    run = loop.run()
    brake = run.stop["brake"]
    assert run.stop["cause"] == "interrupted"
    assert brake["ended"] == "no fresh state"
    assert brake["duration"] <= 0.005 + 2 * P
    np.testing.assert_allclose(loop.interface.writes[-1], _g(robot, brake["q"]), atol=1e-9)


def test_after_a_watchdog_stop_the_held_torque_is_written_once(robot):
    """No fresh state to brake on: G(q) at the last position, written once (no damping
    on a velocity no longer measured), and it is the stop's safe torque."""
    loop, _ = _loop(robot, 1.0, lambda a, c: PacedRecorder(a, c, silent_after=0.3))
    run = loop.run()
    assert run.stop["cause"] == "watchdog"
    writes = loop.interface.writes
    cycles = int(np.count_nonzero(np.isfinite(run.timing["latency"])))
    assert len(writes) == cycles + 1
    np.testing.assert_allclose(writes[-1], _g(robot, run.stop["q"]), atol=1e-9)
    np.testing.assert_allclose(run.stop["safe_tau"], writes[-1], atol=0)


class _NaNBrake:
    """A safe torque whose brake is not finite (a model gone wrong), its held one finite
    or not."""

    def __init__(self, robot, held_finite=True):
        self.robot, self.held_finite = robot, held_finite

    def __call__(self, q, dq):
        return np.full(3, np.nan)

    def held(self, q):
        return _g(self.robot, q) if self.held_finite else np.full(3, np.nan)


def test_a_non_finite_safe_torque_is_never_written(robot):
    """The brake NaN: the held torque G(q) is written instead; that NaN too: zero."""
    loop, _ = _loop(robot, 0.1, lambda a, c: Recorder(a))
    q, dq = np.array([0.1, 0.2, 0.3]), np.array([1.0, -1.0, 0.5])
    loop.safe_torque = _NaNBrake(robot)
    np.testing.assert_allclose(loop._safe_write(q, dq), _g(robot, q), atol=1e-9)
    np.testing.assert_allclose(loop.interface.writes[-1], _g(robot, q), atol=1e-9)
    loop.safe_torque = _NaNBrake(robot, held_finite=False)
    np.testing.assert_array_equal(loop._safe_write(q, dq), np.zeros(3))
    np.testing.assert_array_equal(loop.interface.writes[-1], np.zeros(3))
    assert all(np.isfinite(w).all() for w in loop.interface.writes)


def test_a_miss_stop_at_the_last_cycle_is_recorded_at_that_cycle(robot):
    """The last MPC step (t = 0.2 s, cycle 200 of 0..200) takes 1.5 periods with
    max_misses = 1: the stop is at cycle 200, t = 0.2 s, not past the run."""
    from .test_realtime import _setup

    safety = SafetySettings.unlimited(3, max_misses=1, watchdog=0.005, hold=0.01)
    loop, _, _, _ = _setup(robot, 0.2, safety=safety,
                           cost=lambda t: 1.5 * P if t >= 0.2 - 1e-9 else 0.0)  # fmt: skip
    run = loop.run()
    assert run.stop["cause"] == "misses"
    assert run.stop["cycle"] == 200 and run.stop["t"] == pytest.approx(0.2)
    assert "cycle 200)" in run.stop["reason"]


class Gapped(Overdue):
    """:class:`Overdue` whose skipped periods had no state at all (``gaps``: the stamps
    jumped, as a driver on another clock's or a lost message's)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._jumps = dict(self.extra)  # (Paced pops its extra as it goes)

    @property
    def gaps(self) -> int:
        return sum(n for k, n in self._jumps.items() if k <= self.k)


@pytest.mark.parametrize(
    ("extra", "complete"), [({101: 2, 201: 3}, True), ({101: 3, 201: 3}, False)]
)
def test_a_run_whose_stamps_skip_periods_is_not_complete(robot, extra, complete):
    """Periods the arm's stamps passed with no state for them: up to max_misses (5) the run
    is complete, beyond it not (it reached its end; no stop), with one line naming the
    count and the setting."""
    loop, _ = _loop(robot, 0.5, lambda a, c: Gapped(a, c, extra=extra))
    run = loop.run()
    assert run.stop is None
    assert run.stats["arm_gaps"] == sum(extra.values())
    assert run.complete is complete and run.result.complete is complete
    if not complete:
        assert "passed 6 periods" in run.result.message
        assert "realtime.max_misses = 5" in run.result.message
