"""``hmpc-pin tune``: the Optuna search of observer gain, Q, R, N on the sweep's plants."""

from __future__ import annotations

import sys
from dataclasses import replace

import numpy as np
import pytest

from hmpc_pin.apps.cli import main
from hmpc_pin.apps.tune import apply_params, objective_value, search_space, tune
from hmpc_pin.experiment.build import Experiment
from hmpc_pin.experiment.schema import load_config

from .conftest import CONFIGS

pytest.importorskip("optuna")


def _toy(config):
    """A smooth bowl in the log of the weights, lowest at Q_p = 1e3, R = 1e-5, c = 200."""
    cc = config.controller
    value = ((np.log10(cc.Q[0, 0]) - 3) ** 2 + (np.log10(cc.R) + 5) ** 2
             + (np.log10(cc.observer.gain) - np.log10(200)) ** 2)  # fmt: skip
    return float(value), {"p95_rms": float(value)}


@pytest.fixture
def friction_config():
    return load_config(CONFIGS / "paper_friction.toml")


def test_five_trials_improve_on_the_toy_objective_and_repeat_with_the_seed(
    tmp_path, friction_config
):
    runs = []
    for folder in ("a", "b"):
        (tmp_path / folder).mkdir()
        runs.append(tune(friction_config, tmp_path / folder, trials=5, seed=7, objective=_toy,
                         holdout=0, progress=False))  # fmt: skip
    first, again = runs
    values = [t.value for t in first.study.trials]
    assert values[0] == pytest.approx(_toy(friction_config)[0])  # trial 0: the config as given
    assert min(values) < values[0]
    assert [t.params for t in first.study.trials] == [t.params for t in again.study.trials]
    # the tuned config is the best trial's, written where it loads and runs
    tuned = load_config(tmp_path / "a" / "paper_friction_tuned.toml")
    assert _toy(tuned)[0] == pytest.approx(min(values), rel=1e-9)
    result = Experiment.from_config(tuned).run(duration=0.5)
    assert result.complete
    assert (tmp_path / "a" / "paper_friction_tune_history.png").stat().st_size > 0
    report = (tmp_path / "a" / "paper_friction_tune.md").read_text()
    assert "trial 0 is the config as given" in report


def test_a_study_resumes_from_its_file(tmp_path, friction_config):
    tune(friction_config, tmp_path, trials=3, seed=1, objective=_toy, holdout=0, progress=False)
    resumed = tune(friction_config, tmp_path, trials=2, seed=1, objective=_toy, holdout=0,
                   progress=False)  # fmt: skip
    assert len(resumed.study.trials) == 5


def test_apply_params_sets_the_weights_and_terminal_weight(friction_config):
    space = search_space(friction_config, ts=(0.005, 0.01))
    assert set(space) == {"Q_position", "Q_velocity", "R", "N", "observer_gain", "Ts"}
    cfg = apply_params(friction_config, {"Q_position": 300.0, "Q_velocity": 0.5, "R": 1e-7,
                                         "N": 12, "observer_gain": 150.0, "Ts": 0.005})  # fmt: skip
    cc = cfg.controller
    np.testing.assert_array_equal(cc.P, 2 * cc.Q)
    assert (cc.Q[0, 0], cc.Q[1, 1], cc.R, cc.N, cc.observer.gain, cc.Ts) == (
        300.0, 0.5, 1e-7, 12, 150.0, 0.005)  # fmt: skip


def test_objective_penalises_saturation_and_chattering():
    rows = [{"rms_max": 0.01 * (i + 1), "bounded": True, "saturation": 0.0, "torque_tv": 10.0}
            for i in range(20)]  # fmt: skip
    base, parts = objective_value(rows, 1.0, tv0=10.0)
    assert base == pytest.approx(0.19) and parts["p95_rms"] == pytest.approx(0.19)
    sat = [dict(r, saturation=0.5) for r in rows]
    assert objective_value(sat, 1.0, tv0=10.0)[0] == pytest.approx(0.19 * 1.5)
    tv = [dict(r, torque_tv=30.0) for r in rows]
    assert objective_value(tv, 1.0, tv0=10.0)[0] == pytest.approx(0.19 * (1 + 0.1 * 2))
    lost = [dict(r, bounded=False, t_end=5.0) for r in rows]  # half the run lost
    assert objective_value(lost, 1.0, tv0=10.0, duration=10.0)[1]["p95_rms"] == pytest.approx(
        1.0 * 1.5 + 0.19)  # fmt: skip


def test_a_real_trial_runs_the_sweep(tmp_path, friction_config, capsys):
    """Two trials of 2 samples of 1.5 s on the paper arm, through the command line."""
    path = tmp_path / "short.toml"
    urdf = (CONFIGS.parent / "robots" / "planar3.urdf").as_posix()
    text = (CONFIGS / "paper_friction.toml").read_text()
    text = text.replace('urdf = "../robots/planar3.urdf"', f'urdf = "{urdf}"')
    path.write_text(text)
    code = main(["tune", str(path), "--trials", "2", "--samples", "2", "--jobs", "1",
                 "--duration", "1.5", "--holdout", "2", "--out", str(tmp_path / "out"),
                 "--quiet"])  # fmt: skip
    assert code == 0
    out = capsys.readouterr().out
    assert "held-out samples: p95 worst-joint RMS" in out
    tuned = load_config(tmp_path / "out" / "paper_friction_tuned.toml")
    assert (
        Experiment.from_config(replace(tuned, simulation=replace(tuned.simulation, duration=0.3)))
        .run()
        .complete
    )


def test_without_optuna_the_extra_is_named(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "optuna", None)  # import optuna raises ImportError
    code = main(["tune", str(CONFIGS / "paper_friction.toml"), "--trials", "1",
                 "--out", str(tmp_path / "o")])  # fmt: skip
    assert code == 2
    err = capsys.readouterr().err
    assert "hmpc_pin[tune]" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()


def test_the_observer_can_be_searched_too(tmp_path, friction_config):
    """--observers: the observer is a choice; the tuned config names it (the 0.1 keys
    of the source's [controller.observer] dropped) and loads."""

    def prefer_momentum(config):
        value = _toy(config)[0]
        value += 0.0 if config.controller.compensation == "momentum" else 100.0
        return value, {"p95_rms": value}

    result = tune(friction_config, tmp_path, trials=10, seed=3, objective=prefer_momentum,
                  observers=("chen", "momentum"), holdout=0, progress=False)  # fmt: skip
    best = result.study.best_trial.params
    tuned = load_config(tmp_path / "paper_friction_tuned.toml")
    assert tuned.controller.compensation == best["compensation"] == "momentum"
    assert tuned.controller.observer.gain == pytest.approx(best["observer_gain"])
    with pytest.raises(Exception, match="--observers"):
        search_space(friction_config, observers=("ism",))
