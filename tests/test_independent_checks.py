"""Checks, against independent computations, of code whose one-line bugs the rest of the
suite did not catch: the applied-torque clip, the collision watch, the quaternions, the
pose task's IK residual, the measurement model, the trajectory files' velocity check,
the waypoint retiming, init's speed cap and the MuJoCo model's per-joint parameters.
Each oracle is a closed form, numpy, Pinocchio's FK, MuJoCo's own model, or the limits
themselves, never the code's saved output."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import hmpc_pin
from hmpc_pin import HierarchicalMPC, MPCSettings, SineReference
from hmpc_pin.controllers.wrappers import CollisionReaction, MeasuredController
from hmpc_pin.exceptions import KinematicsError, TrajectoryError
from hmpc_pin.tasks.pose import matrix_to_quat, quat_to_matrix, solve_path_ik

from .test_urdf_joints import chain, joint, rod


# ---------------------------------------------------------------- test compensations
class Scripted:
    """A user compensation whose estimate follows a script: ``values(k)`` at update k;
    it records the torque each update receives."""

    def __init__(self, n, values):
        self.n, self.values = n, values
        self.estimate = np.zeros(n)
        self.k, self.seen = 0, []

    def reset(self, q0, dq0):
        self.estimate, self.k, self.seen = np.zeros(self.n), 0, []

    def update(self, M, nle, q, dq, tau, v):
        self.k += 1
        self.seen.append(np.array(tau, dtype=float))
        self.estimate = np.asarray(self.values(self.k), dtype=float)
        return self.estimate


# ---------------------------------------------------------------- applied-torque clip
def test_the_compensation_gets_the_clipped_torque_of_the_last_period(planar3):
    """Oracle: numpy's clip of the torque the controller returned one step earlier."""
    comp = Scripted(3, lambda k: np.zeros(3))
    ctrl = HierarchicalMPC(planar3, MPCSettings(), comp)
    limit = np.array([5.0, 0.5, 50.0])  # joint 2 saturates (gravity alone needs more)
    ctrl.effort_limit = limit
    ref = SineReference(3, amplitude=0.5, frequency=0.5)
    q, dq = np.array([0.3, -0.2, 0.1]), np.zeros(3)
    ctrl.reset(q, dq)
    taus = []
    for k in range(6):
        taus.append(ctrl.step(0.01 * k, q + 0.01 * k, dq, ref))
    assert len(comp.seen) == 5
    saturated = 0
    for k, seen in enumerate(comp.seen):
        expected = np.clip(taus[k], -limit, limit)
        np.testing.assert_allclose(seen, expected, rtol=0, atol=1e-12)
        saturated += int(np.any(np.abs(taus[k]) > limit))
    assert saturated > 0  # the clip was exercised


# ---------------------------------------------------------------- collision watch
@pytest.mark.parametrize("sign", [1.0, -1.0])
@pytest.mark.parametrize("reaction", ["ignore", "stop"])
def test_collision_flag_on_either_sign_and_what_stop_holds(planar3, sign, reaction):
    """The estimate of joint 2 crosses the threshold (2 N·m) at update 4 with either
    sign; joint 1 stays below its own. Oracle: the script. ``stop`` then holds the
    position measured at that instant with zero velocity and stops feeding back."""
    threshold = np.array([2.0, 2.0, 2.0])
    script = {4: [1.5, 3.0 * sign, 0.0]}
    comp = Scripted(3, lambda k: script.get(k, [1.9 * sign, 1.0 * sign, -1.0]))
    watch = CollisionReaction(HierarchicalMPC(planar3, MPCSettings(), comp), threshold, reaction)
    ref = SineReference(3, amplitude=0.2, frequency=0.5)
    watch.reset(np.zeros(3), np.zeros(3))
    states = [np.array([0.1 * k, -0.05 * k, 0.02 * k]) for k in range(8)]
    for k, q in enumerate(states):
        watch.step(0.01 * k, q, np.full(3, 0.3), ref)
        if k < 4:
            assert watch.detected_at is None, k
    assert watch.detected_at == pytest.approx(0.04) and watch.joint == 1
    if reaction == "stop":
        held_q, held_dq = watch._hold.sample(1.0)
        np.testing.assert_array_equal(held_q, states[4])
        np.testing.assert_array_equal(held_dq, np.zeros(3))
        assert not watch.gate.feed_back
    else:
        assert watch._hold is None and watch.gate.feed_back


# ---------------------------------------------------------------- quaternions
@pytest.mark.parametrize("angle", [0.3, 2.0, 3.5, 5.9])
@pytest.mark.parametrize("axis", [(0, 0, 1), (1, 0, 0), (0.6, 0.0, 0.8)])
def test_quaternions_are_xyzw_with_w_nonnegative(angle, axis):
    """Oracle: the closed forms q = (sin(θ/2) u, cos(θ/2)) and Rodrigues' formula."""
    u = np.asarray(axis, dtype=float)
    u /= np.linalg.norm(u)
    K = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    R = np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
    closed = np.concatenate([np.sin(angle / 2) * u, [np.cos(angle / 2)]])
    np.testing.assert_allclose(quat_to_matrix(closed), R, atol=1e-12)
    np.testing.assert_allclose(quat_to_matrix(-closed), R, atol=1e-12)  # q and -q: one R
    quat = matrix_to_quat(R)
    assert quat[3] >= 0
    np.testing.assert_allclose(quat, closed if closed[3] >= 0 else -closed, atol=1e-12)


# ---------------------------------------------------------------- pose task residual
class _Fixed:
    def __init__(self, p, R):
        self.p, self.R = np.asarray(p, float), np.asarray(R, float)

    def poses(self, times):
        m = len(times)
        return np.tile(self.p, (m, 1)), np.tile(self.R, (m, 1, 1))


def test_pose_ik_refuses_a_bad_position_and_a_bad_orientation_alone(planar3):
    """Oracle: Pinocchio's FK. A pose the planar arm reaches (FK of a posture) is solved
    (FK of the solution matches it); the same position with the tool turned about an
    axis the arm cannot turn, or the same orientation moved out of the arm's plane, is
    refused on that residual alone."""
    pytest.importorskip("pink")
    robot, frame = planar3, planar3.tool_frame
    q_goal = np.array([0.4, -0.6, 0.5])
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q_goal)
    goal = data.oMf[robot.model.getFrameId(frame)]
    times = np.array([0.0, 0.01])
    q_init = np.array([0.3, -0.5, 0.4])
    sol = solve_path_ik(robot, frame, _Fixed(goal.translation, goal.rotation), times, q_init)
    pin.framesForwardKinematics(robot.model, data, sol[-1])
    reached = data.oMf[robot.model.getFrameId(frame)]
    assert np.linalg.norm(reached.translation - goal.translation) < 1e-4
    assert np.linalg.norm(pin.log3(goal.rotation.T @ reached.rotation)) < 1e-3
    # The joints turn about the world y axis: a turn of the tool about x (or z) at the
    # same position cannot be made, nor a shift along y with the same orientation.
    c, s = np.cos(0.3), np.sin(0.3)
    for R in (np.array([[1, 0, 0], [0, c, -s], [0, s, c]]),
              np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])):  # fmt: skip
        with pytest.raises(KinematicsError, match=r"cannot be reached: residual .* m, 0\.\d+ rad"):
            solve_path_ik(robot, frame, _Fixed(goal.translation, R @ goal.rotation), times,
                          q_init)  # fmt: skip
    shifted = goal.translation + np.array([0.0, 0.3, 0.0])
    with pytest.raises(KinematicsError, match=r"cannot be reached: residual 0\.3"):
        solve_path_ik(robot, frame, _Fixed(shifted, goal.rotation), times, q_init)


# ---------------------------------------------------------------- measurement model
def test_measurement_noise_is_the_documented_draw_and_delay(planar3):
    """Oracle: the same seed drawn by numpy directly, 2n standard normals per measurement
    (q's first), scaled by σ_q and σ_dq; the controller gets the one ``delay`` old."""

    class Recorder:
        Ts = 0.01

        def __init__(self):
            self.got = []

        def reset(self, q0, dq0):
            self.got = [(np.array(q0), np.array(dq0))]

        def step(self, t, q, dq, reference):
            self.got.append((np.array(q), np.array(dq)))
            return np.zeros(3)

    rec = Recorder()
    sq, sdq, delay = 0.01, 0.5, 2
    meas = MeasuredController(rec, q_noise=sq, dq_noise=sdq, delay=delay,
                              rng=np.random.default_rng(42))  # fmt: skip
    oracle = np.random.default_rng(42)
    states = [(np.full(3, 1.0 * k), np.full(3, -2.0 * k)) for k in range(12)]
    meas.reset(*states[0])
    taken = []
    for k, (q, dq) in enumerate(states):
        draw = oracle.standard_normal(6)
        taken.append((q + sq * draw[:3], dq + sdq * draw[3:]))
        if k > 0:
            meas.step(0.01 * k, q, dq, None)
        else:
            meas.step(0.0, q, dq, None)
    # reset measured state 0; step 0 reuses it; step k >= 1 measures state k
    delivered = rec.got[1:]
    for k, (q, dq) in enumerate(delivered):
        j = max(0, k - delay)
        np.testing.assert_array_equal(q, taken[j][0])
        np.testing.assert_array_equal(dq, taken[j][1])


# ---------------------------------------------------------------- trajectory files
def test_trajectory_velocity_check_is_per_joint(tmp_path):
    """Joint a moves 1 rad, joint b 0.01 rad; b's velocity column in deg/s must be
    refused naming b (a tolerance taken over all joints would let it through), the exact
    derivatives pass. Oracle: the closed-form derivatives of the sines."""
    t = np.linspace(0.0, 2.0, 201)
    qa, qb = np.sin(np.pi * t), 0.01 * np.sin(np.pi * t)
    dqa, dqb = np.pi * np.cos(np.pi * t), 0.01 * np.pi * np.cos(np.pi * t)

    def write(dq_b):
        path = tmp_path / "traj.csv"
        cols = zip(t, qa, qb, dqa, dq_b, strict=True)
        rows = ["t,a,b,dq_a,dq_b"] + [",".join(repr(float(x)) for x in row) for row in cols]
        path.write_text("\n".join(rows) + "\n", encoding="utf-8")
        return path

    traj = hmpc_pin.load_trajectory(write(dqb), ["a", "b"])
    np.testing.assert_allclose(traj.sample(0.5)[1], [dqa[50], dqb[50]], atol=1e-9)
    for wrong in (np.degrees(dqb), 3.0 * dqb):  # deg/s; a wrong scale of a small motion
        with pytest.raises(TrajectoryError, match="the velocities of b between"):
            hmpc_pin.load_trajectory(write(wrong), ["a", "b"])


# ---------------------------------------------------------------- waypoint retiming
@pytest.mark.parametrize("margin", [0.97, 0.5])
def test_retimed_waypoints_start_on_time_pass_the_waypoints_and_use_the_limits(margin):
    """Oracle: the limits themselves. The motion starts at ``t_start`` at the first
    waypoint at rest, ends at the last at rest, stays within the velocity and acceleration
    limits on a fine grid, and is time-optimal up to the margin: the binding limit is
    reached (a stretch longer than needed would leave every ratio below the margin). With
    margin 0.5 time is stretched about 2x after TOPP-RA: velocity and acceleration must
    scale as 1/λ and 1/λ² (the finite differences below)."""
    pytest.importorskip("toppra")
    way = np.array([[0.0, 0.0], [1.0, 0.5], [0.2, 1.0], [1.2, -0.3]])
    vmax, amax = np.array([1.0, 1.5]), np.array([2.0, 3.0])
    traj = hmpc_pin.retime_waypoints(way, vmax, amax, t_start=0.7, margin=margin)
    assert traj.t_start == pytest.approx(0.7)
    for t, target in ((0.0, way[0]), (0.7, way[0]), (traj.t_end, way[-1])):
        q, dq = traj.sample(t)
        np.testing.assert_allclose(q, target, atol=1e-9)
        np.testing.assert_allclose(dq, 0.0, atol=1e-9)
    fine = np.linspace(traj.t_start, traj.t_end, 20001)
    q, dq = traj.sample_many(fine)
    ddq = traj.acceleration_many(fine)
    v_ratio = np.max(np.abs(dq) / vmax)
    a_ratio = np.max(np.abs(ddq) / amax)
    assert v_ratio <= margin * (1 + 1e-6) and a_ratio <= margin * (1 + 1e-6)
    assert max(v_ratio, a_ratio) >= 0.95 * margin
    # every waypoint is passed, in order (closest approach along the motion)
    idx = [int(np.argmin(np.linalg.norm(q - w, axis=1))) for w in way]
    assert idx == sorted(idx)
    assert max(np.linalg.norm(q[i] - w) for i, w in zip(idx, way, strict=True)) < 2e-2
    # velocity and acceleration are the derivatives of the positions (finite differences)
    h = fine[1] - fine[0]
    np.testing.assert_allclose((q[2:] - q[:-2]) / (2 * h), dq[1:-1], atol=2e-3)
    np.testing.assert_allclose((dq[2:] - dq[:-2]) / (2 * h), ddq[1:-1], atol=0.05 * amax.max())


# ---------------------------------------------------------------- init's speed cap
def test_init_caps_the_sine_speed_at_half_of_each_velocity_limit(tmp_path):
    """Oracle: the URDF's velocity limits (written here): 2π f a_i <= v_i / 2 on every
    joint, with equality on the binding one when that is below 0.1 Hz."""
    from hmpc_pin.experiment.init import plan

    vel = [3.0, 0.2, 5.0]
    parts, parent = [], "base"
    for i, v in enumerate(vel, start=1):
        limit = f'<limit lower="-2" upper="2" effort="200" velocity="{v}"/>'
        parts += [rod(f"l{i}"), joint(f"j{i}", "revolute", parent, f"l{i}",
                                       x=0.0 if i == 1 else 0.5, limit=limit)]  # fmt: skip
        parent = f"l{i}"
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(chain(*parts), encoding="utf-8")
    p = plan(urdf)
    peak = 2 * np.pi * p.frequency * np.asarray(p.amplitude)
    assert np.all(peak <= 0.5 * np.array(vel) * (1 + 1e-9))
    assert np.max(peak / (0.5 * np.array(vel))) == pytest.approx(1.0, rel=1e-9)
    assert int(np.argmax(peak / np.array(vel))) == 1


# ---------------------------------------------------------------- MuJoCo per joint
def test_mujoco_per_joint_parameters_land_on_their_joints_and_forces_oppose_motion(tmp_path):
    """A mimic follower ahead of the controlled joints shifts MuJoCo's degrees of freedom
    away from the controller's order. Oracle: MuJoCo's own model, read by joint name; and
    the damping force -D q̇ (MuJoCo's passive force) in the reported engine force."""
    mujoco = pytest.importorskip("mujoco")
    from hmpc_pin.sim.mujoco import MuJoCoPlant, MuJoCoSettings, mujoco_model

    parts = [  # the mimic follower first: MuJoCo's dofs are jm 0, j1 1, j2 2
        rod("lm"),
        joint("jm", "revolute", "base", "lm", x=0.0, extra='<mimic joint="j1" multiplier="0.5"/>'),
        rod("l1"), joint("j1", "revolute", "base", "l1", x=0.0),
        rod("l2"), joint("j2", "revolute", "l1", "l2"),
    ]  # fmt: skip
    urdf = tmp_path / "mimic.urdf"
    urdf.write_text(chain(*parts), encoding="utf-8")
    robot = hmpc_pin.load_robot(urdf)
    assert list(robot.joint_names) == ["j1", "j2"]
    settings = MuJoCoSettings(damping=(1.0, 3.0), frictionloss=(0.1, 0.3),
                              armature=(0.01, 0.03))  # fmt: skip
    model = mujoco_model(robot, settings)
    for k, name in enumerate(robot.joint_names):
        dof = model.joint(name).dofadr[0]
        assert model.dof_damping[dof] == pytest.approx(settings.damping[k])
        assert model.dof_frictionloss[dof] == pytest.approx(settings.frictionloss[k])
        assert model.dof_armature[dof] == pytest.approx(settings.armature[k])
    assert model.dof_damping[model.joint("jm").dofadr[0]] == 0.0
    # engine force: damping only, no gravity, no torque; with the mimic (its equality's
    # forces mapped by Eᵀ) and without (MuJoCo's forces as they are)
    assert mujoco.__version__
    for arm, dq0 in ((hmpc_pin.load_robot(urdf, gravity=0.0), [1.0, -2.0]),
                     (hmpc_pin.load_robot("planar3", gravity=0.0), [1.0, -2.0, 0.5])):  # fmt: skip
        damping = np.array([2.0, 5.0, 3.0][: arm.nq])
        plant = MuJoCoPlant(arm, None, 0.01, 0.001, MuJoCoSettings(damping=tuple(damping)))
        plant.reset(np.zeros(arm.nq), np.array(dq0))
        _, dq = plant.advance(np.zeros(arm.nq))
        force = plant.engine_force
        assert np.all(np.sign(force) == -np.sign(dq)) and np.all(force != 0), (force, dq)


def test_contact_lines_name_the_joint_of_the_peak_force_and_its_unit():
    """Hand-built arrays (the peak on the prismatic third joint, at t = 0.2 s): the line
    names that joint with newtons; the flag line names the joint and its threshold."""
    from types import SimpleNamespace

    from hmpc_pin.apps.metrics import contact_lines

    t = np.arange(5) * 0.1
    force = np.zeros((5, 3))
    force[2:, 0], force[3, 2] = 1.0, -7.5
    result = SimpleNamespace(
        t=t, q=np.zeros((5, 3)), joint_names=("a", "b", "c"), extra={"contact_force": force},
        meta={"first_contact": 0.2, "joint_kinds": ["revolute", "revolute", "prismatic"],
              "collision": {"detected_at": 0.3, "joint": "b", "reaction": "stop",
                            "threshold": [2.0, 4.0, 1.0]}},
    )  # fmt: skip
    lines = contact_lines(result)
    assert lines[0] == ("contact: first at t = 0.200 s with the obstacle; peak generalized "
                        "contact force 7.5 N at c")  # fmt: skip
    assert lines[1] == ("collision: flagged at t = 0.300 s on b (|d_hat| above its threshold "
                        "4 N·m); reaction: stop")  # fmt: skip
