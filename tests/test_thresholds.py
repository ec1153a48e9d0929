"""Collision thresholds learned from a contact-free run (``identify --thresholds``)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from hmpc_pin.apps.cli import main
from hmpc_pin.exceptions import ConfigError
from hmpc_pin.experiment.build import Experiment
from hmpc_pin.experiment.config import load_config
from hmpc_pin.identification import learn_thresholds
from hmpc_pin.sim.result import Result

from .conftest import CONFIGS

TS = 0.01


def _ar1(rng, steps: int, n: int, rho: float = 0.8, sigma: float = 1.0) -> np.ndarray:
    """A stationary AR(1) residual per joint (the observer's estimate is low-pass)."""
    e = rng.standard_normal((steps, n)) * sigma * np.sqrt(1 - rho**2)
    x = np.empty((steps, n))
    x[0] = rng.standard_normal(n) * sigma
    for k in range(1, steps):
        x[k] = rho * x[k - 1] + e[k]
    return x


def _result(d_hat: np.ndarray) -> Result:
    steps, n = d_hat.shape
    zeros = np.zeros((steps, n))
    t = TS * np.arange(steps)
    return Result(t, zeros, zeros, zeros, zeros, d_hat, zeros, zeros,
                  joint_names=tuple(f"j{i + 1}" for i in range(n)))  # fmt: skip


def test_false_alarm_rate_of_the_learned_thresholds(make_rng):
    """Learned on 2000 s of a synthetic residual with s = 1 and measured on 400 fresh
    10 s stretches: with the shape fitted (GEV), the false-alarm probability over
    H = 10 s is the stated alpha = 0.2 (binomial sd 0.02: between 0.12 and 0.28; without
    the horizon scaling it would be ~1, without the split over the 3 joints ~0.5); the
    Gumbel fit is conservative (at most alpha, module docstring)."""
    rng = make_rng(3)
    n = 3
    train = _result(_ar1(rng, 200_000, n))
    test = np.abs(_ar1(rng, 400 * 1000, n)).reshape(400, 1000, n)

    def rate(thr, factor=1.0):
        return np.any(test > factor * thr.threshold, axis=(1, 2)).mean()

    ev = {"false_alarm": 0.2, "horizon": 10.0, "safety": 1.0, "floor_at_peak": False}
    gev = learn_thresholds(train, method="gev", **ev)
    assert 0.12 <= rate(gev) <= 0.28, rate(gev)
    alone = learn_thresholds(_result(train.d_hat[:, :1]), method="gev", **ev)
    assert alone.threshold[0] < gev.threshold[0]  # one joint: no split, a lower threshold
    gumbel = learn_thresholds(train, **ev)
    assert 0.01 <= rate(gumbel) <= 0.2
    assert rate(gumbel, 1.25) < rate(gumbel)  # a safety factor lowers it
    # by default never below the learning run's own peak (here 2000 s: above the 10 s
    # quantile)
    floored = learn_thresholds(train, false_alarm=0.2, horizon=10.0, safety=1.0)
    np.testing.assert_array_equal(floored.threshold, np.abs(train.d_hat).max(axis=0))


def test_a_move_then_rest_is_not_flagged_on_itself(make_rng):
    """A non-stationary residual (a burst, then noise): the fit of the block maxima is
    below the burst, the threshold is not."""
    d_hat = 0.01 * _ar1(make_rng(2), 6000, 2)
    d_hat[100:250] += 1.0
    thr = learn_thresholds(_result(d_hat))
    assert np.all(thr.threshold >= 1.25 * np.abs(d_hat).max(axis=0))


def test_threshold_table_loads_as_collision(make_rng, write_config):
    thr = learn_thresholds(_result(_ar1(make_rng(0), 6000, 3)))
    text = "[robot]\nurdf = '@URDF@'\n" + thr.toml()
    config = load_config(write_config(text))
    np.testing.assert_allclose(config.collision.threshold, thr.threshold, rtol=1e-5)


def test_bad_options_and_short_runs_are_refused(make_rng):
    run = _result(_ar1(make_rng(0), 6000, 2))
    with pytest.raises(ConfigError, match="--safety"):
        learn_thresholds(run, safety=0.5)
    for alarm in (0.0, 1.0, 1.5, -0.1, float("nan")):  # a probability strictly in (0, 1)
        with pytest.raises(ConfigError, match=r"--false-alarm.*a probability in \(0, 1\)"):
            learn_thresholds(run, false_alarm=alarm)
    for safety in (0.999, float("nan"), float("inf")):
        with pytest.raises(ConfigError, match=r"--safety.*a factor >= 1"):
            learn_thresholds(run, safety=safety)
    for key in ("horizon", "block"):
        for bad in (0.0, -1.0, float("nan"), float("inf")):
            with pytest.raises(ConfigError, match=f"--{key}.*a duration"):
                learn_thresholds(run, **{key: bad})
    with pytest.raises(ConfigError, match="--block"):  # no duration, not 'too short'
        learn_thresholds(run, block=0.0)
    with pytest.raises(ConfigError, match="too short"):
        learn_thresholds(_result(_ar1(make_rng(0), 50, 2)))
    with pytest.raises(ConfigError, match="observer"):
        learn_thresholds(_result(np.zeros((6000, 2))))


def test_no_false_alarm_on_another_contact_free_run(tmp_path, capsys):
    """paper_friction (no contact) learned on one 10 s run; the thresholds written into
    the config watch a second run with another sine phase: no collision is flagged."""
    config = load_config(CONFIGS / "paper_friction.toml")
    run = Experiment.from_config(config).run().save(tmp_path / "learn.npz")
    out = tmp_path / "watch.toml"
    assert main(["identify", str(run), "--thresholds", "--config",
                 str(CONFIGS / "paper_friction.toml"), "--out", str(out)]) == 0  # fmt: skip
    watched = load_config(out)
    assert watched.collision is not None
    q0 = np.sin(0.3) * np.ones(3)
    other = replace(watched, reference=replace(watched.reference, phase=0.3),
                    simulation=replace(watched.simulation, q0=q0))  # fmt: skip
    result = Experiment.from_config(other).run()
    assert result.meta["collision"]["detected_at"] is None


def test_the_sign_of_the_estimate_does_not_matter(make_rng):
    """Thresholds are on |d_hat|: a run whose estimate is the mirror image (-d_hat) learns
    the same thresholds, and one offset to large negative values learns them from their
    magnitude (above its peak |d_hat|), not from the small positive side."""
    rng = make_rng(5)
    d = _ar1(rng, 20_000, 2)
    opts = {"false_alarm": 0.1, "horizon": 10.0, "safety": 1.0, "method": "gev",
            "floor_at_peak": False}  # fmt: skip
    plus, minus = learn_thresholds(_result(d), **opts), learn_thresholds(_result(-d), **opts)
    np.testing.assert_allclose(minus.threshold, plus.threshold, rtol=1e-9)
    low = learn_thresholds(_result(d - 5.0), false_alarm=0.1, horizon=10.0, safety=1.0)
    assert np.all(low.threshold >= np.abs(d - 5.0).max(axis=0))
    assert np.all(low.peak == np.abs(d - 5.0).max(axis=0))


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_a_collision_is_flagged_on_a_negative_estimate_too(sign, planar3):
    """A constant external torque of ±40 N·m on joint 2 from t = 0.5 s: the observer's
    estimate goes to ±40 (its sign), and the collision is flagged on joint 2 within the
    observer's settling (gain 100: time constant M_22/c, well under 0.1 s) for either sign."""
    import hmpc_pin
    from hmpc_pin.controllers.wrappers import CollisionReaction
    from hmpc_pin.sim.disturbances import Disturbance

    class Push(Disturbance):
        def __call__(self, t, q, dq):
            return np.array([0.0, sign * 40.0 if t >= 0.5 else 0.0, 0.0])

    ctrl = CollisionReaction(hmpc_pin.HierarchicalMPC(planar3), threshold=[20.0, 20.0, 20.0],
                             reaction="stop")  # fmt: skip
    ref = hmpc_pin.SineReference(planar3.nq)
    result = hmpc_pin.simulate(planar3, ctrl, ref, Push(), duration=1.0, q0=np.zeros(3))
    assert ctrl.joint == 1
    assert 0.5 <= ctrl.detected_at <= 0.6, ctrl.detected_at
    k = np.searchsorted(result.t, ctrl.detected_at)
    assert np.sign(result.d_hat[k, 1]) == sign and abs(result.d_hat[k, 1]) > 20.0


def test_a_constant_residual_gives_its_value_times_the_safety():
    """|d̂| constant: every block maximum is that value and the extreme-value fit has no
    spread; the threshold is the value times the safety factor (no fit, no NaN)."""
    fit = learn_thresholds(_result(np.full((2001, 2), [0.3, -0.7])), safety=1.25)
    np.testing.assert_allclose(fit.threshold, [0.375, 0.875], rtol=1e-12)


def test_the_sample_at_after_is_kept():
    """--after t0 keeps the sample at t0 itself (t >= t0): a spike there is the peak."""
    d_hat = 0.01 * np.ones((2001, 1))
    t = _result(d_hat).t
    k = 500
    d_hat[k] = 5.0
    fit = learn_thresholds(_result(d_hat), after=float(t[k]), safety=1.0)
    assert fit.peak[0] == pytest.approx(5.0)


def test_the_table_holds_the_thresholds_to_six_digits(make_rng):
    """The [collision] table read back (tomllib) is the thresholds learned, to the 6
    significant digits written."""
    import tomllib

    fit = learn_thresholds(_result(np.abs(_ar1(make_rng(11), 3000, 2)) * 1.2345678))
    table = tomllib.loads(fit.toml())["collision"]["threshold"]
    np.testing.assert_allclose(table, fit.threshold, rtol=5e-6)


@pytest.mark.parametrize("horizon", [np.inf, np.nan, 0.0, -1.0])
def test_a_horizon_that_is_not_a_finite_duration_is_refused(horizon, make_rng):
    """An infinite horizon would make every per-block quantile 1 (an infinite threshold)."""
    with pytest.raises(ConfigError, match="--horizon"):
        learn_thresholds(_result(np.abs(_ar1(make_rng(12), 3000, 2))), horizon=horizon)


def test_a_block_is_a_whole_number_of_periods_nearest_the_one_asked(make_rng):
    """--block 0.296 s at Ts = 0.01 s is 29.6 periods: the block is the nearest whole
    number, 30 periods (0.3 s), not 29 (truncated)."""
    fit = learn_thresholds(_result(np.abs(_ar1(make_rng(13), 3000, 2))), block=0.296)
    assert fit.block == pytest.approx(0.3, rel=1e-9)


def test_the_peak_is_the_runs_after_the_start_up_left_out(make_rng):
    """With --after, the start-up is not part of what the watch must not flag: the peak
    reported (and the floor of the thresholds) is max |d_hat| over t >= after, not the
    start-up's spike."""
    d_hat = np.abs(_ar1(make_rng(14), 3000, 2))
    d_hat[10] = 100.0  # a start-up spike at t = 0.1 s
    fit = learn_thresholds(_result(d_hat), after=0.5)
    np.testing.assert_allclose(fit.peak, np.abs(d_hat[50:]).max(axis=0))
    assert np.all(fit.threshold < 100.0)


def test_the_fitted_location_and_scale_are_the_gumbel_fit_of_the_block_maxima(make_rng):
    """mu and beta reported per joint are scipy's Gumbel fit of the 1 s block maxima of
    |d_hat| (60 blocks of 100 samples, cut in numpy), and the threshold without the floor
    is s [mu - beta ln(-ln p)] at p = (1 - alpha/n)^(B/H) (module docstring)."""
    from scipy.stats import gumbel_r

    d = _ar1(make_rng(7), 6000, 2)
    fit = learn_thresholds(_result(d), floor_at_peak=False)  # alpha 0.01 per 60 s, s 1.25
    maxima = np.abs(d).reshape(60, 100, 2).max(axis=1)
    p = (1 - 0.01 / 2) ** (1.0 / 60.0)
    for i in range(2):
        loc, scale = gumbel_r.fit(maxima[:, i])
        assert fit.loc[i] == pytest.approx(loc, rel=1e-9)
        assert fit.scale[i] == pytest.approx(scale, rel=1e-9)
        assert fit.threshold[i] == pytest.approx(1.25 * (loc - scale * np.log(-np.log(p))),
                                                 rel=1e-9)  # fmt: skip
