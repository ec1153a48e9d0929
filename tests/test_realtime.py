"""The real-time loop (hmpc_pin.realtime) against the in-process plant with an injected
clock (deadlines, misses, watchdog, every safe-stop cause), and short wall-clock runs
against the arm in a separate process (completion and the recorded statistics; no
assertion on wall-clock figures)."""

from __future__ import annotations

import functools
import gc
import os
import signal
import time

import numpy as np
import pinocchio as pin
import pytest

import hmpc_pin
from hmpc_pin.controllers.base import ControllerWrapper
from hmpc_pin.controllers.hierarchical import MPCSettings
from hmpc_pin.realtime import (
    LoopSettings,
    PlantArm,
    ProcessArm,
    RealtimeLoop,
    SafeTorque,
    SafetySettings,
)
from hmpc_pin.sim import Result, RK4Plant
from hmpc_pin.tasks import SineReference

P = 0.001  # interface period [s]
Ts = 0.01  # controller period [s]


@pytest.fixture(scope="module")
def robot():
    return hmpc_pin.load_robot("planar3")


class FakeClock:
    """Seconds that move only when the loop sleeps or a test spends time."""

    def __init__(self, start: float = 100.0):
        self.now = start

    def __call__(self) -> float:
        return self.now

    def sleep(self, deadline: float) -> None:
        self.now = max(self.now, deadline)


class Spend(ControllerWrapper):
    """The wrapped controller, taking ``cost(t)`` seconds of the fake clock per step."""

    def __init__(self, controller, clock, cost, hook=None):
        super().__init__(controller)
        self.clock, self.cost, self.hook = clock, cost, hook

    def step(self, t, q, dq, reference):
        if self.hook is not None:
            self.hook(t)
        tau = self.controller.step(t, q, dq, reference)
        self.clock.now += self.cost(t)
        return tau


class Frozen:
    """An interface whose state stops arriving (stamp and state frozen) after ``t_stop``,
    or turns non-finite after ``t_nan``."""

    def __init__(self, arm, t_stop=np.inf, t_nan=np.inf):
        self.arm, self.t_stop, self.t_nan = arm, t_stop, t_nan
        self.nq, self.period = arm.nq, arm.period
        self._last = None

    def read(self):
        stamp, q, dq = self.arm.read()
        if stamp >= self.t_nan:
            return stamp, np.full(self.nq, np.nan), dq
        if stamp >= self.t_stop and self._last is not None:
            return self._last
        self._last = (stamp, q.copy(), dq.copy())
        return stamp, q, dq

    def write(self, tau):
        self.arm.write(tau)

    def close(self):
        self.arm.close()


def _sine():
    return SineReference(3, amplitude=[0.5, 0.3, 0.2], frequency=[0.5, 0.4, 0.3],
                         offset=[0.3, -0.4, 0.2])  # fmt: skip


def _setup(robot, duration=1.0, *, cost=lambda t: 0.0, hook=None, settings=None,
           safety=None, wrap=None, controller=None, gc_handling=True, reference=None,
           damping=3.0):  # fmt: skip
    clock = FakeClock()
    ref = reference if reference is not None else _sine()
    q0 = _sine().sample(0.0)[0]
    arm = PlantArm(RK4Plant(robot.copy(), None, P, P), q0, clock=clock)
    iface = wrap(arm) if wrap is not None else arm
    ctrl = Spend(controller or hmpc_pin.make_controller(robot), clock, cost, hook)
    loop = RealtimeLoop(
        iface, ctrl, ref, SafeTorque(robot, damping=damping),
        settings or LoopSettings(1.0 / P, duration, gc_handling=gc_handling),
        safety or SafetySettings.unlimited(3, max_misses=5, watchdog=0.005, hold=0.01),
        clock=clock, sleep=clock.sleep, joint_names=tuple(robot.joint_names),
    )  # fmt: skip
    return loop, arm, clock, q0


def _safe(robot, q, dq, damping=3.0):
    """G(q) − D q̇ from Pinocchio's RNEA at zero velocity and acceleration."""
    model = robot.model
    data = model.createData()
    return pin.rnea(model, data, np.asarray(q), np.zeros(3), np.zeros(3)) - damping * dq


def test_without_latency_the_loop_is_the_simulation(robot):
    """Zero compute time: the same torques and states as ``simulate`` (a second loop)."""
    loop, _, _, q0 = _setup(robot, 1.0)
    run = loop.run()
    sim = hmpc_pin.simulate(robot, hmpc_pin.make_controller(robot), _sine(), duration=1.0, q0=q0)
    assert run.complete and run.result.complete
    np.testing.assert_allclose(run.result.t, sim.t, atol=1e-12)
    np.testing.assert_allclose(run.result.q, sim.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(run.result.tau, sim.tau, rtol=0, atol=1e-9)
    assert run.stats["cycles"] == run.stats["cycles_run"] == 1001
    assert run.stats["misses"] == 0
    assert np.isnan(run.result.d).all()  # an arm does not report its disturbance


def test_deadlines_are_absolute_so_compute_time_does_not_drift_them(robot):
    """0.4 P of compute per MPC step: every wake-up is exactly on its deadline (a relative
    sleep of P after each cycle would drift by 0.4 P every controller step)."""
    loop, _, _, _ = _setup(robot, 0.5, cost=lambda t: 0.4 * P)
    run = loop.run()
    tm = run.timing
    np.testing.assert_allclose(tm["wake"], 0.0, atol=1e-9)
    mpc = tm["mpc"]
    assert mpc.sum() == 51 and mpc[::10].all()
    np.testing.assert_allclose(tm["latency"][mpc], 0.4 * P, atol=1e-9)
    np.testing.assert_allclose(tm["latency"][~mpc], 0.0, atol=1e-9)
    assert run.stats["misses"] == 0
    # the arm's stamps follow the grid: cycle k reads the state of k periods after start
    np.testing.assert_allclose(np.diff(tm["stamp"][1:]), P, atol=1e-9)


def test_a_late_cycle_is_a_miss_and_the_next_ones_recover(robot):
    """1.5 P at every MPC step: each MPC cycle misses its period; the next cycle runs
    late but within its own period; no deadline is skipped; k is never reached."""
    loop, _, _, _ = _setup(robot, 0.5, cost=lambda t: 1.5 * P)
    run = loop.run()
    tm = run.timing
    assert run.complete
    assert run.stats["misses"] == 51 == tm["missed"].sum() == tm["mpc"].sum()
    assert (tm["missed"] == tm["mpc"]).all()
    after = np.flatnonzero(tm["mpc"])[:-1] + 1
    np.testing.assert_allclose(tm["wake"][after], 0.5 * P, atol=1e-9)
    assert run.stats["skipped"] == 0 and run.stats["max_consecutive_misses"] == 1
    assert run.stats["miss_fraction"] == pytest.approx(51 / 501)


def test_skipped_deadlines_count_as_misses(robot):
    """3.5 P once at t = 0.2 s: the two deadlines passed meanwhile are skipped."""
    loop, _, _, _ = _setup(robot, 0.5, cost=lambda t: 3.5 * P if abs(t - 0.2) < 1e-9 else 0.0)
    run = loop.run()
    assert run.complete
    assert run.stats["skipped"] == 2 and run.stats["misses"] == 3
    assert run.stats["max_consecutive_misses"] == 3
    k = 200
    assert run.timing["missed"][k : k + 3].all() and not run.timing["missed"][k + 3]
    assert np.isnan(run.timing["latency"][k + 1 : k + 3]).all()
    assert run.stats["miss_fraction"] == pytest.approx(3 / 501)  # of the 501 deadlines due


def _check_stop(robot, run, arm, cause, t_expected, tol, held=None):
    stop = run.stop
    assert not run.complete and not run.result.complete
    assert stop["cause"] == cause
    assert stop["t"] == pytest.approx(t_expected, abs=tol)
    assert run.result.message == stop["reason"] and "safe stop at" in stop["reason"]
    assert "\n" not in stop["reason"]
    assert "gravity compensation + damping 3 N·m·s/rad" in stop["reason"]
    # the safe torque, written in the detecting cycle, is G(q) − D q̇ at the last state
    # (after a watchdog stop, with no fresh state to brake on, G(q): no velocity term)
    assert stop["safe_after_detection"] <= P
    dq_stop = np.zeros(3) if cause == "watchdog" else np.array(stop["dq"])
    np.testing.assert_allclose(stop["safe_tau"], _safe(robot, stop["q"], dq_stop), atol=1e-10)
    # the arm is left holding G(q) at the last finite position (no velocity term): the
    # arm's own position at the end of the brake, or the frozen state it last sent
    brake = stop["brake"]
    q = held[0] if held is not None else arm.q
    np.testing.assert_allclose(brake["q"], q, atol=1e-12)
    np.testing.assert_allclose(arm.tau, _safe(robot, q, np.zeros(3)), atol=1e-10)
    assert np.isfinite(arm.tau).all()
    # the run up to the stop: samples on the controller grid, all before the stop
    assert run.result.t[-1] <= stop["t"] + 1e-12
    np.testing.assert_allclose(np.diff(run.result.t), Ts, atol=1e-12)


class Slow(Frozen):
    """An interface whose read takes 1.2 P of the fake clock from ``t_slow`` on."""

    def __init__(self, arm, clock, t_slow):
        super().__init__(arm)
        self.clock, self.t_slow = clock, t_slow

    def read(self):
        stamp, q, dq = self.arm.read()
        if stamp >= self.t_slow:
            self.clock.now += 1.2 * P
        return stamp, q, dq


def test_k_consecutive_misses_stop_the_loop(robot):
    """Every cycle takes 1.2 P from t = 0.3 s: misses 1, 2, … until k = 5 stops the loop
    (a deadline skipped when the lag passes a period counts too)."""
    slow = []
    loop, arm, _clock, _ = _setup(
        robot, 1.0, wrap=lambda a: slow.append(Slow(a, clock_of(a), 0.3)) or slow[0]
    )
    run = loop.run()
    stop = run.stop
    _check_stop(robot, run, arm, "misses", 0.3035, 0.0036)
    assert "5 consecutive missed deadlines (limit 5)" in stop["reason"]
    assert run.stats["max_consecutive_misses"] == 5
    missed = np.flatnonzero(run.timing["missed"])
    assert missed[0] == 300 and (np.diff(missed) == 1).all()


def clock_of(arm):
    return arm._clock


def test_watchdog_stops_when_the_state_stops_arriving(robot):
    frozen = []
    loop, arm, _, _ = _setup(robot, 1.0, wrap=lambda a: frozen.append(Frozen(a, 0.4)) or frozen[0])
    run = loop.run()
    # last fresh stamp at 0.4 s, watchdog 5 ms: stop in the first cycle after 0.405 s
    _check_stop(robot, run, arm, "watchdog", 0.4055, 0.001, held=frozen[0]._last[1:])
    assert "no new state from the arm" in run.stop["reason"]


def test_non_finite_state_is_a_fault_and_the_safe_torque_uses_the_last_finite_state(robot):
    loop, arm, _, _ = _setup(robot, 1.0, wrap=lambda a: Frozen(a, t_nan=0.25))
    run = loop.run()
    _check_stop(robot, run, arm, "fault", 0.25, 1e-9, held=(run.stop["q"], run.stop["dq"]))
    assert "non-finite state" in run.stop["reason"]
    assert np.isfinite(run.stop["q"]).all()


def test_qp_not_solved_is_a_fault(robot):
    """A real ProxSuite failure: one iteration allowed."""
    # the block QP goes to ProxSuite at every step (the per-joint QPs of this start are
    # answered without it: no bound active, or the active-set shortcut)
    ctrl = hmpc_pin.HierarchicalMPC(robot, MPCSettings(max_iter=1, qp_layout="block"))
    loop, _arm, _, _ = _setup(robot, 1.0, controller=ctrl)
    run = loop.run()
    assert run.stop["cause"] == "fault" and "QP was not solved" in run.stop["reason"]
    assert run.stop["cycle"] == 0 and len(run.result.t) == 0
    np.testing.assert_allclose(run.stop["safe_tau"],
                               _safe(robot, run.stop["q"], np.array(run.stop["dq"])),
                               atol=1e-10)  # fmt: skip


def test_non_finite_reference_mid_run_is_a_fault(robot):
    class Broken:
        def sample(self, t):
            q, dq = _sine().sample(t)
            return (q * np.nan, dq) if t > 0.3 else (q, dq)

    loop, arm, _, _ = _setup(robot, 1.0, reference=Broken())
    run = loop.run()
    # the horizon t + j Ts, j = 1..N, reaches past 0.3 s N steps early: the step at
    # 0.2 s (0.2 + 0.1 rounds above 0.3) or at 0.21 s fails
    _check_stop(robot, run, arm, "fault", 0.205, 0.0051)
    assert "reference is not finite" in run.stop["reason"]


def test_state_beyond_its_bounds_is_a_fault(robot):
    q0 = _sine().sample(0.0)[0]
    upper = np.array([q0[0] + 0.2, np.inf, np.inf])  # joint 1 rises 0.5 rad: crosses it
    safety = SafetySettings(np.full(3, -np.inf), upper, np.full(3, np.inf), max_misses=5,
                            watchdog=0.005, hold=0.01)  # fmt: skip
    loop, arm, _, _ = _setup(robot, 1.0, safety=safety)
    run = loop.run()
    t_cross = np.arcsin(0.2 / 0.5) / (2 * np.pi * 0.5)  # where the reference crosses
    _check_stop(robot, run, arm, "fault", t_cross, 0.02)
    assert f"joint {robot.joint_names[0]!r}" in run.stop["reason"]
    assert run.stop["q"][0] <= upper[0] < run.timing["stamp"].size  # last state kept was inside


def test_ctrl_c_stops_safely_and_restores_the_handler(robot):
    """A real SIGINT, delivered during the step at t = 0.35 s."""
    before = signal.getsignal(signal.SIGINT)

    def hook(t):
        if abs(t - 0.35) < 1e-9:
            os.kill(os.getpid(), signal.SIGINT)

    loop, arm, _, _ = _setup(robot, 1.0, hook=hook)
    run = loop.run()
    _check_stop(robot, run, arm, "interrupted", 0.351, 1e-9)
    assert "interrupted (Ctrl-C)" in run.stop["reason"]
    assert signal.getsignal(signal.SIGINT) is before


def test_partial_run_is_saved_with_complete_false(robot, tmp_path):
    loop, _, _, _ = _setup(robot, 1.0, wrap=lambda a: Frozen(a, t_stop=0.2))
    run = loop.run()
    path = run.result.save(tmp_path / "rt.npz")
    back = Result.load(path)
    assert not back.complete and back.message == run.stop["reason"]
    assert back.meta["stop"]["cause"] == "watchdog"
    assert back.meta["realtime"]["misses"] == run.stats["misses"]
    np.testing.assert_array_equal(back.q, run.result.q)
    timing = np.load(run.save_timing(tmp_path / "rt_timing.npz"))
    np.testing.assert_array_equal(timing["latency"], run.timing["latency"])


def _drift_holding(robot, q, dq, tau, seconds=2.0):
    """The largest |q(t) − q| [rad] over ``seconds`` of the arm holding ``tau`` from
    (q, dq): Pinocchio's ABA, semi-implicit Euler at 1 ms (no friction)."""
    model, data = robot.model, robot.model.createData()
    q, dq, q0 = np.array(q, dtype=float), np.array(dq, dtype=float), np.array(q, dtype=float)
    worst = 0.0
    for _ in range(round(seconds / 1e-3)):
        dq = dq + 1e-3 * pin.aba(model, data, q, dq, np.asarray(tau))
        q = q + 1e-3 * dq
        worst = max(worst, float(np.abs(q - q0).max()))
    return worst


@pytest.mark.parametrize("stop", ["complete", "interrupted", "watchdog"])
def test_the_stop_sequence_leaves_the_arm_still(robot, stop):
    """After every kind of end the last command is G(q) at the last finite position (no
    velocity term); with fresh states the loop brakes until every joint is below
    brake_speed first. Holding that command for 2 s (the arm integrated by ABA, no
    friction) moves it at its residual speed, below brake_speed, with fresh states;
    without (watchdog) the arm coasts at the speed it had, and the command itself adds no
    motion. (Damping 40 N·m·s/rad: planar3's first joint carries
    16 kg·m², a decay time M/D of 0.4 s.)"""
    safety = SafetySettings.unlimited(3, max_misses=5, watchdog=0.005, hold=3.0,
                                      brake_speed=0.005)  # fmt: skip
    hook = None
    if stop == "interrupted":

        def hook(t):
            if abs(t - 0.35) < 1e-9:
                os.kill(os.getpid(), signal.SIGINT)

    wrap = (lambda a: Frozen(a, t_stop=0.4)) if stop == "watchdog" else None
    loop, arm, _, _ = _setup(robot, 0.6, safety=safety, hook=hook, wrap=wrap, damping=40.0)
    run = loop.run()
    brake = run.stats["brake"]
    # the command the arm holds is G at the last finite position (RNEA directly)
    np.testing.assert_allclose(arm.tau, _safe(robot, brake["q"], np.zeros(3), 40.0),
                               atol=1e-10)  # fmt: skip
    if stop == "watchdog":
        assert run.stop["cause"] == "watchdog" and brake["ended"] == "no fresh state"
        assert brake["states"] == 0
        # no velocity term: the command is an equilibrium at the last position the arm
        # sent (the old G − D q̇_frozen was a constant torque accelerating it)
        q = np.array(brake["q"])
        np.testing.assert_allclose(q, run.stop["q"], atol=0)
        ddq = pin.aba(robot.model, robot.model.createData(), q, np.zeros(3), arm.tau)
        np.testing.assert_allclose(ddq, 0.0, atol=1e-9)
    else:
        assert run.complete == (stop == "complete")
        assert brake["ended"] == "still" and brake["states"] > 0
        assert np.abs(arm.dq).max() < safety.brake_speed
        np.testing.assert_allclose(brake["q"], arm.q, atol=1e-12)
        # the held command is an equilibrium at the brake's position (ABA at rest: 0) ...
        model = robot.model
        ddq = pin.aba(model, model.createData(), arm.q, np.zeros(3), arm.tau)
        np.testing.assert_allclose(ddq, 0.0, atol=1e-9)
        # ... and the arm leaves it at the residual speed only: over 0.2 s (before the
        # configuration's gravity instability, a frictionless planar arm held above the
        # horizontal, grows it) it drifts at most 0.2 s · brake_speed
        drift = _drift_holding(robot, arm.q, arm.dq, arm.tau, 0.2)
        assert drift <= 0.2 * safety.brake_speed * 1.1


class Reused:
    """An interface whose ``read`` returns the same two arrays every time (as drivers
    do), filled with NaN from ``t_nan`` on."""

    def __init__(self, arm, t_nan):
        self.arm, self.t_nan = arm, t_nan
        self.nq, self.period = arm.nq, arm.period
        self.q, self.dq = np.zeros(arm.nq), np.zeros(arm.nq)
        self.written = []
        self.events = []  # ("read", stamp) and ("write", tau), in order

    def read(self):
        stamp, q, dq = self.arm.read()
        self.q[:] = np.nan if stamp >= self.t_nan else q
        self.dq[:] = np.nan if stamp >= self.t_nan else dq
        self.events.append(("read", stamp))
        return stamp, self.q, self.dq

    def write(self, tau):
        self.written.append(np.array(tau, dtype=float))
        self.events.append(("write", self.written[-1]))
        self.arm.write(tau)

    def close(self):
        self.arm.close()


def test_no_non_finite_command_when_the_reused_arrays_turn_nan(robot):
    """States turn NaN in the interface's reused arrays: a fault; every command written
    before, during and after the stop is finite, and the last is G at the last finite
    position (the brake ignores the non-finite states)."""
    box = []
    safety = SafetySettings.unlimited(3, max_misses=5, watchdog=0.005, hold=0.05)
    loop, _arm, _, _ = _setup(robot, 1.0, safety=safety,
                             wrap=lambda a: box.append(Reused(a, 0.25)) or box[0])  # fmt: skip
    run = loop.run()
    iface = box[0]
    assert run.stop["cause"] == "fault" and "non-finite state" in run.stop["reason"]
    assert len(iface.written) > 250 and all(np.isfinite(t).all() for t in iface.written)
    # (NaN states keep coming: none braked on, the brake ends at its time bound)
    assert run.stop["brake"]["states"] == 0 and run.stop["brake"]["ended"] == "time bound"
    held = _safe(robot, run.stop["q"], np.zeros(3))
    np.testing.assert_allclose(iface.written[-1], held, atol=1e-10)
    # the stop's damping on the last finite velocity does not stay on the arm while NaN
    # states come: the first fresh (NaN) state after it is answered by the held-safe torque
    ev = iface.events
    first = next(i for i, e in enumerate(ev)
                 if e[0] == "write" and np.allclose(e[1], run.stop["safe_tau"]))  # fmt: skip
    stamp = max(e[1] for e in ev[:first] if e[0] == "read")
    fresh = next(i for i in range(first, len(ev)) if ev[i][0] == "read" and ev[i][1] > stamp)
    assert ev[fresh + 1][0] == "write", ev[fresh : fresh + 3]
    np.testing.assert_allclose(ev[fresh + 1][1], held, atol=1e-10)


def test_garbage_is_collected_only_in_the_slack_and_gc_state_is_restored(robot):
    """Reference cycles made at every step: with GC handling they are collected by the
    loop (automatic collection off), deferred when the slack is too short."""

    def litter(t):
        for _ in range(300):
            a = []
            a.append(a)  # a cycle: only the collector frees it

    assert gc.isenabled()
    loop, _, _, _ = _setup(robot, 0.5, hook=litter)
    run = loop.run()
    assert run.stats["gc_collections"] > 0 and run.stats["gc_deferred"] == 0
    # every collection during the run was the loop's own (automatic collection off)
    assert run.stats["gc_all_collections"] == run.stats["gc_collections"]
    assert gc.isenabled() and gc.get_freeze_count() == 0
    # 0.9 P of compute in the MPC cycles, gc_slack 0.3 P: the collection the litter calls
    # for there is deferred to a later cycle with slack
    settings = LoopSettings(1.0 / P, 0.5, gc_slack=0.3 * P)
    loop, _, _, _ = _setup(robot, 0.5, hook=litter, cost=lambda t: 0.9 * P, settings=settings)
    run = loop.run()
    assert run.stats["gc_collections"] > 0 and run.stats["gc_deferred"] > 0
    collected = np.isfinite(run.timing["gc"])
    assert not (collected & run.timing["mpc"]).any()
    assert (run.timing["latency"][collected] <= 0.7 * P + 1e-12).all()
    assert gc.isenabled() and gc.get_freeze_count() == 0
    # without handling, the loop leaves the collector alone
    loop, _, _, _ = _setup(robot, 0.2, hook=litter, gc_handling=False)
    run = loop.run()
    assert run.stats["gc_collections"] == 0 and not run.stats["gc_handling"]
    # …whose automatic collections (inside the controller's step) are counted
    assert run.stats["gc_all_collections"] > 0
    assert gc.callbacks == [] or all(type(c).__name__ != "_GCWatch" for c in gc.callbacks)


def test_rate_must_divide_the_controller_period(robot):
    with pytest.raises(hmpc_pin.ConfigError, match=r"realtime\.rate"):
        _setup(robot, settings=LoopSettings(750.0, 1.0))
    with pytest.raises(hmpc_pin.ConfigError, match=r"realtime\.duration"):
        LoopSettings(1000.0, -1.0)


def test_spin_busy_waits_the_end_of_the_wait_and_never_returns_early():
    """``sleep_until`` with ``spin``: no ``time.sleep`` for a wait shorter than the spin
    (the clock is polled until the deadline), and on the real clock it never returns
    before the deadline, with or without spin."""
    from hmpc_pin.realtime.loop import sleep_until

    now = [0.0]

    def clock():  # 1 µs per poll
        now[0] += 1e-6
        return now[0]

    sleep_until(1e-4, clock, spin=2e-4)
    assert 1e-4 <= now[0] < 1e-4 + 2e-6 and now[0] > 90e-6  # ~100 polls, no sleep
    now[0] = 0.0
    sleep_until(1e-4, clock)  # no spin: one look at the clock, the sleep is time.sleep's
    assert now[0] == pytest.approx(1e-6)
    for spin in (0.0, 3e-4):
        deadline = time.perf_counter() + 1e-3
        sleep_until(deadline, spin=spin)
        assert time.perf_counter() >= deadline
    with pytest.raises(hmpc_pin.ConfigError, match=r"realtime\.spin"):
        LoopSettings(1000.0, 1.0, spin=1e-3)  # a whole period of spinning


def test_spin_with_an_injected_sleep_does_not_apply(robot):
    with pytest.raises(hmpc_pin.ConfigError, match=r"realtime\.spin.*does not apply"):
        _setup(robot, settings=LoopSettings(1000.0, 1.0, spin=2e-4))


def test_safe_torque_rejects_negative_damping(robot):
    with pytest.raises(hmpc_pin.ConfigError, match="damping"):
        SafeTorque(robot, damping=[-1.0, 0.0, 0.0])
    no_g = SafeTorque(robot, damping=1.0, gravity=False)
    np.testing.assert_allclose(no_g(np.ones(3), np.array([1.0, -2.0, 0.5])), [-1.0, 2.0, -0.5])


# ------------------------------------------------------------ the arm in another process
def _planar_plant(period):
    return RK4Plant(hmpc_pin.load_robot("planar3"), None, period, period)


def _broken_plant():
    raise RuntimeError("no plant here")


def test_wall_clock_run_against_the_arm_process_completes_with_statistics(robot):
    """1 s at 1 kHz on the shared machine: completion and the records, not the figures."""
    ref = _sine()
    q0 = ref.sample(0.0)[0]
    safety = SafetySettings.unlimited(3, max_misses=10**6, watchdog=1.0, hold=0.05)
    with ProcessArm(functools.partial(_planar_plant, P), q0) as arm:
        assert arm.period == P
        loop = RealtimeLoop(arm, hmpc_pin.make_controller(robot), ref, SafeTorque(robot),
                            LoopSettings(1.0 / P, 1.0), safety)  # fmt: skip
        run = loop.run()
        counters = arm.counters
    assert not arm.alive
    why = f"{run.summary()}\narm: {counters}\nstop: {run.stop}"
    assert run.complete, why
    s = run.stats
    assert s["cycles"] == 1001 and s["cycles_run"] + s["skipped"] == 1001
    assert s["misses"] == int(run.timing["missed"].sum())
    for key in ("median_us", "p99_us", "p999_us", "max_us"):
        assert np.isfinite(s["latency"][key]) and s["latency"][key] >= 0
    lat = s["latency"]
    assert lat["median_us"] <= lat["p99_us"] <= lat["p999_us"] <= lat["max_us"]
    assert counters["steps"] > 900, why  # the arm integrated in wall-clock time
    # the arm's time advanced with the wall: stamps increase, in whole periods
    stamps = run.timing["stamp"][np.isfinite(run.timing["stamp"])]
    assert (np.diff(stamps) >= 0).all() and stamps[-1] > 0.9, why
    np.testing.assert_allclose(stamps / P, np.round(stamps / P), atol=1e-6)
    # and the arm tracked (loose: a wall-clock run on a loaded machine)
    assert np.abs(run.result.error[-1]).max() < 0.05, why
    # the record ends at the last control instant that ran: 1 s, or, when the machine made
    # the loop skip its last cycles, at most one run of misses (plus one control period)
    # earlier
    ctrl_period = hmpc_pin.ControllerConfig().Ts
    slack = s["max_consecutive_misses"] * P + ctrl_period
    assert 1.0 - slack - 1e-9 <= run.result.t[-1] <= 1.0 + 1e-9, why


def test_the_arm_process_stall_trips_the_watchdog(robot):
    ref = _sine()
    q0 = ref.sample(0.0)[0]
    safety = SafetySettings.unlimited(3, max_misses=10**6, watchdog=0.05, hold=0.02)
    with ProcessArm(functools.partial(_planar_plant, P), q0) as arm:
        ctrl = ControllerWrapper(hmpc_pin.make_controller(robot))
        loop = RealtimeLoop(arm, ctrl, ref, SafeTorque(robot), LoopSettings(1.0 / P, 5.0),
                            safety)  # fmt: skip
        original = ctrl.step

        def step(t, q, dq, reference):
            if t >= 0.2:
                arm.stall()
            return original(t, q, dq, reference)

        ctrl.step = step
        run = loop.run()
    assert run.stop["cause"] == "watchdog"
    assert 0.2 < run.stop["t"] < 4.0


def test_a_failing_arm_process_reports_its_traceback():
    with pytest.raises(hmpc_pin.SimulationError, match="no plant here"):
        ProcessArm(_broken_plant, np.zeros(3))


class WarmRecorder(Spend):
    """``Spend`` that also forwards ``warm_up``, recording the clock and arguments of each."""

    def __init__(self, controller, clock):
        super().__init__(controller, clock, lambda t: 0.0)
        self.calls = []

    def warm_up(self, t, q, dq, reference):
        self.calls.append((self.clock(), t, np.array(q), np.array(dq)))
        self.controller.warm_up(t, q, dq, reference)


def test_warm_up_runs_in_the_slack_before_each_mpc_cycle_and_changes_no_result(robot):
    """With ``warm_up`` = 2e-4 s the loop calls the controller's ``warm_up`` once before each
    MPC cycle but the first, 2e-4 s before its deadline, with that cycle's time and the last
    measured state; the run equals ``simulate`` (the step it precedes is unchanged)."""
    clock = FakeClock()
    q0 = _sine().sample(0.0)[0]
    arm = PlantArm(RK4Plant(robot.copy(), None, P, P), q0, clock=clock)
    ctrl = WarmRecorder(hmpc_pin.make_controller(robot), clock)
    states = []
    real_read = arm.read

    def read():
        stamp, q, dq = real_read()
        states.append((q.copy(), dq.copy()))
        return stamp, q, dq

    arm.read = read
    loop = RealtimeLoop(
        arm, ctrl, _sine(), SafeTorque(robot, damping=3.0),
        LoopSettings(1.0 / P, 1.0, warm_up=2e-4),
        SafetySettings.unlimited(3, max_misses=5, watchdog=0.005, hold=0.01),
        clock=clock, sleep=clock.sleep, joint_names=tuple(robot.joint_names),
    )  # fmt: skip
    t0 = clock() + P
    run = loop.run()
    m = loop.decimation
    mpc_cycles = list(range(0, 1001, m))
    assert [round(c[1] / P) for c in ctrl.calls] == mpc_cycles[1:]
    for (now, _, q, dq), k in zip(ctrl.calls, mpc_cycles[1:], strict=True):
        assert now == pytest.approx(t0 + k * P - 2e-4, abs=1e-12)
        np.testing.assert_array_equal(q, states[k][0])  # states[0]: before cycle 0
        np.testing.assert_array_equal(dq, states[k][1])
    sim = hmpc_pin.simulate(robot, hmpc_pin.make_controller(robot), _sine(), duration=1.0, q0=q0)
    np.testing.assert_allclose(run.result.q, sim.q, rtol=0, atol=1e-9)
    np.testing.assert_allclose(run.result.tau, sim.tau, rtol=0, atol=1e-6)


def test_warm_up_must_be_below_the_period():
    from hmpc_pin.exceptions import ConfigError

    with pytest.raises(ConfigError, match=r"realtime\.warm_up"):
        LoopSettings(1000.0, 1.0, warm_up=1e-3)
    with pytest.raises(ConfigError, match=r"realtime\.warm_up"):
        LoopSettings(1000.0, 1.0, warm_up=-1e-4)


# ------------------------------------------------------------- paced by the arm
class Paced:
    """A :class:`PlantArm` as a :class:`~hmpc_pin.realtime.PacedInterface` on the fake
    clock: a state every period at t0 + kP; ``wait`` moves the clock to the next one
    (``extra[k]`` more periods pass unanswered before state k is taken; no state after
    ``silent_after``)."""

    def __init__(self, arm, clock, extra=None, silent_after=np.inf):
        self.arm, self._clock = arm, clock
        self.nq, self.period = arm.nq, arm.period
        self.extra, self.silent_after = dict(extra or {}), silent_after
        self.t0, self.k = clock.now, 0
        self._state = (0.0, *arm.read()[1:])

    def clock(self):
        return self._clock.now

    def wait(self, timeout):
        k = self.k + 1
        k += self.extra.pop(k, 0)
        t = self.t0 + k * self.period
        if t > self._clock.now + timeout + 1e-12 or t - self.t0 > self.silent_after:
            self._clock.now += timeout
            return 0
        self._clock.now = max(self._clock.now, t)
        count, self.k = k - self.k, k
        _, q, dq = self.arm.read()
        self._state = (t, q.copy(), dq.copy())
        return count

    def read(self):
        return self._state

    def write(self, tau):
        self.arm.write(tau)

    def close(self):
        self.arm.close()


def _paced(robot, duration=1.0, **kwargs):
    clock = FakeClock()
    q0 = _sine().sample(0.0)[0]
    arm = PlantArm(RK4Plant(robot.copy(), None, P, P), q0, clock=clock)
    iface = Paced(arm, clock, **kwargs)
    ctrl = Spend(hmpc_pin.make_controller(robot), clock, lambda t: 0.0)
    loop = RealtimeLoop(
        iface, ctrl, _sine(), SafeTorque(robot, damping=3.0), LoopSettings(1.0 / P, duration),
        SafetySettings.unlimited(3, max_misses=5, watchdog=0.005, hold=0.01),
        joint_names=tuple(robot.joint_names),
    )  # fmt: skip
    return loop, arm, q0


def test_paced_by_the_arm_without_latency_is_the_simulation(robot):
    """Each state answered at once: the torques and states of ``simulate``; every
    cycle's deadline is its state's stamp (latency 0 on the fake clock)."""
    from hmpc_pin.realtime import PacedInterface

    loop, _, q0 = _paced(robot, 1.0)
    assert isinstance(loop.interface, PacedInterface) and loop.paced
    run = loop.run()
    sim = hmpc_pin.simulate(robot, hmpc_pin.make_controller(robot), _sine(), duration=1.0, q0=q0)
    assert run.complete
    np.testing.assert_allclose(run.result.q, sim.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(run.result.tau, sim.tau, rtol=0, atol=1e-9)
    assert run.stats["cycles_run"] == 1001 and run.stats["misses"] == 0
    assert run.stats["latency"]["max_us"] == 0.0


def test_paced_states_not_answered_are_skipped_misses(robot):
    """Two extra periods pass before the state of cycle 300 is taken: cycles 300 and 301
    are skipped, counted as missed,
    the loop's time keeps the arm's (the run still ends at its duration)."""
    loop, _, _ = _paced(robot, 0.5, extra={301: 2})  # state k is cycle k - 1
    run = loop.run()
    assert run.complete
    assert run.stats["skipped"] == 2 and run.stats["misses"] == 2
    assert run.timing["missed"][300:302].all() and not run.timing["missed"][302]
    assert run.stats["cycles_run"] == 501 - 2


def test_paced_silent_arm_trips_the_watchdog_and_gets_the_safe_torque(robot):
    loop, arm, _ = _paced(robot, 1.0, silent_after=0.3)
    run = loop.run()
    assert not run.complete and run.stop["cause"] == "watchdog"
    assert run.stop["t"] == pytest.approx(0.3, abs=2 * P)
    # no newer state came: at once the held-safe torque G(q) at the last state the arm
    # sent, no velocity term (a damping torque on a frozen speed would push the arm)
    safe = _safe(robot, np.array(run.stop["q"]), np.zeros(3))
    assert run.stop["brake"]["ended"] == "no fresh state"
    np.testing.assert_allclose(run.stop["safe_tau"], safe, atol=1e-9)
    np.testing.assert_allclose(arm.tau, safe, atol=1e-9)


def test_paced_interface_refuses_clock_options(robot):
    clock = FakeClock()
    arm = PlantArm(RK4Plant(robot.copy(), None, P, P), np.zeros(3), clock=clock)
    parts = (hmpc_pin.make_controller(robot), _sine(), SafeTorque(robot),
             LoopSettings(1.0 / P, 0.1), SafetySettings.unlimited(3))  # fmt: skip
    with pytest.raises(hmpc_pin.ConfigError, match="does not apply to an arm that paces"):
        RealtimeLoop(Paced(arm, clock), *parts, sleep=clock.sleep)
    with pytest.raises(hmpc_pin.ConfigError, match="does not apply to an arm that paces"):
        RealtimeLoop(Paced(arm, clock), *parts, clock=clock)


# ------------------------------------------------------------- measured latency
class DelayedPaced(Paced):
    """:class:`Paced` whose states reach the loop ``delay`` [s] after their stamp (a
    transport delay; ``delay`` < P)."""

    def __init__(self, arm, clock, delay):
        super().__init__(arm, clock)
        self.delay = delay

    def wait(self, timeout):
        count = super().wait(timeout)
        if count:
            self._clock.now += self.delay
        return count


def _delayed(robot, delay, declared, duration=0.6):
    clock = FakeClock()
    q0 = _sine().sample(0.0)[0]
    arm = PlantArm(RK4Plant(robot.copy(), None, P, P), q0, clock=clock)
    ctrl = hmpc_pin.make_controller(robot)
    ctrl.set_latency(declared)
    loop = RealtimeLoop(
        DelayedPaced(arm, clock, delay), ctrl, _sine(), SafeTorque(robot, damping=3.0),
        LoopSettings(1.0 / P, duration),
        SafetySettings.unlimited(3, max_misses=5, watchdog=0.005, hold=0.01),
    )  # fmt: skip
    return loop


def test_the_loop_measures_the_latency_and_warns_when_the_declared_one_is_off(robot):
    """A state that reaches the loop 0.8 ms after its stamp: every controller step records
    an age of 0.8 ms (measurement -> torque written, nothing else costs time on the fake
    clock); with no latency declared the loop warns naming the measured median and the
    declared value, and with 0.8 ms declared it does not."""
    from hmpc_pin.exceptions import ValidityWarning

    delay = 0.0008
    loop = _delayed(robot, delay, 0.0)
    with pytest.warns(ValidityWarning, match=r"median 0\.8 ms.*latency = 0 s"):
        run = loop.run()
    assert run.complete
    ages = run.timing["age"][run.timing["mpc"].astype(bool)]
    np.testing.assert_allclose(ages, delay, rtol=0, atol=1e-9)
    assert np.isnan(run.timing["age"][~run.timing["mpc"].astype(bool)]).all()
    assert run.stats["measured_latency"]["median_us"] == pytest.approx(800.0)
    assert run.stats["declared_latency"] == 0.0
    assert "measurement->torque" in run.summary()
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", ValidityWarning)
        run = _delayed(robot, delay, delay).run()
    assert run.complete and run.stats["declared_latency"] == pytest.approx(delay)
    # fewer steps than MIN_LATENCY_SAMPLES (a failed start, a short run): no advice
    from hmpc_pin.realtime.loop import MIN_LATENCY_SAMPLES

    with warnings.catch_warnings():
        warnings.simplefilter("error", ValidityWarning)
        run = _delayed(robot, delay, 0.0, duration=(MIN_LATENCY_SAMPLES - 2) * Ts).run()
    assert run.stats["measured_latency"]["count"] < MIN_LATENCY_SAMPLES


def test_a_polled_arm_on_its_own_clock_has_no_measured_latency(robot):
    """PlantArm's stamps are its plant time: not comparable with the loop's clock."""
    loop, *_ = _setup(robot, 0.05)
    run = loop.run()
    assert run.stats["measured_latency"] is None
    assert np.isnan(run.timing["age"]).all()


def test_latency_tolerance_follows_the_bandwidth_rule():
    """ΔL = max(P/2, 1/(2 r ω_max) − Ts): ω = 10 1/s at Ts = 10 ms allows
    0.5/(1.25·10) − 0.01 = 0.03 s; ω = 1000 1/s allows none but half a period."""
    from hmpc_pin.compensation.bandwidth import latency_tolerance

    assert latency_tolerance(np.array([10.0, 5.0]), 0.01, 0.001) == pytest.approx(0.03)
    assert latency_tolerance(np.array([1000.0]), 0.01, 0.001) == pytest.approx(0.0005)
    assert latency_tolerance(None, 0.01, 0.001) == pytest.approx(0.0005)


def test_latency_tolerance_declared_too_long_follows_its_rule():
    """Declared above measured: ΔL = max(P/2, min(Ts, (1/ω − (r − 2) Ts)/2)), the ΔL at
    which ω (r Ts + 2ΔL − 2Ts) = 1: ω = 1000 1/s at Ts = 10 ms allows
    (0.001 + 0.75·0.01)/2 = 4.25 ms, exactly where overdeclared_limit equals ω; ω = 10 1/s
    is capped at one period (the case is derived up to one); 10/Ts at 1 kHz: half a period."""
    from hmpc_pin.compensation.bandwidth import latency_tolerance, overdeclared_limit

    tol = latency_tolerance(np.array([1000.0, 5.0]), 0.01, 0.001, over=True)
    assert tol == pytest.approx(0.00425)
    assert overdeclared_limit(0.01, tol) == pytest.approx(1000.0)
    assert latency_tolerance(np.array([10.0]), 0.01, 0.001, over=True) == pytest.approx(0.01)
    assert latency_tolerance(np.array([1e4]), 0.001, 0.001, over=True) == pytest.approx(5e-4)
    assert latency_tolerance(None, 0.01, 0.001, over=True) == pytest.approx(0.0005)


def test_a_polled_arm_with_a_stamp_clock_has_its_latency_measured(robot):
    """A polled arm offering ``stamp_clock()`` (the loop's fake clock shifted to the
    arm's plant time, states 0.3 ms old when read): the ages are measured on it."""

    class Stamped:
        def __init__(self, arm, clock):
            self.arm, self.clock0, self._clock = arm, None, clock
            self.nq, self.period = arm.nq, arm.period

        def stamp_clock(self):  # the plant time of the last state + its age
            return self.arm._steps * self.period + 0.0003

        def read(self):
            return self.arm.read()

        def write(self, tau):
            self.arm.write(tau)

        def close(self):
            self.arm.close()

    loop, *_ = _setup(robot, 0.1, wrap=lambda a: Stamped(a, None))
    run = loop.run()
    ages = run.timing["age"][run.timing["mpc"].astype(bool)]
    np.testing.assert_allclose(ages, 0.0003, rtol=0, atol=1e-12)
    assert run.stats["measured_latency"]["median_us"] == pytest.approx(300.0)


class TransportDelayed(Paced):
    """:class:`Paced` whose state k reaches the loop a constant ``delay`` [s] after its
    stamp t0 + kP (a transport delay, any length)."""

    def __init__(self, arm, clock, delay):
        super().__init__(arm, clock)
        self.delay = delay

    def wait(self, timeout):
        k = self.k + 1
        arrive = self.t0 + k * self.period + self.delay
        if arrive > self._clock.now + timeout + 1e-12:
            self._clock.now += timeout
            return 0
        self._clock.now = max(self._clock.now, arrive)
        self.k = k
        _, q, dq = self.arm.read()
        self._state = (self.t0 + k * self.period, q.copy(), dq.copy())
        return 1


class ArrivingPaced(TransportDelayed):
    """:class:`TransportDelayed` that reports each state's arrival and no overdue state
    (what the ROS interface reports for a constant transport delay)."""

    arrival, overdue = 0.0, 0

    def wait(self, timeout):
        count = super().wait(timeout)
        self.arrival = self._clock.now
        return count


@pytest.mark.parametrize("reports_arrival", [False, True])
def test_a_transport_delay_longer_than_the_period_is_no_miss_with_the_arrival(
    robot, reports_arrival
):
    """States reach the loop 1.5 P after their stamp: with the stamp as the deadline every
    cycle misses (k = 5 stops the loop at its fifth cycle); with the arrival as the
    deadline none does, and the stamp-to-torque latency is still measured (1.5 P)."""
    clock = FakeClock()
    q0 = _sine().sample(0.0)[0]
    arm = PlantArm(RK4Plant(robot.copy(), None, P, P), q0, clock=clock)
    cls = ArrivingPaced if reports_arrival else TransportDelayed
    loop = RealtimeLoop(
        cls(arm, clock, 1.5 * P), hmpc_pin.make_controller(robot), _sine(),
        SafeTorque(robot, damping=3.0), LoopSettings(1.0 / P, 0.2),
        SafetySettings.unlimited(3, max_misses=5, watchdog=0.005, hold=0.01),
    )  # fmt: skip
    run = loop.run()
    if not reports_arrival:
        assert run.stop["cause"] == "misses" and run.stop["cycle"] <= 5
        return
    assert run.complete and run.stats["misses"] == 0
    ages = run.timing["age"][run.timing["mpc"].astype(bool)]
    np.testing.assert_allclose(ages, 1.5 * P, atol=1e-9)


def test_the_configs_brake_speed_and_hold_reach_every_loop_built_from_it(tmp_path):
    """``[realtime] brake_speed`` and ``hold`` are read where the safety settings are
    built, so the CLI, the ROS node and the benchmarks all brake as configured."""
    from hmpc_pin.experiment.build import Experiment, realtime_parts
    from hmpc_pin.experiment.config import load_config

    from .test_ros import _write

    for limits in ("true", "false"):
        extra = f"[realtime]\nbrake_speed = 0.0125\nhold = 0.7\nlimits = {limits}\n"
        config = load_config(_write(tmp_path, extra))
        _, safety, _ = realtime_parts(Experiment.from_config(config))
        assert safety.brake_speed == 0.0125 and safety.hold == 0.7


def test_a_reference_made_against_one_swapped_out_since_is_not_taken(robot):
    """``set_reference(..., base=)`` from another thread: a trajectory made continuous with
    the reference of its check is refused when the loop has swapped in another meanwhile
    (it would jump at its start); one made against the current reference supersedes a
    pending one."""
    r0, r1, r2 = _sine(), SineReference(3, amplitude=0.1), SineReference(3, amplitude=0.2)
    box, taken = {}, []

    def hook(t):  # the calls a trajectory worker makes, at chosen loop times
        loop = box["loop"]
        if abs(t - 0.05) < P / 2:
            taken.append(loop.set_reference(r1, at=0.1, base=r0))  # pending until 0.1
        if abs(t - 0.2) < P / 2:
            taken.append(loop.set_reference(r2, at=0.3, base=r0))  # r0 is gone since 0.1
        if abs(t - 0.25) < P / 2:
            taken.append(loop.set_reference(r2, at=0.3, base=r1))

    loop, _, _, _ = _setup(robot, 0.4, hook=hook, reference=r0)
    box["loop"] = loop
    run = loop.run()
    assert taken == [True, False, True]
    assert run.stop is None and loop.reference is r2


# ------------------------------------------------- before the first command, the limits
class Counting(Frozen):
    """:class:`Frozen` that counts the commands written to the arm."""

    def __init__(self, arm, **kwargs):
        super().__init__(arm, **kwargs)
        self.writes = 0

    def write(self, tau):
        self.writes += 1
        super().write(tau)


@pytest.mark.parametrize("first", ["nan", "beyond"])
def test_a_first_state_the_loop_cannot_start_from_is_refused_before_any_command(robot, first):
    """A non-finite first state, or one beyond the bounds: ArmError naming it, and not
    one command written (the arm keeps what it had)."""
    box = {}

    def wrap(arm):
        box["iface"] = Counting(arm, t_nan=0.0 if first == "nan" else np.inf)
        return box["iface"]

    q0 = _sine().sample(0.0)[0]
    hi = q0 + 1.0
    hi[1] = q0[1] - 0.1  # joint 2 starts 0.1 rad above its upper bound
    safety = SafetySettings(q0 - 1.0, hi, np.full(3, 10.0), watchdog=0.005, hold=0.01)
    loop, _, _, _ = _setup(robot, 0.1, wrap=wrap, safety=None if first == "nan" else safety)
    with pytest.raises(hmpc_pin.ArmError, match="nothing was sent") as err:
        loop.run()
    assert ("non-finite" in str(err.value)) == (first == "nan")
    assert (robot.joint_names[1] in str(err.value)) == (first == "beyond")
    assert box["iface"].writes == 0


@pytest.mark.parametrize("how", ["deactivated", "interrupted"])
def test_a_stop_asked_before_the_first_command_sends_nothing(robot, how):
    """Deactivated (or Ctrl-C) before the loop's first command: the arm never had one
    from it, and gets none (no stop sequence, ``safe_tau`` None)."""
    box = {}

    def wrap(arm):
        box["iface"] = Counting(arm)
        return box["iface"]

    loop, _, _, _ = _setup(robot, 0.2, wrap=wrap)
    if how == "deactivated":
        assert loop.request_stop_by("deactivated", timeout=0.0)  # not started: at once
    else:
        loop.request_stop()
    run = loop.run()
    assert box["iface"].writes == 0
    assert run.stop["cause"] == how and run.stop["safe_tau"] is None
    assert "nothing was sent" in run.stop["reason"]
    assert run.stop["brake"]["ended"] == "nothing sent"


def test_a_stop_after_the_first_command_still_runs_the_stop_sequence(robot):
    """The other side of the rule: deactivated after one command, the safe torque and
    the held-safe one are written."""
    box = {}

    def wrap(arm):
        box["iface"] = Counting(arm)
        return box["iface"]

    def hook(t):
        if t > 0:
            box["loop"].request_stop_by("deactivated", timeout=0.0)

    loop, _, _, _ = _setup(robot, 0.2, wrap=wrap, hook=hook)
    box["loop"] = loop
    run = loop.run()
    assert run.stop["cause"] == "deactivated" and run.stop["safe_tau"] is not None
    assert box["iface"].writes >= Ts / P + 2  # the steps, the safe and the held torque


def test_set_reference_reports_the_pending_reference_it_superseded(robot):
    """Two references set before the loop swaps either in: the second supersedes the
    first (``superseded``), which never runs; one set after the swap supersedes none."""
    r0, r1, r2, r3 = _sine(), SineReference(3, amplitude=0.1), SineReference(3, 0.2), _sine()
    seen = []

    def hook(t):
        loop = box["loop"]
        if abs(t - 0.05) < P / 2:
            loop.set_reference(r1, at=0.2)
            seen.append(loop.superseded)
            loop.set_reference(r2, at=0.2)
            seen.append(loop.superseded)
        if abs(t - 0.25) < P / 2:
            loop.set_reference(r3, at=0.3)
            seen.append(loop.superseded)

    box = {}
    loop, _, _, _ = _setup(robot, 0.4, hook=hook, reference=r0)
    box["loop"] = loop
    run = loop.run()
    assert run.stop is None
    assert seen[0] is None and seen[2] is None
    assert seen[1] is not None and seen[1].sample(0.3)[0] == pytest.approx(r1.sample(0.3)[0])
    assert loop.reference is not None and loop.pending_reference is None


def test_safe_torques_are_clipped_to_the_effort_limits(robot):
    """G(q) − D q̇ from RNEA, clipped per joint to the limits (closed form)."""
    q, dq = np.array([0.3, -0.4, 0.2]), np.array([2.0, -3.0, 0.5])
    limit = np.array([1.0, np.inf, 0.5])
    safe = SafeTorque(robot, damping=3.0, effort_limit=limit)
    expected = _safe(robot, q, dq)
    assert safe(q, dq) == pytest.approx(np.clip(expected, -limit, limit), abs=1e-12)
    g = _safe(robot, q, np.zeros(3))
    assert safe.held(q) == pytest.approx(np.clip(g, -limit, limit), abs=1e-12)
    with pytest.raises(hmpc_pin.ConfigError, match="effort_limit"):
        SafeTorque(robot, effort_limit=[1.0, 0.0, 1.0])


def test_the_inertia_brake_slows_every_joint_alike_and_stops_a_heavy_arm(robot):
    """τ = G(q) − M(q) q̇ / T_b on the frictionless planar3 (RK4, 1 kHz zero-order hold):
    with the Coriolis forces power-neutral, the kinetic energy decays as e^(−2t/T_b)
    (closed form; the hold's error is O(P/T_b) = 1 % per time constant). The diagonal
    damping of 2 N·m·s/rad leaves the arm's slowest mode at e^(−t/λmax(M, D)), λmax the
    largest generalized eigenvalue (numpy's non-symmetric eig of D⁻¹M here)."""
    from hmpc_pin.realtime.safety import brake_time_constant

    T_b, P_, T = 0.2, 1e-3, 0.6
    q0, dq0 = np.array([0.3, -0.4, 0.2]), np.array([1.0, -1.0, 0.5])
    model, data = robot.model, robot.model.createData()

    def kinetic(q, dq):
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        return 0.5 * dq @ M @ dq

    for safe, rate in ((SafeTorque(robot, brake_time=T_b), 2.0 / T_b), (SafeTorque(robot), None)):
        plant = RK4Plant(robot.copy(), None, P_, P_)
        plant.reset(q0, dq0, 0.0)
        q, dq = q0.copy(), dq0.copy()
        for _ in range(round(T / P_)):
            q, dq = plant.advance(safe(q, dq))
        ratio = kinetic(q, dq) / kinetic(q0, dq0)
        if rate is not None:
            assert ratio == pytest.approx(np.exp(-rate * T), rel=0.05)
        else:  # the slowest mode decays no faster than e^(-t/λmax): KE ≥ its share
            lam = brake_time_constant(robot.mass_matrix(q0), safe.damping)
            M0 = robot.mass_matrix(q0)
            oracle = np.max(np.linalg.eigvals(np.linalg.solve(np.diag(safe.damping), M0)).real)
            assert lam == pytest.approx(oracle, rel=1e-9)
            assert lam > 5.0  # ~8 s for the paper's arm: the reason for the inertia brake
            assert ratio > 0.5  # most of the energy left after 0.6 s
    assert brake_time_constant(np.eye(3), np.array([1.0, 0.0, 1.0])) == np.inf


def test_the_default_brake_is_the_inertia_brake_and_a_weak_damping_warns(tmp_path):
    """No ``damping`` or ``brake_time``: the inertia brake with T_b = hold/6; an explicit
    damping too weak for the arm's inertia warns with the numbers; both given is an error."""
    from dataclasses import replace as dc_replace

    from hmpc_pin.exceptions import ConfigError, ValidityWarning
    from hmpc_pin.experiment.build import Experiment, realtime_parts
    from hmpc_pin.experiment.config import load_config
    from hmpc_pin.experiment.config.realtime import RealtimeConfig

    config = load_config("paper_combined")
    _, _, safe = realtime_parts(Experiment.from_config(config))
    assert safe.brake_time == pytest.approx(config.realtime.hold / 6)
    weak = dc_replace(config, realtime=RealtimeConfig(damping=2.0))
    with pytest.warns(ValidityWarning, match=r"realtime\.damping.*time constant of") as rec:
        _, _, safe = realtime_parts(Experiment.from_config(weak))
    assert safe.brake_time is None
    # the figure quoted is the arm's slowest mode under D = 2 (numpy's eig of D⁻¹M at q0)
    import re

    quoted = float(re.search(r"time constant of ([0-9.]+) s", str(rec[0].message)).group(1))
    robot = Experiment.from_config(weak).robot
    M0 = robot.mass_matrix(Experiment.from_config(weak).q0)
    assert quoted == pytest.approx(np.max(np.linalg.eigvals(M0 / 2.0).real), rel=5e-3)
    with pytest.raises(ConfigError, match=r"damping.*does not apply with brake_time"):
        RealtimeConfig(damping=2.0, brake_time=0.1)


def test_the_brake_time_is_checked_at_the_rate_that_runs_and_hold_0_is_no_crash():
    """The inertia brake's minimum e·(d+1)·P follows the interface period that runs (a ROS
    rate of 100 Hz, not ``[realtime] rate``) and the declared latency; the discrete brake
    v_{k+1} = v_k − (P/T_b)·v_{k−d} at that minimum decays without changing sign (numpy
    recursion) and at a third of it oscillates; hold = 0 with a damping builds, no error."""
    import math
    from dataclasses import replace as dc_replace

    from hmpc_pin.exceptions import ConfigError
    from hmpc_pin.experiment.build import (
        Experiment,
        brake_settings,
        minimum_brake_time,
        realtime_parts,
    )
    from hmpc_pin.experiment.config import load_config
    from hmpc_pin.experiment.config.realtime import RealtimeConfig

    config = load_config("panda_sine")
    given = dc_replace(config, realtime=RealtimeConfig(brake_time=0.01))
    assert brake_settings(given, 1e-3) == (None, 0.01)  # 1 kHz: minimum e·2·1 ms = 5.4 ms
    with pytest.raises(ConfigError, match=r"realtime\.brake_time.*P = 0\.01 s"):
        brake_settings(given, 1e-2)  # 100 Hz: minimum 54 ms
    late = dc_replace(given, controller=dc_replace(config.controller, latency=3e-3))
    assert minimum_brake_time(late, 1e-3) == pytest.approx(math.e * 5 * 1e-3)  # d = 1 + 3

    def brake(d, T_b, P=1e-3, steps=2000):
        v = np.zeros(steps + d + 1)
        v[: d + 1] = 1.0
        for k in range(d, steps + d):
            v[k + 1] = v[k] - P / T_b * v[k - d]
        return v

    for d in (1, 2, 4):
        shortest = math.e * (d + 1) * 1e-3
        assert np.all(np.diff(brake(d, shortest)) <= 0) and brake(d, shortest)[-1] >= 0
        assert np.any(brake(d, shortest / 3) < 0)  # shorter: it overshoots
    # hold = 0 with an explicit damping (no brake after the first safe torque): no warning
    # arithmetic on hold, a SafeTorque built
    zero = dc_replace(config, realtime=RealtimeConfig(damping=2.0, hold=0.0))
    _, _, safe = realtime_parts(Experiment.from_config(zero))
    assert safe.brake_time is None and safe.damping[0] == 2.0
