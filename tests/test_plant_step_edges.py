"""The stick-slip plant step at the edges its one-line bugs hid in
(benchmarks/tools/mutants_cpp.py), each against a closed form.

- A disc at rest held by Coulomb friction F under a torque ramp d(t) = s c t breaks away
  inside a step at t* = F / c, in either direction s, then I ω̇ = s (c t − F): ω = s c (t − t*)²
  / (2 I), q = s c (t − t*)³ / (6 I), exact for RK4 (q a cubic in t) once the breakaway is
  located inside the step.
- A reset at rest elsewhere: the plant as new (the rest test's gravity not a stale one).
- RK4's period over a torque table linear in time: exact (each stage its row).
"""

from __future__ import annotations

import numpy as np
import pytest

from hmpc_pin.model.robot import load_robot
from hmpc_pin.sim.plants import RK4Plant

from .test_joint_dynamics import I_ZZ, disc_urdf

TS = 0.01


@pytest.mark.parametrize("s", [1.0, -1.0])
def test_a_disc_under_a_torque_ramp_breaks_away_inside_the_step_either_way(tmp_path, s):
    F, c = 0.02, 0.9  # t* = F / c = 22.2 ms: inside the third period, off the substeps
    robot = load_robot(disc_urdf(tmp_path, 0.0, F), 9.81)
    t_star = F / c

    def ramp(t, q, dq):
        return np.array([s * c * t])

    plant = RK4Plant(robot, ramp, TS, TS / 2)
    plant.reset(np.zeros(1), np.zeros(1))
    for k in range(1, 8):
        q, dq = plant.advance(np.zeros(1))
        t = k * TS
        if t <= t_star:
            assert q[0] == 0.0 and dq[0] == 0.0, k  # held: exactly at rest
        else:
            w = s * c * (t - t_star) ** 2 / (2 * I_ZZ)
            x = s * c * (t - t_star) ** 3 / (6 * I_ZZ)
            assert dq[0] == pytest.approx(w, rel=1e-9, abs=1e-12), k
            assert q[0] == pytest.approx(x, rel=1e-8, abs=1e-13), k


def test_a_pendulum_reset_at_rest_elsewhere_falls_as_a_new_plant_does(tmp_path):
    """Held by its friction F at q0 (G(q0) = m g l sin q0 < F), then reset at rest at q1, where
    G(q1) > F: it falls at once, q̈ = (F − G(q1)) / (I + m l²) (closed form, for the first
    period up to the change of G over it), and bit for bit as a new plant reset at q1 does
    (a run does not depend on the runs before it)."""
    from .test_plant_step import PEND_G, PEND_I, PEND_L, PEND_M, _pendulum

    F, q0, q1 = 3.0, 0.3, 1.0
    robot = load_robot(_pendulum(tmp_path, F), PEND_G)
    mgl = PEND_M * PEND_G * PEND_L
    assert mgl * np.sin(q0) < F - 1.0 and mgl * np.sin(q1) > F + 1.0
    used = RK4Plant(robot, None, TS, TS / 2)
    used.reset(np.array([q0]), np.zeros(1))
    for _ in range(3):
        q, dq = used.advance(np.zeros(1))
        assert q[0] == q0 and dq[0] == 0.0  # held
    used.reset(np.array([q1]), np.zeros(1))
    new = RK4Plant(robot, None, TS, TS / 2)
    new.reset(np.array([q1]), np.zeros(1))
    acc = (F - mgl * np.sin(q1)) / (PEND_I + PEND_M * PEND_L**2)
    for k in range(3):
        q, dq = used.advance(np.zeros(1))
        qn, dqn = new.advance(np.zeros(1))
        np.testing.assert_array_equal(q, qn)
        np.testing.assert_array_equal(dq, dqn)
        if k == 0:
            assert dq[0] == pytest.approx(acc * TS, rel=1e-2)


def test_rk4_period_of_a_torque_linear_in_time_is_exact():
    """A unit mass, q̈ = τ(t) = c t, its torque table's rows at each substep's start, midpoint
    and end: RK4 integrates it exactly (q a cubic in t), v = c t² / 2, q = c t³ / 6."""
    from hmpc_pin.native import load as load_native

    core = load_native()
    rk4 = core.RK4(None, n=1, aba=lambda q, v, tau: np.array(tau, dtype=float))
    c, h, S = 3.0, 0.004, 5
    q, v = np.zeros(1), np.zeros(1)
    t0 = 0.0
    for _ in range(3):
        ts = t0 + h * np.arange(S)
        T = np.ascontiguousarray(
            np.concatenate([c * ts, c * (ts + 0.5 * h), c * (ts + h)])[:, None]
        )
        rk4.period(q, v, T, np.zeros(1), np.zeros(1), False, h)
        t0 += S * h
        assert v[0] == pytest.approx(c * t0**2 / 2, rel=1e-12)
        assert q[0] == pytest.approx(c * t0**3 / 6, rel=1e-12)


def test_rk4_period_with_a_disturbance_linear_in_time_is_exact():
    """The same unit mass driven by a disturbance function d(t) = c t (per stage, at its time):
    exact, v = c t² / 2, q = c t³ / 6."""
    from hmpc_pin.native import load as load_native

    core = load_native()
    rk4 = core.RK4(None, n=1, aba=lambda q, v, tau: np.array(tau, dtype=float))
    c, h, S = 3.0, 0.004, 5
    q, v = np.zeros(1), np.zeros(1)
    rk4.period_with(q, v, np.zeros(1), 0.0, h, S, lambda t, qs, vs: np.array([c * t]))
    t = S * h
    assert v[0] == pytest.approx(c * t**2 / 2, rel=1e-12)
    assert q[0] == pytest.approx(c * t**3 / 6, rel=1e-12)


def test_rk4_period_with_fused_damping_decays_as_the_closed_form():
    """A unit mass with the fused damping a = β (friction on, b = 0): v̇ = −β v, v = e^{−β t}
    (RK4's error O(h⁴): 1e-9 here)."""
    from hmpc_pin.native import load as load_native

    core = load_native()
    rk4 = core.RK4(None, n=1, aba=lambda q, v, tau: np.array(tau, dtype=float))
    beta, h, S = 2.0, 0.001, 10
    q, v = np.zeros(1), np.ones(1)
    rk4.period(q, v, np.zeros((3 * S, 1)), np.array([beta]), np.zeros(1), True, h)
    t = S * h
    assert v[0] == pytest.approx(np.exp(-beta * t), abs=1e-9)
    assert q[0] == pytest.approx((1 - np.exp(-beta * t)) / beta, abs=1e-9)
