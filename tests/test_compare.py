"""hmpc-pin compare: every controller on the paper's combined scenario, side by side."""

from __future__ import annotations

import csv
import re

import numpy as np
import pytest

from hmpc_pin.apps.cli import main
from hmpc_pin.apps.compare import parse_controllers, run_comparison
from hmpc_pin.exceptions import ConfigError
from hmpc_pin.experiment.build import run_experiment
from hmpc_pin.experiment.config import CONTROLLER_KINDS, load_config

from .conftest import CONFIGS, ROOT


@pytest.fixture(scope="module")
def combined():
    return run_comparison(load_config(CONFIGS / "paper_combined.toml"))


def _m(comp, kind):
    return comp.runs[kind].metrics


# What each of the seven 0.1 names is on the paper's config (hmpc × Chen's NDO).
PAIRS = {
    "hmpc": "hmpc+chen",
    "hmpc-none": "hmpc+none",
    "hmpc-momentum": "hmpc+momentum",
    "hmpc-ism": "hmpc+ism",
    "hmpc-ism-bl": "hmpc+ism-bl",
    "computed-torque": "computed-torque+none",
    "computed-torque-pid": "computed-torque-pid+none",
}


def test_every_run_completes_on_the_same_reference(combined):
    assert tuple(combined.runs) == CONTROLLER_KINDS and set(PAIRS) == set(CONTROLLER_KINDS)
    first = combined.runs["hmpc"].result
    for kind, run in combined.runs.items():
        assert run.failure is None, kind
        np.testing.assert_array_equal(run.result.q_ref, first.q_ref)
        np.testing.assert_array_equal(run.result.q[0], first.q[0])
        assert run.result.meta["controller"] == PAIRS[kind]
        observer = PAIRS[kind].endswith(("+chen", "+momentum"))
        assert run.observer is observer and run.result.meta["observer"] is observer


def test_hmpc_run_equals_the_plain_run(combined):
    """compare changes nothing but the controller: its hmpc run is the `run` command's."""
    plain = run_experiment(load_config(CONFIGS / "paper_combined.toml"))
    np.testing.assert_array_equal(combined.runs["hmpc"].result.q, plain.q)


def test_ism_chatters_at_least_10x_more_than_the_ndo(combined):
    ism, ndo, bl = (_m(combined, k).tau_tv for k in ("hmpc-ism", "hmpc", "hmpc-ism-bl"))
    assert np.all(ism >= 10 * ndo)
    # the boundary layer removes the chattering: between the two, down to the NDO's level
    assert np.all(bl <= ism / 10) and np.all(bl >= 0.9 * ndo)
    assert np.all(_m(combined, "hmpc-ism").tau_hf_share > 0.5)
    assert np.all(_m(combined, "hmpc").tau_hf_share < 0.01)


def test_hmpc_beats_no_compensation_and_computed_torque(combined):
    hmpc = _m(combined, "hmpc").rms_error
    assert np.all(hmpc < _m(combined, "hmpc-none").rms_error)
    for kind in ("computed-torque", "computed-torque-pid"):
        assert np.sum(hmpc < _m(combined, kind).rms_error) >= 2, kind


def test_boundary_layer_below_half_k_ts_chatters_again():
    """Inside the layer the loop σ⁺ = (1 − Ts K/φ)σ is unstable for φ < K Ts / 2."""
    from dataclasses import replace

    from hmpc_pin.apps.compare import run_one_controller
    from hmpc_pin.experiment.build import with_controller

    # the paper's config has no [controller.ism] (hmpc × chen): take hmpc-ism-bl's
    cfg = with_controller(load_config(CONFIGS / "paper_combined.toml"), "hmpc-ism-bl")
    cc = cfg.controller
    assert cc.label == "hmpc+ism-bl" and cc.ism.boundary_layer is None

    def tv(factor):
        ism = replace(cc.ism, boundary_layer=factor * cc.ism.gain * cc.Ts)
        c = replace(cfg, controller=replace(cc, ism=ism))
        return run_one_controller(c, "hmpc-ism-bl").metrics.tau_tv

    assert np.all(tv(0.45) > 100 * tv(0.55))


def test_compare_command_writes_table_csv_and_figures(tmp_path, capsys):
    out = tmp_path / "cmp"
    argv = ["compare", str(CONFIGS / "paper_combined.toml"), "--out", str(out), "--quiet",
            "--duration", "2", "--controllers", "hmpc,hmpc-ism-bl,computed-torque"]  # fmt: skip
    assert main(argv) == 0
    md = (out / "paper_combined_compare.md").read_text()
    for kind in ("hmpc", "hmpc-ism-bl", "computed-torque"):
        assert f"| {kind} | joint1 |" in md
    assert "Boundary layer" in md
    with open(out / "paper_combined_compare.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [(r["controller"], r["joint"]) for r in rows][:3] == [
        ("hmpc", "joint1"), ("hmpc", "joint2"), ("hmpc", "joint3")]  # fmt: skip
    assert len(rows) == 9
    assert rows[6]["observer_rms"] == "" and rows[0]["observer_rms"] != ""
    assert all(float(r["step_median_us"]) > 0 for r in rows)
    for name in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", md):
        png = out / name
        assert png.read_bytes()[:4] == b"\x89PNG" and png.stat().st_size > 10_000
    assert "| computed-torque | joint3 |" in capsys.readouterr().out


def test_unknown_controller_is_bad_input(tmp_path, capsys):
    argv = ["compare", str(CONFIGS / "paper_combined.toml"), "--out", str(tmp_path),
            "--controllers", "hmpc,mpc-foo"]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "mpc-foo" in err and "hmpc-ism" in err and err.count("\n") == 1
    with pytest.raises(ConfigError):
        parse_controllers(" , ")


def test_controller_names_are_pairs_and_duplicates_are_refused():
    combined = load_config(CONFIGS / "paper_combined.toml")  # hmpc × chen
    names = "hmpc+momentum,computed-torque+chen,hmpc-ism-bl"
    assert parse_controllers(names) == parse_controllers(names, combined)
    assert parse_controllers(names) == ("hmpc+momentum", "computed-torque+chen", "hmpc-ism-bl")
    for bad in ("hmpc+magic", "lqr+chen", "hmpc,mpc-foo"):
        with pytest.raises(ConfigError, match="--controllers"):
            parse_controllers(bad)
    # the same pair under two names, on this config
    for same in ("hmpc,hmpc+chen", "hmpc-momentum,hmpc+momentum", "computed-torque,"
                 "computed-torque+none"):  # fmt: skip
        with pytest.raises(ConfigError, match="same controller"):
            parse_controllers(same, combined)
        assert parse_controllers(same) == tuple(same.split(","))  # no config: not checked
    assert parse_controllers(None, combined) == CONTROLLER_KINDS
    # without compensation in the config, "hmpc" is "hmpc-none": the default keeps it once
    no_ndo = load_config(CONFIGS / "paper_combined_no_ndo.toml")
    assert no_ndo.controller.label == "hmpc+none"
    assert parse_controllers(None, no_ndo) == tuple(k for k in CONTROLLER_KINDS if k != "hmpc-none")
    with pytest.raises(ConfigError, match="same controller"):
        parse_controllers("hmpc,hmpc-none", no_ndo)


def test_default_comparison_runs_each_pair_once(monkeypatch):
    from hmpc_pin.apps import compare

    ran = []
    monkeypatch.setattr(compare, "run_one_controller", lambda config, kind: ran.append(kind))
    no_ndo = load_config(CONFIGS / "paper_combined_no_ndo.toml")
    comp = run_comparison(no_ndo)
    assert ran == [k for k in CONTROLLER_KINDS if k != "hmpc-none"] == list(comp.runs)


def test_timed_controller_is_still_importable_from_compare():
    from hmpc_pin.apps.compare import TimedController
    from hmpc_pin.controllers.wrappers import TimedController as Moved

    assert TimedController is Moved


def test_every_controller_is_documented():
    page = (ROOT / "docs" / "concepts" / "controllers.md").read_text()
    for kind in CONTROLLER_KINDS:
        assert f"`{kind}`" in page, kind
