"""``hmpc-pin plot``: the figures of every kind of file a command writes, the data they
draw read back from the matplotlib artists and compared with the file's arrays read with
numpy (an independent reading); a file that is none of them is one line and exit 2. And
``run``'s progress bar: the run bit-identical with and without it."""

from __future__ import annotations

import csv
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from hmpc_pin.apps.plot import figures, plot_file

ROOT = Path(__file__).resolve().parent.parent


def _cli(*args, cwd=None):
    return subprocess.run(
        [sys.executable, "-m", "hmpc_pin", *map(str, args)],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=600,
    )


def _raw(path: Path) -> dict:
    with np.load(path, allow_pickle=False) as f:
        return {k: f[k] for k in f.files}


def _lines(ax) -> dict:
    """The lines of an Axes by legend label (their data as float arrays)."""
    return {
        line.get_label(): (np.asarray(line.get_xdata(), float), np.asarray(line.get_ydata(), float))
        for line in ax.lines
    }


@pytest.fixture(scope="module")
def sim_run(tmp_path_factory):
    """A short ``run`` of paper_combined saved as the command saves it (in-process)."""
    import hmpc_pin

    out = tmp_path_factory.mktemp("run")
    result = hmpc_pin.Experiment.from_config(hmpc_pin.load_config("paper_combined")).run(
        duration=1.5
    )
    return result.save(out / "paper_combined.npz")


def test_a_run_draws_tracking_error_torque_and_disturbance_of_its_arrays(sim_run):
    kind, figs = figures(sim_run)
    assert kind == "run"
    assert set(figs) == {"tracking", "error", "torque", "disturbance"}  # no timing beside it
    raw = _raw(sim_run)
    t, n = raw["t"], raw["q"].shape[1]
    assert len(t) <= 2000  # short enough to be drawn sample for sample (no envelope)
    for i in range(n):
        lines = _lines(figs["tracking"].axes[i])
        np.testing.assert_array_equal(lines["angle q"][1], raw["q"][:, i])
        np.testing.assert_array_equal(lines["reference r"][1], raw["q_ref"][:, i])
        np.testing.assert_array_equal(lines["angle q"][0], t)
        tau = _lines(figs["torque"].axes[i])
        np.testing.assert_array_equal(tau["commanded τ"][1], raw["tau"][:, i])
        dist = _lines(figs["disturbance"].axes[i])
        np.testing.assert_array_equal(dist["true d"][1], raw["d"][:, i])
        np.testing.assert_array_equal(dist["NDO estimate d̂"][1], raw["d_hat"][:, i])
        err = _lines(figs["error"].axes[i])["with NDO"][1]
        np.testing.assert_allclose(err, np.abs(raw["q"][:, i] - raw["q_ref"][:, i]), atol=1e-9)


def test_plot_writes_the_figures_beside_the_file_or_in_out(sim_run, tmp_path):
    written = plot_file(sim_run, tmp_path)
    assert sorted(p.name for p in written) == sorted(
        f"paper_combined_{k}.png" for k in ("tracking", "error", "torque", "disturbance")
    )
    for p in written:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def realtime_files(tmp_path_factory):
    """A real ``hmpc-pin realtime`` run (short, at a rate a loaded machine keeps; a safe
    stop still writes the files)."""
    out = tmp_path_factory.mktemp("rt")
    proc = _cli("realtime", "paper_combined", "--duration", "0.5", "--rate", "200", "--out", out)
    assert proc.returncode in (0, 1), proc.stderr
    return out / "paper_combined_realtime.npz", out / "paper_combined_realtime_timing.npz"


def _check_latency(fig, timing: dict) -> None:
    ax = fig.axes[0]
    steps = [p for p in ax.patches if hasattr(p, "get_data")]  # the histograms (stairs)
    assert len(steps) >= 2
    for patch, key in zip(steps, ("latency", "compute"), strict=False):
        values, edges, _ = patch.get_data()
        us = timing[key][np.isfinite(timing[key])] * 1e6
        counts, _ = np.histogram(us, bins=edges)
        np.testing.assert_array_equal(values, counts)
        assert values.sum() == len(us)  # every cycle that ran, once


def test_a_realtime_run_draws_its_arrays_and_the_latency_histogram(realtime_files, tmp_path):
    npz, timing_npz = realtime_files
    kind, figs = figures(npz)
    assert kind == "run"
    assert {"tracking", "error", "torque", "disturbance", "latency"} <= set(figs)
    raw = _raw(npz)
    assert np.all(np.isnan(raw["d"]))  # an arm does not report its disturbance
    lines = _lines(figs["disturbance"].axes[0])
    assert "true d" not in lines  # drawn only when the file holds it
    np.testing.assert_array_equal(lines["NDO estimate d̂"][1], raw["d_hat"][:, 0])
    _check_latency(figs["latency"], _raw(timing_npz))
    # the timing file alone, through the command line
    proc = _cli("plot", timing_npz, "--out", tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "paper_combined_realtime_timing_latency.png").is_file()
    kind, figs = figures(timing_npz)
    assert (kind, set(figs)) == ("timing", {"latency"})


def test_a_ros_and_a_franka_run_draw_with_the_arm_records(realtime_files, tmp_path):
    """The ROS file written by the ``ros`` command's own writer (``save_run`` with its
    ``"ros"`` record); a Franka run: the same plus the arm's ``tau_J_d`` and
    ``tau_ext_hat_filtered``."""
    from hmpc_pin.apps.realtime import save_run
    from hmpc_pin.realtime.loop import RealtimeRun
    from hmpc_pin.sim.result import Result

    npz, timing_npz = realtime_files
    result = Result.load(npz)
    result.meta["ros"] = {"node": "hmpc_pin", "stamps": "arrival"}
    run = RealtimeRun(result, _raw(timing_npz), result.meta["realtime"], result.meta["stop"])
    files = save_run(run, tmp_path, "arm_ros", "ros")
    kind, figs = figures(files[0])
    assert kind == "run" and "latency" in figs  # arm_ros_timing.npz beside it
    _check_latency(figs["latency"], _raw(files[1]))

    rng = np.random.default_rng(0)
    shape = result.q.shape
    result.extra["tau_J_d"] = rng.normal(size=shape)
    result.extra["tau_ext_hat_filtered"] = rng.normal(size=shape)
    franka = result.save(tmp_path / "arm_franka.npz")
    raw = _raw(franka)
    _, figs = figures(franka)
    for i in range(shape[1]):
        tau = _lines(figs["torque"].axes[i])
        np.testing.assert_array_equal(tau["τ_J_d (arm)"][1], raw["extra_tau_J_d"][:, i])
        dist = _lines(figs["disturbance"].axes[i])
        np.testing.assert_array_equal(
            dist["τ_ext filtered (arm)"][1], raw["extra_tau_ext_hat_filtered"][:, i]
        )


def test_a_sweep_table_draws_every_runs_rms(tmp_path):
    import hmpc_pin
    from hmpc_pin.apps.sweep import run_sweep

    config = hmpc_pin.load_config("paper_combined")
    from dataclasses import replace

    config = replace(config, simulation=replace(config.simulation, duration=1.5))
    table, _ = run_sweep(config, 3, seed=0, progress=False).write(tmp_path)
    with table.open(newline="") as f:
        rows = list(csv.DictReader(f))
    kind, figs = figures(table)
    assert (kind, set(figs)) == ("sweep", {"rms"})
    ax = figs["rms"].axes[0]
    variants = [t.get_text() for t in figs["rms"].axes[-1].get_xticklabels()]
    drawn = sorted(
        (variants[round(float(x))], float(y))
        for c in ax.collections
        for x, y in np.asarray(c.get_offsets())
    )
    expected = sorted((r["variant"], float(r["rms_max"])) for r in rows)
    assert [v for v, _ in drawn] == [v for v, _ in expected]
    np.testing.assert_allclose([y for _, y in drawn], [y for _, y in expected], rtol=0, atol=0)


@pytest.fixture(scope="module")
def friction_run(tmp_path_factory):
    import hmpc_pin

    out = tmp_path_factory.mktemp("id")
    result = hmpc_pin.Experiment.from_config(hmpc_pin.load_config("paper_friction")).run()
    return result.save(out / "paper_friction.npz")


def test_an_identification_draws_its_fit_over_its_run(friction_run, tmp_path):
    proc = _cli("identify", friction_run)
    assert proc.returncode == 0, proc.stderr
    toml = friction_run.with_name("paper_friction_friction.toml")
    table = tomllib.loads(toml.read_text())["controller"]["friction"]
    kind, figs = figures(toml)
    assert (kind, set(figs)) == ("fit", {"friction"})
    raw = _raw(friction_run)
    keep = raw["t"] >= 0.5
    for i, ax in enumerate(figs["friction"].axes):
        fit = next(line for line in ax.lines if line.get_label().startswith("fit"))
        v, f = np.asarray(fit.get_xdata()), np.asarray(fit.get_ydata())
        np.testing.assert_allclose(
            f, table["viscous"][i] * v + table["coulomb"][i] * np.sign(v), rtol=1e-12
        )
        observed = next(c for c in ax.collections if "observer" in c.get_label())
        xy = np.asarray(observed.get_offsets())
        np.testing.assert_array_equal(xy[:, 0], raw["dq"][keep, i])
        np.testing.assert_array_equal(xy[:, 1], -raw["d_hat"][keep, i])
    proc = _cli("identify", friction_run, "--thresholds", "--out", tmp_path / "watch.toml")
    assert proc.returncode == 0, proc.stderr
    threshold = tomllib.loads((tmp_path / "watch.toml").read_text())["collision"]["threshold"]
    # fitted from a run in another folder: named with --run
    proc = _cli("plot", tmp_path / "watch.toml")
    assert proc.returncode == 2 and "--run" in proc.stderr
    kind, figs = figures(tmp_path / "watch.toml", run=friction_run)
    for i, ax in enumerate(figs["collision"].axes):
        lines = _lines(ax)
        np.testing.assert_array_equal(lines["|d̂|"][1], np.abs(raw["d_hat"][:, i]))
        assert lines["threshold"][1][0] == pytest.approx(threshold[i], rel=1e-12)


@pytest.mark.parametrize(
    "content, says",
    [
        (None, "not found"),
        (b"", "is empty"),
        (b"hello\n", "neither a sweep table nor an identification"),
        (b"\x00\x01\x02\xff", "neither a .npz archive nor text"),
        ("npz", "neither a run nor its timing"),
        (b"PK\x03\x04garbage", "truncated or corrupt"),
        (b"t,q_joint1\n0.0,1.0\n", "a run's CSV table"),
    ],
)
def test_a_file_that_is_no_run_is_one_line_and_exit_2(tmp_path, content, says):
    path = tmp_path / "x.npz"
    if content == "npz":
        np.savez(path, x=np.arange(3))
    elif content is not None:
        path.write_bytes(content)
    proc = _cli("plot", path)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: FILE:"), proc.stderr
    assert says in lines[0]
    assert not list(tmp_path.glob("*.png"))


# --- run's progress bar -------------------------------------------------------------------


def test_progress_bar_changes_nothing_in_the_run(tmp_path, capsys):
    import hmpc_pin
    from hmpc_pin.apps.run import run_one

    config = hmpc_pin.load_config("paper_combined")
    files = {}
    for show in (False, True):
        out = tmp_path / str(show)
        out.mkdir()
        _, _, written, _ = run_one(config, out, figures=False, progress=show)
        files[show] = written
        err = capsys.readouterr().err
        assert ("paper_combined:" in err and "step" in err) is show
    for a, b in zip(files[False], files[True], strict=True):
        assert a.read_bytes() == b.read_bytes()  # byte for byte (.npz and .csv)


def test_progress_is_off_away_from_a_terminal_and_shown_when_forced(tmp_path):
    """A long run (the 10 s scenario twice over) through the command line: with stderr a
    pipe, no bar unless ``--progress``; forced, the bar counts the periods (removed at the end)."""
    args = ("run", "paper_combined", "--duration", "20", "--no-figures", "--out", tmp_path)
    quiet = _cli(*args)
    assert quiet.returncode == 0 and "step" not in quiet.stderr
    loud = _cli(*args, "--progress", "--force")  # the same files again
    assert loud.returncode == 0, loud.stderr
    assert "paper_combined:" in loud.stderr and "/2000 [" in loud.stderr
    assert quiet.stdout == loud.stdout  # the same table


def test_an_out_that_is_a_file_is_one_line_and_exit_2(sim_run, tmp_path):
    (tmp_path / "taken").write_text("")
    proc = _cli("plot", sim_run, "--out", tmp_path / "taken")
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        f"error: --out: output directory '{tmp_path / 'taken'}' is a file; pass --out with "
        "a directory you can write to"
    ]
    assert not list(tmp_path.glob("*.png"))


def test_progress_by_default_on_a_terminal_only_and_after_its_delay(monkeypatch):
    import io

    from hmpc_pin.apps.run import PROGRESS_DELAY, Progress

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    monkeypatch.setattr(sys, "stderr", io.StringIO())
    assert not Progress("x").show  # a pipe or a file: no bar
    monkeypatch.setattr(sys, "stderr", Terminal())
    bar = Progress("x")
    assert bar.show and bar.delay == PROGRESS_DELAY == 2.0
    forced = Progress("x", True)
    assert forced.show and forced.delay == 0.0
    assert not Progress("x", False).show
