"""The ``hmpc-pin`` command line: run, reproduce, exit codes, files written."""

from __future__ import annotations

import csv
import math
import re
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

import hmpc_pin
from hmpc_pin.apps.cli import main

from .conftest import CONFIGS

ALL_CONFIGS = sorted(p.stem for p in CONFIGS.glob("paper_*.toml"))


def test_every_paper_config_exists():
    expected = {
        f"paper_{c}{s}" for c in ("friction", "external", "combined") for s in ("", "_no_ndo")
    }
    assert expected | {"paper_cartesian"} <= set(ALL_CONFIGS)


# Eq 32 read literally without the observer: the run fails by design
# (docs: Concepts, decisions, "Friction sign").
FAILS_BY_DESIGN = ("paper_friction_literal_no_ndo",)


def test_literal_friction_without_observer_fails_and_keeps_its_data(tmp_path, capsys):
    name = FAILS_BY_DESIGN[0]
    assert main(["run", str(CONFIGS / f"{name}.toml"), "--out", str(tmp_path)]) == 1
    assert "error: run failed: simulation stopped in step" in capsys.readouterr().err
    r = hmpc_pin.Result.load(tmp_path / f"{name}.npz")
    assert not r.complete and 0.1 < r.t[-1] < 0.5
    # the friction fed energy in: d has the sign of q̇ (d·q̇ >= 0), the literal Eq 32
    assert np.all(r.d * r.dq >= 0) and np.any(r.d * r.dq > 0)


@pytest.mark.parametrize("name", [c for c in ALL_CONFIGS if c not in FAILS_BY_DESIGN])
def test_run_writes_npz_csv_and_figures(tmp_path, capsys, name):
    assert (
        main(["run", str(CONFIGS / f"{name}.toml"), "--out", str(tmp_path), "--duration", "1.5"])
        == 0
    )
    printed = capsys.readouterr().out
    assert "RMS e" in printed and "joint3" in printed
    result = hmpc_pin.Result.load(tmp_path / f"{name}.npz")
    assert result.complete and result.t[-1] == pytest.approx(1.5)
    label = "hmpc+none" if name.endswith("_no_ndo") else "hmpc+chen"
    assert result.meta["controller"] == label and f"({label}, observer" in printed
    with open(tmp_path / f"{name}.csv", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    joints = ("joint1", "joint2", "joint3")
    arrays = ("q", "dq", "tau", "d", "d_hat", "q_ref", "dq_ref", "tau_applied")
    assert rows[0] == ["t"] + [f"{a}_{j}" for a in arrays for j in joints]
    assert len(rows) == len(result.t) + 1
    np.testing.assert_allclose(np.array(rows[1:], dtype=float)[:, 1:4], result.q, rtol=1e-15)
    for suffix in ("tracking", "disturbance", "error"):
        png = tmp_path / f"{name}_{suffix}.png"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000


def test_no_figures_writes_the_data_files_only_and_the_same_run(tmp_path, capsys):
    """--no-figures: the .npz and .csv of the same run (bit for bit), no PNG, and the table
    printed as with figures."""
    cfg = str(CONFIGS / "paper_friction.toml")
    with_figures, without = tmp_path / "with", tmp_path / "without"
    assert main(["run", cfg, "--out", str(with_figures), "--duration", "1.2"]) == 0
    table = capsys.readouterr().out.split("wrote")[0]
    assert main(["run", cfg, "--out", str(without), "--duration", "1.2", "--no-figures"]) == 0
    printed = capsys.readouterr().out
    assert printed.split("wrote")[0] == table and ".png" not in printed
    assert sorted(p.name for p in without.iterdir()) == ["paper_friction.csv", "paper_friction.npz"]
    assert len(list(with_figures.glob("*.png"))) == 3
    a, b = (hmpc_pin.Result.load(d / "paper_friction.npz") for d in (with_figures, without))
    for name in ("q", "dq", "tau", "d", "d_hat"):
        np.testing.assert_array_equal(getattr(b, name), getattr(a, name))


def test_no_ndo_flag_disables_the_observer(tmp_path):
    cfg = str(CONFIGS / "paper_friction.toml")
    assert main(["run", cfg, "--out", str(tmp_path), "--duration", "1", "--no-ndo"]) == 0
    r = hmpc_pin.Result.load(tmp_path / "paper_friction_no_ndo.npz")
    assert np.all(r.d_hat == 0) and r.meta["observer"] is False
    assert r.meta["controller"] == "hmpc+none"
    # the same run as the baseline config file
    base = tmp_path / "base"
    no_ndo = str(CONFIGS / "paper_friction_no_ndo.toml")
    assert main(["run", no_ndo, "--out", str(base), "--duration", "1"]) == 0
    np.testing.assert_array_equal(hmpc_pin.Result.load(base / "paper_friction_no_ndo.npz").q, r.q)


def test_no_ndo_flag_on_a_config_without_compensation_is_bad_input(tmp_path, capsys):
    cfg = str(CONFIGS / "paper_friction_no_ndo.toml")
    out = tmp_path / "o"
    assert main(["run", cfg, "--out", str(out), "--duration", "1", "--no-ndo"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --no-ndo") and "hmpc+none" in err, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not out.exists() or not any(out.iterdir())


def test_compensation_flag_replaces_the_compensation(tmp_path, capsys):
    from hmpc_pin.experiment.build import run_experiment, with_controller

    cfg = CONFIGS / "paper_friction.toml"
    argv = ["run", str(cfg), "--out", str(tmp_path), "--duration", "1"]
    assert main([*argv, "--compensation", "momentum"]) == 0
    assert "(hmpc+momentum, observer on)" in capsys.readouterr().out
    r = hmpc_pin.Result.load(tmp_path / "paper_friction_momentum.npz")
    assert r.meta["controller"] == "hmpc+momentum" and r.meta["observer"] is True
    assert np.any(r.d_hat != 0)
    config = with_controller(hmpc_pin.load_config(cfg), compensation="momentum")
    np.testing.assert_array_equal(run_experiment(config, duration=1.0).q, r.q)
    assert (tmp_path / "paper_friction_momentum.csv").is_file()
    # on the baseline config too: --compensation adds what the file switched off
    assert main(["run", str(CONFIGS / "paper_friction_no_ndo.toml"), "--out", str(tmp_path),
                 "--duration", "1", "--compensation", "chen"]) == 0  # fmt: skip
    r = hmpc_pin.Result.load(tmp_path / "paper_friction_no_ndo_chen.npz")
    assert r.meta["controller"] == "hmpc+chen" and np.any(r.d_hat != 0)
    capsys.readouterr()
    assert main([*argv, "--compensation", "magic"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --compensation") and "'magic'" in err
    assert len(err.strip().splitlines()) == 1


def test_run_a_packaged_config_by_name(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # no file of that name here: the package's
    assert main(["run", "paper_external", "--out", str(tmp_path), "--duration", "1"]) == 0
    r = hmpc_pin.Result.load(tmp_path / "paper_external.npz")
    assert r.complete and r.meta["config"].endswith("paper_external.toml")


@pytest.mark.parametrize("argv", [["--help"], ["run", "--help"], ["reproduce", "--help"]])
def test_help(argv, capsys):
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 0
    assert "usage: hmpc-pin" in capsys.readouterr().out


def test_python_dash_m_entry_point():
    out = subprocess.run(
        [sys.executable, "-m", "hmpc_pin", "--help"], capture_output=True, text=True, check=True
    )
    assert "reproduce" in out.stdout


def _write(path, text):
    path.write_text(text)
    return path


def _unreachable(tmp_path):
    text = (CONFIGS / "paper_cartesian.toml").read_text()
    text = text.replace("goal_position = [2.423, 2.234]", "goal_position = [4.0, 0.0]")
    text = text.replace(
        'model = "planar3"', f'urdf = "{CONFIGS.parent.as_posix()}/robots/planar3.urdf"'
    )
    path = tmp_path / "far.toml"
    path.write_text(text)
    return path


BAD_INPUTS = {
    "missing config": (lambda tmp: ["run", str(tmp / "none.toml")], "not found"),
    "not TOML": (lambda tmp: ["run", str(_write(tmp / "x.toml", "[[["))], "not valid TOML"),
    "negative duration": (
        lambda tmp: ["run", str(CONFIGS / "paper_combined.toml"), "--duration", "-1"],
        "--duration",
    ),
    "zero duration": (  # the boundary: no simulated time is no run
        lambda tmp: ["run", str(CONFIGS / "paper_combined.toml"), "--duration", "0"],
        "--duration: expected a number of seconds > 0, got 0.0",
    ),
    "unreachable goal": (
        lambda tmp: ["run", str(_unreachable(tmp)), "--out", str(tmp / "o")],
        "cannot reach tool (4, 0)",
    ),
    "output not writable": (
        lambda tmp: [
            "run",
            str(CONFIGS / "paper_combined.toml"),
            "--out",
            str(_write(tmp / "file", "") / "sub"),
        ],
        "not writable",
    ),
}


@pytest.mark.parametrize("case", sorted(BAD_INPUTS))
def test_bad_input_exits_2_with_one_line(tmp_path, capsys, case):
    make, words = BAD_INPUTS[case]
    assert main(make(tmp_path)) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and words in err, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err


def test_failed_run_exits_1_and_keeps_partial_results(tmp_path, capsys):
    """The explicit-Euler observer at c = 200 diverges (docs: Concepts, decisions): exit 1,
    data kept.

    The divergence is caught either as a non-finite state or as the soft
    state-constrained QP failing on the runaway state, whichever comes first."""
    text = (CONFIGS / "paper_combined.toml").read_text()
    text = text.replace('discretization = "implicit"', 'discretization = "explicit"')
    text = re.sub(r"^gain = .*$", "gain = 200.0", text, flags=re.M)
    text = text.replace(
        'model = "planar3"', f'urdf = "{CONFIGS.parent.as_posix()}/robots/planar3.urdf"'
    )
    cfg = tmp_path / "bad.toml"
    cfg.write_text(text)
    assert main(["run", str(cfg), "--out", str(tmp_path)]) == 1
    assert "run failed" in capsys.readouterr().err
    r = hmpc_pin.Result.load(tmp_path / "paper_combined.npz")
    assert not r.complete and 0 < r.t[-1] < 10
    assert "not finite" in r.message or "QP was not solved" in r.message
    assert (tmp_path / "paper_combined.csv").stat().st_size > 0


@pytest.fixture(scope="module")
def reproduced(tmp_path_factory):
    out = tmp_path_factory.mktemp("reproduce")
    assert main(["reproduce", "--out", str(out), "--quiet"]) == 0
    return out


def test_reproduce_writes_report_with_every_figure(reproduced):
    report = (reproduced / "report.md").read_text()
    figures = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", report)
    for fig in ("Figure 3(b)", *(f"Figure {k}" for k in range(4, 11))):
        assert fig in report
    assert len(figures) >= 13
    for name in figures:
        png = reproduced / name
        assert png.read_bytes()[:4] == b"\x89PNG" and png.stat().st_size > 10_000
    for name in ("paper_friction", "paper_external", "paper_combined", "paper_cartesian"):
        assert (reproduced / f"{name}.npz").is_file() and (reproduced / f"{name}.csv").is_file()


def _verdicts(report: str, section: str) -> list[tuple[str, str]]:
    """(check, verdict) of every claim row of ``section`` ("5" or "1")."""
    out = []
    for line in report.splitlines():
        if re.match(rf"^\| {section}(\.\d)? \|", line):
            cells = [c.strip() for c in re.split(r"(?<!\\)\|", line)[1:-1]]
            out.append((cells[2], cells[4]))
    return out


# The verdicts measured on the full-length runs (`hmpc-pin reproduce`), in report order.
# "no" rows are readings under which the paper's sentence does not hold: the physical sign
# without NDO stays bounded (an offset), the literal sign (d = +F) settles after 0.5 s.
SECTION5_VERDICTS = [
    ("RMS(d − d̂) after 1 s below 20 %", "yes"),
    ("'converge' read as 'reach and stay within 0.01 rad'", "yes"),
    ("'converge' read as 'stay bounded': without NDO the run fails or max", "**no**"),
    ("Eq 32 read literally (d = +F), 'converge' read as 'stay bounded'", "yes"),
    ("stays below 0.02 rad (2 % of the amplitude", "yes"),
    ("Eq 32 read literally (d = +F), observer gain c = 300", "**no**"),
    ("peak \\|d − d̂\\| after 1 s below 25 %", "yes"),
    ("every joint stays within 0.01 rad from some finite time on", "yes"),
    ("at least 5× lower than without", "yes"),
    ("time to stay within 0.01 rad at most 0.6 s", "yes"),
    ("final tool position error below 1e-3", "yes"),  # passes without NDO too (5.0e-4)
    ("max tool position error during the move", "yes"),  # 2.3e-3 with NDO, 4.2e-2 without
]
COMPARISON_VERDICTS = [
    ("TV(τ) of hmpc-ism at least 10×", "yes"),
    ("read as 'at least as accurate'", "yes"),
    ("below hmpc-ism-bl", "**no**"),  # the boundary layer tracks as well: not the paper's claim
    ("hmpc-none: some joint never stays within 0.01 rad", "yes"),
    ("below computed-torque on at least 2", "yes"),
    ("below computed-torque-pid on at least 2", "yes"),
]


def test_reproduce_paper_claims_have_the_measured_verdicts(reproduced):
    """Every claim row of Section 5, in order, with the verdict measured on the full runs."""
    rows = _verdicts((reproduced / "report.md").read_text(), "5")
    assert len(rows) == len(SECTION5_VERDICTS), rows
    for (check, verdict), (expected_check, expected) in zip(rows, SECTION5_VERDICTS, strict=True):
        assert expected_check in check and verdict == expected, (check, verdict)


def test_reproduce_report_compares_the_controllers(reproduced):
    """Issue 8: the report holds the controller comparison and a verdict per claim."""
    report = (reproduced / "report.md").read_text()
    assert "## Controller comparison on the Section 5.3 scenario" in report
    for kind in ("hmpc", "hmpc-none", "hmpc-momentum", "hmpc-ism", "hmpc-ism-bl"):
        assert f"| {kind} | joint1 |" in report
    rows = _verdicts(report, "1")
    assert len(rows) == len(COMPARISON_VERDICTS), rows
    for (check, verdict), (expected_check, expected) in zip(rows, COMPARISON_VERDICTS,
                                                            strict=True):  # fmt: skip
        assert expected_check in check and verdict == expected, (check, verdict)
    assert '"the proposed controller provides comparative accuracy and robustness"' in report


def test_run_replay_and_replay_command(tmp_path, capsys):
    """`run --replay` and `replay RESULT.npz` write the same self-contained page."""
    pytest.importorskip("meshcat")
    cfg = str(CONFIGS / "paper_external.toml")
    html = tmp_path / "run.html"
    argv = ["run", cfg, "--out", str(tmp_path), "--duration", "2", "--replay", str(html)]
    assert main(argv) == 0
    again = tmp_path / "again.html"
    assert main(["replay", str(tmp_path / "paper_external.npz"), "--out", str(again)]) == 0
    for page in (html, again):
        text = page.read_text()
        assert "MeshCat.Viewer" in text and "data:application/octet-binary;base64," in text
    assert main(["replay", str(tmp_path / "missing.npz")]) == 2
    assert "not found" in capsys.readouterr().err


def test_run_and_replay_a_panda_with_locked_fingers(tmp_path, capsys):
    """An example-robot-data arm runs from its config, and `replay` rebuilds the reduced
    model from the result's metadata (URDF + locked joints)."""
    cfg = CONFIGS / "panda_sine.toml"
    assert main(["run", str(cfg), "--out", str(tmp_path), "--duration", "1.2"]) == 0
    out = capsys.readouterr().out
    assert "panda_joint7" in out and "limit viol." in out
    npz = tmp_path / "panda_sine.npz"
    html = tmp_path / "panda.html"
    assert main(["replay", str(npz), "--out", str(html)]) == 0
    from .test_viz import _commands

    objects = {c["path"] for c in _commands(html.read_text()) if c["type"] == "set_object"}
    # the fingers are locked, not dropped: their meshes are in the scene
    assert any("panda_leftfinger" in p for p in objects), objects
    assert any("panda_link7" in p for p in objects)


def test_a_warning_of_the_urdf_loaded_twice_is_printed_once(tmp_path, capsys):
    """`init` loads the arm's URDF more than once (without the command line's
    once-per-message rule its warning is printed twice): a link breaking the triangle
    inequality (I1 + I2 = 0.100001 < I3 = 0.28) warns once, as one ``warning:`` line on
    stderr, and the config is written (exit 0)."""
    text = (CONFIGS.parent / "robots" / "planar3.urdf").read_text()
    bad = 'iyy="0.1" iyz="0" izz="0.28125"/>'
    text = text.replace('iyy="0.28125" iyz="0" izz="0.28125"/>', bad, 1)
    assert bad in text
    urdf = _write(tmp_path / "arm.urdf", text)
    out = tmp_path / "arm.toml"
    assert main(["init", str(urdf), "--out", str(out)]) == 0
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if "triangle inequality" in line]
    assert len(lines) == 1 and lines[0].startswith("warning: ") and "'link1'" in lines[0], err
    assert out.is_file()


def _ros_in_netns(tmp_path, command: str, rate: float):
    """``hmpc-pin <command>`` (``ros`` or ``ros-arm``) on panda_sine with ``[ros] rate``
    and ``--duration 0.1``, in a private network namespace; (the finished process, the
    ``--out`` folder given to ``ros``)."""
    text = (CONFIGS / "panda_sine.toml").read_text() + f"\n[ros]\nrate = {rate}\n"
    cfg = _write(tmp_path / "arm.toml", text)
    out = tmp_path / "out"
    args = [command, str(cfg), "--duration", "0.1"] + (
        ["--out", str(out)] if command == "ros" else []
    )
    script = f"ip link set lo up && exec {sys.executable} -m hmpc_pin {' '.join(args)}"
    proc = subprocess.run(["unshare", "-n", "bash", "-c", script], capture_output=True,
                          text=True, timeout=300)  # fmt: skip
    return proc, out


@pytest.mark.parametrize("command, rate", [("ros", 150.0), ("ros-arm", 150.0),
                                           ("ros-arm", 300.0)])  # fmt: skip
def test_a_ros_rate_that_does_not_fit_is_named_ros_rate_before_anything_runs(
    tmp_path, command, rate
):
    """[ros] rate = 150 Hz is 1.5 control periods of 10 ms (the controller node, `ros`,
    and the arm node, `ros-arm`); 300 Hz divides Ts but is no whole number of the arm's
    plant.dt = 1 ms (`ros-arm`): exit 2, one ``error: ros.rate:`` line (not realtime.rate
    nor plant.dt's own error) naming the rate, and for the arm node its period and the
    nearest rates that are whole numbers of plant.dt, 1/(k dt); nothing printed before it,
    no --out folder. In a private network namespace: a node that started anyway would
    speak DDS."""
    from .test_ros import _netns_reason

    reason = _netns_reason()
    if reason:
        pytest.skip(reason)
    proc, out = _ros_in_netns(tmp_path, command, rate)
    assert proc.returncode == 2, (proc.stdout, proc.stderr)
    err = proc.stderr.strip()
    assert err.startswith("error: ros.rate: ") and len(err.splitlines()) == 1, err
    assert "realtime.rate" not in err and "plant.dt=" not in err, err
    assert proc.stdout == "" and not out.exists(), proc.stdout
    if command == "ros-arm":  # one sentence: the rate, its period, what is expected
        k = math.floor(1.0 / rate / 1e-3)  # plant.dt = 1 ms
        near = " or ".join(f"{1.0 / (m * 1e-3):g} Hz" for m in (k, k + 1))
        assert err == (
            f"error: ros.rate: {rate:g} Hz gives the arm node a period 1/rate = {1 / rate:g} s "
            "that is not a whole number of the plant's steps (plant.dt = 0.001 s); expected "
            f"a rate 1/(k plant.dt) with k = 1, 2, ..., e.g. {near}"
        ), err


@pytest.mark.parametrize("command", ["ros-arm", "ros"])
def test_a_ros_run_shorter_than_one_period_is_refused_before_any_node(tmp_path, command):
    """[ros] rate = 0.5 Hz: a --duration of 0.1 s is no period of 2 s (it would run
    round(0.1 * 0.5) = 0 steps and exit 0 as if it had run): exit 2, one line naming
    --duration, the period 1/ros.rate and what is expected; 2 s (one period) is accepted by
    the check (`ros-arm` then refuses nothing more and would start; not run here). In a
    private network namespace: a node that started anyway would speak DDS."""
    from .test_ros import _netns_reason

    reason = _netns_reason()
    if reason:
        pytest.skip(reason)
    proc, out = _ros_in_netns(tmp_path, command, 0.5)
    assert proc.returncode == 2, (proc.stdout, proc.stderr)
    err = proc.stderr.strip()
    assert err == (
        "error: --duration: expected at least one period of the node, 1/ros.rate = 2 s "
        "([ros] rate = 0.5 Hz), got 0.1 s; lengthen it or raise [ros] rate"
    ), err
    assert proc.stdout == "" and not out.exists(), proc.stdout


def test_a_ros_run_length_and_the_arm_nodes_rate_are_checked_against_the_period(tmp_path):
    """The checks behind the two refusals, without a node: a run of at least one period
    1/rate passes (the period itself too, to rounding), a shorter one is refused under the
    key given; a rate 1/(k dt) of the plant's fixed step passes, another names ros.rate."""
    from hmpc_pin.apps.ros import check_arm_rate, check_run_length
    from hmpc_pin.exceptions import ConfigError

    check_run_length(2.0, 0.5, "--duration")
    check_run_length(0.1, 10.0, "--duration")  # 1/10 s, computed as 0.1 again
    with pytest.raises(ConfigError, match=r"^simulation\.duration: .*1/ros\.rate = 0\.5 s"):
        check_run_length(0.499, 2.0, "simulation.duration")
    base = hmpc_pin.load_config(CONFIGS / "panda_sine.toml")
    dt = base.plant.dt
    for k in (1, 3, 7):
        check_arm_rate(replace(base, ros=replace(base.ros, rate=1.0 / (k * dt))))
    with pytest.raises(ConfigError, match=r"^ros\.rate: 300 Hz .*plant\.dt = 0\.001 s"):
        check_arm_rate(replace(base, ros=replace(base.ros, rate=300.0)))


def test_init_writes_the_duration_it_is_given(tmp_path, capsys):
    """``init --duration 3`` writes simulation.duration = 3 s; without it, the run friction
    identification needs: the last pulse (3 s for 3 joints) plus 4 sigma (1.2 s), then a
    whole period of the sine (10 s at 0.1 Hz), in whole seconds: 15 s."""
    for argv, expected in (([], 15.0), (["--duration", "3"], 3.0)):
        out = tmp_path / f"p{len(argv)}.toml"
        assert main(["init", "planar3", "--out", str(out), *argv]) == 0
        config = hmpc_pin.load_config(out)
        assert config.simulation.duration == expected
        pulse = config.disturbance.pulse
        need = max(pulse.center) + 4 * float(pulse.sigma) + 1 / config.reference.frequency
        assert expected == (math.ceil(need) if not argv else 3.0)


@pytest.mark.parametrize("priority, ok", [(0, True), (1, True), (99, True), (-1, False),
                                          (100, False)])  # fmt: skip
def test_priority_zero_is_off_and_1_to_99_are_sched_fifo(priority, ok):
    """--priority 0 turns SCHED_FIFO off (accepted), 1..99 are its priorities; anything
    else is refused naming --priority."""
    from hmpc_pin.apps.cli import _checked_priority
    from hmpc_pin.exceptions import ConfigError

    if ok:
        assert _checked_priority(priority) == priority
    else:
        with pytest.raises(ConfigError, match=r"--priority.*0 \(off\) or 1\.\.99"):
            _checked_priority(priority)
