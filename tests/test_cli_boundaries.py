"""Bad input a wheel user met, each refused at the boundary with one line (exit 2), and
small inconsistencies between commands: a duration too long for the memory, a recorded run
as a trajectory reference, ``check`` of a file that is not a config, warnings on stderr,
``init --list``, a run's files not replaced silently."""

from __future__ import annotations

import re

import pytest

import hmpc_pin
from hmpc_pin.apps.cli import main
from hmpc_pin.exceptions import ConfigError

from .conftest import CONFIGS


def _mem_available() -> float:
    """MemAvailable [bytes], read here independently of the package."""
    with open("/proc/meminfo", encoding="ascii") as f:
        return next(float(ln.split()[1]) * 1024 for ln in f if ln.startswith("MemAvailable:"))


def test_a_duration_too_long_for_the_memory_is_one_line_naming_the_option(tmp_path, capsys):
    """1e9 s at Ts = 0.01 s on 3 joints: 1e11 samples, far beyond any memory; before, a
    numpy MemoryError traceback (exit 1)."""
    out = tmp_path / "o"
    assert main(["run", "paper_combined", "--duration", "1e9", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: --duration: 1e+09 s"), err
    assert "Traceback" not in err[0] and not out.exists()
    # the longest duration it names fills half the memory available: 8 bytes x (9 arrays
    # x 3 joints + t + step time) per sample, one sample per Ts = 0.01 s
    longest = float(re.search(r"at most ([\d.e+]+) s", err[0]).group(1))
    need = 8 * (9 * 3 + 2) * (longest / 0.01 + 1)
    assert need == pytest.approx(0.5 * _mem_available(), rel=0.2)


def test_the_library_refuses_the_same_duration_before_allocating():
    config = hmpc_pin.load_config("paper_combined")
    from dataclasses import replace

    config = replace(config, simulation=replace(config.simulation, duration=1e9))
    with pytest.raises(ConfigError, match=r"simulation\.duration: .* GB"):
        hmpc_pin.Experiment.from_config(config)
    ex = hmpc_pin.Experiment.from_config(hmpc_pin.load_config("paper_combined"))
    with pytest.raises(ConfigError, match=r"^duration: "):
        ex.run(duration=1e9)


# ------------------------------------------------------------- Ctrl-C of a sweep's pool
class _CtrlCOnFirstRow:
    """A progress bar whose first update is a Ctrl-C (as one arriving in the loop)."""

    def update(self):
        raise KeyboardInterrupt


def test_a_stopped_pool_leaves_no_manager_thread_for_the_exit_hook():
    """After a Ctrl-C the pool's manager thread is joined before the interrupt goes on:
    left running, it closed its wake-up pipe while concurrent.futures' exit hook wrote to
    it (no lock in CPython 3.11): ``OSError: Bad file descriptor`` at exit, 1 time in 8."""
    import concurrent.futures.process as cfp

    from hmpc_pin.apps.sweep import _run_pool, draw_samples

    config = hmpc_pin.load_config("paper_combined")
    from dataclasses import replace

    config = replace(config, simulation=replace(config.simulation, duration=0.2))
    params = draw_samples(config, 2, 0)
    tasks = [(p, "ndo", "all") for p in params]
    with pytest.raises(KeyboardInterrupt):
        _run_pool(config, tasks, 2, {}, _CtrlCOnFirstRow())
    alive = [t for t in list(cfp._threads_wakeups) if t.is_alive()]
    assert not alive, alive


@pytest.mark.slow
@pytest.mark.parametrize("after", [1, 3, 5, 6])
def test_ctrl_c_of_a_two_job_sweep_at_any_stage_prints_no_traceback(tmp_path, after):
    """A real SIGINT to the process group of ``hmpc-pin sweep --jobs 2`` once ``after``
    of its 6 runs are done (6: while it shuts its pool down and writes)."""
    import os
    import signal
    import subprocess
    import sys
    import time

    err = open(tmp_path / "err.txt", "w+", encoding="utf-8")  # noqa: SIM115
    proc = subprocess.Popen(
        [sys.executable, "-m", "hmpc_pin", "sweep", "paper_combined", "--samples", "3",
         "--jobs", "2", "--duration", "0.5", "--out", "o"],
        stdout=subprocess.PIPE, stderr=err, text=True, start_new_session=True, cwd=tmp_path,
    )  # fmt: skip
    end = time.monotonic() + 300
    while time.monotonic() < end and proc.poll() is None:
        err.seek(0)
        done = re.findall(r"\| *(\d+)/6 ", err.read())
        if done and int(done[-1]) >= after:
            break
        time.sleep(0.02)
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGINT)
    proc.communicate(timeout=60)
    err.seek(0)
    text = err.read()
    err.close()
    assert "Traceback" not in text and "Bad file descriptor" not in text, text[-3000:]
    assert proc.returncode in (0, 130, -signal.SIGINT), (proc.returncode, text[-2000:])


# ------------------------------------------------- a recorded run as a trajectory reference
def test_a_saved_run_is_a_trajectory_reference_through_its_measured_samples(tmp_path):
    """A run's .npz (t, q, dq, joint_names as the trajectory tutorial asks, plus the run's
    other arrays) was refused ("unknown array 'complete'"); the reference passes through
    its measured samples (an interpolant through its knots), a stopped run's NaN tail cut."""
    import numpy as np

    from hmpc_pin.tasks.trajectory import load_trajectory

    result = hmpc_pin.Experiment.from_config(hmpc_pin.load_config("paper_combined")).run(0.5)
    path = result.save(tmp_path / "rec.npz")
    names = list(result.joint_names)
    traj = load_trajectory(path, names[::-1])  # matched by name, any order
    for k in (0, 7, len(result.t) // 2, len(result.t) - 2):  # (the last point: held)
        q, dq = traj.sample(float(result.t[k]))
        np.testing.assert_allclose(q, result.q[k][::-1], rtol=0, atol=1e-12)
        np.testing.assert_allclose(dq, result.dq[k][::-1], rtol=0, atol=1e-9)
    # a run stopped after 20 samples: NaN afterwards, as a partial run keeps them
    with np.load(path) as f:
        arrays = {k: f[k] for k in f.files}
    for key in ("q", "dq"):
        arrays[key] = arrays[key].copy()
        arrays[key][20:] = np.nan
    arrays["complete"] = np.array(False)
    np.savez(tmp_path / "stopped.npz", **arrays)
    stopped = load_trajectory(tmp_path / "stopped.npz", names)
    np.testing.assert_allclose(stopped.sample(float(result.t[30]))[0], result.q[19], atol=1e-12)


def test_run_takes_a_saved_run_as_reference(tmp_path, capsys):
    run = ["run", "paper_combined", "--duration", "0.3", "--no-figures", "--out"]
    assert main([*run, str(tmp_path / "a")]) == 0
    recorded = str(tmp_path / "a" / "paper_combined.npz")
    code = main([*run, str(tmp_path / "b"), "--reference", recorded])
    assert code == 0, capsys.readouterr().err


# ------------------------------------------------------ init: the plant step and --list
def test_init_xarm7_says_how_to_trade_its_short_plant_step_and_the_trade_runs(tmp_path, capsys):
    """xarm7's stiff joint damping makes init choose dt = 2e-5 s; init says so on stderr
    with [plant] tolerance, and that tolerance works: its step is one the damping allows
    (h b_j (M^-1)_jj <= 1.39 for RK4, from CRBA here), where before it chose a step the
    damping check then refused."""
    import numpy as np
    import pinocchio as pin

    out = tmp_path / "xarm7.toml"
    assert main(["init", "xarm7", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    (note,) = [ln for ln in err.splitlines() if ln.startswith("note: the plant steps at dt")]
    assert "2e-05" in note and "tolerance = 1e-4" in note and "joint_dynamics = false" in note
    text = out.read_text(encoding="utf-8")
    assert re.search(r"^dt = 2e-05$", text, re.M)
    out.write_text(re.sub(r"^dt = 2e-05$", "tolerance = 1e-4", text, flags=re.M))
    config = hmpc_pin.load_config(out)
    ex = hmpc_pin.Experiment.from_config(config)
    plant = ex.make_plant()
    h = config.controller.Ts / plant.substeps
    model = ex.robot.model
    M = pin.crba(model, model.createData(), ex.q0)
    M = np.triu(M) + np.triu(M, 1).T
    lam = np.asarray(ex.robot.joint_damping) * np.diag(np.linalg.inv(M))
    assert h * lam.max() <= 1.39 and h > 2e-5  # allowed, and longer than init's dt
    assert ex.run(0.2).complete


def test_init_list_names_the_floating_base_arms_too(capsys):
    """so100 and so101 (arms example-robot-data mounts on a floating base) were left out."""
    assert main(["init", "--list"]) == 0
    names = [ln.split()[0] for ln in capsys.readouterr().out.splitlines()]
    assert {"planar3", "ur5", "panda", "so100", "so101"} <= set(names)


# ------------------------------------------------------------------- check's messages
def test_check_of_a_saved_run_says_it_is_not_a_config(tmp_path, capsys):
    result = hmpc_pin.Experiment.from_config(hmpc_pin.load_config("paper_combined")).run(0.05)
    path = result.save(tmp_path / "run.npz")
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "utf-8" not in err[0] and "codec" not in err[0]
    assert "is an .npz archive (a saved run or trajectory), not an experiment config" in err[0]
    (tmp_path / "blob.toml").write_bytes(bytes(range(128, 256)))
    assert main(["check", str(tmp_path / "blob.toml")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is not a text file (not UTF-8)" in err[0]


# ------------------------------------------------------------ an earlier run's files
def test_run_keeps_an_earlier_runs_files_without_force(tmp_path, capsys):
    """As ``init`` keeps an existing config: a second run of the same name into the same
    folder is refused before it runs (its data untouched), and replaces them with --force."""
    args = ["run", "paper_combined", "--duration", "0.2", "--no-figures", "--out", str(tmp_path)]
    assert main(args) == 0
    npz = tmp_path / "paper_combined.npz"
    before = npz.read_bytes()
    capsys.readouterr()
    assert main([*args[:3], "0.3", *args[4:]]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--force" in err[0] and str(npz) in err[0], err
    assert npz.read_bytes() == before
    assert main([*args[:3], "0.3", *args[4:], "--force"]) == 0
    import numpy as np

    with np.load(npz) as data:
        assert data["t"][-1] == pytest.approx(0.3)


@pytest.mark.parametrize(
    ("argv", "name"),
    [
        (["compare", "paper_combined", "--controllers", "hmpc"], "paper_combined_compare.csv"),
        (["compare", "paper_combined", "--controllers", "hmpc"], "paper_combined_compare.md"),
        (["sweep", "paper_combined", "--samples", "1", "--jobs", "1"], "paper_combined_sweep.csv"),
        (["realtime", "panda_sine", "--duration", "0.5"], "panda_sine_realtime_timing.npz"),
        (["realtime", "panda_sine", "--duration", "0.5"], "panda_sine_realtime.json"),
        (["ros", "panda_sine", "--duration", "0.5"], "panda_sine_ros.npz"),
        (["franka", "fr3_sine", "--robot-ip", "127.0.0.1"], "fr3_sine_franka_cycles.npz"),
    ],
    ids=lambda x: x if isinstance(x, str) else x[0],
)
def test_every_run_writer_keeps_an_earlier_runs_files(tmp_path, capsys, argv, name):
    """``compare``, ``sweep``, ``realtime``, ``ros`` and ``franka`` refuse, as ``run``
    does, before anything runs (no arm process, node or robot connection), to replace a
    file they would write: exit 2, one line naming the file and --force, the file kept."""
    if argv[0] == "ros":
        pytest.importorskip("rclpy")
    earlier = tmp_path / name
    earlier.write_bytes(b"an earlier run")
    assert main([*argv, "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(earlier) in err[0] and "pass --force" in err[0], err
    assert earlier.read_bytes() == b"an earlier run"
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]  # nothing else written


@pytest.mark.parametrize(
    ("argv", "name"),
    [
        (["compare", "paper_combined", "--controllers", "hmpc"], "paper_combined_compare.csv"),
        (["sweep", "paper_combined", "--samples", "1", "--jobs", "1"], "paper_combined_sweep.csv"),
    ],
    ids=("compare", "sweep"),
)
def test_force_replaces_an_earlier_runs_files(tmp_path, capsys, argv, name):
    """With --force the same command replaces them (here a 0.2 s run)."""
    earlier = tmp_path / name
    earlier.write_bytes(b"an earlier run")
    args = [*argv, "--duration", "0.2", "--quiet", "--out", str(tmp_path), "--force"]
    assert main(args) == 0
    capsys.readouterr()
    assert earlier.read_bytes() != b"an earlier run"
    assert earlier.read_text(encoding="utf-8").startswith(("controller,", "sample,"))  # its table


# ----------------------------------------------------------- hmpc-pin ros --ros-args
def test_ros_args_are_read_as_rcl_reads_them():
    """No ROS needed: the parameters and the node's name and namespace remaps."""
    from hmpc_pin.apps.ros_args import check_parameters, parse_ros_args

    args = ["-p", "use_sim_time:=true", "-r", "__node:=ctrl", "--log-level", "debug",
            "-r", "/joint_states:=/arm/joint_states", "-p", "other:ros.rate:=1.0",
            "-p", "hmpc_pin:realtime.spin:=0.0", "-r", "__ns:=/arm7"]  # fmt: skip
    got = parse_ros_args(args, "hmpc_pin")
    assert got.parameters == {"use_sim_time": "true", "realtime.spin": "0.0"}
    assert (got.node, got.namespace) == ("ctrl", "/arm7")
    check_parameters(got.parameters, ["realtime.spin"])
    with pytest.raises(ConfigError, match=r"-p nosuch\.param: the node has no such parameter; "
                       r"its parameters are .*realtime\.spin.*use_sim_time"):  # fmt: skip
        check_parameters({"nosuch.param": "1"}, ["realtime.spin"])
    with pytest.raises(ConfigError, match="expected name:=value"):
        parse_ros_args(["-p", "use_sim_time"], "hmpc_pin")


def _ros_in_netns(tmp_path, ros_args: str):
    """``hmpc-pin ros`` in a private network namespace (DDS never leaves it), with no
    arm: it names its node, then exits 2 on no joint state within 1 s."""
    import subprocess
    import sys

    from .test_ros import _netns_reason

    reason = _netns_reason()
    if reason:
        pytest.skip(reason)
    text = (CONFIGS / "panda_sine.toml").read_text(encoding="utf-8")
    config = tmp_path / "c.toml"
    config.write_text(text + "\n[ros]\nstart_timeout = 1.0\njoint_states = '/nobody'\n")
    script = (f"ip link set lo up && exec {sys.executable} -m hmpc_pin ros {config} "
              f"--out {tmp_path / 'out'} --duration 1 --ros-args {ros_args}")  # fmt: skip
    return subprocess.run(["unshare", "-n", "bash", "-c", script], capture_output=True,
                          text=True, timeout=300)  # fmt: skip


def test_ros_refuses_a_parameter_the_node_does_not_have(tmp_path):
    """``-p nosuch.param:=1`` was taken silently; now exit 2 before rclpy starts, listing
    the node's parameters."""
    proc = _ros_in_netns(tmp_path, "-p nosuch.param:=1")
    assert proc.returncode == 2, proc.stderr
    (line,) = [x for x in proc.stderr.splitlines() if x.startswith("error:")]
    assert "-p nosuch.param: the node has no such parameter" in line
    assert "ros.rate" in line and "use_sim_time" in line and "Traceback" not in proc.stderr
    assert proc.stdout == ""  # refused before the node's header


def test_ros_header_names_the_remapped_node(tmp_path):
    proc = _ros_in_netns(tmp_path, "-r __node:=my_ctrl -r __ns:=/arm7")
    assert proc.returncode == 2, proc.stderr
    assert "as ROS 2 node /arm7/my_ctrl for" in proc.stdout, proc.stdout


# ----------------------------------------------------- compare on an arm's effort limits
def test_compare_says_why_ism_fails_on_xarm7_and_its_advice_runs(tmp_path, capsys):
    """``compare`` on ``init xarm7`` exited 1 naming hmpc-ism only. The ISM's switching
    gain K = 200 rad/s² (the paper arm's) asks M_jj K beyond xarm7's effort limits: the
    plant clips it and the QP fails. The reason is printed, with the largest K that fits
    (min_j effort_j / M_jj(q0), from CRBA here), and ISM with that gain runs."""
    import numpy as np
    import pinocchio as pin

    cfg = tmp_path / "xarm7.toml"
    assert main(["init", "xarm7", "--out", str(cfg)]) == 0
    capsys.readouterr()
    code = main(["compare", str(cfg), "--controllers", "hmpc-ism", "--duration", "0.3",
                 "--quiet", "--out", str(tmp_path / "cmp")])  # fmt: skip
    assert code == 1
    err = capsys.readouterr().err
    assert re.search(r"^error: hmpc-ism: .*QP", err, re.M), err
    (note,) = [ln for ln in err.splitlines() if ln.startswith("note: hmpc-ism: the switching")]
    fit = float(re.search(r"K <= ([\d.e+-]+) rad/s²", note).group(1))
    ex = hmpc_pin.Experiment.from_config(hmpc_pin.load_config(cfg))
    model = ex.robot.model
    M = pin.crba(model, model.createData(), ex.q0)
    M = np.triu(M) + np.triu(M, 1).T
    expected = np.min(model.effortLimit / np.diag(M))
    assert fit == pytest.approx(expected, rel=2e-3)
    # the advice: a config of compensation = "ism" with that gain runs the same 0.3 s
    text = cfg.read_text(encoding="utf-8")
    text = re.sub(r'^compensation = "general".*$', 'compensation = "ism"', text, flags=re.M)
    text = re.sub(r"^\[controller\.observer\]\n(?:.*\n)*?\n", "", text, flags=re.M)
    (tmp_path / "ism.toml").write_text(text + f"\n[controller.ism]\ngain = {fit:g}\n")
    code = main(["run", str(tmp_path / "ism.toml"), "--duration", "0.3", "--no-figures",
                 "--out", str(tmp_path / "ism")])  # fmt: skip
    assert code == 0, capsys.readouterr().err
