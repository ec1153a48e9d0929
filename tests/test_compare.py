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
    # blanks around names and an empty item (a trailing comma) are no controller
    assert parse_controllers(" hmpc , computed-torque,") == ("hmpc", "computed-torque")
    assert parse_controllers("hmpc,,computed-torque") == ("hmpc", "computed-torque")


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


# ------------------------------------------- the table against the runs' arrays
def _hand_run(kind, seed, *, K=61, dt=0.05, observer=True, failure=None, meta=None, n=3):
    """A ControllerRun of a hand-built result with seeded random arrays over 0..3 s."""
    from hmpc_pin.apps.compare import ControllerRun
    from hmpc_pin.apps.metrics import compute_metrics
    from hmpc_pin.sim.result import Result

    rng = np.random.default_rng(seed)
    t = dt * np.arange(K)
    a = {k: rng.normal(scale=0.1, size=(K, n)) for k in ("q", "dq", "d", "d_hat", "q_ref")}
    tau = rng.normal(scale=20.0, size=(K, n))
    r = Result(t, a["q"], a["dq"], tau, a["d"], a["d_hat"], a["q_ref"], np.zeros((K, n)),
               joint_names=tuple(f"joint{i + 1}" for i in range(n)), meta=meta or {},
               tau_applied=np.clip(tau, -25.0, 25.0))  # fmt: skip
    metrics = compute_metrics(r) if t[-1] >= 1.0 else None
    return ControllerRun(kind, r, metrics, 12.0 + seed, observer, failure)


def _comparison(*runs):
    from hmpc_pin.apps.compare import Comparison

    comp = Comparison(load_config(CONFIGS / "paper_combined.toml"))
    for run in runs:
        comp.runs[run.kind] = run
    return comp


def _md_rows(table: str) -> list[list[str]]:
    lines = [line for line in table.splitlines() if line.startswith("| ")]
    return [[c.strip() for c in re.split(r"(?<!\\)\|", line)[1:-1]] for line in lines]


def test_every_cell_of_the_table_is_recomputed_from_the_runs_arrays():
    """The Markdown table read back, each number against numpy on the run's arrays over
    t >= 1 s (RMS and max |q - r|, RMS d - d̂, RMS τ, TV per second) or the whole run
    (peak |τ| commanded and applied), the observer column empty without an observer, the
    step time on the first row of each controller; a failed run is marked."""
    from hmpc_pin.apps.compare import markdown_table

    runs = [_hand_run("hmpc", 1), _hand_run("computed-torque", 2, observer=False,
                                            failure="stopped at 2.1 s")]  # fmt: skip
    head, *rows = _md_rows(markdown_table(_comparison(*runs)))
    assert head[:2] == ["controller", "joint"] and head[-1] == "step median [µs]"
    assert len(rows) == 6
    col = {h: k for k, h in enumerate(head)}
    for k, row in enumerate(rows):
        run, i = runs[k // 3], k % 3
        r = run.result
        keep = r.t >= 1.0 - 1e-12
        e, w, tau = (r.q - r.q_ref)[keep, i], (r.d - r.d_hat)[keep, i], r.tau[keep, i]
        assert row[0] == run.kind + (" (failed)" if run.failure else "")
        assert row[1] == f"joint{i + 1}"

        def cell(name, value, rel=5e-3, row=row):
            assert float(row[col[name]]) == pytest.approx(value, rel=rel), (name, row)

        cell("RMS e after 1 s [rad]", np.sqrt(np.mean(e**2)))
        cell("max \\|e\\| after 1 s [rad]", np.abs(e).max())
        cell("RMS τ [N·m]", np.sqrt(np.mean(tau**2)))
        cell("peak \\|τ\\| commanded [N·m]", np.abs(r.tau[:, i]).max(), rel=1e-3)
        cell("peak \\|τ\\| applied [N·m]", min(np.abs(r.tau[:, i]).max(), 25.0), rel=1e-3)
        cell("TV(τ) [N·m/s]", np.abs(np.diff(tau)).sum() / (r.t[-1] - 1.0))
        if run.observer:
            cell("RMS d−d̂ [N·m]", np.sqrt(np.mean(w**2)))
        else:
            assert row[col["RMS d−d̂ [N·m]"]] == "—"
        assert row[col["within 0.01 rad from [s]"]] == "never"  # noise of 0.1 rad
        assert row[col["limit excursion [rad]"]] == "n/a"  # no limits recorded
        assert row[col["saturated periods"]] == "0"
        assert row[-1] == (f"{run.step_us:.1f}" if i == 0 else "")


def test_the_csv_holds_the_metrics_at_full_precision(tmp_path):
    """One row per controller and joint; floats written exactly; the observer column empty
    without an observer; a run without metrics has empty cells; completion flag."""
    from hmpc_pin.apps.compare import COLUMNS, write_csv

    runs = [_hand_run("hmpc", 3), _hand_run("hmpc-none", 4, observer=False),
            _hand_run("hmpc-ism", 5, K=15, failure="diverged")]  # fmt: skip
    assert runs[2].metrics is None  # 0.7 s: shorter than the 1 s window
    path = write_csv(_comparison(*runs), tmp_path / "c.csv")
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    assert [(r["controller"], r["joint"]) for r in rows] == [
        (k, f"joint{i}") for k in ("hmpc", "hmpc-none", "hmpc-ism") for i in (1, 2, 3)
    ]
    for row in rows[:6]:
        run = next(r for r in runs if r.kind == row["controller"])
        i = int(row["joint"][-1]) - 1
        for _, attr, _ in COLUMNS:
            if attr == "observer_rms" and not run.observer:
                assert row[attr] == ""
            else:
                value = float(getattr(run.metrics, attr)[i])
                assert float(row[attr]) == value or (np.isnan(value) and row[attr] == "nan")
        assert row["observer"] == str(run.observer) and row["complete"] == "True"
        assert float(row["step_median_us"]) == pytest.approx(run.step_us)
    assert all(rows[k][a] == "" for k in (6, 7, 8) for _, a, _ in COLUMNS)
    assert rows[6]["complete"] == "False"


def test_a_task_space_table_follows_for_a_pose_task():
    from hmpc_pin.apps.compare import markdown_table
    from hmpc_pin.apps.metrics import compute_metrics

    run = _hand_run("hmpc", 6, meta={"task": {"frame": "tool0"}})
    r = run.result
    rng = np.random.default_rng(0)
    r.ee_pos_ref = rng.normal(size=(len(r.t), 3))
    r.ee_pos = r.ee_pos_ref + 0.01 * rng.normal(size=(len(r.t), 3))
    r.ee_quat = r.ee_quat_ref = np.tile([0.0, 0.0, 0.0, 1.0], (len(r.t), 1))
    run.metrics = compute_metrics(r)
    text = markdown_table(_comparison(run))
    assert "position RMS after 1 s [m] (tool0)" in text
    keep = r.t >= 1.0 - 1e-12
    dist = np.linalg.norm((r.ee_pos - r.ee_pos_ref)[keep], axis=1)
    row = text.splitlines()[-1]  # the task table's one row
    assert row.startswith("| hmpc | ")
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert float(cells[1]) == pytest.approx(np.sqrt(np.mean(dist**2)), rel=1e-3)
    assert float(cells[2]) == pytest.approx(dist.max(), rel=1e-3)
    assert float(cells[3]) == float(cells[4]) == 0.0


def test_compare_writes_failures_warnings_and_the_interruption(tmp_path, monkeypatch):
    """The Markdown of a comparison whose second run failed and third was interrupted:
    the table of the runs done, the failure, each run's warnings, where Ctrl-C stopped it,
    no figures; RunInterrupted names the files."""
    from hmpc_pin.apps import compare as compare_module
    from hmpc_pin.exceptions import RunInterrupted

    made = {"hmpc": _hand_run("hmpc", 7), "hmpc-none": _hand_run("hmpc-none", 8,
                                                                  failure="QP failed")}  # fmt: skip

    def fake(config, kind):
        if kind == "hmpc-ism":
            raise KeyboardInterrupt
        return made[kind]

    monkeypatch.setattr(compare_module, "run_one_controller", fake)
    cfg = load_config(CONFIGS / "paper_combined.toml")
    with pytest.raises(RunInterrupted) as info:
        compare_module.compare(cfg, tmp_path, ("hmpc", "hmpc-none", "hmpc-ism"),
                               error_threshold=0.2)  # fmt: skip
    md_path = tmp_path / "paper_combined_compare.md"
    assert [p.name for p in info.value.files] == [md_path.name, "paper_combined_compare.csv"]
    md = md_path.read_text(encoding="utf-8")
    assert "**Interrupted** (Ctrl-C) at set-up in hmpc-ism (2 of 3 controllers finished)." in md
    assert "- `hmpc-none`: QP failed" in md and "| hmpc-none (failed) | joint1 |" in md
    assert "- `hmpc`: tracking error exceeds 0.2 rad after 1 s" in md
    assert "--controllers hmpc,hmpc-none,hmpc-ism" in md
    assert "![" not in md and "Boundary layer" not in md
    assert not list(tmp_path.glob("*.png"))


def test_ctrl_c_in_a_run_keeps_its_partial_result(monkeypatch):
    """A run interrupted after 1 s keeps its partial result, metrics and message; one
    interrupted before 1 s has no metrics."""
    from hmpc_pin.apps import compare as compare_module
    from hmpc_pin.exceptions import RunInterrupted

    for K, has_metrics in ((61, True), (15, False)):
        partial = _hand_run("hmpc-ism", 9, K=K).result
        partial.meta["observer"] = True
        partial.message = "interrupted"

        def fake(config, kind, partial=partial):
            if kind == "hmpc-ism":
                exc = RunInterrupted("t = 2.1 s", files=[])
                exc.result = partial
                raise exc
            return _hand_run(kind, 10)

        monkeypatch.setattr(compare_module, "run_one_controller", fake)
        comp = run_comparison(load_config(CONFIGS / "paper_combined.toml"), ("hmpc", "hmpc-ism"))
        assert comp.interrupted == "t = 2.1 s in hmpc-ism (1 of 2 controllers finished)"
        run = comp.runs["hmpc-ism"]
        assert run.result is partial and run.observer is True and run.failure == "interrupted"
        assert (run.metrics is not None) is has_metrics
        if has_metrics:
            keep = partial.t >= 1.0 - 1e-12
            np.testing.assert_allclose(run.metrics.rms_error, np.sqrt(
                np.mean(partial.error[keep] ** 2, axis=0)))  # fmt: skip


def test_the_boundary_layer_sweep_sets_phi_to_factor_k_ts(monkeypatch):
    """φ = factor · K · Ts for each factor, on the hmpc-ism-bl controller; the table's φ
    column is that product."""
    from hmpc_pin.apps import compare as compare_module
    from hmpc_pin.experiment.build import with_controller

    seen = []

    def fake(config, kind):
        seen.append((kind, config.controller.label, config.controller.ism.boundary_layer))
        return _hand_run(kind, len(seen))

    monkeypatch.setattr(compare_module, "run_one_controller", fake)
    cfg = load_config(CONFIGS / "paper_combined.toml")
    cc = with_controller(cfg, "hmpc-ism-bl").controller
    K, Ts = cc.ism.gain, cc.Ts
    rows = compare_module.boundary_layer_sweep(cfg, factors=(0.3, 2.0))
    assert [f for f, _ in rows] == [0.3, 2.0]
    assert [s[:2] for s in seen] == [("hmpc-ism-bl", "hmpc+ism-bl")] * 2
    assert [s[2] for s in seen] == pytest.approx([0.3 * K * Ts, 2.0 * K * Ts], rel=1e-12)
    seen.clear()
    table = compare_module.boundary_layer_table(cfg, ("joint1", "joint2", "joint3"))
    assert f"K = {K:g} rad/s², Ts = {Ts:g} s" in table
    body = [line for line in table.splitlines() if re.match(r"^\| \d", line)]
    factors = [float(line.split("|")[1]) for line in body]
    assert factors == [0.25, 0.45, 0.55, 1.0, 2.0]
    for line, f in zip(body, factors, strict=True):
        assert float(line.split("|")[2]) == pytest.approx(f * K * Ts, rel=2e-3)


def test_run_one_controller_has_metrics_from_one_second_on():
    """A real run: metrics only when it reaches 1 s; the step times measured; the
    observer flag from the controller's compensation."""
    from dataclasses import replace

    from hmpc_pin.apps.compare import run_one_controller

    cfg = load_config(CONFIGS / "paper_combined.toml")
    for duration, has in ((1.0, True), (0.9, False)):
        short = replace(cfg, simulation=replace(cfg.simulation, duration=duration))
        run = run_one_controller(short, "hmpc")
        assert (run.metrics is not None) is has and run.observer is True
        assert run.failure is None and run.kind == "hmpc"
        # a unit check (ns -> µs), not a speed assertion: a step of a 3-joint controller
        # (CRBA, RNEA, 3 QPs, the observer) takes far more than 0.1 µs on any machine
        assert run.step_us > 0.1
    run = run_one_controller(short, "computed-torque")
    assert run.observer is False


def test_compare_zooms_the_torque_figure_on_the_shortest_runs_window(tmp_path, monkeypatch):
    """The torque figure's window is (min(2, t_end / 2), min(2.5, t_end)) of the shortest
    run; both figures are linked; with hmpc-ism-bl the boundary-layer table follows."""
    from pathlib import Path

    from hmpc_pin.apps import compare as compare_module
    from hmpc_pin.apps import plots

    made = {"hmpc": _hand_run("hmpc", 11), "hmpc-ism-bl": _hand_run("hmpc-ism-bl", 12, K=57)}
    monkeypatch.setattr(compare_module, "run_one_controller", lambda c, k: made.get(k) or
                        _hand_run(k, 13))  # fmt: skip
    drawn = {}

    def fake_plot(name):
        def plot(results, path, title, window=None):
            drawn[name] = (list(results), window, title)
            Path(path).write_bytes(b"\x89PNG")
            return Path(path)

        return plot

    monkeypatch.setattr(plots, "plot_error", fake_plot("error"))
    monkeypatch.setattr(plots, "plot_torques", fake_plot("tau"))
    cfg = load_config(CONFIGS / "paper_combined.toml")
    _, files = compare_module.compare(cfg, tmp_path, ("hmpc", "hmpc-ism-bl"))
    t_end = 0.05 * 56  # the shorter run: 2.8 s
    assert drawn["tau"][1] == pytest.approx((min(2.0, t_end / 2), min(2.5, t_end)))
    assert drawn["error"][0] == drawn["tau"][0] == ["hmpc", "hmpc-ism-bl"]
    assert drawn["tau"][2] == cfg.description
    assert [p.name for p in files] == ["paper_combined_compare.md", "paper_combined_compare.csv",
                                       "paper_combined_compare_error.png",
                                       "paper_combined_compare_tau.png"]  # fmt: skip
    md = files[0].read_text(encoding="utf-8")
    assert "## Boundary layer of hmpc-ism-bl" in md
    assert "![paper_combined_compare_tau](paper_combined_compare_tau.png)" in md
    assert md.startswith(f"# Controller comparison: paper_combined\n\n{cfg.description}.")
    _, files = compare_module.compare(cfg, tmp_path, ("hmpc", "hmpc-ism-bl"),
                                      sweep_boundary_layer=False)  # fmt: skip
    assert "Boundary layer" not in files[0].read_text(encoding="utf-8")
