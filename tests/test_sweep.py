"""Determinism (issue 7, item 3) and the Monte Carlo sweep (item 4)."""

from __future__ import annotations

import csv
import io
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
