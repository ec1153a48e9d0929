"""Every output path is checked before the run, naming its option; saturation and
tracking-error warnings; the applied (clipped) torque beside the commanded one; the
command line's figures, drawn by its figure process."""

from __future__ import annotations

import csv
import os

import numpy as np
import pytest

import hmpc_pin
from hmpc_pin.apps.cli import main
from hmpc_pin.apps.metrics import compute_metrics, run_warnings
from hmpc_pin.exceptions import install_command

from .conftest import CONFIGS

PAPER = str(CONFIGS / "paper_combined.toml")


def _blocker(tmp_path):
    f = tmp_path / "file"
    f.write_text("")
    return f


# ------------------------------------------------------------------ output paths
@pytest.mark.parametrize(
    "case",
    ["replay under a file", "replay is a directory", "out is a file", "out under a file"],
)
def test_output_paths_checked_before_the_run(tmp_path, capsys, case):
    blocker = _blocker(tmp_path)
    out = tmp_path / "out"
    argv = ["run", PAPER, "--duration", "0.2", "--out", str(out)]
    option, expected = {
        "replay under a file": ("--replay", "output directory"),
        "replay is a directory": ("--replay", "is a directory"),
        "out is a file": ("--out", "is a file"),
        "out under a file": ("--out", "is not writable"),
    }[case]
    if case == "replay under a file":
        argv += ["--replay", str(blocker / "r.html")]
    elif case == "replay is a directory":
        argv += ["--replay", str(tmp_path)]
    elif case == "out is a file":
        argv[argv.index("--out") + 1] = str(blocker)
    else:
        argv[argv.index("--out") + 1] = str(blocker / "sub")
    assert main(argv) == 2
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert len(err.splitlines()) == 1 and err.startswith(f"error: {option}: "), err
    assert expected in err and f"pass {option}" in err, err
    assert captured.out == ""  # nothing ran
    assert not list(tmp_path.glob("**/*.npz"))  # no output file written


def test_replay_out_that_is_a_directory(tmp_path, capsys):
    assert main(["run", PAPER, "--duration", "0.05", "--out", str(tmp_path)]) == 0
    capsys.readouterr()
    argv = ["replay", str(tmp_path / "paper_combined.npz"), "--out", str(tmp_path)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --out: output file") and "is a directory" in err, err


# ------------------------------------------------------------------ applied torque
def _saturating_config(write_config, limit: str) -> str:
    text = (CONFIGS / "paper_combined.toml").read_text(encoding="utf-8")
    text = text.replace('model = "planar3"', 'urdf = "@URDF@"')
    text = text.replace('integrator = "rk4"', f'integrator = "rk4"\neffort_limit = {limit}')
    return str(write_config(text))


def test_applied_torque_is_the_clipped_command_and_drives_the_plant(planar3):
    """``tau_applied`` = clip(τ, ±τmax) entrywise (closed form), and integrating the plant
    open loop with ``tau_applied`` reproduces the recorded states exactly (what the plant
    really got), while the commanded ``tau`` does not."""
    limit = np.array([150.0, 60.0, 20.0])
    ctrl = hmpc_pin.HierarchicalMPC(planar3)
    r = hmpc_pin.simulate(planar3, ctrl, hmpc_pin.SineReference(3), duration=1.2,
                          q0=np.zeros(3), effort_limit=limit)  # fmt: skip
    np.testing.assert_array_equal(r.tau_applied, np.minimum(np.maximum(r.tau, -limit), limit))
    assert (np.abs(r.tau) > limit).any(), "the test needs saturated periods"
    steps = (np.abs(r.tau[:-1]) > limit).sum(axis=0)
    assert r.meta["saturation"]["steps"] == steps.tolist()
    m = compute_metrics(r)
    np.testing.assert_array_equal(m.tau_applied_peak, np.abs(r.tau_applied).max(axis=0))
    assert (m.tau_applied_peak <= limit).all() and (m.tau_peak > limit).any()

    def replay(torques):
        plant = hmpc_pin.sim.plants.RK4Plant(planar3.copy(), None, ctrl.Ts, 0.001)
        plant.reset(np.zeros(3), np.zeros(3), 0.0)
        return np.array([np.zeros(3)] + [plant.advance(u)[0].copy() for u in torques[:-1]])

    np.testing.assert_array_equal(replay(r.tau_applied), r.q)
    assert np.abs(replay(r.tau) - r.q).max() > 1e-3


def test_result_file_keeps_the_applied_torque(tmp_path, planar3):
    limit = np.array([150.0, 60.0, 20.0])
    r = hmpc_pin.simulate(planar3, hmpc_pin.HierarchicalMPC(planar3), hmpc_pin.SineReference(3),
                          duration=0.2, q0=np.zeros(3), effort_limit=limit)  # fmt: skip
    loaded = hmpc_pin.Result.load(r.save(tmp_path / "r.npz"))
    np.testing.assert_array_equal(loaded.tau_applied, r.tau_applied)
    # A file written before 0.3 (no tau_applied): tau where nothing saturated, else NaN.
    import zipfile

    old = tmp_path / "old.npz"
    with zipfile.ZipFile(tmp_path / "r.npz") as src, zipfile.ZipFile(old, "w") as dst:
        for item in src.infolist():
            if item.filename != "tau_applied.npy":
                dst.writestr(item, src.read(item))
    assert np.isnan(hmpc_pin.Result.load(old).tau_applied).all()


# ------------------------------------------------------------------ warnings
def test_saturation_and_error_warnings_through_the_cli(tmp_path, capsys, write_config):
    cfg = _saturating_config(write_config, "[150.0, 60.0, 20.0]")
    argv = ["run", cfg, "--duration", "1.5", "--out", str(tmp_path / "o")]
    assert main(argv) == 0
    captured = capsys.readouterr()
    r = hmpc_pin.Result.load(tmp_path / "o" / "paper_combined.npz")
    steps = r.meta["saturation"]["steps"]
    lines = [x for x in captured.err.splitlines() if x.startswith("warning: ")]
    sat = [x for x in lines if "torque saturated" in x]
    assert len(sat) == 1
    for name, k, limit in zip(r.joint_names, steps, (150, 60, 20), strict=True):
        if k:
            peak = np.abs(r.tau[:, r.joint_names.index(name)]).max()
            assert f"{name} {k} of {len(r.t) - 1} periods (commanded peak {peak:.4g} N·m, " \
                   f"limit {limit:.4g} N·m)" in sat[0]  # fmt: skip
    with open(tmp_path / "o" / "paper_combined.csv", encoding="utf-8") as f:
        header = next(csv.reader(f))
    assert header[-3:] == [f"tau_applied_{j}" for j in r.joint_names]
    # The error warning follows --warn-error: below the measured max |e| after 1 s it
    # warns, above it it does not.
    e = np.abs(r.error[r.t >= 1.0 - 1e-12]).max()
    for threshold, warned in ((0.5 * e, True), (2.0 * e, False)):
        assert main([*argv, "--warn-error", repr(float(threshold)), "--force"]) == 0
        err = capsys.readouterr().err
        assert ("tracking error exceeds" in err) is warned, err


@pytest.mark.parametrize("value", ["0", "-0.1", "nan", "inf"])
def test_a_warn_error_threshold_must_be_a_positive_number(tmp_path, capsys, value):
    """``--warn-error`` is a tracking error [rad] > 0 and finite: exit 2, one line naming
    it, before anything is written."""
    out = tmp_path / "o"
    assert main(["run", PAPER, "--duration", "0.1", "--out", str(out), "--warn-error", value]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: --warn-error: expected a tracking")
    assert not out.exists()


def test_clean_run_has_no_warning(tmp_path, capsys):
    assert main(["run", PAPER, "--duration", "1.5", "--out", str(tmp_path)]) == 0
    assert "warning" not in capsys.readouterr().err


def test_run_warnings_from_a_hand_built_result():
    """Known answers: joint b saturates 2 of 4 periods, joint a's error after 1 s is 0.3."""
    t = np.array([0.0, 0.5, 1.0, 1.5, 2.0])
    q = np.zeros((5, 2))
    q[3, 0] = 0.3  # after 1 s on joint a
    q[1, 1] = 0.9  # before 1 s on joint b: not counted
    tau = np.array([[0, 0], [0, 5], [0, -7], [0, 1], [0, 0]], float)
    r = hmpc_pin.Result(t, q, q, tau, q, q, np.zeros_like(q), q, joint_names=("a", "b"),
                        meta={"saturation": {"effort_limit": [10.0, 4.0], "steps": [0, 2],
                                             "max_excess": [0.0, 3.0]}})  # fmt: skip
    lines = run_warnings(r, error_threshold=0.25)
    assert lines[0].startswith("torque saturated: b 2 of 4 periods (commanded peak 7 N·m, limit 4")
    assert lines[1].startswith("tracking error exceeds 0.25 rad after 1 s: max |e| a 0.3 rad")
    assert len(lines) == 2
    assert run_warnings(r, error_threshold=0.3) == lines[:1]  # 0.3 is not above 0.3


def test_replay_without_meshcat_stops_before_the_run(tmp_path):
    """A Python where ``import meshcat`` fails (a package of that name that raises, put
    first on the path): `run --replay` exits 2 before the run, with one line naming the
    extra as a wheel user installs it, and writes nothing."""
    import subprocess
    import sys

    shadow = tmp_path / "shadow" / "meshcat"
    shadow.mkdir(parents=True)
    (shadow / "__init__.py").write_text("raise ImportError('no meshcat here')\n")
    env = {**os.environ, "PYTHONPATH": str(shadow.parent), "MPLBACKEND": "Agg"}
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, "-m", "hmpc_pin", "run", str(CONFIGS / "paper_combined.toml"),
         "--duration", "2", "--replay", str(out / "r.html"), "--out", str(out)],
        capture_output=True, text=True, timeout=300, env=env,
    )  # fmt: skip
    assert proc.returncode == 2, proc.stderr
    err = proc.stderr.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: --replay: meshcat is not installed")
    assert "hmpc_pin[viz]" in err[0] and install_command("viz") in err[0]
    assert not out.exists()


def test_run_prints_the_first_contact_and_the_collision_flag(tmp_path, capsys):
    """MuJoCo, the arm pressing on a table with a collision watch: `run` prints the first
    contact and the flag, each checked against the saved arrays (the first instant the
    contact force is not zero; the first instant |d_hat| exceeds the threshold)."""
    pytest.importorskip("mujoco")
    cfg = CONFIGS / "planar3_contact_mujoco.toml"
    assert main(["run", str(cfg), "--duration", "2.0", "--out", str(tmp_path)]) == 0
    out, err = capsys.readouterr()
    result = hmpc_pin.Result.load(tmp_path / "planar3_contact_mujoco.npz")
    force = np.abs(result.extra["contact_force"]).max(axis=1)
    first = result.t[np.flatnonzero(force > 0)[0]]
    assert f"contact: first at t = {first:.3f} s with the obstacle" in out
    threshold = np.asarray(result.meta["collision"]["threshold"])
    over = np.flatnonzero((np.abs(result.d_hat) > threshold).any(axis=1))
    at = result.t[over[0]]
    joint = result.joint_names[int(np.argmax(np.abs(result.d_hat[over[0]]) / threshold))]
    assert f"collision: flagged at t = {at:.3f} s on {joint} (|d_hat| above its threshold" in out
    assert "reaction: ignore" in out
    for line in err.splitlines():  # the tracking warning says why
        if "tracking error exceeds" in line:
            assert "contact at t =" in line


def test_the_csv_holds_the_runs_arrays_exactly(tmp_path):
    """The CSV read back by the csv module equals the ``.npz`` arrays bit for bit (floats
    written as their shortest round-trip repr), with a NaN and an infinity planted; rows
    end in ``\\r\\n`` as csv.writer's do."""
    from hmpc_pin.apps.run import write_csv
    from hmpc_pin.sim.result import RESULT_ARRAYS

    assert main(["run", PAPER, "--duration", "0.3", "--out", str(tmp_path)]) == 0
    r = hmpc_pin.Result.load(tmp_path / "paper_combined.npz")
    r.q[3, 1] = np.nan
    r.tau[4, 0] = -np.inf
    write_csv(r, tmp_path / "again.csv")
    with open(tmp_path / "again.csv", newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    table = np.array(rows[1:], dtype=float)
    expected = np.column_stack([r.t] + [getattr(r, a) for a in RESULT_ARRAYS[1:]])
    assert table.shape == expected.shape
    np.testing.assert_array_equal(table, expected)
    assert (tmp_path / "again.csv").read_bytes().count(b"\r\n") == len(rows)


# ------------------------------------------------------------------ figures
def _pixels(path) -> np.ndarray:
    from PIL import Image

    with Image.open(path) as image:
        return np.asarray(image.convert("RGBA"))


FIGURES = ("tracking", "disturbance", "error")


def _figure_processes_of(pid: int) -> list[str]:
    """The figure processes (:mod:`hmpc_pin.apps.figure_worker`) started by ``pid``."""
    found = []
    for entry in os.listdir("/proc"):
        try:
            with open(f"/proc/{entry}/cmdline", "rb") as f:
                argv = f.read().decode(errors="replace").split("\0")
        except OSError:  # not a process, or it ended
            continue
        if "hmpc_pin.apps.figure_worker" in argv and str(pid) in argv:
            found.append(entry)
    return found


def test_the_command_lines_figure_process_draws_what_the_library_draws(tmp_path):
    """``hmpc-pin run`` (a real command-line process) draws its figures in its figure
    process: the command itself never imports matplotlib, the PNGs are pixel for pixel
    those the library draws here from the saved run, no ``.part`` file is left, and no
    process of the figures outlives the command."""
    import subprocess
    import sys

    from hmpc_pin.apps import plots
    from hmpc_pin.experiment.config import load_config

    out = tmp_path / "out"
    argv = [sys.executable, "-X", "importtime", "-m", "hmpc_pin", "run", PAPER,
            "--duration", "1.2", "--out", str(out)]  # fmt: skip
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    stdout, stderr = proc.communicate(timeout=300)
    assert proc.returncode == 0, stderr[-3000:]
    if sys.platform.startswith("linux"):
        assert not _figure_processes_of(proc.pid)
    # -X importtime lists the command's imports on its stderr (the figure process's go
    # nowhere): the command imported numpy, never matplotlib
    imported = {line.split("|")[-1].strip() for line in stderr.splitlines() if "|" in line}
    assert "numpy" in imported and "matplotlib" not in imported
    wrote = [line.split()[-1] for line in stdout.splitlines() if line.startswith("wrote ")]
    assert [os.path.basename(p) for p in wrote] == [
        "paper_combined.npz", "paper_combined.csv",
        *(f"paper_combined_{k}.png" for k in FIGURES),
    ]  # fmt: skip
    assert not list(out.glob("*.part"))
    result = hmpc_pin.Result.load(out / "paper_combined.npz")
    title = load_config(PAPER).description
    for kind in FIGURES:
        here = tmp_path / f"{kind}.png"
        plots.draw(kind, result, here, title, "with NDO")
        assert np.array_equal(_pixels(here), _pixels(out / f"paper_combined_{kind}.png")), kind


def test_figures_the_process_cannot_draw_are_drawn_by_the_command(tmp_path, monkeypatch):
    """The figure process cannot read the run (a damaged ``.npz``): the command draws
    every figure itself, the same as the library, and the process is gone."""
    from hmpc_pin import _startup
    from hmpc_pin.apps import figure_worker, plots
    from hmpc_pin.apps.run import draw_figures
    from hmpc_pin.experiment.config import load_config

    assert main(["run", PAPER, "--duration", "0.5", "--out", str(tmp_path), "--no-figures"]) == 0
    result = hmpc_pin.Result.load(tmp_path / "paper_combined.npz")
    config = load_config(PAPER)
    damaged = tmp_path / "damaged.npz"
    damaged.write_bytes(b"not a zip file")
    monkeypatch.setattr(_startup, "is_command_line", lambda: True)
    assert figure_worker.start()
    worker = figure_worker._worker
    files = draw_figures(config, result, tmp_path, "cfg", [damaged], error_label="with NDO")
    assert figure_worker._worker is None and worker.poll() is not None
    assert [p.name for p in files] == ["damaged.npz", *(f"cfg_{k}.png" for k in FIGURES)]
    for kind in FIGURES:
        here = tmp_path / f"{kind}.png"
        plots.draw(kind, result, here, config.description, "with NDO")
        assert np.array_equal(_pixels(here), _pixels(tmp_path / f"cfg_{kind}.png")), kind


@pytest.mark.skipif(not hasattr(os, "killpg"), reason="process groups: POSIX")
def test_ctrl_c_while_the_figure_process_draws(tmp_path):
    """A Ctrl-C in the terminal (SIGINT to the command's process group) once the table is
    printed, while the figure process draws: exit 130 with one line that names the data
    files written, no half-written figure, and no process of the figures left."""
    import signal
    import subprocess
    import sys
    import time

    proc = subprocess.Popen(
        [sys.executable, "-m", "hmpc_pin", "run", "panda_sine", "--out", str(tmp_path)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=True,  # its own process group, as a shell job
    )  # fmt: skip
    for line in proc.stdout:  # the table's last row: the figures are drawn from now on
        if line.startswith("panda_joint7"):
            break
    os.killpg(proc.pid, signal.SIGINT)
    try:
        _, err = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        pytest.fail("no exit within 60 s of SIGINT")
    assert proc.returncode == 130, err
    assert err.strip().startswith("interrupted at drawing the figures of panda_sine"), err
    assert "\n" not in err.strip() and "Traceback" not in err, err
    assert "panda_sine.npz" in err and "panda_sine.csv" in err
    assert hmpc_pin.Result.load(tmp_path / "panda_sine.npz").complete
    assert not list(tmp_path.glob("*.part"))
    for png in tmp_path.glob("*.png"):  # a figure finished before the Ctrl-C is listed
        assert png.name in err, err
    deadline = time.monotonic() + 3.0
    while _figure_processes_of(proc.pid) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not _figure_processes_of(proc.pid)
