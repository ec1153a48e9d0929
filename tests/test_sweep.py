"""Determinism (issue 7, item 3) and the Monte Carlo sweep (item 4)."""

from __future__ import annotations

import csv
import io
import math
from dataclasses import replace

import numpy as np
import pytest

import hmpc_pin
from hmpc_pin.apps.cli import main
from hmpc_pin.apps.sweep import (
    draw_samples,
    resolve_variants,
    run_sample,
    run_sweep,
    variant_config,
)
from hmpc_pin.controllers.wrappers import MeasuredController

from .conftest import CONFIGS

COMBINED = CONFIGS / "paper_combined.toml"


@pytest.fixture(scope="module")
def short_config():
    """The default sweep of the paper's combined scenario, 1.5 s per run."""
    cfg = hmpc_pin.load_config(COMBINED)
    return replace(cfg, simulation=replace(cfg.simulation, duration=1.5))


# ------------------------------------------------------------------- determinism
def test_same_config_saves_bit_identical_files(tmp_path):
    files = []
    for run in ("a", "b"):
        out = tmp_path / run
        assert main(["run", str(COMBINED), "--out", str(out), "--duration", "1.2"]) == 0
        files.append({p.name: p.read_bytes() for p in out.glob("paper_combined.*")})
    assert set(files[0]) == {"paper_combined.npz", "paper_combined.csv"}
    assert files[0] == files[1]


@pytest.fixture(scope="module")
def local_serial(short_config):
    return run_sweep(short_config, 3, seed=7, jobs=1, progress=False)


def test_sweep_is_identical_with_one_or_two_jobs(short_config, local_serial):
    parallel = run_sweep(short_config, 3, seed=7, jobs=2, progress=False)
    assert parallel.csv_text() == local_serial.csv_text()


def test_dask_executor_on_a_local_cluster_matches_local(short_config, local_serial):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster:
        result = run_sweep(
            short_config, 3, seed=7, executor="dask", scheduler=cluster.scheduler_address,
            progress=False,
        )  # fmt: skip
    assert result.csv_text() == local_serial.csv_text()


def test_sample_draws_do_not_depend_on_the_sample_count(short_config):
    assert draw_samples(short_config, 5, seed=3)[:2] == draw_samples(short_config, 2, seed=3)
    assert draw_samples(short_config, 2, seed=3) != draw_samples(short_config, 2, seed=4)


# ------------------------------------------------------------------------- sweep
def test_sweep_rows_and_summary(local_serial, short_config):
    rows = local_serial.rows
    assert [(r["sample"], r["variant"]) for r in rows] == [
        (i, v) for i in range(3) for v in ("ndo", "no-ndo")
    ]
    sc = short_config.sweep
    for r in rows:
        for key in ("mass_1", "mass_2", "mass_3"):
            assert sc.mass[0] <= r[key] <= sc.mass[1]
        for j in ("joint1", "joint2", "joint3"):
            assert sc.friction[0] <= r[f"friction_{j}"] <= sc.friction[1]
            assert sc.disturbance[0] <= r[f"disturbance_{j}"] <= sc.disturbance[1]
        assert r["complete"] and r["bounded"] and r["t_end"] == pytest.approx(1.5)
        assert r["rms_max"] == max(r[f"rms_joint{i}"] for i in (1, 2, 3))
    # the same draws for both variants of a sample (common random numbers)
    for ndo, no in zip(rows[0::2], rows[1::2], strict=True):
        assert {
            k: v for k, v in ndo.items() if k.startswith(("mass", "fric", "dist", "noise"))
        } == {k: v for k, v in no.items() if k.startswith(("mass", "fric", "dist", "noise"))}
    s = local_serial.summary()
    assert s["ndo"]["bounded"] == 1.0 and s["ndo"]["median_rms"] < 1e-2
    assert s["no-ndo"]["median_rms"] > 3 * s["ndo"]["median_rms"]  # the NDO matters
    md = local_serial.summary_markdown()
    assert "| ndo | 3 | 100.0 % |" in md and "| no-ndo | 3 |" in md


def test_run_sample_perturbs_the_plant_only(short_config):
    """A sample with every factor 1 and no noise or delay is the nominal run."""
    cfg = replace(
        short_config, sweep=replace(short_config.sweep, q_noise=0.0, dq_noise=0.0, delay=0)
    )
    params = draw_samples(cfg, 1, seed=0)[0]
    ones = replace(params, mass=(1.0,) * 3, friction=(1.0,) * 3, disturbance=(1.0,) * 3)
    nominal = hmpc_pin.compute_metrics(hmpc_pin.run_experiment(cfg, observer=True))
    row = run_sample(cfg, ones, "ndo")
    np.testing.assert_array_equal([row[f"rms_joint{i}"] for i in (1, 2, 3)], nominal.rms_error)
    heavier = run_sample(cfg, replace(ones, mass=(1.2,) * 3), "ndo")
    assert heavier["rms_max"] != row["rms_max"]


def test_cli_sweep_writes_csv_and_summary(tmp_path, capsys):
    out = tmp_path / "sw"
    argv = ["sweep", str(COMBINED), "--samples", "2", "--seed", "1", "--jobs", "1"]
    assert main([*argv, "--duration", "1.2", "--out", str(out), "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "| ndo | 2 |" in printed and "paper_combined_sweep.csv" in printed
    with open(out / "paper_combined_sweep.csv", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 4 and rows[0]["variant"] == "ndo" and rows[1]["variant"] == "no-ndo"
    assert (out / "paper_combined_sweep.md").read_text().startswith("# Sweep of paper_combined")
    assert not list(out.glob("*.part"))


def test_csv_floats_round_trip_exactly(local_serial):
    rows = list(csv.DictReader(io.StringIO(local_serial.csv_text())))
    assert [float(r["rms_max"]) for r in rows] == [r["rms_max"] for r in local_serial.rows]


# ---------------------------------------------------------------- measurement model
class Recorder:
    """A stand-in controller recording what it is given (duck-typed interface)."""

    Ts = 0.01
    disturbance_estimate = np.zeros(2)

    def reset(self, q0, dq0):
        self.seen = [("reset", q0.copy(), dq0.copy())]

    def step(self, t, q, dq, reference):
        self.seen.append((t, q.copy(), dq.copy()))
        return np.zeros(2)


def test_one_step_delay_and_noise():
    rec = Recorder()
    ctrl = MeasuredController(rec, q_noise=1e-3, dq_noise=0.0, delay=1,
                              rng=np.random.default_rng(0))  # fmt: skip
    states = [np.array([k, -k], float) for k in range(4)]
    ctrl.reset(states[0], np.zeros(2))
    for k, q in enumerate(states):
        ctrl.step(0.01 * k, q, np.zeros(2), None)
    seen_q = [s[1] for s in rec.seen[1:]]
    # step 0 and 1 see the state of step 0; step k sees step k-1
    for k, q in enumerate(seen_q):
        np.testing.assert_allclose(q, states[max(k - 1, 0)], atol=5e-3)
        assert not np.array_equal(q, states[max(k - 1, 0)])  # noisy
    np.testing.assert_array_equal(seen_q[0], seen_q[1])  # the same measurement, not redrawn
    assert all(np.array_equal(s[2], np.zeros(2)) for s in rec.seen)  # σ_q̇ = 0
    assert ctrl.Ts == 0.01 and ctrl.disturbance_estimate is rec.disturbance_estimate


def test_noise_level_matches_sigma():
    rec = Recorder()
    ctrl = MeasuredController(rec, q_noise=1e-3, dq_noise=1e-2, rng=np.random.default_rng(5))
    ctrl.reset(np.zeros(2), np.zeros(2))
    for k in range(4000):
        ctrl.step(0.01 * k, np.zeros(2), np.zeros(2), None)
    q = np.array([s[1] for s in rec.seen[1:]])
    dq = np.array([s[2] for s in rec.seen[1:]])
    assert q.std() == pytest.approx(1e-3, rel=0.05) and dq.std() == pytest.approx(1e-2, rel=0.05)


def test_scaled_inertias_scale_the_dynamics(planar3, make_rng):
    q = make_rng(2).uniform(-1, 1, 3)
    k = np.array([0.8, 1.0, 1.2])
    scaled = planar3.with_scaled_inertias(k)
    # link 3 alone: its mass scales the last diagonal term of M by its factor
    single = planar3.with_scaled_inertias([1.0, 1.0, 1.2])
    assert single.mass_matrix(q)[2, 2] == pytest.approx(1.2 * planar3.mass_matrix(q)[2, 2])
    uniform = planar3.with_scaled_inertias([1.1] * 3)
    np.testing.assert_allclose(uniform.mass_matrix(q), 1.1 * planar3.mass_matrix(q), rtol=1e-12)
    np.testing.assert_allclose(uniform.gravity_torque(q), 1.1 * planar3.gravity_torque(q))
    assert scaled.model is not planar3.model  # a copy: the original is untouched
    assert planar3.model.inertias[1].mass == 1.5
    with pytest.raises(hmpc_pin.DimensionError):
        planar3.with_scaled_inertias([1.0, 1.0])


def test_sweep_per_controller_shares_draws_and_matches_the_named_variants(tmp_path, capsys):
    """Issue 8, item 4: `--controllers` sweeps controller kinds on the same perturbed
    plants; `hmpc`/`hmpc-none` on the paper config are the `ndo`/`no-ndo` variants."""
    out = tmp_path / "swc"
    argv = ["sweep", str(COMBINED), "--samples", "2", "--seed", "3", "--jobs", "1", "--quiet",
            "--duration", "1.5", "--out", str(out),
            "--controllers", "hmpc,hmpc-none,hmpc-ism-bl,computed-torque"]  # fmt: skip
    assert main(argv) == 0
    printed = capsys.readouterr().out
    for kind in ("hmpc", "hmpc-none", "hmpc-ism-bl", "computed-torque"):
        assert f"| {kind} | 2 |" in printed
    with open(out / "paper_combined_sweep.csv", encoding="utf-8") as f:
        rows = {(r["sample"], r["variant"]): r for r in csv.DictReader(f)}
    cfg = hmpc_pin.load_config(COMBINED)
    cfg = replace(cfg, simulation=replace(cfg.simulation, duration=1.5))
    params = draw_samples(cfg, 2, seed=3)
    for p in params:
        for kind, named in (("hmpc", "ndo"), ("hmpc-none", "no-ndo")):
            row = run_sample(cfg, p, named)
            assert float(rows[(str(p.index), kind)]["rms_max"]) == row["rms_max"]
    assert main([*argv[:-1], "hmpc,lqr"]) == 2
    assert main([*argv[:-1], "hmpc,hmpc+chen"]) == 2  # the same pair twice on this config
    assert "same controller (hmpc+chen)" in capsys.readouterr().err


# ---------------------------------------------------------------------- variants
def _variants(config, variants):
    return replace(config, sweep=replace(config.sweep, variants=variants))


NO_NDO = CONFIGS / "paper_combined_no_ndo.toml"


def test_variants_default_to_the_configs_pair_and_the_same_controller_without():
    combined = hmpc_pin.load_config(COMBINED)
    assert combined.sweep.variants == ("ndo", "no-ndo")  # written in the file
    assert resolve_variants(_variants(combined, None)) == ("hmpc+chen", "hmpc+none")
    no_ndo = hmpc_pin.load_config(NO_NDO)
    assert no_ndo.sweep.variants is None and no_ndo.controller.compensation == "none"
    assert resolve_variants(no_ndo) == ("hmpc+none",)  # no compensation: nothing to drop
    ism = hmpc_pin.with_controller(combined, "hmpc-ism")
    assert resolve_variants(_variants(ism, None)) == ("hmpc+ism", "hmpc+none")


def test_variant_names_give_controller_and_compensation():
    combined = hmpc_pin.load_config(COMBINED)
    assert variant_config(combined, "ndo") is combined
    for variant, label in (
        ("no-ndo", "hmpc+none"),
        ("hmpc+momentum", "hmpc+momentum"),
        ("hmpc-ism-bl", "hmpc+ism-bl"),
        ("computed-torque", "computed-torque+none"),
        ("computed-torque-pid+chen", "computed-torque-pid+chen"),
    ):
        assert variant_config(combined, variant).controller.label == label, variant
    mixed = ("hmpc+momentum", "computed-torque", "no-ndo")
    assert resolve_variants(_variants(combined, mixed)) == mixed


@pytest.mark.parametrize(
    ("config", "variants", "words"),
    [
        (NO_NDO, ("ndo",), "'ndo' is the config's controller with its observer"),
        (NO_NDO, ("hmpc-none", "no-ndo"), "same controller (hmpc+none)"),
        (COMBINED, ("ndo", "hmpc"), "same controller (hmpc+chen)"),
        (COMBINED, ("no-ndo", "hmpc-none"), "same controller (hmpc+none)"),
        (COMBINED, ("hmpc+momentum", "hmpc-momentum"), "same controller (hmpc+momentum)"),
        (COMBINED, ("ndo", "magic"), "unknown controller 'magic'"),
    ],
)
def test_bad_variants_are_config_errors(config, variants, words):
    cfg = _variants(hmpc_pin.load_config(config), variants)
    for call in (lambda: resolve_variants(cfg), lambda: run_sweep(cfg, 1, progress=False)):
        with pytest.raises(hmpc_pin.ConfigError) as info:
            call()
        assert info.value.key == "sweep.variants", str(info.value)
        assert words in str(info.value) and str(config) in str(info.value), str(info.value)


def test_ndo_on_an_ism_config_is_an_error():
    ism = hmpc_pin.with_controller(hmpc_pin.load_config(COMBINED), "hmpc-ism")
    with pytest.raises(hmpc_pin.ConfigError, match="'ndo' is the config's controller"):
        variant_config(ism, "ndo")
    assert variant_config(ism, "no-ndo").controller.label == "hmpc+none"


def test_default_variants_run_under_their_labels(short_config):
    cfg = _variants(short_config, None)
    result = run_sweep(cfg, 1, seed=7, jobs=1, progress=False)
    assert result.config.sweep.variants == ("hmpc+chen", "hmpc+none")
    assert [r["variant"] for r in result.rows] == ["hmpc+chen", "hmpc+none"]
    # the same pairs as the named variants ndo / no-ndo, bit for bit
    params = draw_samples(short_config, 1, seed=7)[0]
    for label, named in (("hmpc+chen", "ndo"), ("hmpc+none", "no-ndo")):
        row = run_sample(short_config, params, named)
        assert result.variant_rows(label)[0]["rms_max"] == row["rms_max"]


def test_conditions_perturb_what_they_name(short_config):
    """The interface model (no 0.3 keys): "plant" with unit factors is the nominal run;
    "sensing" and "latency" keep the nominal plant and change the measurement; "all"
    differs from each; every row names its condition."""
    from hmpc_pin.experiment.config.sweep import SweepConfig

    cfg = replace(short_config, sweep=SweepConfig(variants=("ndo",)))
    params = draw_samples(cfg, 1, seed=0)[0]
    ones = replace(params, mass=(1.0,) * 3, friction=(1.0,) * 3, disturbance=(1.0,) * 3)
    nominal = hmpc_pin.compute_metrics(hmpc_pin.run_experiment(cfg, observer=True))
    rows = {c: run_sample(cfg, ones, "ndo", c) for c in ("sensing", "latency", "plant", "all")}
    np.testing.assert_array_equal(
        [rows["plant"][f"rms_joint{i}"] for i in (1, 2, 3)], nominal.rms_error
    )
    assert all(rows[c]["condition"] == c for c in rows)
    values = {c: rows[c]["rms_max"] for c in rows}
    assert len(set(values.values())) == 4  # each condition changes something
    drawn = run_sample(cfg, params, "ndo", "sensing")  # the draws do not enter "sensing"
    assert drawn["rms_max"] == rows["sensing"]["rms_max"]


def test_interface_rate_must_divide_the_period_before_any_run(short_config):
    from hmpc_pin.exceptions import ConfigError
    from hmpc_pin.experiment.config.sensing import SensingConfig
    from hmpc_pin.experiment.config.sweep import SweepConfig

    cfg = replace(short_config, sweep=SweepConfig(sensing=SensingConfig(rate=250.0)))
    with pytest.raises(ConfigError, match="interface periods"):
        run_sweep(cfg, 1, progress=False)


def test_hmpc_is_told_the_latency_plus_the_whole_period_delay_in_seconds(short_config):
    """With ``known_latency`` the hmpc variants compensate the interface's latency plus its
    ``delay`` whole control periods: L = latency + delay Ts [s], under the conditions
    that model timing only."""
    from hmpc_pin.apps.sweep import _told_latency
    from hmpc_pin.experiment.config.sensing import SensingConfig

    Ts = short_config.controller.Ts
    sensing = SensingConfig(latency=0.002, delay=3)
    sweep = replace(short_config.sweep, sensing=sensing, q_noise=None, dq_noise=None, delay=None)
    cfg = replace(short_config, sweep=sweep)
    for condition, expected in (("all", 0.002 + 3 * Ts), ("latency", 0.002 + 3 * Ts),
                                ("plant", short_config.controller.latency)):  # fmt: skip
        told = _told_latency(cfg, condition).controller.latency
        assert told == pytest.approx(expected, rel=1e-12) if expected else not told


def test_a_run_that_stopped_early_is_not_bounded_however_small_its_error(short_config):
    """Bounded means completed and max |e| <= error_bound: a run that diverged and stopped
    (its explicit observer with the gain c = 3/Ts, far outside its stable range) is not
    bounded even under an error bound it never reached."""
    cc = short_config.controller
    obs = replace(cc.observer, gain=3.0 / cc.Ts, discretization="explicit")
    cfg = replace(short_config, controller=replace(cc, observer=obs),
                  sweep=replace(short_config.sweep, error_bound=1e12, after=0.0))  # fmt: skip
    row = run_sample(cfg, draw_samples(cfg, 1, 0)[0], "ndo", "plant")
    assert not row["complete"] and row["t_end"] < 1.5
    assert np.isfinite(row["max_error"]) and row["max_error"] < 1e12
    assert row["bounded"] is False


def test_saturation_is_the_share_of_periods_with_any_joint_clipped():
    """A period counts when the plant clipped the torque of some joint (not all of them):
    10 periods, joint 2 clipped in periods 2 and 5, every joint in period 7 -> 3/10; the
    total variation per second from the commanded torques' differences."""
    from types import SimpleNamespace

    from hmpc_pin.apps.sweep import torque_effort

    t = np.linspace(0.0, 0.9, 10)
    tau = np.outer(np.arange(10.0), [1.0, -2.0, 0.5])
    applied = tau.copy()
    applied[[2, 5], 1] = 0.0
    applied[7] = 0.0
    effort = torque_effort(SimpleNamespace(t=t, tau=tau, tau_applied=applied))
    assert effort["saturation"] == pytest.approx(0.3)
    assert effort["torque_tv"] == pytest.approx(9 * (1.0 + 2.0 + 0.5) / 0.9)


def test_a_sample_is_finished_when_every_variant_ran_under_every_condition(short_config):
    """Two variants under two conditions: a sample is finished with its 4 runs, not with
    3; the interrupted summary counts samples and runs so."""
    from hmpc_pin.apps.sweep import SweepResult

    sweep = replace(short_config.sweep, variants=("hmpc+chen", "hmpc+none"),
                    conditions=("sensing", "all"))  # fmt: skip
    cfg = replace(short_config, sweep=sweep)
    rows = [{"sample": 0}] * 4 + [{"sample": 1}] * 3
    result = SweepResult(cfg, 2, 0, rows, interrupted=True)
    assert result.planned_runs == 8 and result.finished_samples == 1
    assert "1 of 2 samples finished (7 of 8 runs)" in result._interrupted_lines()[0]


# ------------------------------------------------------- options refused by name
@pytest.mark.parametrize(
    ("flags", "named", "expected"),
    [
        (["--jobs", "0"], "--jobs", "an integer >= 1, got 0"),
        (["--samples", "0"], "--samples", "an integer >= 1, got 0"),
        (["--samples", "-3"], "--samples", "an integer >= 1, got -3"),
        (["--seed", "-1"], "--seed", "an integer >= 0, got -1"),
        (["--scheduler", "tcp://localhost:1"], "--scheduler", "--executor dask only"),
    ],
)
def test_each_sweep_option_is_refused_by_its_own_name_before_out_exists(
    flags, named, expected, tmp_path, capsys
):
    """Exit 2, one line naming the option and what was expected, and no --out folder."""
    out = tmp_path / "never"
    argv = ["sweep", str(COMBINED), "--samples", "1", "--jobs", "1", "--quiet", *flags]
    assert main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith(f"error: {named}:"), err
    assert expected in err, err
    assert not out.exists()


def test_dask_without_the_extra_is_refused_before_out_exists(tmp_path, capsys, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "dask.distributed", None)  # as if not installed
    out = tmp_path / "never"
    argv = ["sweep", str(COMBINED), "--samples", "1", "--executor", "dask", "--quiet"]
    assert main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: --executor:") and "hmpc_pin[cluster]" in err, err
    assert not out.exists()


@pytest.mark.parametrize(
    ("kwargs", "named"),
    [
        ({"samples": 0}, "--samples"),
        ({"samples": 1.0}, "--samples"),
        ({"samples": True}, "--samples"),
        ({"seed": -1}, "--seed"),
        ({"jobs": 0}, "--jobs"),
        ({"executor": "ray"}, "--executor"),
        ({"scheduler": "tcp://x:1"}, "--scheduler"),
    ],
)
def test_run_sweep_refuses_bad_options_by_name(kwargs, named, short_config):
    args = {"samples": 1, "seed": 0, "jobs": 1, **kwargs}
    with pytest.raises(hmpc_pin.ConfigError) as info:
        run_sweep(short_config, args.pop("samples"), args.pop("seed"), progress=False, **args)
    assert info.value.key == named, str(info.value)


def test_the_smallest_options_are_accepted(short_config):
    """--samples 1, --seed 0, --jobs 1: the lower bounds themselves are valid."""
    from hmpc_pin.apps.sweep import check_options

    cfg = check_options(short_config, 1, 0, jobs=1)
    assert cfg.sweep.variants == ("ndo", "no-ndo")


# ------------------------------------------------------------------ the draws
def _ranges(config, mass, friction, disturbance):
    sweep = replace(config.sweep, mass=mass, friction=friction, disturbance=disturbance)
    return replace(config, sweep=sweep)


def test_draws_follow_the_documented_seed_sequence(short_config):
    """Sample i: SeedSequence(seed).spawn(K)[i], n mass factors on U(mass), then n friction
    factors on U(friction), n pulse factors on U(disturbance), then the noise seed; three
    disjoint ranges so that a range read for another shows."""
    cfg = _ranges(short_config, (0.7, 0.9), (1.5, 1.6), (2.0, 3.0))
    params = draw_samples(cfg, 4, seed=11)
    assert [p.index for p in params] == [0, 1, 2, 3]
    for p, child in zip(params, np.random.SeedSequence(11).spawn(4), strict=True):
        rng = np.random.default_rng(child)
        np.testing.assert_allclose(p.mass, 0.7 + 0.2 * rng.random(3), rtol=1e-15)
        np.testing.assert_allclose(p.friction, 1.5 + 0.1 * rng.random(3), rtol=1e-15)
        np.testing.assert_allclose(p.disturbance, 2.0 + 1.0 * rng.random(3), rtol=1e-15)
        assert p.noise_seed == int(rng.integers(0, 2**63 - 1))
        assert all(0.7 <= m < 0.9 for m in p.mass) and all(1.5 <= f < 1.6 for f in p.friction)
        assert all(2.0 <= d < 3.0 for d in p.disturbance)


def test_a_range_of_one_value_draws_it_and_keeps_the_other_draws(short_config):
    """[1, 1] draws exactly 1.0, and the noise seed does not move with the ranges."""
    fixed = draw_samples(_ranges(short_config, (1.0, 1.0), (1.0, 1.0), (1.0, 1.0)), 3, 5)
    drawn = draw_samples(_ranges(short_config, (0.5, 2.0), (0.5, 2.0), (0.5, 2.0)), 3, 5)
    for f, d in zip(fixed, drawn, strict=True):
        assert f.mass == f.friction == f.disturbance == (1.0, 1.0, 1.0)
        assert f.noise_seed == d.noise_seed and d.mass != f.mass


def test_perturbed_config_scales_friction_pulses_and_the_mujoco_joints():
    """Per joint: viscous and Coulomb friction by the friction factor, the pulse amplitude
    by the disturbance factor, MuJoCo's frictionloss and damping by the friction factor;
    nothing else."""
    from hmpc_pin.apps.sweep import SampleParams, perturbed_config

    fr, dist = (0.5, 2.0, 3.0), (1.5, 0.25, 4.0)
    p = SampleParams(0, (1.1, 1.2, 1.3), fr, dist, 7)
    cfg = hmpc_pin.load_config(COMBINED)
    new = perturbed_config(cfg, p)
    assert new.controller == cfg.controller and new.plant == cfg.plant
    old_f, new_f = cfg.disturbance.friction, new.disturbance.friction
    np.testing.assert_allclose(new_f.viscous, np.multiply(fr, old_f.viscous), rtol=1e-15)
    np.testing.assert_allclose(new_f.coulomb, np.multiply(fr, old_f.coulomb), rtol=1e-15)
    old_p, new_p = cfg.disturbance.pulse, new.disturbance.pulse
    np.testing.assert_allclose(new_p.amplitude, np.multiply(dist, old_p.amplitude), rtol=1e-15)
    cfg = hmpc_pin.load_config(CONFIGS / "paper_combined_mujoco.toml")
    new = perturbed_config(cfg, p)
    old_m, new_m = cfg.plant.mujoco, new.plant.mujoco
    assert old_m is not None
    for key in ("frictionloss", "damping"):
        expected = np.multiply(fr, np.broadcast_to(getattr(old_m, key), (3,)))
        np.testing.assert_allclose(np.broadcast_to(getattr(new_m, key), (3,)), expected)
    assert new.controller == cfg.controller and new.robot == cfg.robot


# ------------------------------------------------------------ one sample's row
def test_a_rows_numbers_are_those_of_its_run(short_config):
    """Under "plant" with unit factors a row is the nominal run's: recomputed here from the
    run with numpy (RMS per joint and max |e| over t >= after, the worst joint, t_end,
    saturation and torque TV); after = 0.4 s, not the default, so that the window is the
    config's. Bounded is max |e| <= error_bound, the bound itself included."""
    from hmpc_pin.experiment.build import Experiment

    cfg = replace(short_config, sweep=replace(short_config.sweep, after=0.4))
    params = draw_samples(cfg, 1, seed=2)[0]
    ones = replace(params, mass=(1.0,) * 3, friction=(1.0,) * 3, disturbance=(1.0,) * 3)
    result = Experiment.from_config(cfg).run()
    keep = result.t >= 0.4 - 1e-12
    e = result.error[keep]
    rms = np.sqrt((e**2).mean(axis=0))
    row = run_sample(cfg, ones, "ndo", "plant")
    np.testing.assert_array_equal([row[f"rms_joint{i}"] for i in (1, 2, 3)], rms)
    assert row["rms_max"] == rms.max() and row["max_error"] == np.abs(e).max()
    assert row["t_end"] == result.t[-1] == pytest.approx(1.5) and row["complete"] is True
    assert row["message"] == "" and row["sample"] == 0 and row["variant"] == "ndo"
    assert row["condition"] == "plant" and row["noise_seed"] == params.noise_seed
    assert (row["mass_1"], row["friction_joint2"], row["disturbance_joint3"]) == (1.0,) * 3
    clipped = np.any(result.tau != result.tau_applied, axis=1)
    assert row["saturation"] == pytest.approx(clipped.mean(), abs=1e-15)
    tv = np.abs(np.diff(result.tau, axis=0)).sum() / (result.t[-1] - result.t[0])
    assert row["torque_tv"] == pytest.approx(tv, rel=1e-12)
    # bounded: the bound itself is inside, the next float below it is not
    bound = row["max_error"]
    at = replace(cfg, sweep=replace(cfg.sweep, error_bound=bound))
    below = replace(cfg, sweep=replace(cfg.sweep, error_bound=float(np.nextafter(bound, 0))))
    assert run_sample(at, ones, "ndo", "plant")["bounded"] is True
    assert run_sample(below, ones, "ndo", "plant")["bounded"] is False


def test_the_draws_are_written_per_link_and_per_joint(short_config):
    params = draw_samples(_ranges(short_config, (0.7, 0.9), (1.5, 1.6), (2.0, 3.0)), 2, 4)[1]
    row = run_sample(short_config, params, "no-ndo", "sensing")
    assert [row[f"mass_{i}"] for i in (1, 2, 3)] == list(params.mass)
    assert [row[f"friction_joint{i}"] for i in (1, 2, 3)] == list(params.friction)
    assert [row[f"disturbance_joint{i}"] for i in (1, 2, 3)] == list(params.disturbance)
    assert row["sample"] == 1 and row["variant"] == "no-ndo"


def test_an_unknown_condition_is_refused(short_config):
    params = draw_samples(short_config, 1, 0)[0]
    with pytest.raises(hmpc_pin.ConfigError, match="condition"):
        run_sample(short_config, params, "ndo", "everything")


def test_the_legacy_keys_apply_noise_under_sensing_and_the_delay_under_latency(short_config):
    """With the 0.3 keys (noise σ and a delay in periods), "latency" is the delay alone
    (the run with noise 0 and the delay under "all"), "sensing" the noise alone (the run
    with delay 0 under "all", the same noise sequence), "plant" neither (the nominal run);
    unit factors, so that "all" draws no plant."""

    def with_keys(q, dq, delay):
        return replace(short_config, sweep=replace(short_config.sweep, q_noise=q,
                                                   dq_noise=dq, delay=delay))  # fmt: skip

    cfg = with_keys(1e-3, 1e-2, 2)
    params = draw_samples(cfg, 1, seed=9)[0]
    ones = replace(params, mass=(1.0,) * 3, friction=(1.0,) * 3, disturbance=(1.0,) * 3)

    def rms(config, condition):
        row = run_sample(config, ones, "ndo", condition)
        return [row[f"rms_joint{i}"] for i in (1, 2, 3)]

    assert rms(cfg, "latency") == rms(with_keys(0.0, 0.0, 2), "all")
    assert rms(cfg, "sensing") == rms(with_keys(1e-3, 1e-2, 0), "all")
    assert rms(cfg, "plant") == rms(with_keys(0.0, 0.0, 0), "all")
    assert len({tuple(rms(cfg, c)) for c in ("latency", "sensing", "plant", "all")}) == 4


def test_the_0_3_keys_tell_hmpc_no_latency():
    """Only the interface model tells hmpc its latency; with the 0.3 keys, or without
    known_latency, or for another controller, the config is unchanged."""
    from hmpc_pin.apps.sweep import _told_latency
    from hmpc_pin.experiment.config.sensing import SensingConfig

    cfg = hmpc_pin.load_config(COMBINED)
    assert cfg.sweep.legacy
    assert _told_latency(cfg, "all") is cfg
    modern = replace(cfg, sweep=replace(cfg.sweep, q_noise=None, dq_noise=None, delay=None,
                                        sensing=SensingConfig(latency=0.003)))  # fmt: skip
    told = _told_latency(modern, "all").controller.latency
    assert told == pytest.approx(0.003, rel=1e-12)
    assert _told_latency(modern, "sensing") is modern
    unknown = replace(modern, sweep=replace(modern.sweep, known_latency=False))
    assert _told_latency(unknown, "all") is unknown
    ct = hmpc_pin.with_controller(modern, "computed-torque")
    assert _told_latency(ct, "all") is ct


# -------------------------------------------------------------- the summary
def _row(sample, variant, condition, rms, bounded, max_error=None):
    return {"sample": sample, "variant": variant, "condition": condition, "rms_max": rms,
            "bounded": bounded, "max_error": 2 * rms if max_error is None else max_error,
            "message": "" if bounded else f"stopped {sample}"}  # fmt: skip


def _oracle(rows, target):
    """Runs, bounded share, pass share, empirical median / p95 (the smallest value whose
    empirical CDF reaches the level), worst RMS and its row, from the definitions."""
    rms = [r["rms_max"] if r["bounded"] else math.inf for r in rows]
    ordered = sorted(rms)
    n = len(rms)
    worst = max(range(n), key=lambda k: (rms[k], -k))  # the first of the largest
    return {
        "runs": n,
        "bounded": sum(r["bounded"] for r in rows) / n,
        "pass": sum(v <= target for v in rms) / n,
        "median_rms": ordered[math.ceil(0.5 * n) - 1],
        "p95_rms": ordered[math.ceil(0.95 * n) - 1],
        "worst_rms": rms[worst],
        "worst_sample": rows[worst]["sample"],
        "worst_max_error": rows[worst]["max_error"],
        "worst_message": rows[worst]["message"],
    }


def _summary_rows(short_config, make_rng):
    """Seven samples × two variants × two conditions, one run of each variant not bounded
    under "all", one RMS exactly at the target."""
    rng = make_rng(4)
    target = short_config.sweep.rms_target
    rows = []
    for s in range(7):
        for v in ("ndo", "no-ndo"):
            for c in ("sensing", "all"):
                rms = float(rng.uniform(0.2, 3.0) * target)
                bounded = not (c == "all" and s == (2 if v == "ndo" else 5))
                rows.append(_row(s, v, c, target if (s, v, c) == (3, "ndo", "sensing")
                                 else rms, bounded))  # fmt: skip
    return rows


def test_the_summary_is_the_definitions_applied_to_the_rows(short_config, make_rng):
    from hmpc_pin.apps.sweep import SweepResult

    sweep = replace(short_config.sweep, variants=("ndo", "no-ndo"), conditions=("sensing", "all"))
    cfg = replace(short_config, sweep=sweep)
    rows = _summary_rows(cfg, make_rng)
    result = SweepResult(cfg, 7, 3, rows)
    for condition in ("sensing", "all"):
        got = result.summary(condition)
        assert list(got) == ["ndo", "no-ndo"]
        for v in got:
            part = [r for r in rows if r["variant"] == v and r["condition"] == condition]
            assert got[v] == _oracle(part, sweep.rms_target), (condition, v)
    assert result.summary() == result.summary("all")  # the last configured condition
    assert result.variant_rows("no-ndo") == [
        r for r in rows if r["variant"] == "no-ndo" and r["condition"] == "all"
    ]


def _table(md: str) -> list[dict]:
    lines = [line for line in md.splitlines() if line.startswith("| ")]
    head = [c.strip() for c in lines[0].strip("|").split(" | ")]
    return [dict(zip(head, [c.strip() for c in line.strip("|").split(" | ")], strict=True))
            for line in lines[1:]]  # fmt: skip


def test_every_cell_of_the_printed_summary_is_recomputed(short_config, make_rng):
    """The Markdown table read back: each cell against the definitions on the rows (runs,
    bounded and pass shares in percent, median / p95 / worst RMS and its sample, worst
    max |e|), and the settings line against the config."""
    from hmpc_pin.apps.sweep import SweepResult

    sweep = replace(short_config.sweep, variants=("ndo", "no-ndo"), conditions=("sensing", "all"),
                    mass=(0.85, 1.15), friction=(0.6, 1.7), disturbance=(0.3, 2.5),
                    after=0.75, error_bound=0.8, rms_target=0.02)  # fmt: skip
    cfg = replace(short_config, sweep=sweep)
    rows = _summary_rows(cfg, make_rng)
    md = SweepResult(cfg, 7, 3, rows, wall_time=12.34, jobs=2).summary_markdown()
    table = _table(md)
    assert [(r["condition"], r["variant"]) for r in table] == [
        ("sensing", "ndo"), ("sensing", "no-ndo"), ("all", "ndo"), ("all", "no-ndo")]  # fmt: skip
    for cells in table:
        part = [
            r
            for r in rows
            if (r["variant"], r["condition"]) == (cells["variant"], cells["condition"])
        ]
        o = _oracle(part, 0.02)
        assert int(cells["runs"]) == o["runs"] == 7
        assert float(cells["bounded"].rstrip(" %")) == pytest.approx(100 * o["bounded"], abs=0.05)
        assert float(cells["bounded and RMS ≤ 0.02"].rstrip(" %")) == pytest.approx(
            100 * o["pass"], abs=0.05)  # fmt: skip
        for key, col in (("median_rms", "median RMS [rad]"), ("p95_rms", "p95 RMS [rad]")):
            assert float(cells[col]) == pytest.approx(o[key], rel=1e-3), (cells, key)
        worst, sample = cells["worst RMS [rad] (sample)"].split()
        assert float(worst) == pytest.approx(o["worst_rms"], rel=1e-3)
        assert int(sample.strip("()")) == o["worst_sample"]
        assert float(cells["worst max \\|e\\| [rad]"]) == pytest.approx(
            o["worst_max_error"], rel=1e-3)  # fmt: skip
    assert md.startswith("# Sweep of paper_combined: 7 samples, seed 3\n")
    for text in ("×U(0.85, 1.15)", "friction ×U(0.6, 1.7)", "amplitude ×U(0.3, 2.5)",
                 "1.5 s per run", "over t ≥ 0.75 s", "max |e| ≤ 0.8 rad",
                 "noise σ_q = 0.001 rad, σ_q̇ = 0.01 rad/s; delay 1 period(s)",
                 "Wall time 12.3 s (local executor, 2 jobs)."):  # fmt: skip
        assert text in md, text
    assert "Interrupted" not in md


def test_the_interface_model_is_described_with_its_values(short_config):
    from hmpc_pin.apps.sweep import SweepResult
    from hmpc_pin.experiment.config.sensing import SensingConfig

    sensing = SensingConfig(rate=500.0, encoder_counts=4096.0, velocity_filter=80.0,
                            latency=0.0025, delay=2, torque_filter=60.0, q_noise=2e-4,
                            dq_noise=3e-3)  # fmt: skip
    sweep = replace(short_config.sweep, q_noise=None, dq_noise=None, delay=None,
                    sensing=sensing, known_latency=True)  # fmt: skip
    md = SweepResult(
        replace(short_config, sweep=sweep), 1, 0, [_row(0, "ndo", "all", 0.01, True)]
    ).summary_markdown()
    assert ("interface at 500 Hz: encoders of 4096 counts/rev, velocity finite-difference "
            "low-passed at 80 Hz, latency 2.5 ms + 2 period(s), torque filter 60 Hz, noise "
            "σ_q = 0.0002 rad, σ_q̇ = 0.003 rad/s; hmpc told the latency") in md  # fmt: skip
    plain = replace(sweep, sensing=SensingConfig(latency=0.001, torque_filter=0.0),
                    known_latency=False)  # fmt: skip
    md = SweepResult(
        replace(short_config, sweep=plain), 1, 0, [_row(0, "ndo", "all", 0.01, True)]
    ).summary_markdown()
    assert "velocity finite-difference, latency 1 ms;" in md
    assert "period(s)" not in md and "torque filter" not in md and "told" not in md


def test_a_sweep_written_to_disk_is_its_csv_and_summary(short_config, tmp_path):
    from hmpc_pin.apps.sweep import SweepResult

    rows = [dict(_row(s, "ndo", "all", 0.001 * (s + 1), True), rms_joint1=1 / 3) for s in range(2)]
    result = SweepResult(short_config, 2, 0, rows)
    csv_path, md_path = result.write(tmp_path)
    assert (csv_path.name, md_path.name) == ("paper_combined_sweep.csv", "paper_combined_sweep.md")
    assert md_path.read_text(encoding="utf-8") == result.summary_markdown()
    back = list(csv.DictReader(io.StringIO(csv_path.read_text(encoding="utf-8"))))
    assert [float(r["rms_joint1"]) for r in back] == [1 / 3, 1 / 3]  # repr: exact
    assert [int(r["sample"]) for r in back] == [0, 1] and back[0]["bounded"] == "True"
    assert sorted(p.name for p in tmp_path.iterdir()) == [csv_path.name, md_path.name]


def test_ctrl_c_keeps_the_runs_that_finished_in_order(short_config, monkeypatch):
    """Ctrl-C during the 4th run of 2 samples × 2 variants: the result holds the three runs
    that finished, in the order sample, variant, and says it was interrupted."""
    from hmpc_pin.apps import sweep as sweep_module

    calls = []

    def fake(config, params, variant, condition="all"):
        if len(calls) == 3:
            raise KeyboardInterrupt
        calls.append((params.index, variant))
        return _row(params.index, variant, condition, 0.01, True)

    monkeypatch.setattr(sweep_module, "run_sample", fake)
    result = run_sweep(short_config, 2, seed=1, jobs=1, progress=False)
    assert result.interrupted and [(r["sample"], r["variant"]) for r in result.rows] == [
        (0, "ndo"), (0, "no-ndo"), (1, "ndo")]  # fmt: skip
    assert result.finished_samples == 1 and result.planned_runs == 4
    md = result.summary_markdown()
    assert "**Interrupted** (Ctrl-C): 1 of 2 samples finished (3 of 4 runs)" in md


def test_effort_leaves_out_non_finite_torques_and_short_runs():
    """A period whose torque is not finite is neither clipped nor part of the total
    variation; one sample: no variation, no span."""
    from types import SimpleNamespace

    from hmpc_pin.apps.sweep import torque_effort

    t = np.array([0.0, 0.5, 1.0, 1.5, 2.0])
    tau = np.array([[0.0, 1.0], [2.0, 1.0], [np.nan, 0.0], [1.0, -1.0], [1.0, -1.0]])
    applied = np.array([[0.0, 1.0], [1.5, 1.0], [0.0, 0.0], [1.0, -1.0], [1.0, -1.0]])
    effort = torque_effort(SimpleNamespace(t=t, tau=tau, tau_applied=applied))
    assert effort["saturation"] == pytest.approx(1 / 5)  # period 1 only
    # finite rows 0, 1, 3, 4: |2-0| + |0| + |1-2| + |-1-1| + 0 = 5 over 2 s
    assert effort["torque_tv"] == pytest.approx(5.0 / 2.0)
    one = torque_effort(SimpleNamespace(t=t[:1], tau=tau[1:2], tau_applied=tau[1:2] * 0.5))
    assert one == {"saturation": 1.0, "torque_tv": 0.0}
    # a relative tolerance: 1e-12 of a large torque is not a clip, 1e-6 is
    big = np.full((2, 1), 1e4)
    effort = torque_effort(SimpleNamespace(t=t[:2], tau=big, tau_applied=big * (1 - 1e-12)))
    assert effort["saturation"] == 0.0
    effort = torque_effort(SimpleNamespace(t=t[:2], tau=big, tau_applied=big * (1 - 1e-6)))
    assert effort["saturation"] == 1.0
