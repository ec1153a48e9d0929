"""Friction identification and the friction feed-forward (``hmpc-pin identify``)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from hmpc_pin.apps.cli import main
from hmpc_pin.controllers.wrappers import FrictionFeedforward
from hmpc_pin.exceptions import ConfigError, ExcitationError
from hmpc_pin.experiment.build import Experiment
from hmpc_pin.experiment.schema import load_config
from hmpc_pin.identification import ObserverModel, fit_friction, fit_joint

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
    # the friction was most of it: the error falls on every joint, by half over the arm
    # (joint 3's error is mostly the Coulomb jumps at reversals, which no model cancels)
    assert np.all(w1 < w0) and np.linalg.norm(w1) < 0.5 * np.linalg.norm(w0), (w0, w1)
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
