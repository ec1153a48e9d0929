"""HierarchicalMPC: decoupling of Eq (3)-(5), observer in the loop, bad input, solver errors."""

from __future__ import annotations

import copy
import time

import numpy as np
import pinocchio as pin
import pytest

import hmpc_pin
from hmpc_pin.compensation.observers import DisturbanceObserver
from hmpc_pin.controllers.hierarchical import MPCSettings
from hmpc_pin.experiment.config import ControllerConfig, ObserverConfig


def _controller(robot, observer=None, **kw):
    """hmpc with Chen's NDO of the ``observer`` table, or without compensation."""
    if observer is None:
        cc = ControllerConfig(compensation="none", **kw)
    else:
        cc = ControllerConfig(observer=observer, **kw)
    return hmpc_pin.make_controller(robot, cc)


def _rk4_hold(robot, q, dq, tau, d, Ts, steps=100):
    """Integrate the plant over one control period with tau + d held (independent of hmpc_pin)."""
    model, data = robot.model, robot.data
    h = Ts / steps
    for _ in range(steps):

        def f(q, dq):
            return dq, pin.aba(model, data, q, dq, tau + d)

        k1 = f(q, dq)
        k2 = f(q + 0.5 * h * k1[0], dq + 0.5 * h * k1[1])
        k3 = f(q + 0.5 * h * k2[0], dq + 0.5 * h * k2[1])
        k4 = f(q + h * k3[0], dq + h * k3[1])
        q = q + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        dq = dq + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
    return q, dq


def test_default_controller_is_the_papers(planar3):
    ctrl = hmpc_pin.HierarchicalMPC(planar3)
    assert ctrl.settings.N == 10 and ctrl.settings.Nc == 1 and ctrl.Ts == 0.01
    assert isinstance(ctrl.compensation, DisturbanceObserver)
    assert ctrl.compensation.kind == "chen"


def test_inverse_dynamics_decouples_into_double_integrators(planar3):
    """Eq (3) and (5): the torque of Eq (4) makes q̈ = v + M⁻¹(d − d̂) in the plant."""
    rng = np.random.default_rng(1)
    ctrl = _controller(planar3, observer=ObserverConfig(gain=50.0))
    ref = hmpc_pin.SineReference(3)
    model = planar3.model
    data = model.createData()
    for _ in range(10):
        q = rng.uniform(-1, 1, 3)
        dq = rng.normal(0, 1, 3)
        ctrl.reset(q, dq)
        ctrl.step(0.0, q, dq, ref)
        tau = ctrl.step(0.01, q + 0.01 * dq, dq, ref)  # second step: d̂ != 0
        q1 = q + 0.01 * dq
        d_hat = ctrl.disturbance_estimate
        assert np.abs(d_hat).max() > 1e-6
        d = rng.normal(0, 3, 3)
        ddq = pin.aba(model, data, q1, dq, tau + d)
        M = pin.crba(model, data, q1)
        np.testing.assert_allclose(ddq, ctrl.v + np.linalg.solve(M, d - d_hat), atol=1e-9)
        ddq0 = pin.aba(model, data, q1, dq, tau + d_hat)  # d = d̂: exactly v (Eq 3)
        np.testing.assert_allclose(ddq0, ctrl.v, atol=1e-9)


def _observer_residual(robot, Ts, T=1.5):
    d = np.array([4.0, -3.0, 1.5])
    ctrl = _controller(robot, Ts=Ts, observer=ObserverConfig(gain=100.0))
    ref = hmpc_pin.SineReference(3, amplitude=0.3)
    plant = robot.copy()
    q, dq = np.array([0.2, -0.1, 0.3]), np.zeros(3)
    ctrl.reset(q, dq)
    K = round(T / Ts)
    for k in range(K):
        tau = ctrl.step(k * Ts, q, dq, ref)
        q, dq = _rk4_hold(plant, q, dq, tau, d, Ts, steps=1)
    q_ref, _ = ref.sample(K * Ts)
    return ctrl.disturbance_estimate - d, q - q_ref


def test_observer_in_the_loop_cancels_a_constant_disturbance(planar3):
    """Eq (5): with the NDO in the loop, d̂ -> d and the arm tracks.

    On a moving arm the backward-Euler observer keeps a bias of order
    Ts/2 · d(τ − C q̇ − G)/dt; it must be small and shrink linearly with Ts.
    """
    w1, e1 = _observer_residual(planar3, 0.001)
    w2, _ = _observer_residual(planar3, 0.002)
    assert np.abs(w1).max() < 3e-3
    assert np.abs(e1).max() < 1e-3
    ratio = np.abs(w2).max() / np.abs(w1).max()
    assert 1.6 < ratio < 2.4, ratio


def test_state_is_not_shared_between_controllers(planar3):
    a, b = _controller(planar3), _controller(planar3)
    ref = hmpc_pin.SineReference(3)
    q, dq = np.full(3, 0.5), np.zeros(3)
    a.reset(q, dq)
    b.reset(q, dq)
    np.testing.assert_array_equal(a.step(0.0, q, dq, ref), b.step(0.0, q, dq, ref))


class _Ref:
    def __init__(self, q, dq):
        self.q, self.dq = q, dq

    def sample(self, t):
        return self.q, self.dq


NAN3 = np.array([0.1, np.nan, 0.0])
INF3 = np.array([np.inf, 0.0, 0.0])


@pytest.mark.parametrize(
    ("t", "q", "dq", "ref", "name"),
    [
        (np.nan, np.zeros(3), np.zeros(3), _Ref(np.zeros(3), np.zeros(3)), "t"),
        (np.inf, np.zeros(3), np.zeros(3), _Ref(np.zeros(3), np.zeros(3)), "t"),
        (0.0, NAN3, np.zeros(3), _Ref(np.zeros(3), np.zeros(3)), "q"),
        (0.0, np.zeros(3), INF3, _Ref(np.zeros(3), np.zeros(3)), "dq"),
        (0.0, np.zeros(3), np.zeros(3), _Ref(NAN3, np.zeros(3)), "reference"),
        (0.0, np.zeros(3), np.zeros(3), _Ref(np.zeros(3), INF3), "reference"),
    ],
)
def test_non_finite_input_fails_at_once(planar3, t, q, dq, ref, name):
    ctrl = hmpc_pin.HierarchicalMPC(planar3)
    ctrl.reset(np.zeros(3), np.zeros(3))
    start = time.perf_counter()
    with pytest.raises(hmpc_pin.NonFiniteError) as info:
        ctrl.step(t, q, dq, ref)
    assert time.perf_counter() - start < 5.0  # ProxSuite on NaN would spin for tens of seconds
    assert info.value.name == name
    assert isinstance(info.value, ValueError)
    assert "not finite" in str(info.value)


def test_wrong_dimension_is_a_clear_error(planar3):
    ctrl = hmpc_pin.HierarchicalMPC(planar3)
    ctrl.reset(np.zeros(3), np.zeros(3))
    with pytest.raises(hmpc_pin.DimensionError, match=r"q has shape \(2,\).*3 joints"):
        ctrl.step(0.0, np.zeros(2), np.zeros(3), hmpc_pin.SineReference(3))
    with pytest.raises(hmpc_pin.DimensionError, match=r"reference\.sample(_many)? returned"):
        ctrl.step(0.0, np.zeros(3), np.zeros(3), _Ref(np.zeros(2), np.zeros(2)))
    with pytest.raises(hmpc_pin.DimensionError, match="dq0"):
        ctrl.reset(np.zeros(3), np.zeros(4))


@pytest.mark.parametrize("layout", ["block", "joint"])
def test_unsolved_qp_raises_naming_joint_and_status(planar3, layout):
    """A QP stopped by its iteration cap must raise, never return a torque."""
    ctrl = _controller(
        planar3, N=10, Nc=5, max_iter=1, eps_abs=1e-12, v_min=-1.0, v_max=1.0, qp_layout=layout
    )
    ctrl.qps.active_set_iter = -1  # every active box to ProxSuite (the shortcut answers it)
    ctrl.reset(np.zeros(3), np.zeros(3))
    far = _Ref(np.array([2.0, -2.0, 2.0]), np.array([5.0, -5.0, 5.0]))
    with pytest.raises(hmpc_pin.SolverError) as info:
        ctrl.step(0.0, np.zeros(3), np.zeros(3), far)
    err = info.value
    if layout == "joint":
        assert err.joint == 0 and "joint1" in str(err)
    else:
        assert err.joint is None and "all-joint block MPC QP was not solved" in str(err)
    assert "MAX_ITER" in err.status and "not solved" in str(err)


def test_block_qp_run_equals_per_joint_qps(planar3):
    """The fast path (all joints in one block-diagonal QP) gives the same closed loop as
    the straightforward one QP per joint, to solver tolerance, on the paper's combined
    scenario (friction + pulses, NDO on)."""
    from hmpc_pin.sim.simulate import simulate

    d = hmpc_pin.CoulombViscousFriction([10.0, 8.0, 5.0], [3.0, 2.4, 1.8]) + hmpc_pin.GaussianPulse(
        [10.0, 8.0, 0.3], [1.0, 2.0, 3.0], 0.3
    )
    runs = {}
    for layout in ("block", "joint"):
        ctrl = hmpc_pin.HierarchicalMPC(planar3, MPCSettings(qp_layout=layout))
        runs[layout] = simulate(
            planar3, ctrl, hmpc_pin.SineReference(3), d, duration=3.0, q0=np.ones(3)
        )
    np.testing.assert_allclose(runs["block"].q, runs["joint"].q, atol=1e-8)
    np.testing.assert_allclose(runs["block"].tau, runs["joint"].tau, atol=1e-4, rtol=1e-7)


class _SampleOnly:
    """A reference with only ``sample(t)``: the controller's generic sampling path."""

    def __init__(self, ref):
        self.ref = ref

    def sample(self, t):
        return self.ref.sample(t)


@pytest.mark.parametrize("Nc", [1, 5])
def test_sine_sampled_in_place_equals_generic_reference_path(planar3, Nc):
    """The SineReference fast path (``sample_many(times, out)`` writing straight into the
    horizon stack) gives the torques of the generic path (``sample(t)`` per horizon
    instant, through :func:`~hmpc_pin.tasks.base.as_reference`), closed loop."""
    from hmpc_pin.sim.simulate import simulate

    ref = hmpc_pin.SineReference(3, amplitude=[1.0, 0.5, 0.8], frequency=[0.1, 0.3, 0.2],
                                 offset=[0.1, 0.0, -0.2], phase=[0.0, 0.5, 1.0])  # fmt: skip
    d = hmpc_pin.CoulombViscousFriction([10.0, 8.0, 5.0], [3.0, 2.4, 1.8])
    q0 = np.array([0.2, 0.1, -0.1])
    runs = []
    for r in (ref, _SampleOnly(ref)):
        ctrl = hmpc_pin.HierarchicalMPC(planar3, MPCSettings(Nc=Nc))
        runs.append(simulate(planar3, ctrl, r, d, duration=1.0, q0=q0))
    np.testing.assert_allclose(runs[0].tau, runs[1].tau, rtol=0, atol=1e-9)
    np.testing.assert_allclose(runs[0].q, runs[1].q, rtol=0, atol=1e-12)


def test_step_equals_its_equations(planar3):
    """One step against Eq 4 and the MPC written out: M v + C q̇ + G − d̂ with v the clipped
    closed-form minimiser of each joint's 1-input QP (Nc = 1), d̂ from the observer."""
    ctrl = hmpc_pin.HierarchicalMPC(planar3)
    ref = hmpc_pin.SineReference(3)
    model, data = planar3.model, planar3.model.createData()
    rng = np.random.default_rng(3)
    q, dq = rng.uniform(-0.5, 0.5, 3), rng.normal(0, 0.5, 3)
    ctrl.reset(q, dq)
    ctrl.step(0.0, q, dq, ref)
    for k in range(1, 4):
        q, dq = q + 0.01 * dq, dq + rng.normal(0, 0.1, 3)
        tau_prev = ctrl.tau.copy()
        z_prev = ctrl.compensation.z.copy()
        t = 0.01 * k
        tau = ctrl.step(t, q, dq, ref)
        mpc = ctrl.mpc
        times = t + 0.01 * np.arange(1, 11)
        r = np.empty((20, 3))
        for j, tj in enumerate(times):
            r[2 * j], r[2 * j + 1] = ref.sample(tj)
        H = mpc.H[0, 0]
        g = np.array([mpc.F[0] @ np.concatenate([[q[i], dq[i]], r[:, i]]) for i in range(3)])
        v = np.clip(-g / H, -100.0, 100.0)
        M = pin.crba(model, data, q)
        nle = pin.nonLinearEffects(model, data, q, dq)
        cY = 100.0 * np.tril(np.ones((3, 3)))  # the default observer: chen, c = 100
        p = cY @ dq
        L = cY @ np.linalg.inv(M)  # Eq 30
        z = np.linalg.solve(np.eye(3) + 0.01 * L, z_prev + 0.01 * L @ (nle - tau_prev - p))
        np.testing.assert_allclose(ctrl.v, v, rtol=0, atol=1e-7)
        np.testing.assert_allclose(ctrl.disturbance_estimate, z + p, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(tau, M @ ctrl.v + nle - (z + p), rtol=1e-12, atol=1e-10)


def test_observer_is_fed_the_applied_torque_when_the_plant_saturates():
    """Effort limits that clip the start-up torque: fed the clipped torque the plant
    applied, the NDO's estimate still explains the true disturbance (recorded by the
    plant); fed the commanded torque it winds up by the clipped part (the 0.2 behaviour)."""
    import dataclasses

    from hmpc_pin.experiment.build import Experiment

    cfg = hmpc_pin.load_config("paper_combined")
    cfg = dataclasses.replace(
        cfg, plant=dataclasses.replace(cfg.plant, effort_limit=(600.0, 300.0, 150.0))
    )
    rms = {}
    for fed in ("applied", "commanded"):
        ex = Experiment.from_config(cfg)
        np.testing.assert_array_equal(ex.controller.effort_limit, [600.0, 300.0, 150.0])
        if fed == "commanded":
            ex.controller.effort_limit = None
        r = ex.run(duration=3.0)
        assert np.all(np.asarray(r.meta["saturation"]["steps"]) > 0)  # the limits bite
        after = r.t >= 1.0
        rms[fed] = (
            np.sqrt(((r.d - r.d_hat)[after] ** 2).mean(0)),
            np.sqrt((r.d[after] ** 2).mean(0)),
            np.abs(r.q - r.q_ref)[after].max(0),
        )
    err, scale, e = rms["applied"]
    assert np.all(err <= 0.5 * scale), (err, scale)  # d̂ explains >= 75 % of d's power
    assert np.all(e < 0.1), e
    err, scale, _ = rms["commanded"]
    assert np.any(err > 2.0 * scale), (err, scale)  # wind-up: the bound above can fail


def test_the_0_1_constructor_with_a_controller_config_still_works(planar3):
    """``HierarchicalMPC(robot, ControllerConfig)`` (version 0.1): a DeprecationWarning
    naming the replacement, and the controller the config describes."""
    import hmpc_pin

    cfg = hmpc_pin.ControllerConfig(Nc=3, compensation="general")
    with pytest.warns(DeprecationWarning, match="make_controller"):
        ctrl = hmpc_pin.HierarchicalMPC(planar3, cfg)
    assert ctrl.settings.Nc == 3 and ctrl.compensation.kind == "general"
    ref = hmpc_pin.SineReference(3)
    q0, dq0 = ref.sample(0.0)
    ctrl.reset(q0, dq0)
    assert np.all(np.isfinite(ctrl.step(0.0, q0, dq0, ref)))


def test_settings_of_another_type_are_one_error_naming_the_settings_class(planar3):
    """Neither MPCSettings nor a ControllerConfig: an InterfaceError naming both, no
    DeprecationWarning (the 0.1 path takes only the registered config type)."""
    import warnings

    import hmpc_pin

    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        with pytest.raises(hmpc_pin.InterfaceError, match=r"MPCSettings.*make_controller"):
            hmpc_pin.HierarchicalMPC(planar3, {"Ts": 0.01, "compensation": "chen"})
        with pytest.raises(hmpc_pin.InterfaceError, match=r"CTSettings.*make_controller"):
            hmpc_pin.ComputedTorque(planar3, {"Ts": 0.01})


@pytest.mark.parametrize(
    ("layout", "latency", "joint_dynamics", "at"),
    [
        ("joint", 0.0, False, "end"),
        ("block", 0.0, False, "end"),
        ("joint", 0.02, False, "end"),
        ("joint", 0.0, True, "end"),
        ("joint", 0.015, True, "end"),
        ("joint", 0.0, False, "start"),
        ("joint", 0.015, False, "start"),
        ("joint", 0.0, True, "start"),
    ],
)
# (latency, joint dynamics and "start" together: the closed loop amplifies ProxSuite's
# tolerance to 2e-6 of the torque from step 29 on, beyond this test's rtol; each pair is here)
def test_warm_up_leaves_the_next_step_unchanged(planar3, tmp_path, layout, latency,
                                                joint_dynamics, at):  # fmt: skip
    """``warm_up`` (a step undone, run by the real-time loop before an MPC cycle) between
    the steps of a closed loop from 1 rad off, against the same loop without it: the same
    torques and estimates, bit for bit in the "joint" layout (the QPs' warm starts and
    remembered active sets restored), to ProxSuite's tolerance in the "block" layout.
    Also with a measurement latency and with compensated URDF joint dynamics (the compiled
    step's torque histories and joint torque restored), and with the observer's model at
    the start of the period (the previous measurement's M, C q̇ + G restored)."""
    if joint_dynamics:
        from .test_joint_dynamics import _planar3_with_dynamics

        planar3 = hmpc_pin.load_robot(_planar3_with_dynamics(tmp_path), 9.81)
        assert planar3.joint_damping.min() > 0
    Ts = 0.01
    ref = hmpc_pin.SineReference(3)
    d = np.array([3.0, -2.0, 1.0])
    settings = MPCSettings(Ts=Ts, N=10, Nc=3, qp_layout=layout, latency=latency, model_at=at)
    ctrls = [hmpc_pin.HierarchicalMPC(planar3, settings,
                                      DisturbanceObserver(3, Ts, 100.0, "chen", "implicit"))
             for _ in range(2)]  # fmt: skip
    q0, dq0 = np.ones(3), np.zeros(3)
    out = []
    for warm, ctrl in zip((False, True), ctrls, strict=True):
        ctrl.reset(q0, dq0)
        q, dq, taus, dhats = q0.copy(), dq0.copy(), [], []
        q_prev, dq_prev = q.copy(), dq.copy()
        for k in range(60):
            if warm:
                ctrl.warm_up(k * Ts, q_prev, dq_prev, ref)  # before the first step: no-op
            tau = ctrl.step(k * Ts, q, dq, ref)
            taus.append(tau)
            dhats.append(ctrl.disturbance_estimate.copy())
            q_prev, dq_prev = q, dq
            q, dq = _rk4_hold(planar3, q, dq, tau, d, Ts, steps=10)
        out.append((np.array(taus), np.array(dhats), copy.copy(ctrl.qps._core.stats)))
    (tau_a, d_a, c_a), (tau_b, d_b, c_b) = out
    # the QPs' memory (warm starts, remembered active sets) restored after the dry step:
    # the "joint" layout's answers bit for bit; the block QP's ProxSuite solves to its
    # tolerance (its workspace, not restored, differs in the last bits)
    if layout == "joint":
        np.testing.assert_array_equal(tau_b, tau_a)
        np.testing.assert_array_equal(d_b, d_a)
    np.testing.assert_allclose(tau_b, tau_a, rtol=1e-7, atol=1e-4)
    np.testing.assert_allclose(d_b, d_a, rtol=1e-7, atol=1e-4)
    if layout == "joint":  # the exact shortcuts answered (the block QP has none)
        assert all(c.unconstrained_solves + c.active_set_solves > 0 for c in (c_a, c_b))
    assert np.abs(tau_a).max() > 0  # a real run


@pytest.mark.parametrize("bound", [None, 16])
def test_warm_up_leaves_the_soft_limits_next_step_bit_for_bit(bound):
    """Panda at Ts = 1 ms, N = Nc = 100 with the default soft joint limits, a closed loop
    from 0.2 rad off (every joint's soft QP active, answered by the soft active-set
    shortcut from the active sets it remembers; with ``soft_step_exchanges`` = 16 also by
    the fallback): ``warm_up`` before each step leaves the torques and the QPs' counters
    (the paths that answered) bit for bit those of the same loop without it. Measured
    before the QPs' memory was restored: the same torques, 13 soft exchanges more."""
    from benchmarks._fixtures import HOMES, PANDA_LOCKED, load_arm
    from benchmarks.studies.long_horizon_soft import controller

    arm = load_arm("panda", "panda", HOMES["panda"], "general", PANDA_LOCKED)
    robot, ref, Ts = arm.robot, arm.reference(), 0.001
    t = Ts * np.arange(30)
    q_ref, dq_ref = ref.sample_many(t)
    out = []
    for warm in (False, True):
        ctrl = controller(robot, Ts, 100)
        if bound is not None:
            ctrl.qps.soft_step_exchanges = bound
        ctrl.reset(q_ref[0], dq_ref[0])
        q, dq = q_ref[0] + 0.2, dq_ref[0].copy()
        q_prev, dq_prev, taus = q.copy(), dq.copy(), []
        for k in range(len(t)):
            if warm:
                ctrl.warm_up(t[k], q_prev, dq_prev, ref)
            taus.append(ctrl.step(t[k], q, dq, ref))
            v = ctrl.v.copy()
            q_prev, dq_prev = q, dq
            q, dq = q + Ts * dq + 0.5 * Ts * Ts * v, dq + Ts * v
        out.append((np.array(taus), copy.copy(ctrl.qps._core.stats)))
    (tau_a, c_a), (tau_b, c_b) = out
    np.testing.assert_array_equal(tau_b, tau_a)
    assert c_a == c_b, (c_a, c_b)
    assert c_a.soft_active_set_solves > 0
    if bound is not None:
        assert c_a.soft_fallbacks > 0


def test_warm_up_before_the_first_step_changes_nothing(planar3):
    """Right after reset there is nothing to warm: the call leaves every buffer alone."""
    ctrl = hmpc_pin.HierarchicalMPC(planar3)
    ctrl.reset(np.ones(3), np.zeros(3))
    after = (ctrl.tau, ctrl.v, ctrl._data.stack, ctrl.qps.solution, ctrl.qps.slack)
    before = tuple(x.copy() for x in after)
    ctrl.warm_up(0.0, np.ones(3), np.zeros(3), hmpc_pin.SineReference(3))
    for a, b in zip(before, after, strict=True):
        np.testing.assert_array_equal(a, b)


PANDA_HOME = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])  # [rad]


def _soft_closed_loop(ctrl, ref, Ts, steps, offset):
    """Accelerations v (steps, n) of ``ctrl`` in a closed loop of the feedback-linearised
    arm (q̈ = v exactly, Eq 24) started ``offset`` rad off ``ref``, and the steps that solved
    soft-limit QPs."""
    q, dq = ref.sample(0.0)
    q, dq = q + offset, np.array(dq, dtype=float)
    ctrl.reset(q, dq)
    vs, soft = [], 0
    for k in range(steps):
        ctrl.step(k * Ts, q, dq, ref)
        v = ctrl.v.copy()
        vs.append(v)
        soft += ctrl.qps.constrained
        q, dq = q + Ts * dq + 0.5 * Ts * Ts * v, dq + Ts * v
    return np.array(vs), soft


def test_a_reset_controller_steps_as_a_new_one_bit_for_bit():
    """A run after ``reset`` gives, bit for bit, the accelerations of a new controller: no
    warm start, remembered active set or soft-limit guess of the run before reaches the
    next (a run's arrays do not depend on what ran before it; sweeps and tuning reuse a
    controller). The Panda at Ts = 1 ms, N = Nc = 100 with its default soft joint limits
    active (started off a sine, first 0.2 rad above it, then 0.2 rad below): without the
    restart of the QPs at reset the second run differed from a new controller's by 1.4e-12
    rad/s² (ProxSuite warm-started from the first run's last solutions)."""
    from hmpc_pin import load_robot

    robot = load_robot(
        "panda",
        gravity=9.81,
        locked_joints={"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0},
    )
    Ts, N = 0.001, 100
    ref = hmpc_pin.SineReference(7, amplitude=0.3, frequency=0.1, offset=PANDA_HOME)

    def new():
        settings = MPCSettings(Ts=Ts, N=N, Nc=N)
        return hmpc_pin.HierarchicalMPC(robot, settings, DisturbanceObserver(7, Ts, 100.0))

    used = new()
    first, soft_first = _soft_closed_loop(used, ref, Ts, 30, 0.2)
    again, soft_again = _soft_closed_loop(used, ref, Ts, 30, -0.2)
    fresh, _ = _soft_closed_loop(new(), ref, Ts, 30, -0.2)
    assert soft_first > 0 and soft_again > 0  # the soft limits were active in both runs
    np.testing.assert_array_equal(again, fresh)
    # and the first run once more after it: the same, bit for bit
    np.testing.assert_array_equal(_soft_closed_loop(used, ref, Ts, 30, 0.2)[0], first)
