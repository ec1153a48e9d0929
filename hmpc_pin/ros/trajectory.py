"""A ``trajectory_msgs/JointTrajectory`` message as a new joint reference, checked before
it replaces the current one.

The message's points (``positions``, optionally ``velocities``, at ``time_from_start``)
start at ``header.stamp`` (zero: now, as ros2_control's joint trajectory controller
reads it), on the loop's time axis; a stamp in the future is where the new reference
begins (the current one runs until then: the returned trajectory starts at its
``times[0]``). The new reference is the
:class:`~hmpc_pin.tasks.trajectory.JointTrajectory` through

* the current reference's position at the switch time :math:`t_s`, unless the first
  point is at ``time_from_start = 0``, so that the reference moves from where it was to
  the first point (no position jump), then
* the message's points at :math:`t_s + \\text{time\\_from\\_start}`, the last one held.

With velocities in every point and the first at ``time_from_start = 0`` the reference is
the quintic Hermite through positions and velocities; otherwise the clamped cubic spline
through the positions (the message's velocities, if any, checked against its positions).

Joints are matched by name (any order, every controlled joint present). Checked, in
this order, before anything changes: names, at least one point, strictly increasing
times, finite values, velocities for all points or none, a start not in the past, a
single point at ``time_from_start = 0`` (held) without a non-zero velocity, and
position and velocity limits at the samples and 10 points per segment
(:func:`~hmpc_pin.experiment.references.check_trajectory_limits`). A message that fails
is refused with one line naming what was wrong and the current reference is kept.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..exceptions import DimensionError, HmpcError, TrajectoryError
from ..model.robot import Robot
from ..tasks.trajectory import JointTrajectory

__all__ = ["trajectory_from_message"]

_SOURCE = "joint_trajectory message"


def _duration(d) -> float:
    return d.sec + 1e-9 * d.nanosec


def trajectory_from_message(
    msg,
    robot: Robot,
    current,
    now: float,
    lower: np.ndarray,
    upper: np.ndarray,
    *,
    origin: float = 0.0,
) -> JointTrajectory:
    """The reference of ``msg`` (module doc), checked.

    Args:
        msg: A ``trajectory_msgs/JointTrajectory`` (any object with its fields).
        robot: The controller's model (joint names, velocity limits).
        current: The reference in use (sampled at the switch time).
        now: The loop time [s] at which the message takes over (if unstamped or stamped
            earlier).
        lower, upper: Position limits [rad], (n,).
        origin: The loop clock's origin on the system clock [s] (for a stamped start).

    Raises:
        TrajectoryError: A malformed message (names, points, times, values).
        LimitError: The trajectory leaves the limits.
    """
    from ..experiment.references import check_trajectory_limits

    idx = _joint_order(msg, robot)
    times, q, dq = _points(msg, robot, idx)
    # a start in the future: the current reference runs until then (the caller swaps the
    # new one in at its first time, ``traj.times[0]``)
    now = _start(msg, now, origin)
    q_now = np.asarray(current.sample(now)[0], dtype=float)
    times, q, dq = _from_now(robot, now + times, q, dq, now, q_now)
    try:
        traj = JointTrajectory(times, q, dq, robot.joint_names, source=_SOURCE)
    except DimensionError as exc:
        raise TrajectoryError(_SOURCE, str(exc), "consistent shapes") from None
    check_trajectory_limits(
        traj,
        robot,
        lower,
        upper,
        what=_SOURCE,
        hint="the message was refused; the current reference is kept",
    )
    return traj


def _joint_order(msg, robot: Robot) -> np.ndarray:
    """The index in ``msg.joint_names`` of each of the robot's joints.

    Raises:
        TrajectoryError: A controlled joint is missing, or a name repeats.
    """
    names: Sequence[str] = list(msg.joint_names)
    where = {name: i for i, name in enumerate(names)}
    missing = [x for x in robot.joint_names if x not in where]
    if missing:
        raise TrajectoryError(
            _SOURCE,
            f"joint_names {list(names)} lack {missing}",
            f"every controlled joint {list(robot.joint_names)}",
        )
    if len(where) != len(names):
        raise TrajectoryError(
            _SOURCE, f"joint_names {list(names)} repeat a name", "each joint once"
        )
    return np.array([where[x] for x in robot.joint_names])


def _points(msg, robot: Robot, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """The message's points in the robot's joint order.

    Returns:
        ``(times, q, dq)``: the times from the start [s], (P,); the positions [rad],
        (P, n); the velocities [rad/s], (P, n), or ``None`` when the points give none.

    Raises:
        TrajectoryError: No points, velocities in some points only, a point of another
            length than ``joint_names``, a non-finite value, or times not increasing.
    """
    points = list(msg.points)
    if not points:
        raise TrajectoryError(_SOURCE, "no points", "at least one point")
    m = len(msg.joint_names)
    times = np.array([_duration(p.time_from_start) for p in points])
    q = np.full((len(points), robot.nq), np.nan)
    with_dq = [len(p.velocities) > 0 for p in points]
    if any(with_dq) and not all(with_dq):
        raise TrajectoryError(
            _SOURCE, "velocities in some points only", "velocities for every point or for none"
        )
    dq = np.full_like(q, np.nan) if all(with_dq) else None
    for k, p in enumerate(points):
        if len(p.positions) != m:
            raise TrajectoryError(
                _SOURCE,
                f"point {k} has {len(p.positions)} positions for {m} joint_names",
                f"{m} positions",
            )
        q[k] = np.asarray(p.positions, dtype=float)[idx]
        if dq is not None:
            if len(p.velocities) != m:
                raise TrajectoryError(
                    _SOURCE,
                    f"point {k} has {len(p.velocities)} velocities for {m} joint_names",
                    f"{m} velocities",
                )
            dq[k] = np.asarray(p.velocities, dtype=float)[idx]
    if not (np.isfinite(q).all() and (dq is None or np.isfinite(dq).all())):
        raise TrajectoryError(_SOURCE, "a non-finite position or velocity", "finite values")
    if times[0] < 0 or np.any(np.diff(times) <= 0):
        raise TrajectoryError(
            _SOURCE, f"time_from_start {times.tolist()}", "times >= 0, strictly increasing"
        )
    return times, q, dq


def _start(msg, now: float, origin: float) -> float:
    """The loop time [s] the trajectory starts at: its stamp on the loop clock, or ``now``
    for a zero stamp (or a stamp within 1 ms before ``now``).

    Raises:
        TrajectoryError: A stamp further in the past.
    """
    st = msg.header.stamp
    stamp = st.sec + 1e-9 * st.nanosec
    t_s = now if stamp == 0.0 else stamp - origin
    if t_s < now - 1e-3:
        raise TrajectoryError(
            _SOURCE,
            f"header.stamp {t_s - now:.3f} s in the past",
            "a start not in the past (or a zero stamp: now)",
        )
    return max(t_s, now)


def _from_now(
    robot: Robot,
    times: np.ndarray,
    q: np.ndarray,
    dq: np.ndarray | None,
    now: float,
    q_now: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """The points on the loop clock from ``now``: a first point later than ``now`` is
    reached from the current reference's position ``q_now`` (velocities then
    interpolated), a single point at ``now`` held.

    Raises:
        TrajectoryError: A single point with velocities that are not zero.
    """
    if times[0] > now + 1e-9:  # move from the current reference to the first point
        if dq is not None and times.size > 1:  # the message's own velocities checked
            JointTrajectory(times, q, dq, robot.joint_names, source=_SOURCE)
        times = np.concatenate([[now], times])
        q = np.vstack([q_now, q])
        dq = None
    if times.size == 1:  # one point at the switch: hold it
        if dq is not None and np.any(dq[0] != 0.0):
            moving = {
                n: float(v) for n, v in zip(robot.joint_names, dq[0], strict=True) if v != 0.0
            }
            raise TrajectoryError(
                _SOURCE,
                f"one point at time_from_start 0 with velocities {moving} [rad/s]",
                "zero velocities (or none) in a single point: the arm holds it",
            )
        times = np.array([now, now + 1.0])
        q = np.vstack([q, q])
        dq = None if dq is None else np.vstack([dq, np.zeros_like(dq)])
    return times, q, dq


def refusal(exc: HmpcError) -> str:
    """One line for a refused message."""
    return f"refused the joint_trajectory message: {exc}"
