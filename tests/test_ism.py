"""Integral sliding mode baseline (hmpc-ism, hmpc-ism-bl)."""

from __future__ import annotations

import numpy as np
import pytest

import hmpc_pin
from hmpc_pin.compensation.ism import IntegralSlidingMode
from hmpc_pin.experiment.build import make_controller
from hmpc_pin.experiment.config import ControllerConfig


def test_sigma_is_velocity_minus_nominal_integral(make_rng):
    rng = make_rng(3)
    Ts, n = 0.01, 3
    ism = IntegralSlidingMode(n, Ts, gain=200.0)
    dq0 = rng.normal(size=n)
    ism.reset(np.zeros(n), dq0)  # q0 is not used by the ISM
    vs = rng.normal(size=(20, n)) * 10
    M = np.diag([2.0, 1.0, 0.5])
    unused = np.zeros(n)  # nle, q and tau_prev: not used by the ISM
    for k in range(20):
        dq = rng.normal(size=n)
        est = ism.update(M, unused, unused, dq, unused, vs[k])
        sigma = dq - dq0 - Ts * vs[: k + 1].sum(axis=0)
        np.testing.assert_allclose(ism.sigma, sigma, atol=1e-12)
        np.testing.assert_allclose(est, M @ (200.0 * np.sign(sigma)))


def test_boundary_layer_is_linear_inside_and_sign_outside():
    ism = IntegralSlidingMode(2, 0.01, gain=100.0, boundary_layer=0.5)
    np.testing.assert_allclose(ism.switching(np.array([0.25, -2.0])), [0.5, -1.0])
    with pytest.raises(ValueError, match="boundary_layer"):
        IntegralSlidingMode(2, 0.01, gain=100.0, boundary_layer=0.0)


def _setpoint_run(robot, kind, d=None, duration=4.0):
    ctrl = make_controller(robot, ControllerConfig(kind=kind))
    target = np.array([0.5, -0.4, 0.3])
    ref = hmpc_pin.SineReference(3, amplitude=0.0, offset=target)
    dist = None if d is None else (lambda t, q, dq: d)
    r = hmpc_pin.simulate(robot, ctrl, ref, dist, duration=duration, q0=np.array([0.2, -0.1, 0.1]))
    return ctrl, r


def test_discrete_sign_law_keeps_sigma_in_its_band(planar3):
    """With K above |M⁻¹d| the discrete sign law holds |σ| within one period's switch,
    K·Ts, plus the disturbance's share Ts·|M⁻¹d| (the discrete sliding band)."""
    d = np.array([3.0, -2.0, 1.0])
    ctrl, _ = _setpoint_run(planar3, "hmpc-ism", d)
    assert isinstance(ctrl.compensation, IntegralSlidingMode)
    assert np.abs(ctrl.compensation.sigma).max() <= ctrl.Ts * 200.0 * 1.2
    # the compensation chatters: it switches sign from period to period
    assert np.abs(ctrl.disturbance_estimate).max() > 10 * np.abs(d).max()


@pytest.mark.parametrize("kind", ["hmpc-ism-bl", "hmpc", "hmpc-momentum"])
def test_compensation_converges_to_a_constant_disturbance(planar3, kind):
    """Inside its boundary layer the ISM is a linear loop σ⁺ = (1 − Ts K/φ)σ + Ts M⁻¹d, so
    at rest its torque −M u converges to d exactly, like the observers' d̂."""
    d = np.array([3.0, -2.0, 1.0])
    ctrl, r = _setpoint_run(planar3, kind, d)
    np.testing.assert_allclose(ctrl.disturbance_estimate, d, atol=1e-6)
    assert np.abs(r.error[-1]).max() < 1e-7


@pytest.mark.parametrize("kind", ["hmpc", "hmpc-none", "hmpc-momentum", "hmpc-ism-bl"])
def test_zero_steady_error_without_disturbance(planar3, kind):
    _, r = _setpoint_run(planar3, kind)
    assert np.abs(r.error[-100:]).max() < 1e-9


def test_sign_law_without_disturbance_chatters_from_discretisation(planar3):
    """The pure sign law has no zero-error equilibrium in discrete time: the ZOH torque
    on the nonlinear arm leaves σ ≠ 0 after one period, and from then on τ switches by
    2·M·K every period (the reason for the boundary layer)."""
    ctrl, r = _setpoint_run(planar3, "hmpc-ism")
    assert isinstance(ctrl.compensation, IntegralSlidingMode)
    assert np.all(np.abs(ctrl.compensation.sigma) > 0)
    slope = np.sign(np.diff(r.tau[-100:], axis=0))
    assert np.mean(slope[1:] != slope[:-1]) > 0.5  # τ reverses direction most periods


def test_sign_of_zero_is_zero():
    """On the sliding surface (σ = 0 exactly) the pure ISM applies no correction: with
    dq = dq0 and v = 0 on joint 1, σ₁ = 0 and the estimate is M·K·(0, 1, −1)."""
    Ts, n = 0.01, 3
    ism = IntegralSlidingMode(n, Ts, gain=200.0)
    dq0 = np.array([0.3, -0.2, 0.1])
    ism.reset(np.zeros(n), dq0)
    M = np.array([[2.0, 0.3, 0.1], [0.3, 1.0, 0.2], [0.1, 0.2, 0.5]])
    unused = np.zeros(n)
    dq = dq0 + np.array([0.0, 0.5, -0.5])
    est = ism.update(M, unused, unused, dq, unused, np.zeros(n))
    np.testing.assert_array_equal(ism.sigma, [0.0, 0.5, -0.5])
    np.testing.assert_allclose(est, M @ np.array([0.0, 200.0, -200.0]), rtol=1e-15)
    np.testing.assert_array_equal(ism.switching(np.zeros(n)), np.zeros(n))
