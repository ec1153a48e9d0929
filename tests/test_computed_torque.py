"""Computed-torque baseline: MPC-equivalent gains, closed-loop poles, steady-state errors."""

from __future__ import annotations

import numpy as np
import pytest

import hmpc_pin
from hmpc_pin.controllers.computed_torque import (
    ComputedTorque,
    closed_loop_poles,
    fastest_integral_gain,
    mpc_feedback_gain,
)
from hmpc_pin.exceptions import ConfigError
from hmpc_pin.experiment.config import ComputedTorqueConfig, ControllerConfig
from hmpc_pin.mpc.condensed import CondensedMPC

from .conftest import PLANAR3


def _ct(robot, kind="computed-torque", **gains):
    """The controller of ``[controller] kind`` with the ``computed_torque`` table ``gains``."""
    ctrl = hmpc_pin.make_controller(robot, ControllerConfig(kind=kind, computed_torque=gains or {}))
    assert isinstance(ctrl, ComputedTorque)
    return ctrl


def _unconstrained_v0(mpc: CondensedMPC, x0) -> float:
    """First input of the unconstrained minimiser, from three cost evaluations.

    With Nc = 1 the cost is an exact parabola in U, so its vertex is the minimiser;
    this uses only :meth:`CondensedMPC.cost`, not H or F.
    """
    ref = np.zeros(2 * mpc.N)
    c = [mpc.cost(np.array([u]), np.asarray(x0, float), ref) for u in (-1.0, 0.0, 1.0)]
    return 0.5 * (c[0] - c[2]) / (c[0] - 2 * c[1] + c[2])


def test_pd_gains_are_the_mpcs_state_feedback():
    mpc = CondensedMPC(0.01, 10, 1, np.diag([50.0, 0.0]), 1e-6, np.diag([100.0, 0.0]))
    kp, kd = mpc_feedback_gain(mpc)
    assert kp == pytest.approx(-_unconstrained_v0(mpc, [1.0, 0.0]), rel=1e-9)
    assert kd == pytest.approx(-_unconstrained_v0(mpc, [0.0, 1.0]), rel=1e-9)


def test_error_decays_as_the_predicted_discrete_poles():
    """Inverse dynamics makes each joint a double integrator: after a small step (no
    clipping) the error of the nonlinear Pinocchio plant follows x⁺ = (A − BK)x. Without
    gravity the only difference is second order (M(q) and C q̇ changing within a held
    period), so the relative mismatch must shrink tenfold with a tenfold smaller step."""
    robot = hmpc_pin.load_robot(PLANAR3, gravity=0.0)
    target = np.array([0.3, -0.2, 0.4])
    ref = hmpc_pin.SineReference(3, amplitude=0.0, offset=target)

    def relative_mismatch(scale):
        ctrl = _ct(robot)
        e0 = scale * np.array([1.0, -0.8, 0.5])
        r = hmpc_pin.simulate(robot, ctrl, ref, duration=0.5, q0=target - e0)
        Ts = ctrl.Ts
        A = np.array([[1.0, Ts], [0.0, 1.0]])
        B = np.array([Ts * Ts / 2, Ts])
        Acl = A - np.outer(B, [ctrl.kp, ctrl.kd])
        x = np.vstack([r.q[0] - target, r.dq[0]])
        worst = 0.0
        for k in range(1, len(r.t)):
            x = Acl @ x
            worst = max(worst, np.abs(r.q[k] - target - x[0]).max())
        return worst / scale

    big, small = relative_mismatch(1e-3), relative_mismatch(1e-4)
    assert small < 1e-5
    assert 8 < big / small < 12


@pytest.mark.parametrize("kind", ["computed-torque", "computed-torque-pid"])
def test_zero_steady_error_without_disturbance(planar3, kind):
    ref = hmpc_pin.SineReference(3, amplitude=0.0, offset=np.array([0.5, -0.4, 0.3]))
    r = hmpc_pin.simulate(
        planar3, _ct(planar3, kind), ref, duration=20.0, q0=np.array([0.2, -0.1, 0.1])
    )
    assert np.abs(r.error[-100:]).max() < 1e-9


def test_pd_offset_is_m_inverse_d_over_kp_and_pid_removes_it(planar3):
    """Under a constant torque d at a set point the PD settles at e = M⁻¹d / kp (closed
    form: v = kp·e must cancel the acceleration M⁻¹d); the integral removes it."""
    target = np.array([0.5, -0.4, 0.3])
    ref = hmpc_pin.SineReference(3, amplitude=0.0, offset=target)
    d = np.array([2.0, -1.0, 0.5])

    def run(kind):
        ctrl = _ct(planar3, kind)
        r = hmpc_pin.simulate(planar3, ctrl, ref, lambda t, q, dq: d, duration=20.0, q0=target)
        return ctrl, r

    pd, r_pd = run("computed-torque")
    expected = np.linalg.solve(planar3.mass_matrix(r_pd.q[-1]), d) / pd.kp
    np.testing.assert_allclose(r_pd.q_ref[-1] - r_pd.q[-1], -expected, rtol=1e-6)
    _, r_pid = run("computed-torque-pid")
    assert np.abs(r_pid.error[-1]).max() < 1e-8


def test_fastest_integral_gain_is_a_local_minimum_of_the_spectral_radius():
    Ts, kp, kd = 0.01, 273.9, 22.73
    ki = fastest_integral_gain(Ts, kp, kd)

    def radius(k):
        return np.abs(closed_loop_poles(Ts, kp, kd, k)).max()

    assert radius(ki) < 1
    assert radius(ki) <= min(radius(0.9 * ki), radius(1.1 * ki)) + 1e-12
    # at the optimum the three poles share one modulus
    assert np.ptp(np.abs(closed_loop_poles(Ts, kp, kd, ki))) < 1e-6


def test_unstable_gains_are_refused(planar3):
    with pytest.raises(ConfigError, match="unit circle"):
        _ct(planar3, kp=1e6, kd=10.0)


def test_gain_overrides_apply(planar3):
    ctrl = _ct(planar3, "computed-torque-pid", kp=100.0, kd=20.0, ki=50.0)
    assert (ctrl.kp, ctrl.kd, ctrl.ki) == (100.0, 20.0, 50.0)
    assert _ct(planar3).ki == 0.0
    with pytest.raises(ConfigError, match="kp"):
        ComputedTorqueConfig(kp=-1.0)


def test_acceleration_is_clipped_to_the_mpc_bounds(planar3):
    ctrl = _ct(planar3)
    ref = hmpc_pin.SineReference(3, amplitude=0.0, offset=np.full(3, 1.0))
    ctrl.reset(np.zeros(3), np.zeros(3))
    ctrl.step(0.0, np.zeros(3), np.zeros(3), ref)  # 274 rad/s² requested, 100 allowed
    np.testing.assert_array_equal(ctrl.v, np.full(3, 100.0))


def test_sine_reference_acceleration_is_the_derivative_of_its_velocity():
    """r̈ against a central finite difference of ṙ (independent of the closed form)."""
    ref = hmpc_pin.SineReference(3, amplitude=[1.0, 0.4, 2.0], frequency=[0.1, 0.7, 1.3],
                                 offset=[0.0, 0.3, -0.2], phase=[0.0, 0.5, -1.0])  # fmt: skip
    h = 1e-5
    for t in (0.0, 0.37, 1.9, 4.2):
        fd = (ref.sample(t + h)[1] - ref.sample(t - h)[1]) / (2 * h)
        np.testing.assert_allclose(ref.acceleration(t), fd, rtol=1e-6, atol=1e-8)


def test_pid_integral_does_not_wind_up_while_saturated(planar3):
    """Conditional integration, by hand: the arm held 2 rad from a constant reference
    saturates v at v_max for 50 periods (the integral must not grow), then sits 1e-3 rad
    away for 10 periods (unsaturated: I = 10·Ts·1e-3), and v = kp·e − kd·q̇ + ki·I exactly."""
    ctrl = _ct(planar3, "computed-torque-pid")
    assert ctrl.ki > 0
    r0 = np.array([0.5, -0.3, 0.2])
    ref = hmpc_pin.SineReference(3, amplitude=0.0, offset=r0)
    ctrl.reset(np.zeros(3), np.zeros(3))
    far = r0 - 2.0
    for k in range(50):
        ctrl.step(k * ctrl.Ts, far, np.zeros(3), ref)
    np.testing.assert_array_equal(ctrl.v, np.full(3, 100.0))  # saturated at v_max
    np.testing.assert_array_equal(ctrl.integral, np.zeros(3))
    near = r0 - 1e-3
    for k in range(50, 60):
        ctrl.step(k * ctrl.Ts, near, np.zeros(3), ref)
    integral = 9 * ctrl.Ts * 1e-3  # the integral used in step 60 holds 9 unsaturated periods
    np.testing.assert_allclose(ctrl.v, ctrl.kp * 1e-3 + ctrl.ki * integral, rtol=1e-12)
    np.testing.assert_allclose(ctrl.integral, 10 * ctrl.Ts * 1e-3, rtol=1e-12)
