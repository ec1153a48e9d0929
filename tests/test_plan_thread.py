"""The MPC in a compiled planner thread (hmpc_pin._core.PlanThread,
hmpc_pin.realtime.threaded_law.InnerLawThreaded): its plan equals the synchronous step's
bit for bit when it waits for it, a plan older than the staleness bound is never used, and
the thread stops and joins on every stop path. No wall clock: the plan's clock is driven by
hand and the hand-over is waited for."""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import textwrap
import threading
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import hmpc_pin
from hmpc_pin.compensation.observers import default_observer
from hmpc_pin.controllers.hierarchical import HierarchicalMPC
from hmpc_pin.exceptions import ConfigError
from hmpc_pin.experiment.build import Experiment
from hmpc_pin.experiment.config import load_config
from hmpc_pin.native import load as load_native
from hmpc_pin.realtime.inner_law import InnerLawEveryCycle
from hmpc_pin.realtime.threaded_law import InnerLawThreaded
from hmpc_pin.sim import RK4Plant

ROOT = Path(__file__).resolve().parents[1]
PERIOD = 0.001
# the configs' observer on the Panda (a validity warning, not this file's subject)
pytestmark = pytest.mark.filterwarnings("ignore::hmpc_pin.exceptions.ValidityWarning")


def _arm(config: str):
    exp = Experiment.from_config(load_config(ROOT / "configs" / f"{config}.toml"))
    return exp.robot, exp.controller.settings, exp.q0, exp.reference


def _law(kind, robot, settings, **kw):
    ctrl = HierarchicalMPC(robot, settings)
    obs = default_observer(robot.nq, PERIOD)
    return kind(ctrl, obs, PERIOD, None, **kw)


def _closed_loop(law, robot, q0, reference, cycles, plant_Ts=PERIOD):
    """The law against the RK4 plant from 0.1 rad off q0: torques, accelerations held."""
    plant = RK4Plant(robot, Ts=plant_Ts, dt=plant_Ts)
    q = np.asarray(q0, dtype=float) + 0.1
    dq = np.zeros(robot.nq)
    plant.reset(q, dq)
    law.reset(q, dq)
    taus, vs = [], []
    for k in range(cycles):
        tau = law.step(k * PERIOD, q, dq, reference)
        taus.append(tau.copy())
        vs.append(law._v.copy())
        q, dq = plant.advance(tau)
    return np.array(taus), np.array(vs), q


@pytest.mark.parametrize(
    "config, Ts, N, Nc",
    [
        ("paper_combined", 0.005, 20, 1),
        ("paper_combined", 0.004, 15, 4),
        ("panda_sine", 0.005, 20, 2),
    ],
)
def test_waited_plan_equals_the_synchronous_step_bit_for_bit(config, Ts, N, Nc):
    robot, settings, q0, reference = _arm(config)
    settings = replace(settings, Ts=Ts, N=N, Nc=Nc)
    cycles = 300
    sync = _law(InnerLawEveryCycle, robot, settings)
    tau_s, v_s, q_s = _closed_loop(sync, robot, q0, reference, cycles)
    with _law(InnerLawThreaded, robot, settings, wait=True) as threaded:
        tau_t, v_t, _ = _closed_loop(threaded, robot, q0, reference, cycles)
        assert threaded.fallbacks == 0
        assert threaded.planner.published == cycles // threaded.mpc_every
        assert threaded.planner.stale == 0
    # the MPC's plan, used for the cycles it covers, and the torques: identical
    np.testing.assert_array_equal(v_t, v_s)
    np.testing.assert_array_equal(tau_t, tau_s)
    # and the loop did something: it left the start and the plan changed
    assert np.ptp(v_s, axis=0).max() > 1e-3
    assert np.abs(q_s - (np.asarray(q0) + 0.1)).max() > 1e-3


def test_the_plan_equals_the_joint_qps_of_the_synchronous_step():
    """PlanThread alone against HierarchicalMPC.step: the same U row 0 (v) on every step
    of a closed loop, and the whole sequence U equal to the step's QP solution."""
    robot, settings, q0, reference = _arm("panda_sine")
    settings = replace(settings, Ts=0.002, N=30, Nc=3)
    ctrl = HierarchicalMPC(robot, settings)
    twin = InnerLawThreaded(ctrl, default_observer(robot.nq, PERIOD), PERIOD, None, wait=True)
    planner = twin.planner
    plant = RK4Plant(robot, Ts=settings.Ts, dt=0.001)
    q = np.asarray(q0, dtype=float) - 0.05
    dq = np.zeros(robot.nq)
    plant.reset(q, dq)
    ctrl.reset(q, dq)
    planner.reset()
    port = hmpc_pin.tasks.base.reference_port(hmpc_pin.tasks.base.as_reference(reference))
    assert port is not None  # the planner samples the compiled reference itself
    planner.set_reference(port)
    for k in range(150):
        t = k * settings.Ts
        tau = ctrl.step(t, q, dq, reference)
        planner.request(t, q, dq)
        assert planner.wait()
        np.testing.assert_array_equal(planner.plan, ctrl.qps.solution)
        assert planner.plan_time == t
        q, dq = plant.advance(tau)
    twin.close()
    assert not planner.running


def _planner(n_req=1, max_age=0.025):
    robot, settings, q0, reference = _arm("paper_combined")
    settings = replace(settings, Ts=0.01, N=10, Nc=3)
    law = _law(InnerLawThreaded, robot, settings, max_age=max_age)
    law.reset(np.asarray(q0, float), np.zeros(robot.nq))
    return law, np.asarray(q0, float), reference


def test_a_plan_older_than_the_bound_is_never_used():
    law, q0, reference = _planner(max_age=0.025)
    p, n = law.planner, law.robot.nq
    v = np.full(n, 7.0)
    assert not p.input(0.0, v)  # no plan yet: refused, v untouched
    np.testing.assert_array_equal(v, 7.0)
    law._request(1.0, q0 + 0.2, np.zeros(n), reference)
    assert p.wait()
    U = p.plan
    assert U.shape == (3, n) and np.abs(U).max() > 0
    # the clock driven by hand: row ⌊(t − t_plan)/Ts⌋, the last row held past Nc
    for t, row in [(1.0, 0), (1.0049, 0), (1.01, 1), (1.0199, 1), (1.02, 2), (1.025, 2)]:
        assert p.input(t, v), t
        np.testing.assert_array_equal(v, U[row])
    refused = p.stale
    for t in (1.0251, 1.03, 5.0, 0.999):  # older than the bound, or from the future
        v[:] = 7.0
        assert not p.input(t, v), t
        np.testing.assert_array_equal(v, 7.0)
    assert p.stale == refused + 4
    law.close()


def test_the_law_brakes_on_a_stale_plan_and_counts_it():
    law, q0, reference = _planner(max_age=0.015)
    n = law.robot.nq
    dq = np.linspace(-1.0, 1.0, n)
    law._request(0.0, q0, dq, reference)
    assert law.planner.wait()
    law._k = 10  # a request cycle: the planner is idle, the plan of t = 0 used
    law._request = lambda *a: None
    law.step(0.0, q0, dq, reference)
    assert law.fallbacks == 0
    # a cycle 21 ms later without a new request (the next MPC instant put off)
    law._next = 1.0
    law.step(0.021, q0, dq, reference)
    assert law.fallbacks == 1
    vmin, vmax = law.controller.settings.bounds(n)
    np.testing.assert_array_equal(law._v, np.clip(-dq / 0.01, vmin, vmax))
    law.close()


def test_the_planner_raises_its_failure_on_the_caller_thread():
    law, q0, reference = _planner()
    bad = q0.copy()
    bad[0] = np.nan
    law._request(0.0, bad, np.zeros(law.robot.nq), reference)
    with pytest.raises(hmpc_pin.exceptions.NonFiniteError):
        law.planner.wait()
    # the planner goes on: a good request is answered
    law._request(0.0, q0, np.zeros(law.robot.nq), reference)
    assert law.planner.wait()
    law.close()


def test_the_thread_stops_and_joins_on_every_stop_path():
    PlanThread = load_native().PlanThread
    before = PlanThread.live()
    law, q0, reference = _planner()
    assert law.planner.running and PlanThread.live() == before + 1
    law.close()
    assert not law.planner.running and PlanThread.live() == before
    law.close()  # idempotent
    # the object's end (the destructor joins)
    law, q0, reference = _planner()
    assert PlanThread.live() == before + 1
    del law
    import gc

    gc.collect()
    assert PlanThread.live() == before
    # an exception inside `with`
    with pytest.raises(RuntimeError), _planner()[0] as law:
        assert PlanThread.live() == before + 1
        raise RuntimeError("boom")
    assert PlanThread.live() == before and not law.planner.running
    # a request after stop is refused
    with pytest.raises(Exception, match="stopped"):
        law._request(0.0, q0, np.zeros(law.robot.nq), reference)


def test_ctrl_c_while_waiting_for_a_plan_stops_the_thread():
    """SIGINT while the 1 kHz side waits for a plan (a long horizon): KeyboardInterrupt,
    and the `with` block joins the thread; the process exits normally."""
    script = textwrap.dedent(
        f"""
        import os, signal, threading, sys
        from dataclasses import replace
        import numpy as np
        sys.path.insert(0, {str(ROOT / "tests")!r})
        from test_plan_thread import _arm, _law
        from hmpc_pin.native import load as load_native
        from hmpc_pin.realtime.threaded_law import InnerLawThreaded
        robot, settings, q0, reference = _arm("panda_sine")
        settings = replace(settings, Ts=0.005, N=200, Nc=10, max_iter=100000)
        law = _law(InnerLawThreaded, robot, settings, wait=True)
        q = np.asarray(q0, float) + 0.2
        law.reset(q, np.zeros(7))
        timer = threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT))
        timer.daemon = True
        timer.start()
        try:
            with law:
                for k in range(10**6):
                    law.step(k * 0.001, q, np.zeros(7), reference)
        except KeyboardInterrupt:
            print("interrupted", load_native().PlanThread.live(), law.planner.running)
        """
    )
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["interrupted", "0", "False"]


# --- plans at 1 kHz with a long horizon and soft limits ---------------------------------


def _soft_planner(max_age: float, Ts: float = 0.001, N: int = 100, vel: float = 1.0):
    """Three double-integrator joints (Eq 24) with soft velocity limits, N = Nc: the
    condensed MPC, the planner's joint QPs and its PlanThread."""
    from hmpc_pin.mpc.condensed import CondensedMPC, JointQPs, StateLimits

    from .test_joint_mpc import EPS_ABS, P_PAPER, Q_PAPER, R_PAPER, SOFT, V_LIMIT

    mpc = CondensedMPC(Ts, N, N, Q_PAPER, R_PAPER, P_PAPER)
    limits = StateLimits(np.full(3, -2.0), np.full(3, 2.0), np.full(3, vel), SOFT["rho2"],
                         SOFT["rho1"])  # fmt: skip
    qps = JointQPs(mpc, -V_LIMIT, V_LIMIT, ("a", "b", "c"), eps_abs=EPS_ABS, limits=limits)
    planner = load_native().PlanThread(mpc.FT, N, qps._core, Ts * np.arange(1, N + 1), Ts, max_age)
    return mpc, qps, planner


def _sine(t):
    """r, ṙ of three sines (0.5 rad, 1 Hz, phases 0, 1, 2: their velocity π rad/s beyond
    the 1 rad/s limit), shape (2, 3)."""
    phase, w = np.array([0.0, 1.0, 2.0]), 2.0 * np.pi
    return np.vstack([0.5 * np.sin(w * t + phase), 0.5 * w * np.cos(w * t + phase)])


def _stack(x, t, Ts, N):
    """The stack [q; q̇; r_1..r_N; ṙ_1..ṙ_N] ((2 + 2N)×n) and the interleaved reference
    (2N, n) of own_soft_qp."""
    ref = np.vstack([_sine(t + j * Ts) for j in range(1, N + 1)])
    return np.vstack([x, ref[0::2], ref[1::2]]), ref


def test_plans_at_1khz_with_soft_limits_satisfy_the_soft_qp_kkt_conditions():
    """The planner's plans along a closed loop at Ts = 1 ms, N = Nc = 100, started 0.2 rad
    off sines faster than the velocity limit (the soft limits active from the first plan):
    each joint's (U, s) satisfies the KKT conditions of the soft-limit QP built here in
    numpy (tests/test_joint_mpc.py: own_soft_qp, soft_kkt_residual), to the solver's
    tolerance; the plan row used by the loop is U's first."""
    from .test_joint_mpc import EPS_ABS, own_soft_qp, soft_kkt_residual

    Ts, N = 0.001, 100
    _, qps, planner = _soft_planner(max_age=2 * Ts)
    x = _sine(0.0) + np.array([[0.2], [0.0]])
    A_dyn = np.array([[1.0, Ts], [0.0, 1.0]])
    B_dyn = np.array([[Ts * Ts / 2.0], [Ts]])
    soft = 0
    try:
        for k in range(12):
            t = k * Ts
            S, ref = _stack(x, t, Ts, N)
            planner.request_stack(t, S)
            assert planner.wait()
            U = planner.plan
            assert planner.plan_time == t
            soft += qps.constrained
            for i in range(3):
                z = np.append(U[:, i], qps.slack[i])
                Hz, gz, A, b = own_soft_qp(x[:, i], ref[:, i], N, N, Ts, -2.0, 2.0, 1.0)
                violation, residual = soft_kkt_residual(Hz, gz, A, b, z, active_tol=1e-7)
                assert violation <= 1e-7, (k, i, violation)
                assert residual <= 100.0 * EPS_ABS, (k, i, residual)
            v = np.empty(3)
            assert planner.input(t, v)
            np.testing.assert_array_equal(v, U[0])
            x = A_dyn @ x + B_dyn @ U[:1]
    finally:
        planner.stop()
    assert soft >= 10 * 3  # the soft limits were active


def test_a_late_cycle_uses_the_last_plan_shifted_and_a_stale_one_brakes():
    """A hand-driven clock over a planner that is late: every cycle whose plan has not come
    uses the previous plan's row for its time (row ⌊(t − t_plan)/Ts⌋), while the plan is
    within the staleness bound (the default: its control horizon, Nc·Ts); past it, and
    before the first plan (the first cycle does not wait for it), the law brakes, counted
    in ``fallbacks``."""
    robot, settings, q0, reference = _arm("paper_combined")
    Ts = 0.002
    settings = replace(settings, Ts=Ts, N=20, Nc=5)
    # the arm's period P = Ts/2: a request every second cycle
    law = InnerLawThreaded(HierarchicalMPC(robot, settings), default_observer(robot.nq, Ts / 2),
                           Ts / 2, None)  # fmt: skip
    assert law.max_age == pytest.approx(5 * Ts)  # the default: the control horizon
    n = robot.nq
    q = np.asarray(q0, float) + 0.1
    dq = np.zeros(n)
    with law:
        law.reset(q, dq)
        request, law._request = law._request, lambda *a: None  # requests withheld
        # the first cycle does not wait for a plan: none yet, it brakes (at rest: v = 0)
        law.step(0.0, q, dq, reference)
        assert law.fallbacks == 1
        np.testing.assert_array_equal(law._v, np.zeros(n))
        request(0.0, q, dq, reference)  # the plan of t = 0, waited for
        assert law.planner.wait()
        law._k = 2  # a request cycle, the request withheld: the plan of t = 0 used
        law.step(0.0, q, dq, reference)
        U = law.planner.plan
        assert law.planner.plan_time == 0.0 and law.fallbacks == 1
        # the planner is stopped from answering: a request is never taken (planner idle,
        # the request replaced): here by cycles that are not request cycles (k odd)
        for k, t in enumerate(np.arange(1, 10) * Ts / 2 + 1e-12):
            law._k = 2 * k + 1  # never a multiple of mpc_every = 2: no request
            law.step(float(t), q, dq, reference)
            row = min(int(np.floor(t / Ts + 1e-9)), 4)
            np.testing.assert_array_equal(law._v, U[row], err_msg=f"t = {t}")
            assert law.planner.last_age == pytest.approx(t)
        assert law.fallbacks == 1
        # past the bound (10 ms = 5 Ts): braked, counted
        law._k = 21
        dq = np.linspace(-1.0, 1.0, n)
        law.step(0.0101, q, dq, reference)
        assert law.fallbacks == 2
        vmin, vmax = settings.bounds(n)
        np.testing.assert_array_equal(law._v, np.clip(-dq / Ts, vmin, vmax))


def test_the_franka_app_runs_the_threaded_law_at_1_ms_and_recommends_it():
    """At Ts = the arm's period the threaded law applies (the MPC off the cycle), the
    synchronous inner law does not (the whole step every cycle); the advice to thread the
    MPC comes when the activation step's CPU time exceeds the period, and its measurement
    leaves the controller as reset (its next steps those of a new controller, bit for
    bit)."""
    from hmpc_pin.apps.franka import activation_step_cpu, threaded_advice
    from hmpc_pin.experiment.inner_law import why_not_inner_law

    robot, settings, q0, reference = _arm("panda_sine")
    settings = replace(settings, Ts=PERIOD)
    ctrl = HierarchicalMPC(robot, settings, default_observer(robot.nq, PERIOD))
    assert why_not_inner_law(ctrl, PERIOD, "threaded") is None
    assert "equals the interface period" in why_not_inner_law(ctrl, PERIOD, "every-cycle")
    advice = threaded_advice(1.5e-3, PERIOD)
    assert advice is not None and "--inner-law threaded" in advice and "1500 us" in advice
    assert threaded_advice(0.9e-3, PERIOD) is None
    cpu = activation_step_cpu(ctrl, reference, q0)
    assert cpu > 0.0
    fresh = HierarchicalMPC(robot, settings, default_observer(robot.nq, PERIOD))
    fresh.reset(np.asarray(q0, float), np.zeros(robot.nq))
    q = np.asarray(q0, float) + 0.05
    for k in range(3):
        tau = ctrl.step(k * PERIOD, q, np.zeros(robot.nq), reference)
        np.testing.assert_array_equal(tau, fresh.step(k * PERIOD, q, np.zeros(robot.nq), reference))


def test_the_planner_gets_the_controllers_knobs_and_the_default_bound():
    """The planner's QPs carry the controller's soft exchange bounds; the default staleness
    bound is the control horizon, and two MPC periods with Nc = 1."""
    robot, settings, _, _ = _arm("panda_sine")
    ctrl = HierarchicalMPC(robot, replace(settings, Ts=0.002, N=20, Nc=1))
    ctrl.qps.soft_step_work = 1600
    ctrl.qps.soft_step_exchanges = 5
    with InnerLawThreaded(ctrl, default_observer(robot.nq, PERIOD), PERIOD, None) as law:
        assert law._qps.soft_step_work == 1600 and law._qps.soft_step_exchanges == 5
        assert law.max_age == pytest.approx(2 * 0.002)
    with _law(InnerLawThreaded, robot, replace(settings, Ts=0.002, N=20, Nc=8)) as law:
        assert law.max_age == pytest.approx(8 * 0.002)


def test_a_reset_starts_the_counters_of_a_run():
    """The planner's counters are a run's, as the law's fallbacks: a step and a reset before
    the run (the real-time loop's warm-up) leave nothing counted."""
    law, q0, reference = _planner()
    p, n = law.planner, law.robot.nq
    law._request(0.0, q0, np.zeros(n), reference)
    assert p.wait()
    law._request = lambda *a: None  # requests withheld
    law.step(5.0, q0, np.zeros(n), reference)  # the plan of t = 0 far too old: braked
    assert law.fallbacks == p.stale == 1 and p.requests == p.published == 1
    law.reset(q0, np.zeros(n))
    assert law.fallbacks == p.stale == p.requests == p.published == p.dropped == 0
    law.step(0.0, q0, np.zeros(n), reference)  # no plan since the reset: braked
    assert law.fallbacks == p.stale == 1
    law.close()


def _niceness(tid: int) -> int:
    return os.getpriority(os.PRIO_PROCESS, tid)


@contextlib.contextmanager
def _fifo(priority: int = 2):
    """The calling thread under SCHED_FIFO (skipped where it may not)."""
    old = os.sched_getscheduler(0), os.sched_getparam(0)
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except PermissionError:
        pytest.skip("SCHED_FIFO is not permitted here")
    try:
        yield
    finally:
        os.sched_setscheduler(0, *old)


def test_the_planner_is_niced_under_a_normal_loop_and_not_under_a_realtime_one():
    """The rule (threaded_law's module doc), read back from the kernel by the planner's tid."""
    base = _niceness(0)  # this thread's
    law, q0, reference = _planner()
    with law:
        tid = law.planner.tid
        assert tid > 0 and tid != threading.get_native_id()
        assert _niceness(tid) == base  # started at the caller's niceness
        law.step(0.0, q0, np.zeros(law.robot.nq), reference)  # a normal loop's first cycle
        assert _niceness(tid) == min(base + 10, 19) == law.planner.nice
        s = law.summary()
        assert (s["planner_nice"], s["planner_policy"]) == (min(base + 10, 19), "normal")
        law.step(0.001, q0, np.zeros(law.robot.nq), reference)  # applied once per run
        assert _niceness(tid) == min(base + 10, 19)
        with _fifo():
            law.reset(q0, np.zeros(law.robot.nq))
            law.step(0.0, q0, np.zeros(law.robot.nq), reference)  # a real-time loop's
            if law.planner.nice != base:  # lowering refused here (no CAP_SYS_NICE)
                assert _niceness(tid) == min(base + 10, 19)
            else:
                assert _niceness(tid) == base
            assert os.sched_getscheduler(tid) == os.SCHED_OTHER
    assert law.planner.tid == 0  # stopped


def test_a_planner_started_by_a_realtime_loop_leaves_its_policy():
    """Created by a SCHED_FIFO thread the planner inherits its policy: the rule puts it
    under the normal one (it must never compete with the loop at the loop's priority), or
    one priority below the loop with planner_scheduling = "fifo"."""
    with _fifo(3):
        law, q0, reference = _planner()
        with law:
            tid = law.planner.tid
            assert os.sched_getscheduler(tid) == os.SCHED_FIFO  # inherited
            law.step(0.0, q0, np.zeros(law.robot.nq), reference)
            assert os.sched_getscheduler(tid) == os.SCHED_OTHER
            law.planner_scheduling = "fifo"
            law.reset(q0, np.zeros(law.robot.nq))
            law.step(0.0, q0, np.zeros(law.robot.nq), reference)
            assert os.sched_getscheduler(tid) == os.SCHED_FIFO
            assert os.sched_getparam(tid).sched_priority == 2
            assert law.summary()["planner_policy"] == "SCHED_FIFO 2"
    law, q0, reference = _planner()
    with law:  # "fifo" under a normal loop: the rule's niceness
        law.planner_scheduling = "fifo"
        law.step(0.0, q0, np.zeros(law.robot.nq), reference)
        assert os.sched_getscheduler(law.planner.tid) == os.SCHED_OTHER
        assert _niceness(law.planner.tid) == min(_niceness(0) + 10, 19)


def test_set_nice_is_validated_and_a_bad_scheduling_is_refused():
    law, q0, reference = _planner()
    with law:
        for bad in (20, -21, 100):
            with pytest.raises(ValueError, match=r"niceness in -20\.\.19, got " + str(bad)):
                law.planner.set_nice(bad)
        assert _niceness(law.planner.tid) == law.planner.nice == _niceness(0)  # unchanged
        law.planner.set_nice(15)
        assert _niceness(law.planner.tid) == law.planner.nice == 15
        with pytest.raises(TypeError):
            law.planner.set_nice("high")
        law.planner_scheduling = "fast"
        with pytest.raises(ConfigError, match=r"planner_scheduling.*'fast'"):
            law.step(0.0, q0, np.zeros(law.robot.nq), reference)
