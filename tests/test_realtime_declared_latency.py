"""A latency declared above the measured one warns in the real-time loop
(:meth:`hmpc_pin.realtime.loop.RealtimeLoop`): the controller then predicts further ahead
than its measurements are old. The loop and the arm of ``tests/test_realtime.py`` (a fake
clock, states reaching the loop 0.8 ms after their stamp)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from hmpc_pin.compensation.bandwidth import MASS_RATIO, implied_bandwidth
from hmpc_pin.exceptions import ValidityWarning

from .test_realtime import _delayed, _sine, robot  # noqa: F401  (the fixture)

DELAY = 0.0008  # [s] the measured latency


def _tolerance(arm, Ts: float) -> float:
    """How much longer the declared latency may be, from case 4 of the bandwidth rule
    solved for ΔL, ω (r Ts + 2ΔL − 2Ts) = 1 (at most a period, at least half an
    interface period), with ω from Chen's gain and Pinocchio's M(q0), computed here."""
    comp = _delayed(arm, DELAY, DELAY).controller.compensation
    M0 = arm.mass_matrix(_sine().sample(0.0)[0])  # the arm moves ±1 rad: margins of 50 %
    w = float(np.max(implied_bandwidth(comp.cY, M0)))
    return max(0.0005, min(Ts, 0.5 * (1.0 / w - (MASS_RATIO - 2.0) * Ts)))


@pytest.mark.parametrize("excess_share, warns", [(0.5, False), (1.5, True)])
def test_a_latency_declared_above_the_measured_one_warns(robot, excess_share, warns):  # noqa: F811
    Ts = 0.01
    tol = _tolerance(robot, Ts)
    declared = DELAY + excess_share * tol
    loop = _delayed(robot, DELAY, declared)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ValidityWarning)
        run = loop.run()
    lines = [str(w.message) for w in caught if issubclass(w.category, ValidityWarning)]
    younger = [x for x in lines if "younger than declared" in x]
    assert run.stats["declared_latency"] == pytest.approx(declared)
    assert run.stats["measured_latency"]["median_us"] == pytest.approx(1e6 * DELAY)
    assert bool(younger) == warns, lines
    if warns:
        assert f"latency = {declared:g} s" in younger[0]
