"""A latency of several control periods with finite-difference velocities
(:class:`~hmpc_pin.sim.sensing.SensedController`): the controller gets exactly the past
state, checked against the closed form of a cubic motion (which the cubic Hermite
interpolant of the plant's states reproduces exactly)."""

from __future__ import annotations

import numpy as np
import pytest

from hmpc_pin.sim.sensing import FiniteDifference, Latency, SensedController, Sensing

#: q(t) = c0 + c1 t + c2 t² + c3 t³ per joint [rad]: two joints.
COEFFS = np.array([[0.1, -0.2], [0.5, 0.3], [-1.2, 0.8], [2.0, -1.5]])


def _q(t: float) -> np.ndarray:
    return COEFFS[0] + COEFFS[1] * t + COEFFS[2] * t**2 + COEFFS[3] * t**3


def _dq(t: float) -> np.ndarray:
    return COEFFS[1] + 2 * COEFFS[2] * t + 3 * COEFFS[3] * t**2


class _Probe:
    """A controller that records what it is handed."""

    def __init__(self, n: int, Ts: float):
        self.Ts, self.n = Ts, n
        self.seen: list[tuple[np.ndarray, np.ndarray]] = []
        self.disturbance_estimate = np.zeros(n)

    def reset(self, q0, dq0):
        self.seen = [(np.array(q0), np.array(dq0))]

    def step(self, t, q, dq, reference):
        self.seen.append((np.array(q), np.array(dq)))
        return np.zeros(self.n)


@pytest.mark.parametrize("periods", [1.0, 3.4, 7.0])
def test_a_multi_period_latency_with_finite_differences_gives_exactly_the_past_state(periods):
    """At t_k the controller gets q(t_k − L) and (q(t_k − L) − q(t_k − L − P))/P, P the
    1 ms interface period, for L = 1, 3.4 and 7 control periods of 10 ms."""
    Ts, rate = 0.01, 1000.0
    P, L = 1.0 / rate, periods * Ts
    probe = _Probe(2, Ts)
    sensing = Sensing(rate=rate, velocity=FiniteDifference(P), latency=Latency(L))
    sensed = SensedController(probe, sensing)
    sensed.reset(_q(0.0), _dq(0.0))
    K = 40
    for k in range(K):
        sensed.step(k * Ts, _q(k * Ts), _dq(k * Ts), None)
    checked = 0
    for k in range(1, K):
        t = k * Ts - L
        if t - P < 0:  # before the start the arm is extrapolated, not the cubic
            continue
        q_seen, dq_seen = probe.seen[k + 1]
        np.testing.assert_allclose(q_seen, _q(t), rtol=0, atol=1e-12)
        np.testing.assert_allclose(dq_seen, (_q(t) - _q(t - P)) / P, rtol=0, atol=1e-9)
        checked += 1
    assert checked >= K - periods - 2
