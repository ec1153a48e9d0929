"""``trajectory_msgs/JointTrajectory`` messages as references, without DDS (the message
types are constructed, rclpy is not initialised): matching by name, stamps and
``time_from_start`` in seconds and nanoseconds, the interpolation (quintic Hermite with
velocities from t = 0, else the clamped cubic, compared with scipy's), and every refusal
with its one line."""

from __future__ import annotations

import numpy as np
import pytest

from hmpc_pin.exceptions import LimitError, TrajectoryError
from hmpc_pin.model.robot import load_robot
from hmpc_pin.tasks.trajectory import JointTrajectory as Reference

from .conftest import PLANAR3

msgs = pytest.importorskip("trajectory_msgs.msg", reason="extra hmpc_pin[ros] not installed")

NAMES = ["joint1", "joint2", "joint3"]
LOWER = np.array([-1.5, -1.5, -2.3])
UPPER = np.array([1.5, 1.5, 2.3])
QA = np.array([0.1, -0.2, 0.3])
V = np.array([0.01, 0.02, -0.01])  # the current reference: QA + V t, exactly


@pytest.fixture(scope="module")
def robot():
    return load_robot(PLANAR3)


@pytest.fixture(scope="module")
def current():
    """A reference moving at constant speed (quintic Hermite through consistent
    velocities: linear), so that sampling it at the wrong time shows."""
    return Reference([0.0, 100.0], [QA, QA + 100 * V], [V, V], NAMES)


def _at(t):
    return QA + V * t


def _msg(names, points, stamp=(0, 0)):
    """``points``: (t [s], positions, velocities or None); ``stamp``: (sec, nanosec)."""
    msg = msgs.JointTrajectory()
    msg.joint_names = list(names)
    msg.header.stamp.sec, msg.header.stamp.nanosec = stamp
    for t, q, dq in points:
        p = msgs.JointTrajectoryPoint()
        p.positions = [float(x) for x in q]
        if dq is not None:
            p.velocities = [float(x) for x in dq]
        ns = round(t * 1e9)
        p.time_from_start.sec, p.time_from_start.nanosec = divmod(ns, 1_000_000_000)
        msg.points.append(p)
    return msg


def _convert(msg, robot, current, now, origin=0.0):
    from hmpc_pin.ros.trajectory import trajectory_from_message

    return trajectory_from_message(msg, robot, current, now, LOWER, UPPER, origin=origin)


def test_names_in_another_order_with_velocities_from_zero_are_a_quintic_hermite(robot, current):
    """Points at time_from_start 0 with velocities, joints in reverse order plus a gripper:
    the reference passes through each point's positions AND velocities, in the robot's
    order, from the first point (no move from the current reference)."""
    now = 1.25
    t = np.array([0.0, 0.75, 1.5])
    amp = np.array([0.3, -0.2, 0.1])  # q = 0.1 + amp sin(t), velocities its derivative
    q = 0.1 + amp * np.sin(t)[:, None]
    dq = amp * np.cos(t)[:, None]
    order = [2, 1, 0]  # reversed
    points = [
        (t[k], [0.04, *q[k, order]], [0.0, *dq[k, order]]) for k in range(3)
    ]  # a gripper first
    traj = _convert(_msg(["gripper", *[NAMES[i] for i in order]], points), robot, current, now)
    assert traj.times[0] == pytest.approx(now)
    for k in range(3):
        qk, dqk = traj.sample(now + t[k])
        np.testing.assert_allclose(qk, q[k], atol=1e-12)
        if k < 2:  # (the last point is held: no velocity after it)
            np.testing.assert_allclose(dqk, dq[k], atol=1e-12)
    # the last point held
    q_end, dq_end = traj.sample(now + 10.0)
    np.testing.assert_allclose(q_end, q[-1], atol=1e-12)
    np.testing.assert_allclose(dq_end, 0.0, atol=1e-12)


def test_without_velocities_a_clamped_cubic_from_the_current_reference(robot, current):
    """No velocities, the first point later than 0: the reference moves from where the
    current one is at the switch, through the points, as scipy's clamped cubic spline."""
    from scipy.interpolate import CubicSpline

    now = 2.0
    q = np.array([[0.3, 0.1, 0.2], [0.5, -0.1, 0.4]])
    t = [0.5, 1.5]
    traj = _convert(_msg(NAMES, [(t[0], q[0], None), (t[1], q[1], None)]), robot, current, now)
    knots = np.array([now, now + t[0], now + t[1]])
    values = np.vstack([_at(now), q])
    spline = CubicSpline(knots, values, bc_type="clamped")
    fine = np.linspace(now, now + t[1], 31)
    got_q, got_dq = traj.sample_many(fine)
    np.testing.assert_allclose(got_q, spline(fine), atol=1e-10)
    np.testing.assert_allclose(got_dq, spline(fine, 1), atol=1e-9)


def test_velocities_with_a_later_first_point_are_checked_then_dropped(robot, current):
    """Velocities given, first point at 0.5 s: the move from the current reference has no
    velocity there, so the clamped cubic through the positions is used; the message's own
    velocities are still checked against its positions (degrees/s are refused)."""
    from scipy.interpolate import CubicSpline

    now = 0.5
    q = np.array([[0.3, 0.1, 0.2], [0.5, -0.1, 0.4]])
    rate = (q[1] - q[0]) / 1.0
    points = [(0.5, q[0], rate), (1.5, q[1], rate)]
    traj = _convert(_msg(NAMES, points), robot, current, now)
    spline = CubicSpline([now, now + 0.5, now + 1.5], np.vstack([_at(now), q]), bc_type="clamped")
    fine = np.linspace(now, now + 1.5, 16)
    np.testing.assert_allclose(traj.sample_many(fine)[0], spline(fine), atol=1e-10)
    bad = [(0.5, q[0], np.degrees(rate)), (1.5, q[1], np.degrees(rate))]
    with pytest.raises(TrajectoryError, match="velocities of joint1"):
        _convert(_msg(NAMES, bad), robot, current, now)


def test_one_point_at_zero_is_held_and_one_point_later_is_reached(robot, current):
    now = 3.0
    target = np.array([0.2, 0.2, 0.2])
    held = _convert(_msg(NAMES, [(0.0, target, None)]), robot, current, now)
    for t in (now, now + 0.5, now + 7.0):
        np.testing.assert_allclose(held.sample(t)[0], target, atol=1e-12)
        np.testing.assert_allclose(held.sample(t)[1], 0.0, atol=1e-12)
    # with a zero velocity: the same hold; a moving single point cannot be held
    still = _convert(_msg(NAMES, [(0.0, target, [0.0] * 3)]), robot, current, now)
    np.testing.assert_allclose(still.sample(now + 0.5)[0], target, atol=1e-12)
    with pytest.raises(TrajectoryError) as refused:
        _convert(_msg(NAMES, [(0.0, target, [0.1, 0.0, -0.1])]), robot, current, now)
    # the point as sent, no interval the message did not hold
    assert "one point at time_from_start 0" in str(refused.value)
    assert "'joint1': 0.1" in str(refused.value) and "'joint3': -0.1" in str(refused.value)
    assert "joint2" not in str(refused.value) and "between" not in str(refused.value)
    # one point 0.25 s later: from the current reference's position to it
    later = _convert(_msg(NAMES, [(0.25, target, None)]), robot, current, now)
    np.testing.assert_allclose(later.sample(now)[0], _at(now), atol=1e-12)
    np.testing.assert_allclose(later.sample(now + 0.25)[0], target, atol=1e-12)


def test_stamp_seconds_and_nanoseconds_on_the_loops_axis(robot, current):
    """header.stamp = origin + 3.25 s (sec and nanosec), the loop at 1 s: the reference
    starts at 3.25 s, from the current reference's position THEN, and reaches the point
    time_from_start = 0.5 s (nanoseconds only) later."""
    origin = 1_700_000_000.0
    now = 1.0
    target = np.array([0.3, 0.0, -0.2])
    msg = _msg(NAMES, [(0.5, target, None)], stamp=(1_700_000_003, 250_000_000))
    assert msg.points[0].time_from_start.sec == 0
    traj = _convert(msg, robot, current, now, origin=origin)
    assert traj.times[0] == pytest.approx(3.25, abs=1e-6)
    np.testing.assert_allclose(traj.sample(3.25)[0], _at(3.25), atol=1e-6)
    np.testing.assert_allclose(traj.sample(3.75)[0], target, atol=1e-9)
    # a zero stamp is now, whatever the origin
    traj = _convert(_msg(NAMES, [(0.5, target, None)]), robot, current, now, origin=origin)
    assert traj.times[0] == pytest.approx(now)
    np.testing.assert_allclose(traj.sample(now + 0.5)[0], target, atol=1e-12)


def test_a_stamp_up_to_one_millisecond_in_the_past_is_now(robot, current):
    now = 4.0
    target = np.array([0.3, 0.0, -0.2])
    recent = _msg(NAMES, [(1.0, target, None)], stamp=(3, 999_500_000))  # 0.5 ms ago
    traj = _convert(recent, robot, current, now)
    assert traj.times[0] == pytest.approx(now)
    np.testing.assert_allclose(traj.sample(now + 1.0)[0], target, atol=1e-12)
    old = _msg(NAMES, [(1.0, target, None)], stamp=(3, 998_000_000))  # 2 ms ago
    with pytest.raises(TrajectoryError, match=r"header\.stamp -0\.002 s in the past"):
        _convert(old, robot, current, now)


def _refused(msg, robot, current, now=0.0):
    from hmpc_pin.ros.trajectory import refusal

    with pytest.raises((TrajectoryError, LimitError)) as info:
        _convert(msg, robot, current, now)
    line = refusal(info.value)
    assert line == f"refused the joint_trajectory message: {info.value}"
    assert "\n" not in line and "Error(" not in line
    return line


P = np.array([0.1, 0.1, 0.1])


@pytest.mark.parametrize(
    ("names", "points", "words"),
    [
        (NAMES[:2], [(1.0, P[:2], None)], "lack ['joint3']"),
        ([*NAMES, "joint1"], [(1.0, [*P, 0.0], None)], "repeat a name"),
        (NAMES, [], "no points"),
        (NAMES, [(1.0, P, [0.0] * 3), (2.0, P, None)], "velocities in some points only"),
        (NAMES, [(1.0, P, None), (2.0, P, [0.0] * 3)], "velocities in some points only"),
        (NAMES, [(1.0, P[:2], None)], "point 0 has 2 positions for 3 joint_names"),
        (NAMES, [(1.0, P, None), (2.0, [*P, 0.0], None)], "point 1 has 4 positions"),
        (NAMES, [(1.0, P, [0.0] * 2)], "point 0 has 2 velocities for 3 joint_names"),
        (NAMES, [(1.0, [0.1, np.nan, 0.1], None)], "non-finite"),
        (NAMES, [(1.0, P, [0.0, np.inf, 0.0])], "non-finite"),
        (NAMES, [(1.0, P, None), (1.0, P, None)], "time_from_start [1.0, 1.0]"),
        (NAMES, [(2.0, P, None), (1.0, P, None)], "time_from_start [2.0, 1.0]"),
        (NAMES, [(0.0, P, None), (0.0, P, None)], "strictly increasing"),
        (NAMES, [(0.5, [1.6, 0.1, 0.1], None)], "joint1"),  # beyond upper = 1.5
        (NAMES, [(0.5, [0.1, -1.6, 0.1], None)], "joint2"),  # below lower = -1.5
    ],
)
def test_bad_messages_are_one_line_naming_what_was_wrong(robot, current, names, points, words):
    assert words in _refused(_msg(names, points), robot, current)


def test_a_negative_time_from_start_is_refused(robot, current):
    msg = _msg(NAMES, [(1.0, P, None)])
    msg.points[0].time_from_start.sec = -1
    assert "times >= 0" in _refused(msg, robot, current)


def test_positions_on_the_limits_pass_and_just_beyond_are_refused(robot, current):
    """A point exactly at a limit (held, no overshoot of the clamped cubic) is accepted;
    1e-6 rad beyond is refused, naming the joint and the limit."""
    on = np.array([UPPER[0], LOWER[1], 0.0])
    _convert(_msg(NAMES, [(0.0, on, None)]), robot, current, 0.0)
    beyond = on + np.array([1e-6, 0.0, 0.0])
    line = _refused(_msg(NAMES, [(0.0, beyond, None)]), robot, current)
    assert "joint1" in line and "outside its limits" in line


def test_a_move_faster_than_the_velocity_limit_is_refused():
    """Panda's URDF velocity limits (2.175 rad/s on joint 1): 0.5 rad in 0.1 s (a clamped
    cubic peaks at 1.5 x 5 rad/s) is refused as a velocity; 0.5 rad in 2 s is not."""
    panda = load_robot("panda")
    names = list(panda.joint_names)
    q0 = np.zeros(panda.nq)
    q0[3], q0[5] = -1.5, 1.5  # inside the limits
    cur = Reference([0.0, 1.0], [q0, q0], None, names)
    lo, hi = panda.lower, panda.upper
    from hmpc_pin.ros.trajectory import trajectory_from_message

    target = q0.copy()
    target[0] += 0.5
    fast = _msg(names, [(0.1, target, None)])
    with pytest.raises(LimitError, match=r"velocity.*panda_joint1"):
        trajectory_from_message(fast, panda, cur, 0.0, lo, hi)
    trajectory_from_message(_msg(names, [(2.0, target, None)]), panda, cur, 0.0, lo, hi)
