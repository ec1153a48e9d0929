"""The reference of an experiment: ``[reference]`` → a :class:`~hmpc_pin.tasks.base.Reference`
(the sine of Eq 31, the Section 5.4 move, a trajectory file, waypoints or an end-effector
path), checked against the robot's limits before a run."""

from __future__ import annotations

import numpy as np

from ..exceptions import (
    LimitError,
)
from ..model.robot import Robot
from ..sim.result import Result
from ..tasks.base import Reference
from ..tasks.pose import (
    QUATERNION_ORDER,
    CirclePath,
    LinePath,
    PoseReference,
    PoseWaypoints,
    check_frame,
    frame_pose,
    plane_axes,
    quat_series,
    quat_to_matrix,
)
from ..tasks.quintic import QuinticReference
from ..tasks.sine import SineReference
from ..tasks.trajectory import JointTrajectory, load_trajectory
from ..tasks.waypoints import retime_waypoints
from .config import (
    ExperimentConfig,
)

__all__ = ["build_reference", "build_task_reference", "check_trajectory_limits", "task_space"]


def build_reference(config: ExperimentConfig, robot: Robot) -> Reference:
    """The joint reference of ``config``: the sine of Eq 31 or the Section 5.4 motion.

    For ``kind = "cartesian"`` both tool poses are solved by inverse kinematics
    inside the joint limits (the goal on the branch closest to the start) and
    joined by a quintic. Raises :class:`~hmpc_pin.exceptions.KinematicsError`
    naming the pose when one is unreachable.
    """
    n = robot.nq
    rc = config.reference
    if rc.kind in ("trajectory", "waypoints", "pose"):
        return build_task_reference(config, robot)
    if rc.kind == "cartesian":
        from ..model.planar import solve_pose

        cc = rc.cartesian
        q_start = solve_pose(robot, cc.start_position, np.deg2rad(cc.start_angle))
        q_goal = solve_pose(robot, cc.goal_position, np.deg2rad(cc.goal_angle), near=q_start)
        return QuinticReference(q_start, q_goal, cc.t_start, cc.move_time)
    return SineReference(
        n,
        amplitude=config.vector("reference.amplitude", n),
        frequency=config.vector("reference.frequency", n),
        offset=config.vector("reference.offset", n),
        phase=config.vector("reference.phase", n),
    )


def _task_limits(config: ExperimentConfig, robot: Robot) -> tuple[np.ndarray, np.ndarray]:
    """Position limits a task must keep: ``[controller.constraints]`` overrides, else the
    URDF's; none (±inf) for a joint without a range (lower >= upper, a 0/0 URDF limit) and for
    every joint when ``controller.constraints.position = false``."""
    con = config.controller.constraints
    over = con.overrides(robot.nq) if con is not None else {"lower": None, "upper": None}
    lower = np.array(over["lower"] if over["lower"] is not None else robot.lower, dtype=float)
    upper = np.array(over["upper"] if over["upper"] is not None else robot.upper, dtype=float)
    none = lower >= upper
    if con is not None and not con.position:
        none[:] = True
    lower[none], upper[none] = -np.inf, np.inf
    return lower, upper


def check_trajectory_limits(
    trajectory: JointTrajectory,
    robot: Robot,
    lower: np.ndarray,
    upper: np.ndarray,
    what: str = "reference",
    hint: str | None = None,
    velocity_hint: str | None = None,
) -> None:
    """Check a joint trajectory against position and (URDF) velocity limits at its samples
    and 10 points per segment between them.

    Args:
        hint: What to do when a position limit is left (and a velocity limit, unless
            ``velocity_hint`` is given). A revolute joint whose positions, read as
            degrees, would lie inside its limits gets a "degrees?" note.

    Raises:
        LimitError: Naming the first joint and time where a limit is left.
    """
    t = trajectory.times
    fine = np.union1d(t, np.linspace(t[0], t[-1], 10 * (t.size - 1) + 1))
    q, dq = trajectory.sample_many(fine)
    names = robot.joint_names
    bad = (q < lower - 1e-9) | (q > upper + 1e-9)
    if bad.any():
        k, i = np.argwhere(bad)[0]
        radians = np.radians(q[:, i])
        if (
            robot.joint_kinds[i] != "prismatic"
            and np.abs(q[:, i]).max() > 2 * np.pi
            and np.all((radians >= lower[i]) & (radians <= upper[i]))
        ):
            peak = np.abs(q[:, i]).max()
            todo = hint or "change the file"
            hint = (
                f"its positions look like degrees (max |q| = {peak:.4g}; trajectory "
                f"files are in rad): convert them; or {todo}"
            )
        raise LimitError(what, names[i], float(fine[k]), float(q[k, i]), lower[i], upper[i], hint)
    vmax = np.where(robot.velocity_limit > 0, robot.velocity_limit, np.inf)
    bad = np.abs(dq) > vmax * (1 + 1e-9)
    if bad.any():
        k, i = np.argwhere(bad)[0]
        raise LimitError(
            f"{what} velocity",
            names[i],
            float(fine[k]),
            float(dq[k, i]),
            -vmax[i],
            vmax[i],
            velocity_hint or hint,
        )


def _pose_path(pc, robot: Robot, q_init: np.ndarray):
    """The target path of ``[reference.pose]`` (orientation and start from ``q_init``)."""
    frame = pc.frame or robot.tool_frame
    p0, R0 = frame_pose(robot, frame, q_init)
    p0, R0 = p0[0], R0[0]
    R_held = quat_to_matrix(pc.orientation) if pc.orientation is not None else R0
    if pc.path == "circle":
        u, v = plane_axes(pc.plane)
        center = pc.center if pc.center is not None else p0 - pc.radius * u
        return CirclePath(center, pc.radius, pc.frequency, u, v, R_held, ramp=pc.ramp)
    if pc.path == "line":
        start = pc.start if pc.start is not None else p0
        return LinePath(start, pc.end, pc.t_start, pc.duration, R_held)
    rots = (
        np.array([quat_to_matrix(q) for q in pc.orientations])
        if pc.orientations is not None
        else np.repeat(R0[None], len(pc.times), axis=0)
    )
    return PoseWaypoints(pc.times, pc.positions, rots)


def build_task_reference(config: ExperimentConfig, robot: Robot) -> Reference:
    """The reference of ``kind = "trajectory" | "waypoints" | "pose"`` (docs, "Tutorials"),
    checked against the joint position and velocity limits before any run.

    Raises:
        TrajectoryError: A bad file or waypoint list. KinematicsError: an unknown frame or
            an unreachable pose. LimitError: a limit left (joint and time named).
    """
    rc = config.reference
    lower, upper = _task_limits(config, robot)
    names = robot.joint_names
    if rc.kind == "trajectory":
        trajectory = load_trajectory(rc.trajectory.file, names)
        check_trajectory_limits(
            trajectory,
            robot,
            lower,
            upper,
            f"reference ({rc.trajectory.file.name})",
            "change the file (positions inside the limits) or the limits (the URDF's or "
            "controller.constraints.lower/upper)",
            "change the file: a slower motion (velocity limits: the URDF's)",
        )
        return trajectory
    if rc.kind == "waypoints":
        wc = rc.waypoints
        n = robot.nq
        for p, point in enumerate(wc.points):
            for i in np.flatnonzero((point < lower) | (point > upper)):
                raise LimitError(
                    f"waypoint {p}",
                    names[i],
                    None,
                    point[i],
                    lower[i],
                    upper[i],
                    "move the waypoint (reference.waypoints.points) inside the limits",
                )
        vmax = (
            config.vector("reference.waypoints.velocity_limit", n)
            if wc.velocity_limit is not None
            else robot.velocity_limit
        )
        trajectory = retime_waypoints(
            wc.points,
            vmax,
            config.vector("reference.waypoints.acceleration_limit", n),
            t_start=wc.t_start,
            dt=config.controller.Ts,
            joint_names=names,
        )
        check_trajectory_limits(
            trajectory,
            robot,
            lower,
            upper,
            "waypoint path",
            "the spline through the waypoints overshoots: add a waypoint or move them away "
            "from the limit",
        )
        return trajectory
    pc = rc.pose
    n = robot.nq
    if pc.q_init is not None:
        q_init = config.vector("reference.pose.q_init", n)
    elif config.simulation.q0 is not None:
        q_init = config.vector("simulation.q0", n)
    else:
        q_init = np.where(np.isfinite(lower + upper), (lower + upper) / 2, 0.0)
    frame = pc.frame or robot.tool_frame
    check_frame(robot, frame)
    for i in np.flatnonzero((q_init < lower) | (q_init > upper)):
        raise LimitError(
            "reference.pose.q_init",
            names[i],
            None,
            q_init[i],
            lower[i],
            upper[i],
            "give reference.pose.q_init inside the limits",
        )
    cc = config.controller
    t_end = config.simulation.duration + (cc.N + 2) * cc.Ts
    reference = PoseReference.solve(
        robot,
        frame,
        _pose_path(pc, robot, q_init),
        t_end,
        q_init,
        dt=pc.dt,
        posture_cost=pc.posture_cost,
    )
    check_trajectory_limits(
        reference.trajectory,
        robot,
        lower,
        upper,
        f"pose task ({frame})",
        "the spline through the IK samples leaves a limit: lower reference.pose.dt or move "
        "the path away from the limits",
    )
    return reference


def task_space(reference, robot: Robot, result: Result) -> Result:
    """``result`` with the task-space arrays of a pose task: the frame's position
    ``ee_pos`` and quaternion ``ee_quat`` (x, y, z, w) from the measured joints by Pinocchio's
    forward kinematics, and the targets ``ee_pos_ref``, ``ee_quat_ref``; unchanged for a
    joint-space reference."""
    if not isinstance(reference, PoseReference) or len(result.t) == 0:
        return result
    pos, rot = frame_pose(robot, reference.frame, result.q)
    pos_ref, quat_ref = reference.target(result.t)
    result.ee_pos, result.ee_pos_ref = pos, pos_ref
    result.ee_quat = quat_series(rot, like=quat_ref)  # the target's hemisphere
    result.ee_quat_ref = quat_ref
    result.meta["task"] = {"frame": reference.frame, "quaternion": QUATERNION_ORDER}
    return result
