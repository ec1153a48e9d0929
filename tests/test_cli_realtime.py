"""``hmpc-pin realtime``: files and statistics, bad input (exit 2), Ctrl-C (exit 130)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

import hmpc_pin
from hmpc_pin.apps.cli import main

from .conftest import CONFIGS

# Generous safety limits: a wall-clock run on a loaded machine must not stop on misses.
TOLERANT = "\n[realtime]\nmax_misses = 1000000\nwatchdog = 1.0\nhold = 0.05\n"


def _config(tmp_path, extra=TOLERANT, name="rt"):
    text = (CONFIGS / "paper_combined.toml").read_text(encoding="utf-8")
    path = tmp_path / f"{name}.toml"
    text = text.replace('name = "paper_combined"', f'name = "{name}"')
    path.write_text(text + extra)
    return path


def test_realtime_writes_run_timing_and_statistics(tmp_path, capsys):
    cfg = _config(tmp_path)
    assert main(["realtime", str(cfg), "--duration", "1.5", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    for text in ("latency deadline->torque [us]: median", "p99.9", "missed deadlines",
                 "RMS e (t>=1s)", "joint3", "1000 Hz interface"):  # fmt: skip
        assert text in out
    result = hmpc_pin.Result.load(tmp_path / "rt_realtime.npz")
    # (the last step's cycle may be skipped on a loaded machine: 1.49 then)
    assert result.complete and result.t[-1] == pytest.approx(1.5, abs=0.015)
    assert result.meta["realtime"]["cycles"] == 1501 and result.meta["stop"] is None
    assert result.meta["urdf"] and result.meta["controller"] == "hmpc+chen"
    summary = json.loads((tmp_path / "rt_realtime.json").read_text())
    assert set(summary["realtime"]["latency"]) == {"median_us", "p99_us", "p999_us", "max_us",
                                                   "count"}  # fmt: skip
    assert summary["realtime"]["brake"]["ended"] in ("still", "time bound")
    assert len(summary["tracking"]["rms_error"]) == 3
    timing = np.load(tmp_path / "rt_realtime_timing.npz")
    assert timing["latency"].shape == (1501,)
    assert int(timing["missed"].sum()) == summary["realtime"]["misses"]


@pytest.mark.parametrize(
    ("extra", "args", "match"),
    [
        (TOLERANT, ["--rate", "750"], "realtime.rate"),
        (TOLERANT, ["--rate", "-5"], "--rate: expected a rate [Hz] > 0"),
        (TOLERANT + "jitter = 1\n", [], "realtime.jitter: unknown key"),
        ("\n[realtime]\nlimits = false\nposition_margin = 0.1\n", [], "does not apply"),
        ("\n[realtime]\ndamping = [1.0, 2.0]\n", [], "realtime.damping: has 2 entries"),
        ("\n[realtime]\nmax_misses = 0\n", [], "realtime.max_misses"),
        (TOLERANT, ["--rate", "2000"], "plant.dt"),
        (TOLERANT, ["--spin", "0.002"], "--spin: expected a time [s] below the period"),
        ("\n[realtime]\nspin = -1e-4\n", [], "realtime.spin: expected a number >= 0"),
        # the inertia brake's minimum e·(d+1)·P at the rate that runs: 5.4 ms at 1 kHz, 27 ms
        # at --rate 200 (a brake of 10 ms passes the first and not the second)
        ("\n[realtime]\nbrake_time = 0.003\n", [], "realtime.brake_time: is 0.003 s, below"),
        ("\n[realtime]\nbrake_time = 0.01\n", ["--rate", "200"], "realtime.brake_time"),
        ("\n[realtime]\nbrake_time = 0.1\ndamping = 2.0\n", [], "does not apply with brake_time"),
    ],
)
def test_bad_realtime_input_exits_2_with_one_line(tmp_path, capsys, extra, args, match):
    cfg = _config(tmp_path, extra)
    assert main(["realtime", str(cfg), "--out", str(tmp_path), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert match in err and "\n" not in err
    assert not list(tmp_path.glob("*.npz"))


def test_ctrl_c_stops_safely_exits_130_and_keeps_the_partial_run(tmp_path):
    """SIGINT to the whole process group (what Ctrl-C in a terminal does): the arm
    process ignores it, the loop commands the safe torque and saves the run."""
    cfg = _config(tmp_path)
    env = {**os.environ, "MPLBACKEND": "Agg"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "hmpc_pin", "realtime", str(cfg), "--duration", "60",
         "--out", str(tmp_path)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
        start_new_session=True,
    )  # fmt: skip
    try:
        lines = [proc.stdout.readline() for _ in range(2)]  # the title, then readiness
        assert lines[1].startswith("arm process ready"), lines
        time.sleep(1.0)  # a second of the loop
        os.killpg(proc.pid, signal.SIGINT)
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    assert "interrupted at t=" in err
    result = hmpc_pin.Result.load(tmp_path / "rt_realtime.npz")
    assert not result.complete
    stop = result.meta["stop"]
    assert stop["cause"] == "interrupted" and 0 < stop["t"] < 60
    assert result.message == stop["reason"] and "interrupted (Ctrl-C)" in stop["reason"]
    assert result.meta["arm"]["steps"] > 0
    assert "latency deadline->torque" in out


def _planar_plant(period=0.001):
    return hmpc_pin.RK4Plant(hmpc_pin.load_robot("planar3"), None, period, period)


def test_live_view_beside_the_loop_draws_the_arm_process(tmp_path):
    """A real Meshcat server fed by the viewer process from the arm's shared memory, seen
    in headless Chromium: released (zero torque), the arm falls and the picture changes."""
    pytest.importorskip("meshcat", reason="meshcat is not installed (pip install -e '.[viz]')")
    from hmpc_pin.apps.realtime import ArmView
    from hmpc_pin.experiment.build import Experiment
    from hmpc_pin.realtime import ProcessArm

    from .test_viz import CHROMIUM, _differs, _screenshot

    if CHROMIUM is None:
        pytest.skip("chromium is not installed (apt-get install chromium)")
    exp = Experiment.from_config(hmpc_pin.load_config(_config(tmp_path)))
    with ProcessArm(_planar_plant, exp.q0) as arm:
        view = ArmView(arm, exp, fps=30.0)
        try:
            assert view.url is not None and view.url.startswith("http://127.0.0.1:")
            time.sleep(0.5)
            before = _screenshot(view.url, tmp_path / "before.png", tmp_path / "p0")
            arm.write(np.zeros(3))
            time.sleep(1.5)
            after = _screenshot(view.url, tmp_path / "after.png", tmp_path / "p1")
        finally:
            view.close()
    assert _differs(before, after) > 0.002


def test_realtime_with_viz_runs_and_saves(tmp_path, capsys):
    pytest.importorskip("meshcat", reason="meshcat is not installed (pip install -e '.[viz]')")
    cfg = _config(tmp_path)
    assert main(["realtime", str(cfg), "--duration", "1", "--viz", "--out", str(tmp_path)]) == 0
    assert "Meshcat live view: open http://127.0.0.1:" in capsys.readouterr().out
    assert hmpc_pin.Result.load(tmp_path / "rt_realtime.npz").complete
