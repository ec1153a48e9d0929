"""Observer gains in bandwidth units and the rule relating bandwidth, Ts and latency
(hmpc_pin.compensation.bandwidth)."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from hmpc_pin.compensation.bandwidth import (
    bandwidth_limit,
    check_bandwidth,
    implied_bandwidth,
    observer_cY,
    overdeclared_excess,
    overdeclared_limit,
)
from hmpc_pin.compensation.observers import DisturbanceObserver
from hmpc_pin.exceptions import ConfigError, ValidityWarning
from hmpc_pin.experiment.config.controller import ControllerConfig
from hmpc_pin.experiment.controllers import bandwidth_posture, make_compensation

NAMES = ("joint1", "joint2", "joint3")


def test_bandwidth_is_the_error_decay_rate(planar3):
    """With cY = diag(ω) M(q0), at q0 at rest the implicit observer's error obeys
    e_k = (I + Ts diag(ω))^{-1} e_{k-1} (backward Euler on ė = −ω e), joint by joint."""
    Ts, w = 0.01, np.array([5.0, 20.0, 80.0])
    q0 = np.array([0.2, -0.4, 0.6])
    M0 = planar3.mass_matrix(q0)
    obs = DisturbanceObserver(3, Ts, 1.0, "general", cY=observer_cY(w, M0))
    np.testing.assert_allclose(implied_bandwidth(obs.cY, M0), w, rtol=1e-12)
    obs.reset(q0, np.zeros(3))
    d = np.array([1.0, -2.0, 0.5])
    import pinocchio as pin

    nle = pin.nonLinearEffects(planar3.model, planar3.data, q0, np.zeros(3))
    e_prev = d.copy()
    for _ in range(5):  # at rest: τ balances gravity and d (M·0 = τ + d − nle)
        d_hat = obs.update(M0, nle, q0, np.zeros(3), nle - d)
        e = d - d_hat
        np.testing.assert_allclose(e, e_prev / (1 + Ts * w), rtol=1e-9, atol=1e-13)
        e_prev = e


@pytest.mark.parametrize("D", [1, 2, 3])
def test_rule_keeps_a_joint_with_unknown_latency_stable(D):
    """At the rule's bound (ω r (Ts + D Ts) = 1/2, r = 1.25) the simulated joint of
    benchmarks/studies/observer_rule.py converges, at 8× the bound it does not (D = 1: 16×)."""
    from benchmarks.studies.observer_rule import final_error

    Ts, r = 0.01, 1.25
    limit = bandwidth_limit(Ts, D * Ts, r)
    assert final_error(limit, Ts, r, D) < 1e-6
    assert final_error((16 if D == 1 else 8) * limit, Ts, r, D) > 1e-2


def test_warning_fires_and_names_the_joint():
    Ts = 0.01
    limit = bandwidth_limit(Ts, Ts)
    assert limit == pytest.approx(0.5 / (1.25 * 2 * Ts))
    with pytest.warns(ValidityWarning, match="'joint3'") as rec:
        check_bandwidth(np.array([1.0, 1.0, 2 * limit]), Ts, 0.0, NAMES)
    assert "'joint1'" not in str(rec[0].message)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_bandwidth(np.full(3, 0.99 * limit), Ts, 0.0, NAMES)  # below: silent
        check_bandwidth(np.full(3, 100 * limit), Ts, 0.001, NAMES)  # latency declared


def test_explicit_observer_pole_outside_the_unit_circle_is_an_error():
    with pytest.raises(ConfigError, match=r"joint2.*explicit"):
        check_bandwidth(np.array([1.0, 250.0, 1.0]), 0.01, 0.001, NAMES, explicit=True)
    check_bandwidth(np.array([1.0, 150.0, 1.0]), 0.01, 0.001, NAMES, explicit=True)


def test_config_bandwidth_keys(planar3):
    cc = ControllerConfig(compensation="general", observer={"bandwidth": [10.0, 20.0, 30.0]})
    assert cc.observer.gain is None
    obs = make_compensation(planar3, cc)
    M0 = planar3.mass_matrix(bandwidth_posture(planar3))
    np.testing.assert_allclose(implied_bandwidth(obs.cY, M0), [10, 20, 30], rtol=1e-12)
    mom = make_compensation(planar3, ControllerConfig(compensation="momentum",
                                                      observer={"bandwidth": 40.0}))  # fmt: skip
    np.testing.assert_array_equal(mom.K, [40.0, 40.0, 40.0])
    with pytest.raises(ConfigError, match="not both"):
        ControllerConfig(compensation="general", observer={"bandwidth": 10.0, "gain": 5.0})
    with pytest.raises(ConfigError, match="chen"):
        ControllerConfig(compensation="chen", observer={"bandwidth": 10.0})
    with pytest.raises(ConfigError, match="3 joints"):
        two = ControllerConfig(compensation="general", observer={"bandwidth": [1.0, 2.0]})
        make_compensation(planar3, two)
    # an earlier gain still loads, as the gain
    old = ControllerConfig(compensation="general", observer={"gain": 100.0})
    assert old.observer.gain == 100.0 and old.observer.bandwidth is None


def test_experiment_makes_the_bandwidth_exact_at_the_start(write_config):
    """Built from a config, the general observer's bandwidth is exact at the run's q0."""
    import hmpc_pin

    cfg = hmpc_pin.load_config(write_config(
        "[robot]\nurdf = '@URDF@'\n[controller]\ncompensation = 'general'\nlatency = 0.001\n"
        "[controller.observer]\nbandwidth = [300.0, 400.0, 500.0]\n"
        "[simulation]\nq0 = [0.4, -0.3, 0.9]\n"
    ))  # fmt: skip
    exp = hmpc_pin.Experiment.from_config(cfg)
    M0 = exp.robot.mass_matrix(np.array([0.4, -0.3, 0.9]))
    cY = exp.controller.compensation.cY
    np.testing.assert_allclose(implied_bandwidth(cY, M0), [300, 400, 500], rtol=1e-12)


@pytest.mark.parametrize("beta", [0.5, 1.0])
def test_rule_keeps_a_joint_with_an_overdeclared_latency_stable(beta):
    """A latency declared β Ts too long at Ts = 1 ms (the simulated joint of
    benchmarks/studies/observer_rule.py --over, r = 1.25): at the rule's bound
    ω (r Ts + 2ΔL − 2Ts) = 1 it converges; at 1.25× the stability bound (2.5× the rule)
    its estimate alternates in sign and grows."""
    from benchmarks.studies.observer_rule import final_error_over

    Ts, r = 0.001, 1.25
    limit = overdeclared_limit(Ts, beta * Ts, r)
    assert Ts * limit == pytest.approx(1.0 / (r + 2 * beta - 2))
    assert final_error_over(limit, Ts, r, beta) < 1e-6
    assert final_error_over(2.5 * limit, Ts, r, beta) > 1e-2
    # the bound's closed form: the estimate's recursion with v = 0 (numpy), its poles
    # z^2 − (1 − g(r + β)) z − gβ inside the unit circle below ω (r Ts + 2ΔL − 2Ts) = 2
    for factor, stable in ((0.95, True), (1.05, False)):
        w = factor * 2 * limit
        g = Ts * w / (1 + Ts * w)
        d = [1.0, 1.0]
        for _ in range(4000):
            d.append((1 - g * (r + beta)) * d[-1] + g * beta * d[-2])
        assert (abs(d[-1]) < 1e-3) == stable


def test_overdeclared_limit_is_unbounded_for_a_small_excess():
    """No bound while r Ts + 2ΔL <= 2 Ts: the 0.5 ms check at Ts = 10 ms, 2 ms."""
    assert overdeclared_limit(0.01, 0.0005) == math.inf
    assert overdeclared_limit(0.002, 0.0005) == math.inf
    assert overdeclared_excess(0.01, 0.001) == pytest.approx(0.0005)
    assert overdeclared_excess(0.001, 0.01) == pytest.approx(0.0005)
    assert overdeclared_excess(0.001, 0.0) == 0.0


def test_warning_for_an_overdeclared_latency_names_the_joint():
    """With a latency declared, the check warns above the rule for half a cycle too many:
    Ts = 1 ms, latency 1 ms → ΔL = 0.5 ms, limit 1/(0.25 Ts) = 4000 1/s."""
    Ts = 0.001
    limit = overdeclared_limit(Ts, 0.0005)
    assert limit == pytest.approx(4000.0)
    with pytest.warns(ValidityWarning, match=r"'joint2'.*declared") as rec:
        check_bandwidth(np.array([1000.0, 10000.0, 1000.0]), Ts, 0.001, NAMES)
    assert "'joint1'" not in str(rec[0].message)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_bandwidth(np.full(3, 0.99 * limit), Ts, 0.001, NAMES)
        check_bandwidth(np.full(3, 1000.0), 0.01, 0.001, NAMES)  # 10/Ts at 10 ms: no bound
