"""Tasks beyond sines: trajectory files, waypoints retimed by TOPP-RA, pose tasks by pink.

Every check is against an independent computation: the file's own samples, finite
differences, a closed-form function, Pinocchio's forward kinematics, the URDF limits.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import hmpc_pin
from hmpc_pin.apps.cli import main
from hmpc_pin.exceptions import KinematicsError, LimitError, TrajectoryError
from hmpc_pin.tasks import JointTrajectory, load_trajectory, retime_waypoints
from hmpc_pin.tasks.pose import (
    CirclePath,
    LinePath,
    PoseReference,
    PoseWaypoints,
    plane_axes,
    quat_series,
    quat_to_matrix,
    rotation_angle,
)

from .conftest import CONFIGS

PANDA_READY = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
UR5_HOME = np.array([0.0, -1.2, 1.4, -1.0, -1.57, 0.0])
FINGERS = {"panda_finger_joint1": 0.02, "panda_finger_joint2": 0.02}


@pytest.fixture(scope="module")
def panda():
    return hmpc_pin.load_robot("panda", gravity=9.81, locked_joints=FINGERS)


@pytest.fixture(scope="module")
def ur5():
    return hmpc_pin.load_robot("ur5", gravity=9.81)


def _bump(t, T=2.0):
    """q = 1 − cos(πt/T) per joint (scaled): zero velocity at 0 and at T, closed form."""
    k = np.array([0.3, -0.2, 0.5])
    w = np.pi / T
    return k * (1 - np.cos(w * t))[:, None], k * (w * np.sin(w * t))[:, None]


def _fd(traj, ts, h=1e-6):
    qp, dqp = traj.sample_many(ts + h)
    qm, dqm = traj.sample_many(ts - h)
    return (qp - qm) / (2 * h), (dqp - dqm) / (2 * h)


# ------------------------------------------------------------------ interpolation
def test_cubic_spline_hits_the_samples_and_its_derivatives_match_finite_differences():
    t = np.linspace(0.0, 2.0, 21)
    q, _ = _bump(t)
    traj = JointTrajectory(t, q)
    np.testing.assert_allclose(traj.sample_many(t)[0], q, atol=1e-14)
    ts = np.linspace(0.013, 1.987, 397)
    dq_fd, ddq_fd = _fd(traj, ts)
    np.testing.assert_allclose(traj.sample_many(ts)[1], dq_fd, atol=1e-7)
    np.testing.assert_allclose(traj.acceleration_many(ts), ddq_fd, atol=1e-5)
    # between the samples: the clamped spline's error bound 5/384 h^4 max|q''''|
    q_cf, _ = _bump(ts)
    h, q4 = 0.1, 0.5 * (np.pi / 2) ** 4
    np.testing.assert_allclose(traj.sample_many(ts)[0], q_cf, atol=5 / 384 * h**4 * q4 * 1.01)
    # C²: the acceleration is continuous at every inner sample
    e = 1e-9
    jump = traj.acceleration_many(t[1:-1] + e) - traj.acceleration_many(t[1:-1] - e)
    assert np.abs(jump).max() < 1e-6


def test_quintic_hermite_matches_positions_and_velocities_and_is_c2():
    t = np.linspace(0.0, 2.0, 11)
    q, dq = _bump(t)
    traj = JointTrajectory(t, q, dq)
    got_q, got_dq = traj.sample_many(t)
    np.testing.assert_allclose(got_q, q, atol=1e-13)
    np.testing.assert_allclose(got_dq, dq, atol=1e-12)
    ts = np.linspace(0.011, 1.989, 301)
    dq_fd, ddq_fd = _fd(traj, ts)
    np.testing.assert_allclose(traj.sample_many(ts)[1], dq_fd, atol=1e-7)
    np.testing.assert_allclose(traj.acceleration_many(ts), ddq_fd, atol=1e-5)
    e = 1e-9
    jump = traj.acceleration_many(t[1:-1] + e) - traj.acceleration_many(t[1:-1] - e)
    assert np.abs(jump).max() < 1e-6


def test_the_ends_are_held_with_zero_velocity():
    t = np.linspace(1.0, 3.0, 9)
    q, _ = _bump(t - 1.0)
    traj = JointTrajectory(t, q)
    before, after = traj.sample_many(np.array([-5.0, 0.5])), traj.sample_many(np.array([3.5, 1e3]))
    np.testing.assert_array_equal(before[0], np.tile(q[0], (2, 1)))
    np.testing.assert_array_equal(after[0], np.tile(q[-1], (2, 1)))
    assert np.abs(before[1]).max() == 0 and np.abs(after[1]).max() == 0


def _write_csv(path: Path, header, rows) -> Path:
    text = ",".join(header) + "\n" + "\n".join(",".join(map(str, r)) for r in rows) + "\n"
    path.write_text(text, encoding="utf-8")
    return path


def test_csv_columns_are_matched_by_name_and_velocity_columns_give_the_hermite(tmp_path):
    names = ("a", "b", "c")
    t = np.linspace(0.0, 2.0, 6)
    q, dq = _bump(t)
    rows = [[tk, *qk[::-1], *dqk] for tk, qk, dqk in zip(t, q, dq, strict=True)]
    header = ["t", "c", "q_b", "a", "dq_a", "dq_b", "dq_c"]
    traj = load_trajectory(_write_csv(tmp_path / "x.csv", header, rows), names)
    got_q, got_dq = traj.sample_many(t)
    np.testing.assert_allclose(got_q, q, atol=1e-12)
    np.testing.assert_allclose(got_dq, dq, atol=1e-12)
    np.savez(tmp_path / "x.npz", t=t, q=q[:, ::-1], joint_names=np.array(names[::-1]))
    from_npz = load_trajectory(tmp_path / "x.npz", names)
    np.testing.assert_allclose(from_npz.sample_many(t)[0], q, atol=1e-12)


@pytest.mark.parametrize(
    ("header", "rows", "match"),
    [
        (["t", "a", "b", "c"], [[0, 0, 0, 0], [1, 0, 0, 0], [1, 0, 0, 0]], "strictly increasing"),
        (["t", "a", "b"], [[0, 0, 0], [1, 0, 0]], "no column for joint 'c'"),
        (["t", "a", "b", "c"], [[0, 0, 0, 0], [1, "nan", 0, 0]], "finite"),
        (["t", "a", "b", "c", "d"], [[0, 0, 0, 0, 0], [1, 0, 0, 0, 0]], "unknown column 'd'"),
        (["t", "a", "b", "c", "dq_a"], [[0, 0, 0, 0, 0], [1, 0, 0, 0, 0]], "every joint"),
        (["t", "a", "b", "c"], [[0, 0, 0, 0], [1, "x", 0, 0]], "a number"),
    ],
)
def test_bad_trajectory_files_name_what_is_wrong(tmp_path, header, rows, match):
    with pytest.raises(TrajectoryError, match=match):
        load_trajectory(_write_csv(tmp_path / "bad.csv", header, rows), ("a", "b", "c"))


# ---------------------------------------------------------------------- retiming
def test_retiming_respects_every_limit_at_every_sample_and_passes_the_waypoints(panda):
    step1 = np.array([0.5, 0.4, 0.2, 0.5, 0.3, 0.3, -0.3])
    step2 = np.array([-0.3, 0.1, -0.2, 0.1, -0.2, -0.2, 0.2])
    way = np.array([PANDA_READY, PANDA_READY + step1, PANDA_READY + step2])
    vmax, amax = panda.velocity_limit, np.full(7, 3.0)
    traj = retime_waypoints(way, vmax, amax, t_start=0.5, dt=0.01)
    ts = np.linspace(0.0, traj.t_end + 0.5, 40001)  # 20x finer than the samples
    q, dq = traj.sample_many(ts)
    assert np.all(np.abs(dq) <= vmax)
    assert np.all(np.abs(traj.acceleration_many(ts)) <= amax)
    # an independent acceleration: finite differences of the velocity
    _, ddq_fd = _fd(traj, ts[1:-1])
    assert np.all(np.abs(ddq_fd) <= amax * (1 + 1e-4))
    # at rest at both ends, through every waypoint, in order
    np.testing.assert_allclose(q[0], way[0], atol=0)
    np.testing.assert_allclose(q[-1], way[-1], atol=1e-12)
    assert np.abs(dq[[0, -1]]).max() == 0
    closest = np.argmin(np.linalg.norm(q[:, None, :] - way[None], axis=2), axis=0)
    assert np.all(np.diff(closest) > 0)
    assert np.linalg.norm(q[closest[1]] - way[1]) < 1e-3
    # time-optimal: some limit is active (≥ 90 % of a limit reached somewhere)
    ratio = max(np.max(np.abs(dq) / vmax), np.max(np.abs(traj.acceleration_many(ts)) / amax))
    assert ratio > 0.9


def test_retiming_rejects_repeated_waypoints(panda):
    with pytest.raises(TrajectoryError, match="equals waypoint 0"):
        retime_waypoints(np.array([PANDA_READY, PANDA_READY]), 1.0, 1.0)


# ------------------------------------------------------------------------- poses
def _fk(robot, frame, qs):
    model, data = robot.model, robot.model.createData()
    fid = model.getFrameId(frame)
    pos, rot = [], []
    for q in qs:
        pin.forwardKinematics(model, data, q)
        pin.updateFramePlacements(model, data)
        pos.append(data.oMf[fid].translation.copy())
        rot.append(data.oMf[fid].rotation.copy())
    return np.array(pos), np.array(rot)


@pytest.mark.parametrize(
    ("arm", "frame", "q_init"),
    [("panda", "panda_hand_tcp", PANDA_READY), ("ur5", "tool0", UR5_HOME)],
)
def test_circle_ik_is_checked_by_forward_kinematics_within_the_limits(request, arm, frame, q_init):
    robot = request.getfixturevalue(arm)
    p0, R0 = _fk(robot, frame, [q_init])
    u, v = plane_axes("yz")
    path = CirclePath(p0[0] - 0.1 * u, 0.1, 0.2, u, v, R0[0])
    ref = PoseReference.solve(robot, frame, path, 5.2, q_init)
    ts = np.linspace(0.0, 5.2, 1041)
    q, dq = ref.sample_many(ts)
    pos, rot = _fk(robot, frame, q)
    # the circle, independently: centre, radius, plane; orientation held
    rel = pos - (p0[0] - 0.1 * u)
    np.testing.assert_allclose(np.linalg.norm(rel, axis=1), 0.1, atol=2e-5)
    np.testing.assert_allclose(rel @ np.array([1.0, 0.0, 0.0]), 0.0, atol=2e-5)
    angle = 2 * np.pi * 0.2 * ts
    np.testing.assert_allclose(rel[:, 1], 0.1 * np.cos(angle), atol=2e-5)
    np.testing.assert_allclose(rel[:, 2], 0.1 * np.sin(angle), atol=2e-5)
    assert rotation_angle(np.repeat(R0, len(ts), 0), rot).max() < 1e-4
    assert np.all((q >= robot.lower) & (q <= robot.upper))
    assert np.all(np.abs(dq) <= robot.velocity_limit)


def test_line_and_pose_waypoints_reach_their_targets(panda):
    frame = "panda_hand_tcp"
    p0, R0 = _fk(panda, frame, [PANDA_READY])
    end = p0[0] + [0.05, 0.1, -0.05]
    line = PoseReference.solve(panda, frame, LinePath(p0[0], end, 0.5, 2.0, R0[0]), 3.0,
                               PANDA_READY)  # fmt: skip
    pos, _ = _fk(panda, frame, line.sample_many(np.array([0.0, 1.5, 3.0]))[0])
    np.testing.assert_allclose(pos[0], p0[0], atol=1e-5)
    np.testing.assert_allclose(pos[1], (p0[0] + end) / 2, atol=1e-5)  # min-jerk: half at mid
    np.testing.assert_allclose(pos[2], end, atol=1e-5)
    R1 = R0[0] @ pin.exp3(np.array([0.0, 0.0, 0.4]))
    way = PoseWaypoints(np.array([0.0, 2.0]), np.array([p0[0], end]), np.array([R0[0], R1]))
    ref = PoseReference.solve(panda, frame, way, 2.5, PANDA_READY)
    pos, rot = _fk(panda, frame, ref.sample_many(np.array([2.5]))[0])
    np.testing.assert_allclose(pos[0], end, atol=1e-5)
    assert rotation_angle(R1[None], rot)[0] < 1e-4


def test_an_unknown_frame_suggests_the_closest_names(panda):
    with pytest.raises(KinematicsError, match="closest: 'panda_hand'"):
        PoseReference.solve(panda, "panda_hnd", None, 1.0, PANDA_READY)


def test_a_pose_outside_the_workspace_names_the_pose_and_the_residual(panda):
    far = LinePath(np.array([0.3, 0.0, 0.5]), np.array([2.5, 0.0, 0.5]), 0.0, 1.0, np.eye(3))
    with pytest.raises(KinematicsError, match=r"cannot be reached: residual [0-9.e-]+ m"):
        PoseReference.solve(panda, "panda_hand_tcp", far, 1.0, PANDA_READY)


def test_quaternion_convention_is_xyzw():
    R = quat_to_matrix([0.0, 0.0, np.sin(0.25), np.cos(0.25)])  # 0.5 rad about z
    np.testing.assert_allclose(R, pin.exp3(np.array([0.0, 0.0, 0.5])), atol=1e-15)


# ------------------------------------------------------- configs and the command line
def _cli(argv, capsys):
    code = main(argv)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _config(tmp_path, body: str, name="task.toml") -> Path:
    head = (
        '[robot]\nmodel = "panda"\ngravity = 9.81\n[robot.locked_joints]\n'
        "panda_finger_joint1 = 0.02\npanda_finger_joint2 = 0.02\n"
        '[controller.observer]\nkind = "general"\n[simulation]\nduration = 0.3\n'
    )
    path = tmp_path / name
    path.write_text(head + body, encoding="utf-8")
    return path


def _panda_csv(tmp_path, q, t=None, name="traj.csv", names=None) -> Path:
    names = names or [f"panda_joint{i}" for i in range(1, 8)]
    t = np.arange(len(q)) * 0.5 if t is None else t
    rows = [[tk, *qk] for tk, qk in zip(t, q, strict=True)]
    return _write_csv(tmp_path / name, ["t", *names], rows)


BAD_INPUTS = {
    "time not increasing": (
        lambda d: _panda_csv(d, [PANDA_READY] * 3, t=[0.0, 0.5, 0.5]), "strictly increasing"),
    "missing joint column": (
        lambda d: _panda_csv(d, [PANDA_READY[:6]] * 2,
                             names=[f"panda_joint{i}" for i in range(1, 7)]),
        "no column for joint 'panda_joint7'"),
    "NaN in the file": (
        lambda d: _panda_csv(d, [PANDA_READY, [*PANDA_READY[:6], np.nan]]), "finite"),
    "path crossing a joint limit": (
        lambda d: _panda_csv(d, [PANDA_READY, PANDA_READY + np.eye(7)[3] * 2.5]),
        "joint 'panda_joint4'"),
}  # fmt: skip


@pytest.mark.parametrize("case", sorted(BAD_INPUTS))
def test_bad_reference_files_exit_2_with_one_line_and_write_nothing(tmp_path, capsys, case):
    make, match = BAD_INPUTS[case]
    csv = make(tmp_path)
    out = tmp_path / "out"
    config = _config(tmp_path, f'[reference]\nkind = "trajectory"\n[reference.trajectory]\n'
                     f'file = "{csv.name}"\n')  # fmt: skip
    for argv in (["run", str(config), "--out", str(out)],
                 ["run", "panda_sine", "--reference", str(csv), "--out", str(out)]):  # fmt: skip
        code, stdout, err = _cli(argv, capsys)
        assert code == 2, (stdout, err)
        assert match in err and err.count("\n") == 1, err
        assert not out.exists()


POSE_BAD = {
    "unknown frame": ('frame = "panda_hnd"\npath = "circle"\nradius = 0.1\nfrequency = 0.2\n',
                      "closest: 'panda_hand'"),
    "pose outside the workspace": (
        'path = "line"\nstart = [0.3, 0.0, 0.5]\nend = [2.5, 0.0, 0.5]\nduration = 0.2\n',
        "cannot be reached"),
}  # fmt: skip


@pytest.mark.parametrize("case", sorted(POSE_BAD))
def test_bad_pose_tasks_exit_2_with_one_line_and_write_nothing(tmp_path, capsys, case):
    body, match = POSE_BAD[case]
    q_init = f"q_init = {PANDA_READY.tolist()}\n"
    config = _config(tmp_path, '[reference]\nkind = "pose"\n[reference.pose]\n' + q_init + body)
    out = tmp_path / "out"
    code, stdout, err = _cli(["run", str(config), "--out", str(out)], capsys)
    assert code == 2, (stdout, err)
    assert match in err and err.count("\n") == 1, err
    assert not out.exists()


def test_a_waypoint_path_prints_its_duration_and_keys_of_other_kinds_are_errors(tmp_path, capsys):
    way = [PANDA_READY.tolist(), (PANDA_READY + 0.2).tolist()]
    config = _config(tmp_path, '[reference]\nkind = "waypoints"\n[reference.waypoints]\n'
                     f"points = {way}\nacceleration_limit = 4.0\n")  # fmt: skip
    code, stdout, err = _cli(["run", str(config), "--out", str(tmp_path / "o")], capsys)
    assert code == 0, err
    assert "waypoints retimed by TOPP-RA: motion of" in stdout
    bad = _config(tmp_path, '[reference]\nkind = "waypoints"\namplitude = 0.3\n'
                  f"[reference.waypoints]\npoints = {way}\n", "bad.toml")  # fmt: skip
    code, _, err = _cli(["run", str(bad), "--out", str(tmp_path / "o")], capsys)
    assert code == 2 and "reference.amplitude" in err


# ------------------------------------------------------------- closed loop (short)
def _short(name: str, duration: float):
    config = hmpc_pin.load_config(CONFIGS / f"{name}.toml")
    from dataclasses import replace

    config = replace(config, simulation=replace(config.simulation, duration=duration))
    return hmpc_pin.Experiment.from_config(config).run()


def test_panda_trajectory_config_tracks_its_file_within_1e_3_rad():
    result = _short("panda_trajectory", 3.0)
    assert result.complete
    m = hmpc_pin.compute_metrics(result)
    assert m.rms_error.max() <= 1e-3
    assert np.all(m.limit_violation == 0)
    traj = load_trajectory(CONFIGS / "panda_trajectory.csv", result.joint_names)
    np.testing.assert_allclose(result.q_ref, traj.sample_many(result.t)[0], atol=0)


@pytest.mark.parametrize("name", ["panda_circle", "ur5_circle"])
def test_circle_configs_track_the_tool_circle(name, tmp_path):
    result = _short(name, 3.0)
    assert result.complete
    tm = hmpc_pin.compute_metrics(result).task
    assert tm.position_rms <= 1e-3 and tm.orientation_rms <= 0.01
    # the saved task-space arrays are the forward kinematics of the saved joints
    back = hmpc_pin.Result.load(result.save(tmp_path / "r.npz"))
    robot = hmpc_pin.Experiment.from_config(hmpc_pin.load_config(CONFIGS / f"{name}.toml")).robot
    pos, rot = _fk(robot, back.meta["task"]["frame"], back.q[::50])
    np.testing.assert_allclose(back.ee_pos[::50], pos, atol=1e-12)
    R = np.array([quat_to_matrix(q) for q in back.ee_quat[::50]])
    np.testing.assert_allclose(R, rot, atol=1e-9)
    # the target is the circle: after half a period (2.5 s at 0.2 Hz) a diameter, 0.2 m, away
    k = int(np.argmin(np.abs(back.t - 2.5)))
    assert np.linalg.norm(back.ee_pos_ref[k] - back.ee_pos_ref[0]) == pytest.approx(0.2, abs=1e-12)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["panda_trajectory", "panda_circle", "ur5_circle"])
def test_acceptance_full_runs(name):
    result = _short(name, 10.0)
    m = hmpc_pin.compute_metrics(result)
    if m.task is None:
        assert m.rms_error.max() <= 1e-3 and np.all(m.limit_violation == 0)
    else:
        assert m.task.position_rms <= 1e-3 and m.task.orientation_rms <= 0.01


def test_limit_errors_name_joint_and_time(panda):
    from hmpc_pin.experiment.build import check_trajectory_limits

    q = np.array([PANDA_READY, PANDA_READY + np.eye(7)[6] * 0.1])
    traj = JointTrajectory(np.array([0.0, 0.01]), q, joint_names=panda.joint_names)
    with pytest.raises(LimitError, match=r"velocity of joint 'panda_joint7' .* at t="):
        check_trajectory_limits(traj, panda, panda.lower, panda.upper)


@pytest.mark.parametrize(("module", "body"), [
    ("toppra", f'kind = "waypoints"\n[reference.waypoints]\npoints = '
               f"{[PANDA_READY.tolist(), (PANDA_READY + 0.1).tolist()]}\n"),
    ("pink", '[reference]\nkind = "pose"\n[reference.pose]\npath = "circle"\nradius = 0.1\n'
             f"frequency = 0.2\nq_init = {PANDA_READY.tolist()}\n"),
])  # fmt: skip
def test_a_missing_extra_is_one_line_naming_it(tmp_path, capsys, monkeypatch, module, body):
    monkeypatch.setitem(__import__("sys").modules, module, None)  # import fails as if absent
    if module == "toppra":
        body = "[reference]\n" + body
    config = _config(tmp_path, body)
    code, _, err = _cli(["run", str(config), "--out", str(tmp_path / "o")], capsys)
    assert code == 2 and "hmpc_pin[tasks]" in err and err.count("\n") == 1, err


def test_velocity_columns_in_another_unit_are_rejected():
    t = np.linspace(0.0, 2.0, 11)
    q, dq = _bump(t)
    with pytest.raises(TrajectoryError, match="velocities of b between t"):
        JointTrajectory(t, q, dq * [1.0, 57.3, 1.0], ("a", "b", "c"))


@pytest.mark.parametrize(
    ("table", "match"),
    [
        ('[reference.pose]\npath = "circle"\nradius = 0.1\nfrequency = 0.2\nend = [0, 0, 1]\n',
         "reference.pose.end: does not apply to path = 'circle'"),
        ('[reference.pose]\npath = "circle"\nradius = 0.1\n', "needs radius and frequency"),
        ('[reference.pose]\npath = "spiral"\n', "reference.pose.path: expected one of"),
        ('[reference.pose]\npath = "line"\nend = [0, 0, 1]\nduration = 1.0\n'
         "orientation = [0, 0, 0, 0]\n", "reference.pose.orientation: expected a quaternion"),
        ('[reference.pose]\npath = "waypoints"\ntimes = [0.0, 1.0]\npositions = [[0, 0, 1]]\n',
         "expected 2 points"),
        ('[reference.pose]\npath = "circle"\nradius = 0.1\nfrequency = 0.2\nplane = "xx"\n',
         "reference.pose.plane"),
        ('[reference.trajectory]\nfile = "x.csv"\n', "reference.trajectory: applies only to "
         "kind = 'trajectory'"),
        ('[reference.pose]\npath = "circle"\nradius = 0.1\nfrequency = 0.2\nspeed = 1\n',
         "reference.pose.speed: unknown key"),
    ],
)  # fmt: skip
def test_pose_table_errors_name_the_key(tmp_path, table, match):
    config = _config(tmp_path, '[reference]\nkind = "pose"\n' + table)
    with pytest.raises(hmpc_pin.ConfigError, match=match):
        hmpc_pin.load_config(config)


def test_waypoints_of_the_wrong_length_and_outside_the_limits(tmp_path):
    short = _config(tmp_path, '[reference]\nkind = "waypoints"\n[reference.waypoints]\n'
                    "points = [[0.0, 0.1], [0.2, 0.3]]\n")  # fmt: skip
    with pytest.raises(hmpc_pin.ConfigError, match="entries but the robot has 7 joints"):
        hmpc_pin.Experiment.from_config(hmpc_pin.load_config(short))
    out = (PANDA_READY + np.eye(7)[0] * 5.0).tolist()
    far = _config(tmp_path, '[reference]\nkind = "waypoints"\n[reference.waypoints]\n'
                  f"points = [{PANDA_READY.tolist()}, {out}]\n", "far.toml")  # fmt: skip
    with pytest.raises(LimitError, match="waypoint 1 of joint 'panda_joint1'"):
        hmpc_pin.Experiment.from_config(hmpc_pin.load_config(far))


def test_a_circle_in_a_plane_given_by_its_normal(ur5):
    normal = np.array([1.0, 1.0, 1.0]) / np.sqrt(3)
    u, v = plane_axes(normal.tolist())
    np.testing.assert_allclose([u @ normal, v @ normal, u @ v], 0.0, atol=1e-15)
    p0, R0 = _fk(ur5, "tool0", [UR5_HOME])
    path = CirclePath(p0[0] - 0.05 * u, 0.05, 0.5, u, v, R0[0])
    ref = PoseReference.solve(ur5, "tool0", path, 2.0, UR5_HOME)
    pos, _ = _fk(ur5, "tool0", ref.sample_many(np.linspace(0.0, 2.0, 201))[0])
    np.testing.assert_allclose((pos - (p0[0] - 0.05 * u)) @ normal, 0.0, atol=2e-5)


def test_a_circle_ramp_starts_at_rest_and_reaches_full_speed_smoothly():
    u, v = plane_axes("xy")
    path = CirclePath(np.zeros(3), 0.1, 0.2, u, v, np.eye(3), ramp=1.0)
    h = 1e-5
    t = np.array([0.0, 0.5, 1.0, 2.0])
    speed = (path.angle(t + h) - path.angle(np.maximum(t - h, 0.0))) / (
        (t + h) - np.maximum(t - h, 0.0)
    )
    w = 2 * np.pi * 0.2
    np.testing.assert_allclose(speed, [0.0, w / 2, w, w], atol=1e-6)  # smoothstep: half at mid
    # continuous angle at the end of the ramp, then the full-speed circle delayed by T_r / 2
    np.testing.assert_allclose(path.angle(np.array([1.0, 3.0])), [w * 0.5, w * 2.5], atol=1e-12)


def test_a_sweep_of_a_pose_task_records_its_task_space_errors(tmp_path):
    from dataclasses import replace

    from hmpc_pin.apps.sweep import draw_samples, run_sample

    config = hmpc_pin.load_config(CONFIGS / "ur5_circle.toml")
    config = replace(config, simulation=replace(config.simulation, duration=1.5))
    params = draw_samples(config, 1, 0)[0]
    row = run_sample(config, params, "hmpc+general")
    # under the sweep's noise, delay and plant perturbation the errors are far above the
    # nominal run's; the row must carry them, finite and positive, beside the joint RMS
    assert row["complete"] and np.isfinite([row["position_rms"], row["orientation_rms"]]).all()
    assert row["position_rms"] > 0 and row["orientation_rms"] > 0 and "rms_max" in row


def test_compare_of_a_pose_task_tables_its_task_space_errors():
    from dataclasses import replace

    from hmpc_pin.apps.compare import markdown_table, run_comparison

    config = hmpc_pin.load_config(CONFIGS / "ur5_circle.toml")
    config = replace(config, simulation=replace(config.simulation, duration=1.5))
    comp = run_comparison(config, ("hmpc", "computed-torque"))
    table = markdown_table(comp)
    assert "position RMS after 1 s [m] (tool0)" in table
    rows = {line.split(" | ")[0][2:]: line for line in table.splitlines()[-2:]}
    assert set(rows) == {"hmpc", "computed-torque"}
    for kind, run in comp.runs.items():  # the table's numbers are the runs' task metrics
        assert f"{run.metrics.task.position_rms:.3e}" in rows[kind]


def test_a_joint_without_a_range_is_not_checked_for_position(tmp_path):
    """double_pendulum's URDF limits are 0/0 (no range, no velocity limit): a trajectory file
    loads with controller.constraints.position = false, the run tracks it."""
    csv = _write_csv(tmp_path / "dp.csv", ["t", "joint1", "joint2"],
                     [[0.0, 0.0, 0.0], [1.0, 1.0, -0.5], [2.0, 1.5, 0.5]])  # fmt: skip
    path = tmp_path / "dp.toml"
    path.write_text(
        '[robot]\nmodel = "double_pendulum"\n[controller.constraints]\nposition = false\n'
        f'[reference]\nkind = "trajectory"\n[reference.trajectory]\nfile = "{csv.name}"\n'
        "[simulation]\nduration = 2.5\n",
        encoding="utf-8",
    )
    exp = hmpc_pin.Experiment.from_config(hmpc_pin.load_config(path))
    result = exp.run()
    np.testing.assert_allclose(result.q_ref[-1], [1.5, 0.5], atol=1e-12)
    assert hmpc_pin.compute_metrics(result).rms_error.max() < 1e-2


def _bang_bang_time(delta, vmax, amax, margin=0.97) -> float:
    """Closed form: the fastest rest-to-rest motion along the straight segment ``delta``
    with |q̇_i| <= α v_i and |q̈_i| <= α a_i. On the path q = q0 + s Δ, s in [0, 1], the
    limits are ṡ <= V = α min v_i/|Δ_i|, s̈ <= A = α min a_i/|Δ_i|: accelerate at A,
    cruise at V if it is reached, decelerate at A. T = 1/V + V/A, or 2/sqrt(A) when V is
    not reached (V² > A)."""
    d = np.abs(delta)
    V = margin * np.min(vmax / d)
    A = margin * np.min(amax / d)
    return 1 / V + V / A if V * V <= A else 2 / np.sqrt(A)


def _quintic_overshoot(a0: float, a1: float) -> float:
    """Worst peak |q̈| / max(|a0|, |a1|) of the quintic Hermite through the exact
    q, q̇, q̈ at the ends of one sample interval in which the acceleration steps from a0
    to a1 (over every instant of the step): what a C² interpolant of a bang-bang
    profile can overshoot, computed here with numpy (a 6 x 6 solve per instant)."""
    M = np.array([[1, 0, 0, 0, 0, 0], [0, 1, 0, 0, 0, 0], [0, 0, 2, 0, 0, 0],
                  [1, 1, 1, 1, 1, 1], [0, 1, 2, 3, 4, 5], [0, 0, 2, 6, 12, 20]], float)  # fmt: skip
    t = np.linspace(0.0, 1.0, 401)
    worst = 0.0
    for tau in np.linspace(0.0, 1.0, 401):
        q1 = a0 * tau**2 / 2 + a0 * tau * (1 - tau) + a1 * (1 - tau) ** 2 / 2
        c = np.linalg.solve(M, [0.0, 0.0, a0, q1, a0 * tau + a1 * (1 - tau), a1])
        acc = 2 * c[2] + 6 * c[3] * t + 12 * c[4] * t**2 + 20 * c[5] * t**3
        worst = max(worst, np.abs(acc).max() / max(abs(a0), abs(a1)))
    return worst


@pytest.mark.parametrize(
    ("delta", "vmax", "amax", "steps"),
    [
        (np.array([1.0, -0.5, 0.2]), np.array([0.5, 1.0, 1.0]), np.array([2.0, 2.0, 2.0]),
         (1.0, 0.0)),  # accelerate, cruise, brake: steps A -> 0 -> -A
        (np.array([0.3, 0.1, -0.2]), np.array([5.0, 5.0, 5.0]), np.array([1.0, 4.0, 0.5]),
         (1.0, -1.0)),  # never at the velocity limit: one step A -> -A
    ],
    ids=["cruise at the velocity limit", "triangle: the velocity limit never reached"],
)  # fmt: skip
@pytest.mark.parametrize("dt", [0.01, 0.005, 0.002])
def test_retiming_one_segment_against_the_bang_bang_optimum(delta, vmax, amax, steps, dt):
    """Two waypoints: a straight segment, whose time-optimal motion has a closed form.
    The retimed motion is never faster than it, stays on the segment, meets every limit
    with one of them active (the stretch is the least that makes the interpolant fit),
    and is slower than the optimum by at most what the C² interpolant's overshoot of the
    optimum's acceleration steps costs: t ≤ t* sqrt(overshoot) (velocity / λ,
    acceleration / λ²)."""
    q0 = np.array([0.1, -0.2, 0.3])
    traj = retime_waypoints(np.array([q0, q0 + delta]), vmax, amax, dt=dt)
    optimum = _bang_bang_time(delta, vmax, amax)
    bound = optimum * np.sqrt(_quintic_overshoot(*steps))
    assert optimum * (1 - 1e-3) <= traj.t_end <= bound * (1 + 1e-3), (traj.t_end, optimum)
    ts = np.linspace(0.0, traj.t_end, 20001)
    q, dq = traj.sample_many(ts)
    ratio = max(np.max(np.abs(dq) / vmax), np.max(np.abs(traj.acceleration_many(ts)) / amax))
    assert 0.97 * (1 - 2e-3) <= ratio <= 1.0  # a limit is active at its margin α, none crossed
    # on the segment: every sample is q0 + s Δ with s in [0, 1]
    s = (q - q0) @ delta / (delta @ delta)
    np.testing.assert_allclose(q, q0 + s[:, None] * delta, atol=1e-9)
    assert s.min() >= -1e-9 and s.max() <= 1 + 1e-9


def test_a_pose_path_through_a_half_turn_keeps_its_quaternions_continuous():
    """A rotation of 4.8 rad about z in two segments passes w = 0; the target's
    quaternions follow the closed form (0, 0, sin θ/2, cos θ/2) with θ the min-jerk angle,
    with no jump to -q. Waypoints given as q and -q (one rotation) hold still."""

    def rz(a):
        return pin.exp3(np.array([0.0, 0.0, a]))

    path = PoseWaypoints(np.array([0.0, 1.0, 2.0]), np.zeros((3, 3)),
                         np.array([rz(0.0), rz(2.4), rz(4.8)]))  # fmt: skip
    t = np.linspace(0.0, 2.0, 401)
    _, rot = path.poses(t)
    quats = quat_series(rot)
    s = np.where(t >= 1.0, t - 1.0, t)
    theta = np.where(t >= 1.0, 2.4, 0.0) + 2.4 * s**3 * (10 - 15 * s + 6 * s**2)
    theta[-1] = 4.8
    expected = np.column_stack([0 * t, 0 * t, np.sin(theta / 2), np.cos(theta / 2)])
    np.testing.assert_allclose(quats, expected, atol=1e-9)
    assert np.max(np.linalg.norm(np.diff(quats, axis=0), axis=1)) < 0.05
    q = np.array([0.2, -0.4, 0.1, 0.8]) / np.linalg.norm([0.2, -0.4, 0.1, 0.8])
    still = PoseWaypoints(np.array([0.0, 1.0]), np.zeros((2, 3)),
                          np.array([quat_to_matrix(q), quat_to_matrix(-q)]))  # fmt: skip
    held = quat_series(still.poses(t[:201])[1])
    np.testing.assert_allclose(held, np.tile(q, (201, 1)), atol=1e-12)
    # a measured orientation is given in its target's hemisphere
    np.testing.assert_allclose(quat_series(rot[:3], like=-quats[:3]), -quats[:3], atol=1e-12)
