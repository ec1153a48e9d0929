"""The plant's step: Coulomb friction integrated as stick-slip, and the step chosen by its
error (``[plant] tolerance``).

- Order: with the velocity's sign changes located, the RK4 plant's error against an
  independent integration (scipy's DOP853 at 1e-12 with the same stick-slip law and its own
  events, ``tests/reference/rk4.py``) falls as h⁴ on a 3-joint arm with joint damping and
  Coulomb friction whose joints reverse; the per-stage sgn falls as h.
- Sticking: a disc braked by Coulomb friction stops at t* = I ω₀ / f and stays there (closed
  form); an arm whose friction exceeds the torques keeps its joints exactly at rest, the
  holding torque φ = −τ without gravity (closed form), and with gravity agrees with the
  oracle's stuck joints.
- The step chosen by ``tolerance``: the largest Ts/m within it (the next larger is not), a
  run's error against a fine integration within it; the keys that do not apply.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import replace

import numpy as np
import pytest

from hmpc_pin.exceptions import ConfigError
from hmpc_pin.experiment.config import PlantConfig, load_config
from hmpc_pin.model.robot import load_robot
from hmpc_pin.sim.plants import RK4Plant, choose_step

from .conftest import CONFIGS
from .reference.rk4 import stick_slip_period
from .test_joint_dynamics import I_ZZ, _planar3_with_dynamics, disc_urdf

TS = 0.01


def _arm(tmp_path, friction_scale: float = 1.0, gravity: float = 9.81):
    """planar3 with joint damping (0.4, 0.5, 0.6) and Coulomb friction (0.7, 0.8, 0.9) ×
    ``friction_scale`` [N·m]."""
    robot = load_robot(_planar3_with_dynamics(tmp_path), gravity)
    robot.joint_friction[:] = robot.joint_friction * friction_scale
    return robot


def _oracle_run(robot, q0, dq0, periods, torque):
    """The oracle's states over ``periods`` and the torques held (from its own states)."""
    q, v = np.array(q0, dtype=float), np.array(dq0, dtype=float)
    states, taus, events = [(q, v)], [], 0
    for k in range(periods):
        tau = torque(q, k)
        q, v, e = stick_slip_period(robot.model, q, v, tau, TS, robot.joint_friction,
                                    robot.joint_damping)  # fmt: skip
        states.append((q, v))
        taus.append(tau)
        events += e
    return states, taus, events


def _zero(t, q, dq):
    return np.zeros_like(q)


def _error(robot, states, taus, h, coulomb="stick-slip", disturbance=None):
    """The largest state error max(|Δq|, Ts |Δq̇|) of the plant with step h, driven by the
    oracle's torques from its initial state (a disturbance function: the period that calls
    it per stage)."""
    plant = RK4Plant(robot, disturbance, TS, h, coulomb=coulomb)
    plant.reset(*states[0])
    err = 0.0
    for k, tau in enumerate(taus):
        q, dq = plant.advance(tau)
        err = max(err, np.abs(q - states[k + 1][0]).max(), TS * np.abs(dq - states[k + 1][1]).max())
    return err, plant


@pytest.mark.parametrize("disturbance", [None, _zero])
def test_stick_slip_rk4_converges_at_fourth_order_where_the_sign_law_is_first(
    tmp_path, disturbance
):
    robot = _arm(tmp_path)

    def torque(q, k):
        return np.array([5.0, 2.0, 1.0]) * np.sin(0.2 * k) + robot.gravity_torque(q)

    states, taus, events = _oracle_run(robot, [0.3, -0.4, 0.2], [0.5, -0.2, 0.1], 40, torque)
    assert events >= 2  # velocities reverse within periods
    e1, plant = _error(robot, states, taus, TS / 2, disturbance=disturbance)
    e2, _ = _error(robot, states, taus, TS / 4, disturbance=disturbance)
    assert plant.events >= 2 and plant.fused is (disturbance is None)
    # the errors stand far above the oracle's (rtol 1e-12 over 40 periods)
    assert e2 > 1e-11
    order = math.log2(e1 / e2)
    # RK4 on the smooth field between located events: 4 (+ O(h) before the asymptote)
    assert 3.0 < order < 5.0, (e1, e2, order)
    s1, _ = _error(robot, states, taus, TS / 2, "sign")
    s2, _ = _error(robot, states, taus, TS / 4, "sign")
    assert 0.5 < math.log2(s1 / s2) < 1.5  # sgn per stage: first order at the switch
    assert s2 > 1e4 * e2


def test_a_braked_disc_stops_at_i_w0_over_f_and_stays(tmp_path):
    """I ω̇ = −f until ω = 0 at t* = I ω₀/f = 0.055 s, then at rest (|τ| = 0 < f) at
    q* = ω₀ t*/2: exact for RK4 (ω linear in t) up to rounding, with the stop inside a step."""
    f, w0 = 0.02, 0.11
    robot = load_robot(disc_urdf(tmp_path, 0.0, f), 9.81)
    plant = RK4Plant(robot, None, TS, TS / 3)
    plant.reset(np.zeros(1), np.array([w0]))
    t_star = I_ZZ * w0 / f
    for k in range(1, 21):
        q, dq = plant.advance(np.zeros(1))
        t = k * TS
        if t < t_star:
            assert dq[0] == pytest.approx(w0 - f / I_ZZ * t, abs=1e-12)
        else:
            assert dq[0] == 0.0  # stuck, not chattering about 0
            assert q[0] == pytest.approx(0.5 * w0 * t_star, abs=1e-12)
    # the sign law chatters about zero instead
    sign = RK4Plant(robot, None, TS, TS / 3, coulomb="sign")
    sign.reset(np.zeros(1), np.array([w0]))
    for _ in range(20):
        _, dq = sign.advance(np.zeros(1))
    assert dq[0] != 0.0


def test_joints_stick_while_the_torque_is_within_their_friction(tmp_path):
    """Without gravity and at rest, a joint sticks iff |τ_i| <= F_i with the others stuck
    (φ = −τ keeps M q̈ = τ + φ at 0): all within → nothing moves, bit for bit."""
    robot = _arm(tmp_path, 2.0, gravity=0.0)  # F = 1.4, 1.6, 1.8
    plant = RK4Plant(robot, None, TS, TS / 4)
    q0 = np.array([0.3, -0.4, 0.2])
    plant.reset(q0, np.zeros(3))
    for _ in range(5):
        q, dq = plant.advance(np.array([1.3, -1.5, 1.7]))
    np.testing.assert_array_equal(q, q0)
    np.testing.assert_array_equal(dq, np.zeros(3))
    # joint 0 pushed past its friction slides, in the torque's direction
    q, dq = plant.advance(np.array([1.5, 0.0, 0.0]))
    assert dq[0] > 0.0 and q[0] > q0[0]


def test_stuck_and_sliding_joints_agree_with_the_oracle(tmp_path):
    """Friction ×3: two joints come to rest and stay stuck for most of the run; the states
    agree with the oracle within the plant's own error estimate (the step against its
    half, twice, as for a 4th-order method the error is 16/15 of that difference), and the
    stuck joints are exactly at rest in both."""
    robot = _arm(tmp_path, 3.0)

    def torque(q, k):
        return np.array([3.0, 2.0, 1.0]) * np.sin(0.15 * k) + robot.gravity_torque(q)

    states, taus, _ = _oracle_run(robot, [0.3, -0.4, 0.2], [0.5, -0.2, 0.1], 60, torque)
    stuck = sum(int((v == 0).sum()) for _, v in states)
    assert stuck > 60  # joint-periods at rest
    coarse = RK4Plant(robot, None, TS, TS / 2)
    fine = RK4Plant(robot, None, TS, TS / 4)
    coarse.reset(*states[0])
    fine.reset(*states[0])
    for k, tau in enumerate(taus):
        q, dq = coarse.advance(tau)
        qf, _ = fine.advance(tau)
        q_want, dq_want = states[k + 1]
        np.testing.assert_array_equal(dq == 0.0, dq_want == 0.0)
        bound = 2 * np.abs(q - qf).max() + 1e-10  # (+ the oracle's own error)
        assert np.abs(q - q_want).max() <= bound, k


def test_the_tolerance_picks_the_largest_step_within_it(planar3):
    robot = planar3
    rng = np.random.default_rng(3)
    samples = [(0.01 * k, rng.uniform(-1, 1, 3), rng.uniform(-2, 2, 3),
                robot.gravity_torque(np.zeros(3)) + rng.uniform(-5, 5, 3))
               for k in range(8)]  # fmt: skip

    def error(h):  # E(h) = K max_k e_k, computed here from its definition
        worst = 0.0
        for t, q, dq, tau in samples:
            a, b = RK4Plant(robot, None, TS, h), RK4Plant(robot, None, TS, h / 2)
            a.reset(q, dq, t)
            b.reset(q, dq, t)
            (qa, va), (qb, vb) = a.advance(tau), b.advance(tau)
            worst = max(worst, np.abs(qa - qb).max(), TS * np.abs(va - vb).max())
        return 100 * worst

    tol = 1e-7
    h, err = choose_step(lambda h: RK4Plant(robot, None, TS, h), TS, samples, tol, periods=100)
    m = round(TS / h)
    assert m > 1 and err <= tol
    assert error(h) == pytest.approx(err, rel=1e-12)
    assert error(TS / (m - 1)) > tol  # the next larger step is not within it
    with pytest.raises(ConfigError, match=r"plant\.tolerance"):
        choose_step(lambda h: RK4Plant(robot, None, TS, h), TS, samples, 1e-300, 100, 4)


def test_a_run_with_the_chosen_step_is_within_the_tolerance_of_a_fine_one():
    from hmpc_pin.experiment.build import Experiment

    config = load_config(CONFIGS / "paper_combined.toml")
    config = replace(config, simulation=replace(config.simulation, duration=2.0))
    pc = config.plant
    tol = 1e-5
    chosen = Experiment.from_config(replace(config, plant=replace(pc, dt=None, tolerance=tol)))
    plant = chosen.make_plant()
    assert plant.h > pc.dt  # coarser than the fixed 1 ms
    fine = Experiment.from_config(replace(config, plant=replace(pc, dt=1e-4)))
    run = chosen.run()
    err = np.abs(run.q - fine.run().q).max()
    assert err <= tol
    assert run.meta["plant_step"] == plant.h and run.meta["coulomb"] == "stick-slip"


@pytest.mark.parametrize("kw, match", [
    ({"tolerance": 1e-6, "dt": 0.001}, "both given"),
    ({"tolerance": 0.0}, "tolerance"),
    ({"tolerance": 1e-6, "engine": "mujoco"}, "does not apply to engine = 'mujoco'"),
    ({"coulomb": "sign", "integrator": "euler"}, "integrator = 'euler'"),
    ({"coulomb": "smooth"}, "coulomb"),
])  # fmt: skip
def test_plant_keys_that_do_not_apply_are_errors(kw, match):
    with pytest.raises(ConfigError, match=match) as info:
        PlantConfig(**kw)
    assert info.value.key.split(".")[-1] in ("tolerance", "coulomb")


def test_a_friction_term_follows_the_same_law_fused_or_in_a_function(tmp_path):
    """The paper's friction alone (fused) and summed with a function of the user's (then
    evaluated as a function): the same stick-slip law, equal to rounding through reversals
    and sticking."""
    from hmpc_pin.sim.disturbances import CoulombViscousFriction

    robot = _arm(tmp_path)
    friction = CoulombViscousFriction([1.0, 0.8, 0.5], [3.0, 2.4, 1.8])
    fused = RK4Plant(robot, friction, TS, TS / 4)
    function = RK4Plant(robot, friction + _zero, TS, TS / 4)
    assert fused.fused and not function.fused
    for plant in (fused, function):
        plant.reset(np.array([0.3, -0.4, 0.2]), np.array([0.5, -0.2, 0.1]))
    rests = 0
    for k in range(60):
        tau = np.array([5.0, 2.0, 1.0]) * np.sin(0.2 * k) + robot.gravity_torque(fused.q)
        q, dq = fused.advance(tau)
        q2, dq2 = function.advance(tau)
        np.testing.assert_allclose(q2, q, rtol=0, atol=1e-12)
        np.testing.assert_allclose(dq2, dq, rtol=0, atol=1e-10)
        rests += int((dq == 0).sum())
    assert rests > 0 and fused.events >= 2


def test_the_stick_slip_period_on_a_python_aba_equals_the_compiled_one(tmp_path):
    """The kernel on ABA given from Python (models the compiled dynamics cannot load) takes
    the same events and stuck joints as on the compiled dynamics, to rounding."""
    import pinocchio as pin

    from hmpc_pin.native import load, model_string

    robot = _arm(tmp_path, 3.0)
    core = load()
    data = robot.model.createData()
    compiled = core.RK4(model_string(robot))
    python = core.RK4(None, 3, lambda q, v, u: pin.aba(robot.model, data, q, v, u))
    q1, v1 = np.array([0.3, -0.4, 0.2]), np.array([0.5, -0.2, 0.1])
    q2, v2 = q1.copy(), v1.copy()
    zero = np.zeros(3)
    for kernel in (compiled, python):
        kernel.set_joint_dynamics(robot.joint_damping, robot.joint_friction)
    for k in range(40):
        tau = np.array([3.0, 2.0, 1.0]) * np.sin(0.15 * k) + robot.gravity_torque(q1)
        T = np.tile(tau, (12, 1))  # 4 steps: rows t_s, t_s + h/2, t_s + h
        compiled.period(q1, v1, T, zero, zero, False, TS / 4)
        python.period(q2, v2, T, zero, zero, False, TS / 4)
        np.testing.assert_allclose(q2, q1, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(v2 == 0.0, v1 == 0.0)
    assert compiled.events == python.events >= 2


# -- at rest: the holding torque's closed form, breakaway, and what a run records -------------

PEND_M, PEND_L, PEND_G, PEND_I = 1.0, 0.5, 9.81, 0.01  # [kg, m, m/s², kg·m² about the CoM]


def _pendulum(tmp_path, friction: float) -> str:
    """A pendulum about y, its CoM at l below the joint: G(q) = m g l sin q, Coulomb friction
    ``friction`` [N·m] as the joint's own."""
    text = f"""<?xml version="1.0"?>
<robot name="pendulum">
  <link name="base"/>
  <link name="bob">
    <inertial><origin xyz="0 0 {-PEND_L}" rpy="0 0 0"/><mass value="{PEND_M}"/>
      <inertia ixx="{PEND_I}" iyy="{PEND_I}" izz="{PEND_I}" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <joint name="swing" type="revolute">
    <parent link="base"/><child link="bob"/><origin xyz="0 0 0" rpy="0 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-1000" upper="1000" effort="100" velocity="1000"/>
    <dynamics damping="0" friction="{friction}"/>
  </joint>
</robot>
"""
    path = tmp_path / "pendulum.urdf"
    path.write_text(text)
    return str(path)


def test_a_pendulum_held_by_friction_breaks_away_where_its_holding_torque_reaches_f(tmp_path):
    """At rest at q0 the friction holds G(q0) − τ = m g l sin q0 − τ while that is within
    ±F: with τ raised by δ per period the state stays exactly as it was (bit for bit) until
    the first period with τ > m g l sin q0 + F (closed form), where it moves, in τ's
    direction. The whole run, the breakaway and the swing after it, agrees with scipy's
    DOP853 (the oracle, its own events) within the plant's own error estimate."""
    F, q0, delta = 3.0, 0.4, 0.05
    robot = load_robot(_pendulum(tmp_path, F), PEND_G)
    G0 = PEND_M * PEND_G * PEND_L * math.sin(q0)
    np.testing.assert_allclose(robot.gravity_torque(np.array([q0])), [G0], rtol=1e-12)
    k_star = math.floor((G0 + F) / delta) + 1  # the first k with k·δ > G0 + F
    assert min(k_star * delta - (G0 + F), (G0 + F) - (k_star - 1) * delta) > 1e-3
    plants = {h: RK4Plant(robot, None, TS, h) for h in (TS / 2, TS / 4)}
    for plant in plants.values():
        plant.reset(np.array([q0]), np.zeros(1))
    state = (np.array([q0]), np.zeros(1))
    for k in range(k_star + 15):
        tau = np.array([k * delta])
        q, dq = plants[TS / 2].advance(tau)
        qf, _ = plants[TS / 4].advance(tau)
        state = stick_slip_period(robot.model, *state, tau, TS, robot.joint_friction)[:2]
        if k < k_star:
            assert q[0] == q0 and dq[0] == 0.0, k
        elif k == k_star:
            assert q[0] > q0 and dq[0] > 0.0
        assert abs(q[0] - state[0][0]) <= 2 * abs(q[0] - qf[0]) + 1e-10, k


def test_the_rest_shortcut_takes_the_steps_the_general_algebra_takes(tmp_path):
    """planar3 with joint friction ×6, at rest, a torque ramping within each period (its
    stage rows) from holding to past the friction of joint 0, then back until the arm
    sticks again: the compiled
    kernel (which holds an arm at rest by φ = G(q) − τ) and the kernel on ABA from Python
    (the stuck joints' algebra (M⁻¹)_SS φ_S = −(M⁻¹u)_S at every stage) give the same
    states, the same joints at rest and the same events, to rounding."""
    import pinocchio as pin

    from hmpc_pin.native import load, model_string

    robot = _arm(tmp_path, 6.0)  # F = 4.2, 4.8, 5.4
    core = load()
    data = robot.model.createData()
    compiled = core.RK4(model_string(robot))
    python = core.RK4(None, 3, lambda q, v, u: pin.aba(robot.model, data, q, v, u))
    for kernel in (compiled, python):
        kernel.set_joint_dynamics(robot.joint_damping, robot.joint_friction)
    q1, v1 = np.array([0.3, -0.4, 0.2]), np.zeros(3)
    q2, v2 = q1.copy(), v1.copy()
    zero, S, h = np.zeros(3), 4, TS / 4
    hold = robot.gravity_torque(q1)
    rests, moved = 0, False
    for k in range(100):
        t_s = k * TS + h * np.arange(S)
        times = np.concatenate([t_s, t_s + h / 2, t_s + h])
        push = 6.0 * np.sin(np.pi * times / 0.6)  # 0 → 6 N·m → 0 over 0.6 s, on joint 0
        T = np.tile(hold, (3 * S, 1))
        T[:, 0] += push
        compiled.period(q1, v1, T, zero, zero, False, h)
        python.period(q2, v2, T, zero, zero, False, h)
        np.testing.assert_allclose(q2, q1, rtol=0, atol=1e-12)
        np.testing.assert_allclose(v2, v1, rtol=0, atol=1e-10)
        np.testing.assert_array_equal(v2 == 0.0, v1 == 0.0)
        rests += bool((v1 == 0.0).all())
        moved = moved or (v1 != 0.0).any()
    assert rests >= 10 and moved and compiled.events == python.events >= 2


def _held_planar3(tmp_path, joint_friction: bool, function: bool = False):
    """planar3 (joint friction 0.7, 0.8, 0.9 when ``joint_friction``) with the disturbance
    −(a q̇ + b sgn q̇), b = (10, 8, 5): fused, or (``function``) summed with a function of
    the user's that is zero (then called per stage)."""
    from hmpc_pin.sim.disturbances import CoulombViscousFriction

    plain = CONFIGS.parent / "robots" / "planar3.urdf"
    robot = load_robot(_planar3_with_dynamics(tmp_path) if joint_friction else str(plain), 9.81)
    a, b = np.array([1.0, 0.8, 0.5]), np.array([10.0, 8.0, 5.0])
    friction = CoulombViscousFriction(a, b)
    plant = RK4Plant(robot, friction + _zero if function else friction, TS, TS / 4)
    assert plant.fused is not function
    return robot, plant, a, b


@pytest.mark.parametrize(("joint_friction", "function"), [(False, False), (True, False),
                                                          (True, True)])  # fmt: skip
def test_the_applied_disturbance_of_a_stuck_arm_is_its_holding_torque(
    tmp_path, joint_friction, function
):
    """Every joint at rest and held: the friction applied is what RNEA at q̇ = q̈ = 0 needs
    beyond τ, φ = G(q) − τ (Pinocchio), the disturbance's share b/(F + b) of it when the
    joints have their own friction F; disturbance_now() says 0 there (sgn 0 = 0). The
    same with the friction in a disturbance called as a function."""
    import pinocchio as pin

    robot, plant, _, b = _held_planar3(tmp_path, joint_friction, function)
    q0 = np.array([0.3, -0.2, 0.4])
    zero = np.zeros(3)
    G = pin.rnea(robot.model, robot.model.createData(), q0, zero, zero)
    tau = G + np.array([2.0, -3.0, 1.0])
    F = robot.joint_friction if joint_friction else zero
    plant.reset(q0, zero)
    d_now = plant.disturbance_now()
    q, _ = plant.advance(tau)
    np.testing.assert_array_equal(q, q0)  # held
    np.testing.assert_array_equal(d_now, zero)
    np.testing.assert_allclose(plant.applied_disturbance(d_now), (G - tau) * b / (F + b),
                               rtol=0, atol=1e-10)  # fmt: skip


def test_the_applied_disturbance_with_a_joint_sliding_and_two_stuck(tmp_path):
    """Joint 0 slides (q̇_0 = 0.5), joints 1, 2 at rest and held: the sliding joint's
    disturbance is −a q̇ − b sgn q̇; the stuck joints' is their holding torque
    φ_S = M_S0 q̈_0 + (C q̇ + G)_S − τ_S with q̈_0 from row 0, M_00 q̈_0 + (C q̇ + G)_0 =
    τ_0 − a_0 q̇_0 − b_0 (q̈_S = 0; Pinocchio's CRBA and RNEA)."""
    import pinocchio as pin

    robot, plant, a, b = _held_planar3(tmp_path, False)
    q0, dq0 = np.array([0.3, -0.2, 0.4]), np.array([0.5, 0.0, 0.0])
    data = robot.model.createData()
    M = pin.crba(robot.model, data, q0)
    M = np.triu(M) + np.triu(M, 1).T
    nle = pin.rnea(robot.model, data, q0, dq0, np.zeros(3))
    tau = nle + np.array([5.0, 1.0, -0.5])
    d0 = -a[0] * dq0[0] - b[0]
    qdd0 = (tau[0] + d0 - nle[0]) / M[0, 0]
    phi = M[1:, 0] * qdd0 + nle[1:] - tau[1:]
    assert (np.abs(phi) < b[1:]).all()  # they stick
    plant.reset(q0, dq0)
    d_now = plant.disturbance_now()
    _, dq = plant.advance(tau)
    assert dq[0] != 0.0 and (dq[1:] == 0.0).all()
    d = plant.applied_disturbance(d_now)
    assert d[0] == d_now[0] == pytest.approx(d0, abs=1e-12)
    np.testing.assert_allclose(d[1:], phi, rtol=0, atol=1e-9)


class _Hold:
    """A controller that holds the torque ``tau`` [N·m]."""

    Ts = TS

    def __init__(self, tau):
        self.tau, self.disturbance_estimate = tau, np.zeros(len(tau))

    def reset(self, q0, dq0):
        pass

    def step(self, t, q, dq, reference):
        return self.tau.copy()


@pytest.mark.parametrize("coulomb", ["stick-slip", "sign"])
def test_a_run_records_the_holding_torque_of_an_arm_held_by_friction(tmp_path, coulomb):
    """A run of planar3 held at rest by the fused friction: every sample that starts a
    period records d = G(q0) − τ (stick-slip: what the plant applied), the compiled loop
    and the per-step oracle alike; the last sample, which starts none, records 0
    (sgn 0 = 0). The sign law, which applies sgn 0 = 0 at rest and so lets the arm creep,
    records −(a q̇ + b sgn q̇) of each sample's state, as before."""
    import hmpc_pin
    from hmpc_pin.sim.disturbances import CoulombViscousFriction

    from .reference.loop import per_step

    robot, _, a, b = _held_planar3(tmp_path, False)
    q0 = np.array([0.3, -0.2, 0.4])
    tau = robot.gravity_torque(q0) + np.array([2.0, -3.0, 1.0])
    want = robot.gravity_torque(q0) - tau
    runs = []
    for loop in (contextlib.nullcontext(), per_step()):
        plant = RK4Plant(robot, CoulombViscousFriction(a, b), TS, TS / 4, coulomb=coulomb)
        with loop:
            runs.append(hmpc_pin.simulate(robot, _Hold(tau), hmpc_pin.SineReference(3),
                                          duration=0.1, q0=q0, plant=plant))  # fmt: skip
    for r in runs:
        if coulomb == "sign":
            assert np.abs(r.q - q0).max() > 1e-6  # the sign law lets it creep
            np.testing.assert_array_equal(r.d, -(a * r.dq + b * np.sign(r.dq)))
            continue
        np.testing.assert_array_equal(r.q, np.tile(q0, (len(r.t), 1)))
        np.testing.assert_allclose(r.d[:-1], np.tile(want, (len(r.t) - 1, 1)), atol=1e-10)
        np.testing.assert_array_equal(r.d[-1], np.zeros(3))
    np.testing.assert_array_equal(runs[0].d, runs[1].d)
