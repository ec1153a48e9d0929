"""Friction identification and the friction feed-forward (``hmpc-pin identify``)."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from hmpc_pin.apps.cli import main
from hmpc_pin.controllers.wrappers import FrictionFeedforward
from hmpc_pin.exceptions import ConfigError, ExcitationError
from hmpc_pin.experiment.build import Experiment
from hmpc_pin.experiment.config import load_config
from hmpc_pin.identification import ObserverModel, fit_friction, fit_joint
from hmpc_pin.sim.result import Result

from .conftest import CONFIGS

VISCOUS, COULOMB = np.array([10.0, 8.0, 5.0]), np.array([3.0, 2.4, 1.8])  # paper_friction


def _run(config):
    return Experiment.from_config(config).run()


@pytest.fixture(scope="module")
def friction_run():
    """paper_friction (known friction, Eq 32 opposing) for 5 s: every joint moves both ways."""
    config = load_config(CONFIGS / "paper_friction.toml")
    config = replace(config, simulation=replace(config.simulation, duration=5.0))
    exp = Experiment.from_config(config)
    return exp, exp.run()


def test_exact_data_are_fitted_exactly(make_rng):
    dq = np.sin(np.linspace(0, 20, 2000)) + 0.01 * make_rng().standard_normal(2000)
    fit = fit_joint(3.0 * dq + 1.5 * np.sign(dq), dq)
    assert fit.viscous == pytest.approx(3.0, abs=1e-12)
    assert fit.coulomb == pytest.approx(1.5, abs=1e-12)
    assert fit.residual_rms < 1e-12


def test_confidence_intervals_cover_the_truth_at_their_level(make_rng):
    """White noise: the 95 % intervals hold the true value in ~95 % of 300 independent
    fits (binomial: 95 % ± 4 % covers 3.2 standard deviations)."""
    rng = make_rng(1)
    t = np.linspace(0, 10, 500)
    dq = np.sin(1.3 * t)
    hits = np.zeros(2)
    for _ in range(300):
        y = 2.0 * dq + 0.7 * np.sign(dq) + 0.3 * rng.standard_normal(len(t))
        fit = fit_joint(y, dq, confidence=0.95)
        hits += [fit.viscous_ci[0] <= 2.0 <= fit.viscous_ci[1],
                 fit.coulomb_ci[0] <= 0.7 <= fit.coulomb_ci[1]]  # fmt: skip
    assert np.all(np.abs(hits / 300 - 0.95) < 0.04), hits / 300


def test_dynamics_source_recovers_the_plants_friction(friction_run):
    """The model's inverse dynamics over each period against the applied torque: the
    plant (RK4, 1 ms) and the model are the same arm, so the fit is exact up to the
    integration and the mid-period state (well below 0.1 %)."""
    exp, result = friction_run
    fit = fit_friction(result, source="dynamics", robot=exp.robot)
    np.testing.assert_allclose(fit.viscous, VISCOUS, rtol=1e-3)
    np.testing.assert_allclose(fit.coulomb, COULOMB, rtol=1e-3)


def test_observer_source_with_its_dynamics_recovers_the_friction(friction_run):
    """The observer's estimate with the regressors passed through its own dynamics: no
    lag bias (the issue's bar is 10 %; the Coulomb jump inside a period leaves ~1 %)."""
    exp, result = friction_run
    cc = exp.config.controller
    om = ObserverModel(cc.compensation, cc.observer.gain, cc.Ts, exp.robot)
    fit = fit_friction(result, source="observer", observer=om)
    np.testing.assert_allclose(fit.viscous, VISCOUS, rtol=0.03)
    np.testing.assert_allclose(fit.coulomb, COULOMB, rtol=0.03)
    # without the observer's dynamics the lag biases the slow joint: the filter matters
    plain = fit_friction(result, source="observer")
    assert abs(plain.coulomb[0] - COULOMB[0]) > 3 * abs(fit.coulomb[0] - COULOMB[0])


def test_a_joint_that_does_not_move_is_refused_naming_it(tmp_path, capsys):
    config = load_config(CONFIGS / "paper_friction.toml")
    ref = replace(config.reference, amplitude=np.array([1.0, 1.0, 0.0]))
    config = replace(config, reference=ref,
                     simulation=replace(config.simulation, duration=3.0,
                                        q0=np.array([1.0, 1.0, 0.0])))  # fmt: skip
    result = _run(config)
    with pytest.raises(ExcitationError, match="joint3") as info:
        fit_friction(result)
    assert info.value.joint == "joint3"
    path = result.save(tmp_path / "still.npz")
    assert main(["identify", str(path), "--out", str(tmp_path / "f.toml")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "joint3" in err[0] and "moves both ways" in err[0]
    assert not (tmp_path / "f.toml").exists()


def test_one_way_motion_is_refused(make_rng):
    dq = 0.5 + 0.1 * np.sin(np.linspace(0, 30, 1000))
    with pytest.raises(ExcitationError, match=r"backward in 0\.0 %"):
        fit_joint(dq, dq, name="elbow")


def test_feedforward_adds_the_models_torque():
    class Zero:
        Ts = 0.01
        disturbance_estimate = np.zeros(2)
        compensation = None

        def reset(self, q0, dq0):
            pass

        def step(self, t, q, dq, reference):
            return np.zeros(2)

    ff = FrictionFeedforward(Zero(), [2.0, 1.0], [0.5, 0.3])
    tau = ff.step(0.0, np.zeros(2), np.array([0.2, -0.4]), None)
    np.testing.assert_allclose(tau, [2.0 * 0.2 + 0.5, -1.0 * 0.4 - 0.3])
    smooth = FrictionFeedforward(Zero(), [0.0, 0.0], [1.0, 1.0], smoothing=0.1)
    np.testing.assert_allclose(smooth.step(0.0, np.zeros(2), np.array([0.05, 0.0]), None),
                               [np.tanh(0.5), 0.0])  # fmt: skip


def test_identified_friction_fed_forward_lowers_the_observer_error(tmp_path, friction_run, capsys):
    """identify --config writes a config that loads; with the friction fed forward the
    observer only estimates what the model leaves, and tracking is no worse."""
    _, result = friction_run
    run = result.save(tmp_path / "run.npz")
    out = tmp_path / "ff.toml"
    assert main(["identify", str(run), "--config", str(CONFIGS / "paper_friction.toml"),
                 "--out", str(out)]) == 0  # fmt: skip
    config = load_config(out)
    assert config.controller.friction is not None
    config = replace(config, simulation=replace(config.simulation, duration=5.0))
    with_ff = _run(config)
    w0 = np.sqrt(np.mean(result.observer_error[result.t >= 1] ** 2, axis=0))
    w1 = np.sqrt(np.mean(with_ff.observer_error[with_ff.t >= 1] ** 2, axis=0))
    # the friction was most of it: the error falls on joints 1 and 2, by half over the arm.
    # Joint 3's is the Coulomb jump at reversals: the plant's friction passes through its
    # stuck interval as a holding torque within +/- b, while the fed-forward law
    # b sgn(q̇) jumps by 2b there, a step the observer lags; it stays below the level b
    assert np.all(w1[:2] < w0[:2]) and np.linalg.norm(w1) < 0.5 * np.linalg.norm(w0), (w0, w1)
    assert w1[2] < COULOMB[2], (w0, w1)
    e0 = np.sqrt(np.mean(result.error[result.t >= 1] ** 2, axis=0))
    e1 = np.sqrt(np.mean(with_ff.error[with_ff.t >= 1] ** 2, axis=0))
    assert np.all(e1 <= 1.05 * e0), (e0, e1)
    # identified again from the run with feed-forward: still the plant's total friction
    refit = fit_friction(with_ff, source="dynamics", robot=Experiment.from_config(config).robot)
    np.testing.assert_allclose(refit.viscous, VISCOUS, rtol=1e-3)


def test_friction_table_keys_are_checked(write_config):
    base = "[robot]\nurdf = '@URDF@'\n[controller.friction]\n"
    with pytest.raises(ConfigError, match=r"controller\.friction\.damping"):
        load_config(write_config(base + "damping = 1.0\n"))
    with pytest.raises(ConfigError, match="smoothing"):
        load_config(write_config(base + "smoothing = -1.0\n"))
    config = load_config(write_config(base + "viscous = [1.0, 2.0]\n"))
    with pytest.raises(ConfigError, match=r"controller\.friction\.viscous"):
        Experiment.from_config(config)


def test_identify_options_of_the_other_mode_are_errors(friction_run, tmp_path, capsys):
    path = friction_run[1].save(tmp_path / "run.npz")
    assert main(["identify", str(path), "--thresholds", "--source", "dynamics"]) == 2
    assert "--source" in capsys.readouterr().err
    assert main(["identify", str(path), "--safety", "2"]) == 2
    assert "--thresholds" in capsys.readouterr().err


def test_regressor_source_fits_the_rigid_body_too():
    """Plant links 2 and 3 30 % heavier than the model: the model's inverse dynamics
    blames the friction for the missing inertia and gravity, the regressor source fits
    the base inertial parameters alongside and recovers the plant's friction."""
    config = load_config(CONFIGS / "paper_friction.toml")
    config = replace(config, simulation=replace(config.simulation, duration=5.0))
    exp = Experiment.from_config(config)
    exp.plant = exp.plant.with_scaled_inertias([1.0, 1.3, 1.3])
    result = exp.run()
    biased = fit_friction(result, source="dynamics", robot=exp.robot)
    assert np.max(np.abs(biased.viscous / VISCOUS - 1)) > 0.2
    fit = fit_friction(result, source="regressor", robot=exp.robot)
    np.testing.assert_allclose(fit.viscous, VISCOUS, rtol=2e-3)
    np.testing.assert_allclose(fit.coulomb, COULOMB, rtol=2e-3)


@pytest.mark.parametrize("form", ["implicit matrix", "explicit matrix", "momentum"])
def test_observer_model_is_the_observer_that_runs(form, planar3):
    """The filter identify passes the regressors through is the observer's own response:
    the compiled NDO / the momentum observer, run on an arm held at rest against a
    constant disturbance (τ = G(q) - d, so q̈ = 0), give the estimate the model's
    filter gives for that disturbance, to rounding."""
    from hmpc_pin.compensation.observers import DisturbanceObserver, MomentumObserver

    n, Ts = planar3.nq, 0.01
    q, dq, d = np.array([0.3, -0.5, 0.8]), np.zeros(3), np.array([2.0, -1.0, 0.5])
    M, G = planar3.mass_matrix(q), planar3.gravity_torque(q)
    cY = np.diag([30.0, 40.0, 50.0]) @ M + 0.1 * np.ones((n, n))  # not symmetric, not Y
    if form == "momentum":
        obs = MomentumObserver(planar3, Ts, np.array([20.0, 35.0, 50.0]))
    else:
        obs = DisturbanceObserver(n, Ts, 1.0, "general", form.split()[0], cY=cY)
    obs.reset(q, dq)
    estimates = [np.zeros(n)]
    for _ in range(30):
        estimates.append(obs.update(M, G, q, dq, G - d))
    model = ObserverModel.of(obs, planar3)
    g = model.filter(np.tile(q, (31, 1)), np.tile(np.diag(d)[None], (31, 1, 1)))
    np.testing.assert_allclose(g.sum(axis=2), np.array(estimates), rtol=1e-9, atol=1e-12)
    back = ObserverModel.from_record(json.loads(json.dumps(model.record())), planar3, n)
    np.testing.assert_array_equal(
        back.filter(np.tile(q, (31, 1)), np.tile(np.diag(d)[None], (31, 1, 1))), g
    )


def test_observer_model_at_start_uses_the_previous_posture(planar3, make_rng):
    """model_at = "start": the period's M is the one at q_{k-1}; the response equals
    the "end" model's on the posture sequence delayed by one sample."""
    rng = make_rng(3)
    q = np.cumsum(0.05 * rng.standard_normal((40, 3)), axis=0)
    phi = rng.standard_normal((40, 3, 2))
    start = ObserverModel("general", 1.0, 0.01, planar3, True, 20.0 * np.eye(3), "start")
    end = replace(start, model_at="end")
    np.testing.assert_allclose(start.filter(q, phi), end.filter(np.vstack([q[:1], q[:-1]]), phi),
                               rtol=1e-12)  # fmt: skip
    assert np.max(np.abs(start.filter(q, phi) - end.filter(q, phi))) > 1e-6  # it matters


def _ar1(rng, m: int, rho: float, sigma: float) -> np.ndarray:
    """AR(1) noise of stationary standard deviation ``sigma``."""
    e = np.empty(m)
    e[0] = sigma * rng.standard_normal()
    innov = sigma * np.sqrt(1 - rho**2) * rng.standard_normal(m)
    for k in range(1, m):
        e[k] = rho * e[k - 1] + innov[k]
    return e


def test_intervals_widen_with_correlated_residuals_and_keep_their_level(make_rng):
    """AR(1) residuals (ρ = 0.7) on a slow velocity sweep: the OLS variance is larger by
    about (1+ρ)/(1-ρ) = 5.7 than white noise of the same variance, so the intervals
    must widen by about sqrt(5.7) = 2.4 and still hold the true value at their level.
    400 seeded fits: coverage 95 % ± 4 % (3.7 binomial standard deviations); the
    white-noise formula (no correction) would cover about 60 %."""
    rng = make_rng(7)
    t = np.linspace(0, 20, 1000)
    dq = np.sin(0.9 * t)
    hits, widths, white = np.zeros(2), [], []
    for _ in range(400):
        y = 2.0 * dq + 0.7 * np.sign(dq) + _ar1(rng, len(t), 0.7, 0.3)
        fit = fit_joint(y, dq, confidence=0.95)
        hits += [fit.viscous_ci[0] <= 2.0 <= fit.viscous_ci[1],
                 fit.coulomb_ci[0] <= 0.7 <= fit.coulomb_ci[1]]  # fmt: skip
        widths.append(fit.viscous_ci[1] - fit.viscous_ci[0])
        w = fit_joint(2.0 * dq + 0.7 * np.sign(dq) + 0.3 * rng.standard_normal(len(t)), dq)
        white.append(w.viscous_ci[1] - w.viscous_ci[0])
    assert np.all(np.abs(hits / 400 - 0.95) < 0.04), hits / 400
    ratio = np.median(widths) / np.median(white)
    assert 1.8 < ratio < 3.2, ratio  # sqrt((1+ρ)/(1-ρ)) = 2.38


def test_no_interval_below_the_effective_samples_needed(make_rng):
    """The interval is given exactly when m_e - 2 >= MIN_DEGREES_OF_FREEDOM: residuals
    from white to nearly a random walk (ρ up to 0.995) on 400 samples."""
    from hmpc_pin.identification.friction_fit import MIN_DEGREES_OF_FREEDOM

    rng = make_rng(11)
    dq = np.sin(np.linspace(0, 12, 400))
    seen = set()
    for rho in (0.0, 0.9, 0.95, 0.97, 0.98, 0.99, 0.995):
        fit = fit_joint(dq + np.sign(dq) + _ar1(rng, 400, rho, 0.2), dq)
        enough = fit.effective_samples - 2 >= MIN_DEGREES_OF_FREEDOM
        assert fit.has_interval == enough, (rho, fit.effective_samples)
        seen.add(enough)
    assert seen == {True, False}


def test_a_joint_moving_below_the_excitation_velocity_is_refused():
    """A joint shaken both ways but never faster than the excitation velocity (0.05 rad/s)
    is refused even though it moves faster than the velocity threshold (0.01 rad/s)."""
    dq = 0.04 * np.sin(np.linspace(0, 30, 2000))
    y = 3.0 * dq + 0.5 * np.sign(dq)
    with pytest.raises(ExcitationError, match=r"faster than 0\.05 rad/s"):
        fit_joint(y, dq, name="wrist")
    fit = fit_joint(y, dq, excitation_velocity=0.03)  # the same motion, a lower bar
    assert fit.viscous == pytest.approx(3.0, rel=1e-9)


GOOD_RECORD = {"kind": "general", "Ts": 0.01, "matrix": np.eye(3).tolist(),
               "discretization": "implicit", "model_at": "end"}  # fmt: skip


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"kind": "ism"}, "kind"),
        ({"Ts": -0.01}, "period"),
        ({"Ts": "fast"}, "period"),
        ({"Ts": None}, "period"),
        ({"Ts": [0.01]}, "period"),
        ({"model_at": "middle"}, "model_at"),
        ({"matrix": np.eye(2).tolist()}, "shape"),
        ({"matrix": [[1.0, np.nan, 0], [0, 1, 0], [0, 0, 1]]}, "finite"),
        ({"matrix": None, "gain": None}, "older version"),
        ({"matrix": None, "gain": [1.0, 2.0, 3.0]}, "per-joint gain"),
        ({"matrix": None, "gain": -5.0}, "gain"),
        ({"matrix": None, "gain": 0.0}, "gain"),  # an observer that estimates nothing
        ({"matrix": None, "kind": "momentum", "gain": [10.0, 0.0, 10.0]}, "gain"),
    ],
)
def test_an_unusable_observer_record_is_one_error_naming_it(change, match, planar3):
    record = {**GOOD_RECORD, **change}
    with pytest.raises(ConfigError, match=match) as info:
        ObserverModel.from_record(record, planar3, 3)
    assert info.value.key == "observer_model" and "--source dynamics" in str(info.value)
    assert ObserverModel.from_record(GOOD_RECORD, planar3, 3).matrix.shape == (3, 3)


def test_the_model_of_a_watched_observer_looks_through_the_gate(planar3):
    """With a [collision] watch the compensation is behind a FeedbackGate; the record is
    the observer's own."""
    from hmpc_pin.compensation.gate import FeedbackGate
    from hmpc_pin.compensation.observers import DisturbanceObserver

    obs = DisturbanceObserver(3, 0.01, 50.0, "chen")
    model = ObserverModel.of(FeedbackGate(obs), planar3)
    np.testing.assert_array_equal(model.matrix, obs.cY)
    assert ObserverModel.of(object(), planar3) is None


def test_anti_correlated_residuals_count_no_more_samples_than_they_have(make_rng):
    """m_e = m(1 − ρ)/(1 + ρ) corrects for positively correlated residuals; residuals
    that alternate in sign (ρ < 0) are not worth more than m independent samples: the
    effective samples never exceed the samples fitted."""
    rng = make_rng(3)
    dq = np.sin(np.linspace(0, 12, 400))
    alternating = 0.2 * (-1.0) ** np.arange(400) * (1 + 0.1 * rng.standard_normal(400))
    fit = fit_joint(dq + np.sign(dq) + alternating, dq)
    assert fit.effective_samples <= 400


def test_an_interval_with_uncorrelated_residuals_is_the_textbook_ols_one(make_rng):
    """Residuals with no positive autocorrelation (m_e = m): the interval is the ordinary
    least-squares one, θ ± t_(0.975, m−2) sqrt(s² (AᵀA)⁻¹_jj), s² = rᵀr/(m − 2), computed
    here with numpy (30 samples: m − 2 against m differs by 7 %)."""
    from scipy.stats import t as student_t

    rng = make_rng(5)
    dq = np.sin(np.linspace(0.3, 12, 30))
    noise = 0.2 * (-1.0) ** np.arange(30) * (1 + 0.3 * rng.standard_normal(30))
    y = 1.5 * dq + 0.4 * np.sign(dq) + noise
    fit = fit_joint(y, dq)
    A = np.column_stack([dq, np.sign(dq)])
    theta, *_ = np.linalg.lstsq(A, y, rcond=None)
    r = y - A @ theta
    assert np.dot(r[1:], r[:-1]) <= 0  # no positive autocorrelation: m_e = m
    half = student_t.ppf(0.975, 28) * np.sqrt(r @ r / 28 * np.diag(np.linalg.inv(A.T @ A)))
    np.testing.assert_allclose([fit.viscous, fit.coulomb], theta, rtol=1e-9)
    np.testing.assert_allclose(np.diff(fit.viscous_ci), 2 * half[0], rtol=1e-6)
    np.testing.assert_allclose(np.diff(fit.coulomb_ci), 2 * half[1], rtol=1e-6)


def test_samples_slower_than_the_velocity_threshold_are_left_out():
    """Samples with |q̇| <= v0 (stiction, sign changes) do not enter the fit: garbage
    there leaves the noise-free fit exact."""
    dq = np.sin(np.linspace(0, 30, 3000))
    y = 2.0 * dq + 0.5 * np.sign(dq)
    y[np.abs(dq) <= 0.01] = 100.0
    fit = fit_joint(y, dq, velocity_threshold=0.01)
    assert (fit.viscous, fit.coulomb) == (
        pytest.approx(2.0, rel=1e-9),
        pytest.approx(0.5, rel=1e-9),
    )


def test_a_joints_figures_are_numpys(make_rng):
    """Every figure of a joint's fit against numpy on the same samples: the residual RMS
    sqrt(mean r²) of the least-squares residual, m, m_e = m(1 − ρ)/(1 + ρ) with ρ the
    residual's lag-1 autocorrelation, the condition number of A with unit columns, and
    the coverage as shares of all the samples (half of these are too slow to count);
    the table shows m and m_e, the TOML the coefficients to 6 digits."""
    import tomllib

    from hmpc_pin.identification.friction_fit import FrictionFit

    rng = make_rng(7)
    m = 1200
    fast = 8.0 * np.sin(np.linspace(0, 40, m // 2))  # |q̇| up to 8 rad/s: unnormalised A
    slow = 0.02 * np.sin(np.linspace(0, 40, m // 2))  # within the excitation velocity
    dq = np.concatenate([fast, slow])
    y = 1.2345678 * dq + 0.7123456 * np.sign(dq) + _ar1(rng, m, 0.6, 0.3)
    fit = fit_joint(y, dq, name="elbow")
    keep = np.abs(dq) > 0.01
    A = np.column_stack([dq[keep], np.sign(dq[keep])])
    theta, *_ = np.linalg.lstsq(A, y[keep], rcond=None)
    r = y[keep] - A @ theta
    rho = float(np.dot(r[1:], r[:-1]) / np.dot(r, r))
    m_e = len(r) * (1 - rho) / (1 + rho)
    assert fit.residual_rms == pytest.approx(np.sqrt(np.mean(r**2)), rel=1e-9)
    assert fit.samples == len(r) and fit.effective_samples == pytest.approx(m_e, rel=1e-9)
    assert m_e < 0.5 * len(r)  # (the correction matters here)
    assert fit.condition == pytest.approx(np.linalg.cond(A / np.linalg.norm(A, axis=0)))
    forward = np.count_nonzero(dq > 0.05) / m
    backward = np.count_nonzero(dq < -0.05) / m
    assert fit.coverage == (pytest.approx(forward), pytest.approx(backward))
    assert 0.2 < forward < 0.3  # half the samples are slow: a quarter each way
    whole = FrictionFit((fit,), "observer", 0.95)
    row = next(line for line in whole.table().splitlines() if line.startswith("| elbow"))
    assert f"| {len(r)} ({m_e:.0f}) |" in row, row
    lo, hi = fit.viscous_ci
    assert lo < fit.viscous < hi and f"| {fit.viscous:.4g} [{lo:.4g}, {hi:.4g}] |" in row, row
    table = tomllib.loads(whole.toml())["controller"]["friction"]
    np.testing.assert_allclose(table["viscous"], [fit.viscous], rtol=5e-6)  # 6 digits
    np.testing.assert_allclose(table["coulomb"], [fit.coulomb], rtol=5e-6)


def test_a_confidence_of_one_is_refused(friction_run):
    """A 100 % interval is infinitely wide: the level must be in (0, 1)."""
    _, result = friction_run
    for level in (1.0, 0.0, 1.5):
        with pytest.raises(ConfigError, match="--confidence"):
            fit_friction(result, source="observer", confidence=level)


def test_the_last_samples_applied_torque_is_not_read(friction_run):
    """No period follows the last sample: its applied torque (NaN in a run stopped
    there) is not read by the dynamics source, and nothing is counted as left out."""
    exp, result = friction_run
    tau = np.array(result.tau_applied, dtype=float)
    tau[-1] = np.nan
    fit = fit_friction(replace(result, tau_applied=tau), source="dynamics", robot=exp.robot)
    assert fit.excluded == 0
    tau[-2] = np.nan  # a sample inside the run: the two periods it ends and starts, counted
    fit = fit_friction(replace(result, tau_applied=tau), source="dynamics", robot=exp.robot)
    assert fit.excluded == 2


def test_joints_fitted_together_are_weighted_by_their_residual_variance(make_rng):
    """The observer source fits all joints in one least-squares problem (its filter
    couples them): feasible GLS, each joint's rows weighted by 1/s_i², s_i² the mean
    squared residual of the ordinary fit on that joint's rows (numpy: lstsq twice). A
    joint 30 times noisier then barely moves the shared estimate, and the ordinary fit
    differs from it."""
    from hmpc_pin.identification.friction import _least_squares

    rng = make_rng(9)
    theta_true = np.array([2.0, -0.5, 1.0])
    blocks = []
    for sigma in (0.01, 0.3):
        a = rng.standard_normal((400, 3)) * np.array([1.0, 10.0, 0.1])
        blocks.append((a, a @ theta_true + sigma * rng.standard_normal(400)))
    A = np.vstack([a for a, _ in blocks])
    y = np.concatenate([v for _, v in blocks])
    ols, *_ = np.linalg.lstsq(A, y, rcond=None)
    w = np.concatenate([np.full(400, 1 / np.sqrt(np.mean((v - a @ ols) ** 2))) for a, v in blocks])
    gls, *_ = np.linalg.lstsq(A * w[:, None], y * w, rcond=None)
    theta, _half, res, _m_eff = _least_squares(blocks, 0.95)
    np.testing.assert_allclose(theta, gls, rtol=1e-9)
    assert np.max(np.abs(gls - ols) / np.abs(theta_true)) > 1e-4  # the weights matter
    np.testing.assert_allclose(np.concatenate(res), y - A @ gls, atol=1e-12)


def test_identify_config_changes_the_friction_table_alone(tmp_path, friction_run, capsys):
    """identify --config writes the config with [controller.friction] set to the fit and
    every other controller setting as the source has it (the table, not [controller],
    is replaced)."""
    _, result = friction_run
    run = result.save(tmp_path / "run.npz")
    out = tmp_path / "ff.toml"
    source = tmp_path / "own.toml"  # settings of its own, none the default
    urdf = (CONFIGS.parent / "robots" / "planar3.urdf").as_posix()
    text = (CONFIGS / "paper_friction.toml").read_text()
    text = (text.replace('model = "planar3"', f'urdf = "{urdf}"').replace("N = 10 ", "N = 17 ")
            .replace("R = 1e-6", "R = 2e-6").replace("gain = 100.0", "gain = 80.0"))  # fmt: skip
    source.write_text(text)
    assert load_config(source).controller.N == 17
    assert main(["identify", str(run), "--config", str(source), "--out", str(out)]) == 0
    capsys.readouterr()
    before, after = load_config(source).controller, load_config(out).controller
    for key in ("Ts", "N", "Nc", "R", "compensation", "latency"):
        assert getattr(after, key) == getattr(before, key), key
    np.testing.assert_array_equal(after.Q, before.Q)
    np.testing.assert_array_equal(after.P, before.P)
    for key in ("gain", "discretization", "model_at"):
        assert getattr(after.observer, key) == getattr(before.observer, key), key
    assert before.friction is None and after.friction is not None
    np.testing.assert_allclose(after.friction.viscous, VISCOUS, rtol=0.05)


def test_the_excitation_error_names_the_peak_speed_either_way():
    """A joint that moves backward only: the message's peak |q̇| is the largest speed,
    here 1 rad/s backward (numpy: max |q̇|), not the largest signed velocity."""
    dq = -0.5 * (1.0 + np.sin(np.linspace(0, 20, 1000)))
    with pytest.raises(ExcitationError) as info:
        fit_joint(0.3 * dq, dq, name="wrist")
    assert f"peak |q̇| {np.max(np.abs(dq)):.3g} rad/s" in str(info.value)


def test_the_regressor_source_needs_the_arm_too(friction_run):
    _, result = friction_run
    with pytest.raises(ConfigError, match="'regressor' source needs the arm's model"):
        fit_friction(result, source="regressor")


def test_the_dynamics_source_starts_at_the_first_period_whose_middle_is_after(friction_run):
    """A period's sample is at its middle, (t_k + t_k+1)/2: with --after a quarter period
    past t_50, the period from t_50 (middle t_50 + Ts/2) is kept. The samples counted per
    joint are numpy's: periods whose middle is >= after and whose mean speed is above
    the velocity threshold."""
    exp, result = friction_run
    t = result.t
    after = float(t[50] + 0.25 * (t[51] - t[50]))
    fit = fit_friction(result, source="dynamics", robot=exp.robot, after=after)
    mid = 0.5 * (t[1:] + t[:-1])
    dq_mid = 0.5 * (result.dq[1:] + result.dq[:-1])
    for j, joint in enumerate(fit.joints):
        expected = np.count_nonzero((mid >= after) & (np.abs(dq_mid[:, j]) > 0.01))
        assert joint.samples == expected


@pytest.mark.parametrize("form", ["implicit", "explicit", "momentum"])
def test_the_observers_time_constant_is_its_free_responses_decay(form, planar3):
    """The time constant identify waits after a stuck joint is the observer's own: the
    filter's response to one pulse, at rest, falls by e every tau (its late decay, over
    100 periods where the slowest mode leaves the others 1e-10 behind); the momentum
    observer's is Ts / ln(1 + Ts K_min) in closed form."""
    n, Ts = planar3.nq, 0.01
    q = np.tile([0.3, -0.5, 0.8], (201, 1))
    M = planar3.mass_matrix(q[0])
    if form == "momentum":
        model = ObserverModel("momentum", np.array([20.0, 35.0, 50.0]), Ts, planar3)
        assert model.time_constant(q) == pytest.approx(Ts / np.log(1 + Ts * 20.0), rel=1e-12)
        assert not model.coupled()
    else:
        cY = np.diag([10.0, 40.0, 50.0]) @ M + 0.1 * np.ones((n, n))
        model = ObserverModel("general", 1.0, Ts, planar3, form == "implicit", cY)
        assert model.coupled()
    phi = np.zeros((201, n, 1))
    phi[1, :, 0] = [1.0, -2.0, 0.5]  # every mode excited
    g = np.linalg.norm(model.filter(q, phi)[:, :, 0], axis=1)
    measured = -100 * Ts / np.log(g[200] / g[100])
    assert model.time_constant(q) == pytest.approx(measured, rel=1e-6)


def test_a_stuck_joint_is_one_at_rest_for_a_period_within_its_noise(make_rng):
    """A joint at rest for 30 samples under a velocity noise of 0.004 rad/s is found
    stuck over those samples (the band 4 sigma: the estimate of sigma from the second
    differences of its slow motion within 15 % of the noise drawn); one sweeping through
    zero at speed is not, nor a noise-free joint whose velocity is exactly zero at one
    sample."""
    from hmpc_pin.identification.friction import stuck_samples, velocity_noise

    rng = make_rng(5)
    t = np.arange(400) * 0.01
    sweep = np.sin(2 * np.pi * 2.0 * t)  # through zero at 12.6 rad/s²: in the band 3 ms
    rest = np.where((t >= 1.0) & (t < 1.3), 0.0, np.cos(np.pi * t))
    exact = np.round(np.sin(np.pi * (t - 0.005)), 12)
    exact[200] = 0.0
    noise = 0.004 * rng.standard_normal((400, 2))
    dq = np.column_stack([sweep + noise[:, 0], rest + noise[:, 1], exact])
    sigma = velocity_noise(dq)
    assert sigma[1] == pytest.approx(0.004, rel=0.15)  # (the fast sweep's own curvature adds)
    mask, ranges = stuck_samples(dq, 0.01)
    assert ranges[0] == [] and ranges[2] == []
    assert not mask[:, [0, 2]].any()
    plateau = np.flatnonzero((t >= 1.0) & (t < 1.3))
    assert mask[plateau, 1].mean() > 0.95  # a 4-sigma band holds 99.99 % of the noise
    inside = np.concatenate([np.arange(s, e) for s, e in ranges[1]])
    assert np.all(np.abs(dq[inside, 1]) <= 4 * sigma[1] + 1e-12)


def test_the_refusal_states_each_ways_share_of_the_samples():
    """A joint moving forward in 30 % of the samples and backward in 2 % (both faster
    than 0.05 rad/s; the rest at rest): the message gives those shares, each its way."""
    dq = np.concatenate([np.full(300, 1.0), np.full(20, -1.0), np.zeros(680)])
    with pytest.raises(ExcitationError) as info:
        fit_joint(2.0 * dq + np.sign(dq), dq, name="wrist")
    assert "moves forward in 30.0 % and backward in 2.0 % of the samples" in str(info.value)


def test_without_the_observers_model_only_the_stuck_samples_are_left_out(friction_run):
    """fit_friction without observer= takes d_hat as the disturbance itself: the stuck
    samples (at rest, |q̇| <= 0.01 rad/s, for two samples or more, and the first moving
    one after) are left out, with no settling (the observer is not known) and no note
    of one; the count is numpy's, over the samples after --after (0.5 s)."""
    _, result = friction_run
    fit = fit_friction(result)
    t, dq = result.t, result.dq
    stuck = np.zeros(len(t), dtype=bool)
    for i in range(dq.shape[1]):
        slow = np.abs(dq[:, i]) <= 0.01
        k = 0
        while k < len(t):
            if slow[k]:
                e = k
                while e < len(t) and slow[e]:
                    e += 1
                if e - k >= 2:
                    stuck[k : min(e, len(t) - 1) + 1] = True
                k = e
            else:
                k += 1
    expected = int(np.count_nonzero(stuck & (t >= 0.5)))
    note = next(x for x in fit.notes() if "stuck" in x)
    assert expected > 0 and note.startswith(f"{expected} samples left out where ")
    assert fit.settling == 0 and "after each" not in note


def _sweeping_run(joint_names=(), gap=None) -> Result:
    """Two joints sweeping through zero at speed (q̇ = sin 3t, sin 4t: within
    0.01 rad/s of zero for under one 10 ms period, so never stuck), 10 s; the estimate is
    exactly the friction's torque, -(a q̇ + b sgn q̇) with a = (2, 1), b = (0.5, 0.3);
    ``gap``: rows whose velocities are NaN (a dropped message)."""
    t = 0.01 * np.arange(1000)
    dq = np.column_stack([np.sin(3.0 * t), np.sin(4.0 * t)])
    q = np.column_stack([(1 - np.cos(3.0 * t)) / 3.0, (1 - np.cos(4.0 * t)) / 4.0])
    d_hat = -(np.array([2.0, 1.0]) * dq + np.array([0.5, 0.3]) * np.sign(dq))
    if gap is not None:
        dq[gap] = np.nan
    zeros = np.zeros_like(dq)
    return Result(t, q, dq, zeros, -d_hat, d_hat, q, dq, joint_names=joint_names)


def test_a_gap_in_the_record_is_no_stuck_joint():
    """Five samples of NaN velocity in the middle of a sweep (a dropped message): they
    are left out and counted as such, and no joint is called stuck for them (no joint
    of this run ever is: each crosses zero at speed); the fit is exact."""
    fit = fit_friction(_sweeping_run(gap=slice(300, 305)))
    assert fit.excluded == 5 and fit.stuck == 0 and fit.stuck_joints == ()
    assert not any("stuck" in note for note in fit.notes()), fit.notes()
    np.testing.assert_allclose(fit.viscous, [2.0, 1.0], rtol=1e-9)
    np.testing.assert_allclose(fit.coulomb, [0.5, 0.3], rtol=1e-9)


def test_joints_of_an_unnamed_run_are_numbered_from_one_as_in_its_thresholds():
    """A run that names no joints: the friction table calls them joint1, joint2 (as the
    thresholds do, and as a person counts them), and a refusal names the joint by it."""
    from hmpc_pin.identification import learn_thresholds

    run = _sweeping_run()
    assert [j.name for j in fit_friction(run).joints] == ["joint1", "joint2"]
    assert learn_thresholds(run).names == ("joint1", "joint2")
    still = replace(run, dq=run.dq * np.array([1.0, 0.0]))
    with pytest.raises(ExcitationError) as info:
        fit_friction(still)
    assert info.value.joint == "joint2"


def test_an_ndo_model_without_the_arm_is_one_error_naming_it():
    """The NDO's L = cY M(q)^-1 needs the arm's M(q): its model built without a robot
    says so when it is used (not an AttributeError on None); the momentum observer's
    L = diag(K_O) needs none (its time constant is -Ts / ln(1 / (1 + Ts K_O)) [s])."""
    q = np.zeros((5, 3))
    ndo = ObserverModel("general", 1.0, 0.01, None, True, 20.0 * np.eye(3))
    with pytest.raises(ConfigError, match="needs the arm's model") as info:
        ndo.time_constant(q)
    assert info.value.key == "robot"
    with pytest.raises(ConfigError, match="needs the arm's model"):
        ndo.filter(q, np.ones((5, 3, 1)))
    momentum = ObserverModel("momentum", np.array([10.0, 20.0, 40.0]), 0.01)
    assert momentum.time_constant(q) == pytest.approx(-0.01 / np.log(1 / 1.1), rel=1e-12)
