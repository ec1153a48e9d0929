"""A running observer's bandwidth (hmpc_pin.compensation.bandwidth.compensation_bandwidth)
against the decay of its estimation error, the closed form of a first-order observer:
per period the implicit observer's error is divided by 1 + Ts ω, so ω is read off two
successive errors as (e_{k-1}/e_k − 1)/Ts, joint by joint, also through the collision
reaction's gate."""

from __future__ import annotations

import itertools

import numpy as np
import pinocchio as pin
import pytest

from hmpc_pin.compensation.bandwidth import compensation_bandwidth, observer_cY
from hmpc_pin.compensation.gate import FeedbackGate
from hmpc_pin.compensation.observers import DisturbanceObserver, MomentumObserver

Ts = 0.01
Q0 = np.array([0.2, -0.4, 0.6])
D = np.array([1.0, -2.0, 0.5])  # the constant disturbance [N·m]


def _decay_rates(robot, obs) -> np.ndarray:
    """ω per joint from the observer's error at rest under :data:`D` (3 periods)."""
    nle = pin.nonLinearEffects(robot.model, robot.data, Q0, np.zeros(3))
    M0 = robot.mass_matrix(Q0)
    obs.reset(Q0, np.zeros(3))
    errors = [D.copy()]
    for _ in range(3):  # at rest: τ balances gravity and d (M·0 = τ + d − nle)
        errors.append(D - obs.update(M0, nle, Q0, np.zeros(3), nle - D))
    rates = [(a / b - 1.0) / Ts for a, b in itertools.pairwise(errors)]
    np.testing.assert_allclose(rates[1:], rates[:-1], rtol=1e-7)  # first order: one rate
    return rates[-1]


@pytest.mark.parametrize("gated", [False, True])
def test_the_ndos_bandwidth_is_its_error_decay_rate(planar3, gated):
    w = np.array([5.0, 20.0, 80.0])
    M0 = planar3.mass_matrix(Q0)
    obs = DisturbanceObserver(3, Ts, 1.0, "general", cY=observer_cY(w, M0))
    measured = _decay_rates(planar3, obs)
    comp = FeedbackGate(obs) if gated else obs
    np.testing.assert_allclose(compensation_bandwidth(comp, M0), measured, rtol=1e-7)


@pytest.mark.parametrize("gated", [False, True])
def test_the_momentum_observers_bandwidth_is_its_error_decay_rate(planar3, gated):
    obs = MomentumObserver(planar3, Ts, np.array([4.0, 12.5, 30.0]))
    measured = _decay_rates(planar3, obs)
    comp = FeedbackGate(obs) if gated else obs
    bw = compensation_bandwidth(comp, planar3.mass_matrix(Q0))
    np.testing.assert_allclose(bw, measured, rtol=1e-7)


def test_a_scalar_gain_is_one_bandwidth_per_joint(planar3):
    class Gain:  # a compensation exposing its gain as one number
        K = 12.5

    bw = compensation_bandwidth(Gain(), planar3.mass_matrix(Q0))
    assert bw is not None and bw.shape == (3,)
    np.testing.assert_array_equal(bw, np.full(3, 12.5))


def test_no_observer_has_no_bandwidth(planar3):
    class Compensation:
        estimate = np.zeros(3)

    assert compensation_bandwidth(Compensation(), planar3.mass_matrix(Q0)) is None
    assert compensation_bandwidth(FeedbackGate(Compensation()), planar3.mass_matrix(Q0)) is None
