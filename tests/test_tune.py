"""``hmpc-pin tune``: the Optuna search of observer gain, Q, R, N on the sweep's plants."""

from __future__ import annotations

import math
import sys
from dataclasses import replace

import numpy as np
import pytest

from hmpc_pin.apps.cli import main
from hmpc_pin.apps.tune import tune
from hmpc_pin.apps.tune_objective import objective_value
from hmpc_pin.apps.tune_space import apply_params, search_space
from hmpc_pin.experiment.build import Experiment
from hmpc_pin.experiment.config import load_config

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
    smooth = [dict(r, torque_tv=5.0) for r in rows]  # smoother than as given: no bonus
    assert objective_value(smooth, 1.0, tv0=10.0)[0] == pytest.approx(0.19)
    lost = [dict(r, bounded=False, t_end=5.0) for r in rows]  # half the run lost
    assert objective_value(lost, 1.0, tv0=10.0, duration=10.0)[1]["p95_rms"] == pytest.approx(
        1.0 * 1.5 + 0.19)  # fmt: skip


def test_a_real_trial_runs_the_sweep(tmp_path, friction_config, capsys):
    """Two trials of 2 samples of 1.5 s on the paper arm, through the command line."""
    path = tmp_path / "short.toml"
    urdf = (CONFIGS.parent / "robots" / "planar3.urdf").as_posix()
    text = (CONFIGS / "paper_friction.toml").read_text()
    text = text.replace('model = "planar3"', f'urdf = "{urdf}"')
    path.write_text(text)
    code = main(["tune", str(path), "--trials", "2", "--samples", "2", "--jobs", "1",
                 "--duration", "1.5", "--holdout", "2", "--out", str(tmp_path / "out"),
                 "--quiet"])  # fmt: skip
    assert code == 0
    out = capsys.readouterr().out
    assert "held-out samples: p95 worst-joint RMS" in out
    # the report's ratio is the shipped config's p95 over the tuned one's, from its table
    report = (tmp_path / "out" / "paper_friction_tune.md").read_text()
    p95 = {row.split("|")[1].strip(): float(row.split("|")[2]) for row in report.splitlines()
           if row.startswith(("| shipped |", "| tuned |"))}  # fmt: skip
    ratio = float(report.split("Shipped / tuned p95: ")[1].split()[0].rstrip("."))
    assert ratio == pytest.approx(p95["shipped"] / p95["tuned"], rel=2e-3), report
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


def _short_config(tmp_path):
    """paper_friction with an absolute URDF path (copied into a test folder)."""
    path = tmp_path / "short.toml"
    urdf = (CONFIGS.parent / "robots" / "planar3.urdf").as_posix()
    text = (CONFIGS / "paper_friction.toml").read_text()
    path.write_text(text.replace('model = "planar3"', f'urdf = "{urdf}"'))
    return path


class _StopAt:
    """The toy objective, with Ctrl-C arriving during call ``stop`` (0-based)."""

    def __init__(self, stop: int):
        self.stop, self.calls = stop, 0

    def __call__(self, config):
        self.calls += 1
        if self.calls > self.stop:
            raise KeyboardInterrupt
        return _toy(config)


def test_ctrl_c_keeps_the_best_of_the_finished_trials(tmp_path, friction_config):
    """Ctrl-C in trial 3 of 10: the tuned config is the best of trials 0-2, the report
    says where it stopped, and the study resumes from its file."""
    from hmpc_pin.exceptions import RunInterrupted

    with pytest.raises(RunInterrupted) as info:
        tune(friction_config, tmp_path, trials=10, seed=5, objective=_StopAt(3), holdout=0,
             progress=False)  # fmt: skip
    assert info.value.where.startswith("trial 3 of the study (3 finished")
    files = {p.name for p in info.value.files}
    assert {"paper_friction_tuned.toml", "paper_friction_tune.md"} <= files
    report = (tmp_path / "paper_friction_tune.md").read_text()
    assert "Interrupted (Ctrl-C) at trial 3" in report and "4 trials (3 finished)" in report
    import optuna

    db = tmp_path / "paper_friction_tune.db"
    study = optuna.load_study(study_name="paper_friction", storage=f"sqlite:///{db}")
    values = [t.value for t in study.trials if t.value is not None]
    assert len(values) == 3
    tuned = load_config(tmp_path / "paper_friction_tuned.toml")
    assert _toy(tuned)[0] == pytest.approx(min(values), rel=1e-9)
    resumed = tune(friction_config, tmp_path, trials=2, seed=5, objective=_toy, holdout=0,
                   progress=False)  # fmt: skip
    assert sum(t.value is not None for t in resumed.study.trials) == 5


def test_ctrl_c_before_any_trial_finished_writes_no_config(tmp_path, friction_config):
    from hmpc_pin.exceptions import RunInterrupted

    with pytest.raises(RunInterrupted, match="no trial finished"):
        tune(friction_config, tmp_path, trials=3, objective=_StopAt(0), holdout=0,
             progress=False)  # fmt: skip
    assert not (tmp_path / "paper_friction_tuned.toml").exists()


def test_sigint_through_the_command_line(tmp_path):
    """A real study of real sweeps: SIGINT to the process group once a trial finished ->
    exit 130, one line naming the files, the tuned config of the finished trials."""
    import contextlib
    import sqlite3

    from .test_interrupts import _interrupt, _last_line, _start, _wait_for

    config = _short_config(tmp_path)
    out = tmp_path / "out"
    proc, err = _start(["tune", str(config), "--trials", "200", "--samples", "1", "--jobs",
                        "1", "--duration", "1.5", "--holdout", "1", "--out", str(out),
                        "--quiet"], tmp_path)  # fmt: skip
    db = out / "paper_friction_tune.db"

    def finished() -> bool:  # read-only: Optuna's load_study would write the schema
        if not db.exists():
            return False
        try:
            with contextlib.closing(sqlite3.connect(f"file:{db}?mode=ro", uri=True)) as con:
                rows = con.execute("SELECT count(*) FROM trials WHERE state = 'COMPLETE'")
                return rows.fetchone()[0] >= 2
        except sqlite3.Error:  # the tables are not created yet
            return False

    _wait_for(finished, proc, 300, "two finished trials")
    code, _, _, stderr = _interrupt(proc, err, True, set())
    assert code == 130, stderr
    assert "Traceback" not in stderr
    line = _last_line(stderr)
    assert line.startswith("interrupted at trial") and "paper_friction_tuned.toml" in line, line
    assert load_config(out / "paper_friction_tuned.toml").controller.Q.shape == (2, 2)
    # the report of the trials done; Ctrl-C also stops what was to follow them (the
    # held-out comparison of --holdout 1 is not run after it)
    report = (out / "paper_friction_tune.md").read_text()
    assert "Interrupted (Ctrl-C) at trial" in report and "Held-out comparison" not in report
    assert "paper_friction_tune.md" in line


@pytest.mark.parametrize(
    ("flags", "named"),
    [
        (["--seed", str(2**32)], "--seed"),
        (["--seed", "-1"], "--seed"),
        (["--holdout", "-1"], "--holdout"),
        (["--holdout-seed", "-1"], "--holdout-seed"),
        (["--holdout-seed", str(2**32)], "--holdout-seed"),
        (["--samples", "0"], "--samples"),
        (["--trials", "0"], "--trials"),
        (["--jobs", "0"], "--jobs"),
        (["--duration", "0.5"], "--duration"),  # shorter than sweep.after = 1 s
        (["--duration", "1.0"], "--duration"),  # no time left after sweep.after
        (["--ts", "0.01,-1"], "--ts"),
        (["--ts", "0.01,0"], "--ts"),  # a period of 0 s
        (["--observers", "ism"], "--observers"),
        (["--scheduler", "foo:1"], "--scheduler"),  # the default executor is local
        (["--executor", "local", "--scheduler", "foo:1"], "--scheduler"),
        (["--holdout", "0", "--holdout-seed", "3"], "--holdout-seed"),  # no held-out samples
    ],
)
def test_each_option_is_refused_by_its_own_name_before_out_exists(flags, named, tmp_path,
                                                                  capsys):  # fmt: skip
    out = tmp_path / "never"
    trials = [] if "--trials" in flags else ["--trials", "1"]
    code = main(["tune", str(_short_config(tmp_path)), *trials, *flags, "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    assert err.startswith(f"error: {named}:"), err
    assert "an integer an integer" not in err, err  # the message reads once
    assert not out.exists()


def test_the_largest_seed_is_accepted(tmp_path, friction_config):
    """2**32 - 1: the sampler's largest seed, also when the study resumes (its sampler
    is seeded seed + trials done); the held-out seed wraps to 0."""
    result = tune(friction_config, tmp_path, trials=2, seed=2**32 - 1, objective=_toy,
                  holdout=0, progress=False)  # fmt: skip
    assert len(result.study.trials) == 2
    resumed = tune(
        friction_config,
        tmp_path,
        trials=1,
        seed=2**32 - 1,
        objective=_toy,
        holdout=0,
        progress=False,
    )  # its sampler's seed wraps past 2**32 - 1
    assert len(resumed.study.trials) == 3


def test_trial_0_shows_the_configs_own_weights(tmp_path, friction_config):
    """paper_friction's velocity weight is 0, below the search range (its enqueued value
    is clipped to 1e-4); the report's trial 0 is the config as given: 0."""
    assert friction_config.controller.Q[1, 1] == 0.0
    tune(friction_config, tmp_path, trials=2, seed=2, objective=_toy, holdout=0, progress=False)
    report = (tmp_path / "paper_friction_tune.md").read_text().splitlines()
    header = next(line for line in report if line.startswith("| trial | J |"))
    row0 = next(line for line in report if line.startswith("| 0 |"))
    cells = dict(zip([c.strip() for c in header.split("|")], [c.strip() for c in row0.split("|")],
                     strict=True))  # fmt: skip
    assert float(cells["Q_velocity"]) == 0.0
    assert float(cells["Q_position"]) == friction_config.controller.Q[0, 0]


def test_the_score_ranks_a_later_failure_before_an_earlier_one():
    """Two runs that did not stay bounded, one lost at 8 s and one at 2 s of 10 s: the
    later failure scores lower (better), any bounded run lower than both, and among
    runs lost at the same time the smaller error lower."""
    from hmpc_pin.apps.tune_objective import run_score

    late = {"rms_max": 0.5, "bounded": False, "t_end": 8.0}
    early = {"rms_max": 0.5, "bounded": False, "t_end": 2.0}
    worst_bounded = {"rms_max": 0.999, "bounded": True, "t_end": 10.0}
    s_late, s_early = run_score(late, 1.0, 10.0), run_score(early, 1.0, 10.0)
    assert run_score(worst_bounded, 1.0, 10.0) < s_late < s_early
    assert s_late == pytest.approx(1.0 * (1 + 0.2) + 0.5)  # b (1 + lost) + e
    assert run_score(dict(late, rms_max=0.1), 1.0, 10.0) < s_late
    assert run_score(dict(late, rms_max=np.inf), 1.0, 10.0) == pytest.approx(1.2 + 10.0)


def test_an_observer_given_by_its_bandwidth_is_tuned_by_its_bandwidth(tmp_path):
    """A config whose observer is a per-joint bandwidth (what init writes for a spatial
    arm; it has no gain): the trials scale every joint's bandwidth together, and the
    tuned config keeps the per-joint shape."""
    text = (CONFIGS / "paper_friction.toml").read_text()
    urdf = (CONFIGS.parent / "robots" / "planar3.urdf").as_posix()
    text = text.replace('model = "planar3"', f'urdf = "{urdf}"')
    text = text.replace('kind = "chen"', 'kind = "general"')
    text = text.replace("gain = 100.0", "bandwidth = [10.0, 15.0, 20.0]")
    path = tmp_path / "bw.toml"
    path.write_text(text)
    config = load_config(path)
    assert config.controller.observer.gain is None

    def prefer_5(cfg):
        w = np.asarray(cfg.controller.observer.bandwidth)
        np.testing.assert_allclose(w / w.max(), [0.5, 0.75, 1.0])  # the shape is kept
        value = (np.log10(w.max()) - np.log10(5.0)) ** 2
        return float(value), {"p95_rms": float(value)}

    (tmp_path / "o").mkdir()
    result = tune(config, tmp_path / "o", trials=12, seed=1, objective=prefer_5, holdout=0,
                  progress=False)  # fmt: skip
    assert "observer_bandwidth" in result.best
    tuned = load_config(tmp_path / "o" / f"{config.name}_tuned.toml")
    w = np.asarray(tuned.controller.observer.bandwidth)
    np.testing.assert_allclose(w / w.max(), [0.5, 0.75, 1.0])
    assert w.max() == pytest.approx(result.best["observer_bandwidth"])
    assert abs(np.log10(w.max() / 5.0)) < abs(np.log10(20.0 / 5.0))  # moved toward 5


def test_trial_0_records_what_it_ran_and_a_winning_trial_0_is_written_as_it_ran(tmp_path):
    """A config outside the search space (Ts not among --ts, its observer not among
    --observers, Q_velocity 0 below the range, P ≠ 2Q): trial 0 runs the config's own
    values, records them, the report shows them and says where the sampler's record
    differs, and when trial 0 wins the written config is the one that ran."""
    path = _short_config(tmp_path)
    path.write_text(path.read_text().replace("P = [100.0, 0.0]", "P = [300.0, 0.0]"))
    config = load_config(path)
    seen = []

    def first_wins(cfg):
        seen.append(cfg.controller)
        value = 0.0 if len(seen) == 1 else 1.0
        return value, {"p95_rms": value}

    (tmp_path / "o").mkdir()
    result = tune(config, tmp_path / "o", trials=3, seed=4, ts=(0.005, 0.02),
                  observers=("general", "momentum"), objective=first_wins, holdout=0,
                  progress=False)  # fmt: skip
    ran = seen[0]
    assert (ran.Ts, ran.compensation, ran.Q[1, 1]) == (0.01, "chen", 0.0)  # its own values
    assert result.study.trials[0].user_attrs["ran"] == result.best
    assert result.best["Ts"] == 0.01 and result.best["compensation"] == "chen"
    written = load_config(tmp_path / "o" / "paper_friction_tuned.toml").controller
    for key in ("Q", "P", "R", "N", "Ts", "compensation"):
        np.testing.assert_array_equal(getattr(written, key), getattr(ran, key), err_msg=key)
    assert written.observer.gain == ran.observer.gain
    report = (tmp_path / "o" / "paper_friction_tune.md").read_text()
    assert "Ts = 0.005 (ran 0.01)" in report and "compensation = general (ran chen)" in report
    assert "Q_velocity = 0.0001 (ran 0)" in report and "P = 2Q" in report


def test_the_observer_gains_range_is_a_tenth_to_five_times_the_configs(friction_config):
    """The module's search space: the observer gain log-uniform on [c0/10, 5 c0]."""
    c0 = friction_config.controller.observer.gain
    kind, low, high = search_space(friction_config)["observer_gain"]
    assert kind == "log" and low == pytest.approx(c0 / 10) and high == pytest.approx(5 * c0)


def test_a_bandwidths_range_is_a_tenth_to_five_times_the_configs_largest(tmp_path):
    """An observer given by per-joint bandwidths [10, 15, 20] 1/s: the trials scale them
    together by the largest, log-uniform on [20/10, 5 x 20] = [2, 100] 1/s, the gain's
    range relative to the config's."""
    text = (CONFIGS / "paper_friction.toml").read_text()
    urdf = (CONFIGS.parent / "robots" / "planar3.urdf").as_posix()
    text = text.replace('model = "planar3"', f'urdf = "{urdf}"')
    text = text.replace('kind = "chen"', 'kind = "general"')
    text = text.replace("gain = 100.0", "bandwidth = [10.0, 15.0, 20.0]")
    path = tmp_path / "bw.toml"
    path.write_text(text)
    kind, low, high = search_space(load_config(path))["observer_bandwidth"]
    assert kind == "log" and low == pytest.approx(2.0) and high == pytest.approx(100.0)


def test_trial_zero_starts_at_the_period_nearest_the_configs(friction_config):
    """--ts choices: trial 0 records the config's own Ts where it is listed, else the
    nearest listed period (not the first)."""
    from hmpc_pin.apps.tune_space import current_params

    space = search_space(friction_config, ts=(0.002, 0.01, 0.02))
    assert current_params(friction_config, space)["Ts"] == 0.01  # the config's Ts
    space = search_space(friction_config, ts=(0.001, 0.009, 0.05))
    assert current_params(friction_config, space)["Ts"] == 0.009


def test_the_saturation_penalty_is_the_share_of_saturated_samples():
    """J = p95 (1 + w_sat mean(saturation) + ...): one sample of four saturated for its
    whole run counts 1/4, not as if every sample had saturated (closed form)."""
    from hmpc_pin.apps.tune_objective import SATURATION_WEIGHT

    rows = [{"rms_max": 0.1, "bounded": True, "saturation": s, "torque_tv": 1.0}
            for s in (0.0, 0.0, 0.0, 1.0)]  # fmt: skip
    value, parts = objective_value(rows, 1.0, tv0=1.0)
    assert parts["saturation"] == pytest.approx(0.25)
    assert value == pytest.approx(0.1 * (1 + SATURATION_WEIGHT * 0.25))


def test_a_resumed_study_does_not_repeat_the_first_ones_suggestions(tmp_path, friction_config):
    """A study resumed with the same seed samples new points: its sampler is seeded past
    the trials already in the file (the same seed again would replay the first study)."""
    first = tune(friction_config, tmp_path, trials=3, seed=1, objective=_toy, holdout=0,
                 progress=False)  # fmt: skip
    before = [t.params for t in first.study.trials]
    resumed = tune(friction_config, tmp_path, trials=2, seed=1, objective=_toy, holdout=0,
                   progress=False)  # fmt: skip
    after = [t.params for t in resumed.study.trials[3:]]
    assert len(after) == 2 and all(p not in before for p in after)


def test_the_record_says_when_the_configs_terminal_weight_is_not_2q(friction_config):
    """Every trial runs P = 2Q with a diagonal Q: a config whose P is another multiple of
    its (diagonal) Q is told that trial 0 differs from it there; P = 2Q is not."""
    from hmpc_pin.apps.tune_space import sampler_record

    space = search_space(friction_config)
    cc = friction_config.controller
    Q = np.diag([cc.Q[0, 0], cc.Q[1, 1]])
    for P, told in ((2 * Q, False), (3 * Q, True)):
        config = replace(friction_config, controller=replace(cc, Q=Q, P=P))
        lines = sampler_record(config, space)
        assert any(line.startswith("P = 2Q") for line in lines) == told, lines


@pytest.mark.parametrize(("holdout", "seed", "expected"), [(None, 3, (8, 3)), (4, 3, (4, 3)),
                                                           (None, None, (8, 6))])  # fmt: skip
def test_a_holdout_seed_alone_is_accepted(holdout, seed, expected, friction_config):
    """--holdout-seed without --holdout (default: --samples held out) applies; only with
    --holdout 0, which draws nothing, is it refused. The default seed is --seed + 1."""
    from hmpc_pin.apps.tune import check_options

    out = check_options(friction_config, trials=1, samples=8, seed=5, jobs=1,
                        holdout=holdout, holdout_seed=seed)  # fmt: skip
    assert out == expected


def test_the_search_space_is_the_guides(friction_config):
    """The ranges the identification-and-tuning guide states, as the search space has
    them (observer gain [c0/10, 5 c0])."""
    from .conftest import ROOT

    guide = (ROOT / "docs" / "guide" / "identification-and-tuning.md").read_text()
    space = search_space(friction_config)
    for text, key, spec in (
        ("q_p ∈ [1, 10⁴]", "Q_position", ("log", 1.0, 1e4)),
        ("q_v ∈ [10⁻⁴, 10²]", "Q_velocity", ("log", 1e-4, 1e2)),
        ("R ∈ [10⁻⁸, 10⁻³]", "R", ("log", 1e-8, 1e-3)),
        ("N ∈ [5, 30]", "N", ("int", 5, 30)),
        ("[c₀/10, 5c₀]", "observer_gain", ("log", 10.0, 500.0)),  # c0 = 100
    ):
        assert text in guide, text
        assert space[key][0] == spec[0] and space[key][1:] == pytest.approx(spec[1:]), key


@pytest.mark.parametrize(
    ("observers", "first"),
    [(("momentum", "chen"), "chen"), (("momentum", "general"), "momentum")],
)
def test_trial_0_keeps_the_configs_observer_when_it_is_listed(observers, first, friction_config):
    """--observers momentum,chen on a chen config: trial 0 is the config as given (chen);
    when its observer is not listed, the first listed."""
    from hmpc_pin.apps.tune_space import current_params

    assert friction_config.controller.compensation == "chen"
    space = search_space(friction_config, observers=observers)
    assert current_params(friction_config, space)["compensation"] == first


def test_apply_params_keeps_the_configs_own_value_of_each_parameter_not_given(
    friction_config,
):
    """A partial parameter set (library use: only R) keeps every other value of the
    config: Q's diagonal as it is (each entry its own), P = 2Q."""
    cc = friction_config.controller
    Q = np.diag([400.0, 3.0])  # different entries: a mix-up of the two shows
    config = replace(friction_config, controller=replace(cc, Q=Q, P=2 * Q))
    new = apply_params(config, {"R": 1e-6}).controller
    np.testing.assert_array_equal(new.Q, Q)
    np.testing.assert_array_equal(new.P, 2 * Q)
    assert new.R == 1e-6 and new.N == cc.N and new.Ts == cc.Ts
    new = apply_params(config, {"Q_position": 50.0}).controller
    np.testing.assert_array_equal(new.Q, np.diag([50.0, 3.0]))


def test_a_study_resumed_with_another_seed_is_refused(tmp_path, friction_config):
    """The study's samples are drawn from --seed: resuming it with another seed would mix
    two sets of plants in one ranking; refused naming both options, the study untouched."""
    from hmpc_pin.exceptions import ConfigError

    tune(friction_config, tmp_path, trials=2, seed=1, objective=_toy, holdout=0, progress=False)
    with pytest.raises(ConfigError, match=r"--samples/--seed.*--seed 1"):
        tune(friction_config, tmp_path, trials=1, seed=2, objective=_toy, holdout=0,
             progress=False)  # fmt: skip
    resumed = tune(friction_config, tmp_path, trials=1, seed=1, objective=_toy, holdout=0,
                   progress=False)  # fmt: skip
    assert len(resumed.study.trials) == 3


def test_the_held_out_table_and_ratio_of_the_report(tmp_path, friction_config):
    """The report's held-out section: each config's p95 [rad], bounded share and saturation
    in percent, and the ratio shipped / tuned (4 for 0.04 rad against 0.01 rad)."""
    from hmpc_pin.apps.tune_report import write_report

    result = tune(friction_config, tmp_path, trials=2, seed=1, objective=_toy, holdout=0,
                  progress=False)  # fmt: skip

    def parts(p95, bounded, saturation):
        return {"p95_rms": p95, "bounded": bounded, "saturation": saturation, "torque_tv": 1.0}

    comparison = {"shipped": parts(0.04, 0.5, 0.25), "tuned": parts(0.01, 1.0, 0.0)}
    write_report(friction_config, result.study, result.best, tmp_path, comparison, 8, 1, 8, 2)
    report = (tmp_path / "paper_friction_tune.md").read_text()
    assert "## Held-out comparison: 8 other samples (seed 2)" in report
    assert "| shipped | 0.04 | 50 % | 25.00 % | 1 |" in report
    assert "| tuned | 0.01 | 100 % | 0.00 % | 1 |" in report
    assert "Shipped / tuned p95: 4." in report


# ------------------------------------------------------ option bounds, by value
@pytest.mark.parametrize(
    ("kwargs", "named", "words"),
    [
        ({"trials": 0}, "--trials", "expected an integer >= 1, got 0"),
        ({"samples": 0}, "--samples", "expected an integer >= 1, got 0"),
        ({"jobs": 0}, "--jobs", "expected an integer >= 1, got 0"),
        ({"seed": -1}, "--seed", "expected an integer in [0, 4294967295], got -1"),
        ({"seed": 2**32}, "--seed", "expected an integer in [0, 4294967295], got 4294967296"),
        ({"seed": 1.0}, "--seed", "got 1.0"),
        ({"trials": True}, "--trials", "got True"),
        ({"holdout": -1}, "--holdout", "expected an integer >= 0, got -1"),
        ({"holdout_seed": 2**32}, "--holdout-seed", "in [0, 4294967295], got 4294967296"),
        ({"ts": ()}, "--ts", "expected control periods [s] > 0"),
        ({"ts": (0.01, float("inf"))}, "--ts", "expected control periods [s] > 0"),
        ({"ts": (0.01, float("nan"))}, "--ts", "expected control periods [s] > 0"),
        ({"observers": ("chen", "ism")}, "--observers", "got ('chen', 'ism')"),
        ({"scheduler": "tcp://x:1", "executor": "local"}, "--scheduler", "--executor local"),
        ({"holdout": 0, "holdout_seed": 1}, "--holdout-seed", "--holdout 0"),
    ],
)
def test_check_options_names_the_option_and_the_expected_value(kwargs, named, words,
                                                               friction_config):  # fmt: skip
    from hmpc_pin.apps.tune import check_options
    from hmpc_pin.exceptions import ConfigError

    args = {"trials": 1, "samples": 2, "seed": 0, "jobs": 1, **kwargs}
    with pytest.raises(ConfigError) as info:
        check_options(friction_config, **args)
    assert info.value.key == named and words in str(info.value), str(info.value)


def test_the_bounds_of_every_option_are_accepted(friction_config):
    """The smallest trials, samples, jobs, seed 0, --holdout 0 and the largest seeds are
    valid; the held-out seed defaults to seed + 1, wrapping past 2**32 - 1 to 0."""
    from hmpc_pin.apps.tune import MAX_SEED, check_options

    args = {"trials": 1, "samples": 1, "jobs": 1}
    assert check_options(friction_config, seed=0, holdout=0, **args) == (0, 1)
    assert check_options(friction_config, seed=MAX_SEED, **args) == (1, 0)
    assert check_options(friction_config, seed=3, holdout_seed=MAX_SEED, **args) == (1, MAX_SEED)
    assert check_options(friction_config, seed=np.int64(4), **args) == (1, 5)


def test_a_config_not_from_a_file_and_a_duration_within_after_are_refused(friction_config):
    from hmpc_pin.apps.tune import check_options
    from hmpc_pin.exceptions import ConfigError

    args = {"trials": 1, "samples": 1, "seed": 0, "jobs": 1}
    with pytest.raises(ConfigError) as info:
        check_options(replace(friction_config, source=None), **args)
    assert info.value.key == "CONFIG"
    short = replace(friction_config, simulation=replace(friction_config.simulation, duration=1.0))
    with pytest.raises(ConfigError) as info:
        check_options(short, **args)
    assert info.value.key == "simulation.duration"
    assert "sweep.after = 1 s" in str(info.value) and "got 1 s" in str(info.value)
    longer = replace(short, simulation=replace(short.simulation, duration=1.01))
    assert check_options(longer, **args) == (1, 1)


# ----------------------------------------------------------------- the score
def test_run_score_clips_the_lost_share_and_the_error():
    """The share lost is in [0, 1] (a run past its duration lost nothing), no duration or
    no t_end: nothing lost; the error counts at most 10 b, a non-finite one as 10 b; a
    'bounded' run with a non-finite error is scored as not bounded."""
    from hmpc_pin.apps.tune_objective import run_score

    b = 0.5
    row = {"rms_max": 0.2, "bounded": False, "t_end": 12.0}
    assert run_score(row, b, 10.0) == pytest.approx(b + 0.2)  # past the end: lost 0
    assert run_score(dict(row, t_end=-1.0), b, 10.0) == pytest.approx(2 * b + 0.2)  # lost <= 1
    assert run_score(row, b, None) == pytest.approx(b + 0.2)
    no_t = {"rms_max": 0.2, "bounded": False}
    assert run_score(no_t, b, 10.0) == pytest.approx(b + 0.2)
    assert run_score(dict(row, rms_max=7.0, t_end=5.0), b, 10.0) == pytest.approx(1.5 * b + 5.0)
    assert run_score(dict(row, rms_max=np.nan, t_end=5.0), b, 10.0) == pytest.approx(
        1.5 * b + 5.0)  # fmt: skip
    assert run_score({"rms_max": np.inf, "bounded": True, "t_end": 10.0}, b, 10.0) == (
        pytest.approx(b + 10 * b))  # fmt: skip
    assert run_score({"rms_max": 0.3, "bounded": True, "t_end": 2.0}, b, 10.0) == 0.3


def test_the_objective_is_its_formula_on_mixed_rows(make_rng):
    """J = p95 (1 + w_s mean s + w_tv max(0, mean TV / TV0 - 1)), p95 the empirical
    quantile (the smallest score whose CDF reaches 0.95), the runs scored by run_score;
    the parts: p95, mean saturation, mean TV and the bounded share. Without TV0 (or 0)
    no TV penalty; the weights and the duration are the caller's."""
    from hmpc_pin.apps.tune_objective import run_score

    rng = make_rng(12)
    rows = [{"rms_max": float(v), "bounded": bool(k % 5), "saturation": float(s),
             "torque_tv": float(tv), "t_end": float(te)}
            for k, (v, s, tv, te) in enumerate(zip(rng.uniform(0.01, 0.3, 13),
                                                   rng.uniform(0, 0.2, 13),
                                                   rng.uniform(5, 15, 13),
                                                   rng.uniform(1, 4, 13),
                                                   strict=True))]  # fmt: skip
    scores = sorted(run_score(r, 0.4, 4.0) for r in rows)
    p95 = scores[math.ceil(0.95 * 13) - 1]
    sat = np.mean([r["saturation"] for r in rows])
    tv = np.mean([r["torque_tv"] for r in rows])
    value, parts = objective_value(rows, 0.4, tv0=6.0, saturation_weight=2.0, tv_weight=0.5,
                                   duration=4.0)  # fmt: skip
    assert value == pytest.approx(p95 * (1 + 2.0 * sat + 0.5 * max(0.0, tv / 6.0 - 1)), rel=1e-12)
    assert parts == pytest.approx({"p95_rms": p95, "saturation": sat, "torque_tv": tv,
                                   "bounded": 10 / 13}, rel=1e-12)  # fmt: skip
    for tv0 in (None, 0.0):
        assert objective_value(rows, 0.4, tv0=tv0, duration=4.0)[0] == pytest.approx(
            p95 * (1 + 1.0 * sat), rel=1e-12)  # fmt: skip


# ----------------------------------------------------------- the search space
def test_the_search_space_follows_the_controller(friction_config):
    """N only for hmpc; no observer parameter without an observer; --observers refused on
    a config without one; the periods as given."""
    from hmpc_pin.experiment.build import with_controller

    ct = with_controller(friction_config, "computed-torque-pid")
    assert set(search_space(ct)) == {"Q_position", "Q_velocity", "R"}
    none = with_controller(friction_config, "hmpc-none")
    assert set(search_space(none, ts=(0.01,))) == {"Q_position", "Q_velocity", "R", "N", "Ts"}
    assert search_space(none, ts=(0.01, 0.02))["Ts"] == ("choice", (0.01, 0.02))
    with pytest.raises(Exception, match="--observers") as info:
        search_space(none, observers=("chen",))
    assert "hmpc+none" in str(info.value)
    space = search_space(friction_config, observers=("momentum", "chen"))
    assert space["compensation"] == ("choice", ("momentum", "chen"))


def test_trial_0_is_recorded_at_the_nearest_point_of_each_range(friction_config):
    """Values above a range are clipped to its top, below to its bottom, an integer stays
    an integer."""
    from hmpc_pin.apps.tune_space import current_params

    cc = friction_config.controller
    Q = np.diag([5e4, 0.0])
    cfg = replace(friction_config, controller=replace(cc, Q=Q, P=2 * Q, R=1e-2, N=40))
    near = current_params(cfg, search_space(cfg))
    assert near["Q_position"] == 1e4 and near["Q_velocity"] == 1e-4 and near["R"] == 1e-3
    assert near["N"] == 30 and isinstance(near["N"], int)
    low = replace(cfg, controller=replace(cfg.controller, N=2, R=1e-12))
    near = current_params(low, search_space(low))
    assert near["N"] == 5 and near["R"] == 1e-8


def test_apply_params_scales_every_bandwidth_by_the_proposed_largest(tmp_path):
    from hmpc_pin.apps.tune_space import apply_params

    text = _short_config(tmp_path).read_text()
    text = text.replace('kind = "chen"', 'kind = "general"')
    text = text.replace("gain = 100.0", "bandwidth = [10.0, 15.0, 20.0]")
    path = tmp_path / "bw.toml"
    path.write_text(text)
    config = load_config(path)
    new = apply_params(config, {"observer_bandwidth": 40.0}).controller
    np.testing.assert_allclose(new.observer.bandwidth, [20.0, 30.0, 40.0], rtol=1e-15)
    new = apply_params(config, {"compensation": "momentum", "R": 1e-6}).controller
    assert new.compensation == "momentum" and new.R == 1e-6


# ------------------------------------------------ the study, the report, Ctrl-C
def _rows_of(config, samples, seed):
    """Sweep rows of a trial, a smooth function of the config's settings (the toy bowl),
    so that trials differ; `samples` rows, their saturation from the seed."""
    value = 0.01 * (1 + _toy(config)[0])
    return [{"rms_max": value * (1 + 0.1 * k), "bounded": True, "saturation": 0.01 * (seed % 3),
             "torque_tv": 10.0 + k, "t_end": config.simulation.duration}
            for k in range(samples)]  # fmt: skip


class _FakeSweep:
    """tune's `_evaluate` replaced: records (label, samples, seed) of every call and
    returns `_rows_of`; Ctrl-C at call `stop` (0-based)."""

    def __init__(self, stop=None):
        self.calls, self.stop = [], stop

    def __call__(self, config, samples, seed, jobs, executor, scheduler):
        if self.stop is not None and len(self.calls) == self.stop:
            raise KeyboardInterrupt
        self.calls.append((config, samples, seed))
        return _rows_of(config, samples, seed)


def _report_table(report: str, heading: str) -> list[dict]:
    lines = report.split(heading, 1)[1].splitlines()
    start = next(k for k, line in enumerate(lines) if line.startswith("| "))
    rows = []
    for line in lines[start:]:  # the first table after the heading
        if not line.startswith("|"):
            break
        rows.append(line)
    head = [c.strip() for c in rows[0].strip("|").split("|")]
    out = []
    for line in rows[1:]:
        if line.startswith("|---"):
            continue
        out.append(dict(zip(head, [c.strip() for c in line.strip("|").split("|")], strict=True)))
    return out


def test_the_study_and_the_held_out_comparison_through_the_command_line(tmp_path, capsys,
                                                                        monkeypatch):  # fmt: skip
    """Four trials on 3 samples (seed 5), held out on 2 samples (seed 9): each trial's
    sweep is drawn with --samples/--seed, the comparison with --holdout/--holdout-seed;
    the report's trials table holds each trial's J and p95 as the study recorded them
    (J recomputed from the rows), the held-out table each config's parts, the printed
    line their ratio."""
    from hmpc_pin.apps import tune as tune_module

    fake = _FakeSweep()
    monkeypatch.setattr(tune_module, "_evaluate", fake)
    out = tmp_path / "out"
    code = main(["tune", str(_short_config(tmp_path)), "--trials", "4", "--samples", "3",
                 "--seed", "5", "--holdout", "2", "--holdout-seed", "9", "--jobs", "1",
                 "--out", str(out), "--quiet"])  # fmt: skip
    assert code == 0
    assert [c[1:] for c in fake.calls] == [(3, 5)] * 4 + [(2, 9)] * 2
    import optuna

    study = optuna.load_study(study_name="paper_friction",
                              storage=f"sqlite:///{out / 'paper_friction_tune.db'}")  # fmt: skip
    tv0 = np.mean([r["torque_tv"] for r in _rows_of(fake.calls[0][0], 3, 5)])
    assert study.user_attrs["tv0"] == pytest.approx(tv0)
    for trial, (cfg, samples, seed) in zip(study.trials, fake.calls, strict=False):
        expected = objective_value(_rows_of(cfg, samples, seed), cfg.sweep.error_bound, tv0,
                                   duration=cfg.simulation.duration)[0]  # fmt: skip
        assert trial.value == pytest.approx(expected, rel=1e-12)
    report = (out / "paper_friction_tune.md").read_text(encoding="utf-8")
    assert report.startswith("# Tuning of paper_friction: 4 trials (4 finished)")
    assert "3 sweep samples per trial (seed 5)" in report
    trials = _report_table(report, "## Trials")
    assert [int(r["trial"]) for r in trials] == [0, 1, 2, 3]
    for row, trial in zip(trials, study.trials, strict=True):
        assert float(row["J"]) == pytest.approx(trial.value, rel=1e-3)
        assert float(row["p95 RMS [rad]"]) == pytest.approx(trial.user_attrs["p95_rms"], rel=1e-3)
        if trial.number:
            assert float(row["R"]) == pytest.approx(trial.params["R"], rel=1e-3)
            assert int(row["N"]) == trial.params["N"]
    best = study.best_trial
    assert f"Best: trial {best.number}, J = {best.value:.4g}: " in report
    # the held-out comparison: the config as given and the tuned one on 2 samples, seed 9
    shipped, tuned = fake.calls[4][0], fake.calls[5][0]
    given = load_config(_short_config(tmp_path)).controller
    for key in ("Q", "P", "R", "N", "Ts"):
        np.testing.assert_array_equal(getattr(shipped.controller, key), getattr(given, key))
    assert shipped.controller.observer.gain == given.observer.gain
    best_r = best.params["R"] if best.number else shipped.controller.R
    assert pytest.approx(best_r) == tuned.controller.R
    assert "## Held-out comparison: 2 other samples (seed 9)" in report
    held = {r["config"]: r for r in _report_table(report, "## Held-out comparison")}
    parts = {label: objective_value(_rows_of(cfg, 2, 9), cfg.sweep.error_bound, tv0,
                                    duration=cfg.simulation.duration)[1]
             for label, cfg in (("shipped", shipped), ("tuned", tuned))}  # fmt: skip
    for label, p in parts.items():
        assert float(held[label]["p95 worst RMS [rad]"]) == pytest.approx(p["p95_rms"], rel=1e-3)
        assert held[label]["bounded"] == "100 %"
        assert held[label]["saturation"] == f"{100 * p['saturation']:.2f} %" == "0.00 %"
        assert float(held[label]["torque TV [N·m/s]"]) == pytest.approx(p["torque_tv"], rel=1e-3)
    ratio = parts["shipped"]["p95_rms"] / parts["tuned"]["p95_rms"]
    assert f"Shipped / tuned p95: {ratio:.3g}." in report
    printed = capsys.readouterr().out
    assert (
        f"held-out samples: p95 worst-joint RMS {parts['shipped']['p95_rms']:.4g} rad as "
        f"given, {parts['tuned']['p95_rms']:.4g} rad tuned (ratio {ratio:.3g})"
    ) in printed
    assert f"paper_friction: 4 trials; best trial {best.number}, J = {best.value:.4g}" in printed
    for name in ("paper_friction_tuned.toml", "paper_friction_tune.db",
                 "paper_friction_tune.md", "paper_friction_tune_history.png",
                 "paper_friction_tune_importance.png"):  # fmt: skip
        assert f"wrote {out / name}" in printed, name


def test_ctrl_c_in_the_held_out_comparison_keeps_the_tuned_config(tmp_path, monkeypatch):
    """Ctrl-C during the comparison (after every trial): the tuned config and the report of
    the trials are written, without a held-out section; RunInterrupted says where and
    names the files, the study's file second."""
    from hmpc_pin.apps import tune as tune_module
    from hmpc_pin.exceptions import RunInterrupted

    config = load_config(_short_config(tmp_path))
    monkeypatch.setattr(tune_module, "_evaluate", _FakeSweep(stop=3))  # trials 0-1, shipped
    (tmp_path / "o").mkdir()
    with pytest.raises(RunInterrupted) as info:
        tune(config, tmp_path / "o", trials=2, samples=2, seed=1, holdout=2, progress=False)
    assert info.value.where == "the held-out comparison, after 2 trials"
    names = [p.name for p in info.value.files]
    assert names[:3] == ["paper_friction_tuned.toml", "paper_friction_tune.db",
                         "paper_friction_tune.md"]  # fmt: skip
    report = (tmp_path / "o" / "paper_friction_tune.md").read_text(encoding="utf-8")
    assert "Interrupted (Ctrl-C) at the held-out comparison, after 2 trials" in report
    assert "Held-out comparison" not in report and "2 trials (2 finished)" in report
    assert load_config(tmp_path / "o" / "paper_friction_tuned.toml").name == "paper_friction_tuned"


def test_ctrl_c_with_no_trial_finished_names_the_study_file_only(tmp_path, monkeypatch):
    from hmpc_pin.apps import tune as tune_module
    from hmpc_pin.exceptions import RunInterrupted

    config = load_config(_short_config(tmp_path))
    monkeypatch.setattr(tune_module, "_evaluate", _FakeSweep(stop=0))
    (tmp_path / "o").mkdir()
    with pytest.raises(RunInterrupted) as info:
        tune(config, tmp_path / "o", trials=2, samples=2, seed=1, holdout=2, progress=False)
    assert info.value.where == (
        "trial 0 of the study (0 finished; run again with the same --out to resume it): "
        "no trial finished, no config written")  # fmt: skip
    assert [p.name for p in info.value.files] == ["paper_friction_tune.db"]
    assert sorted(p.name for p in (tmp_path / "o").iterdir()) == ["paper_friction_tune.db"]


def test_a_study_resumed_with_other_samples_is_refused(tmp_path, friction_config):
    from hmpc_pin.exceptions import ConfigError

    tune(friction_config, tmp_path, trials=1, samples=4, seed=1, objective=_toy, holdout=0,
         progress=False)  # fmt: skip
    with pytest.raises(ConfigError, match=r"--samples 4 --seed 1"):
        tune(friction_config, tmp_path, trials=1, samples=5, seed=1, objective=_toy, holdout=0,
             progress=False)  # fmt: skip


def test_a_uniform_bandwidth_is_written_as_one_number_and_the_header_names_the_trial(tmp_path):
    """The tuned config of an observer given by one bandwidth for every joint writes one
    number (no gain key), and its header names the best trial, the count and J."""
    import tomllib

    text = _short_config(tmp_path).read_text()
    text = text.replace('kind = "chen"', 'kind = "general"').replace(
        "gain = 100.0", "bandwidth = 20.0"
    )
    path = tmp_path / "bw.toml"
    path.write_text(text)
    config = load_config(path)

    def prefer_40(cfg):
        w = float(np.max(cfg.controller.observer.bandwidth))
        value = (np.log10(w) - np.log10(40.0)) ** 2
        return float(value), {"p95_rms": float(value)}

    (tmp_path / "o").mkdir()
    result = tune(config, tmp_path / "o", trials=4, seed=2, objective=prefer_40, holdout=0,
                  progress=False)  # fmt: skip
    written = (tmp_path / "o" / f"{config.name}_tuned.toml").read_text(encoding="utf-8")
    obs = tomllib.loads(written)["controller"]["observer"]
    assert "gain" not in obs and isinstance(obs["bandwidth"], float)
    assert obs["bandwidth"] == pytest.approx(result.best["observer_bandwidth"])
    best = result.study.best_trial
    assert f"(trial {best.number} of 4, objective {best.value:.4g})" in written


def test_a_ctrl_c_during_a_database_write_waits_for_the_write(tmp_path, friction_config,
                                                             monkeypatch):  # fmt: skip
    """SIGINT while trial 2's results are written to the study (Optuna's SQLite storage):
    the write completes (trial 2 finished) and the study stops at the next trial, which
    is recorded as failed; raised inside the write, it left the database locked or
    Optuna's state half-updated (a traceback, exit 1)."""
    import os
    import signal

    import optuna

    from hmpc_pin.exceptions import RunInterrupted

    original = optuna.trial.Trial.set_user_attr

    def interrupted_write(self, key, value):
        if self.number == 2 and key == "p95_rms":
            os.kill(os.getpid(), signal.SIGINT)  # delivered within this call
        return original(self, key, value)

    monkeypatch.setattr(optuna.trial.Trial, "set_user_attr", interrupted_write)
    with pytest.raises(RunInterrupted) as info:
        tune(friction_config, tmp_path, trials=10, seed=5, objective=_toy, holdout=0,
             progress=False)  # fmt: skip
    assert info.value.where.startswith("trial 3 of the study (3 finished"), info.value.where
    storage = f"sqlite:///{tmp_path / 'paper_friction_tune.db'}"
    study = optuna.load_study(study_name="paper_friction", storage=storage)
    states = [t.state.name for t in study.trials]
    assert states == ["COMPLETE"] * 3 + ["FAIL"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # restored


def test_a_ctrl_c_kept_back_is_raised_at_the_next_evaluation_or_check():
    import os
    import signal

    from hmpc_pin._startup import DeferredInterrupt

    with DeferredInterrupt() as sigint:
        os.kill(os.getpid(), signal.SIGINT)
        assert sigint.pending  # kept back, not raised
        with pytest.raises(KeyboardInterrupt):
            sigint.evaluating(lambda: pytest.fail("ran after a kept-back Ctrl-C"))
    with DeferredInterrupt() as sigint:
        with pytest.raises(KeyboardInterrupt):
            sigint.evaluating(os.kill, os.getpid(), signal.SIGINT)  # at once, inside
        assert not sigint.pending
        assert sigint.evaluating(lambda x: 2 * x, 4) == 8
        sigint.check()  # nothing kept back: no raise
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
