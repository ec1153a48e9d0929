"""End-effector tasks on any arm: a frame's SE(3) path turned into a joint trajectory.

A target path :math:`T^*(t) = (p^*(t), R^*(t)) \\in SE(3)` of one frame of the robot —
timed pose waypoints (:class:`PoseWaypoints`), a line (:class:`LinePath`) or a circle
(:class:`CirclePath`) — is solved by differential inverse kinematics with **pink** on the
controller's own Pinocchio model, before the run, at the sample times
:math:`t_k = t_0 + k\\,\\Delta t`. Each sample is one QP step of pink (ProxQP through
qpsolvers) from the previous solution:

.. math::

    \\min_{\\Delta q}\\ \\tfrac12\\|J\\Delta q + e(q_k, T^*(t_{k+1}))\\|^2_{W}
        + \\tfrac{w_p}{2}\\|\\Delta q + q_k - q_{init}\\|^2
    \\quad\\text{s.t.}\\quad q_{min} \\le q_k + \\Delta q \\le q_{max},\\
    |\\Delta q| \\le \\dot q_{max}\\,\\Delta t,

with :math:`e` the frame's SE(3) error (pink's ``FrameTask``, gain 1: one Gauss–Newton
step) and a small posture term :math:`w_p` (pink's ``PostureTask``) that fixes the
redundant directions of a 7-joint arm. So the joint positions stay inside their limits and
the joint velocities :math:`\\Delta q/\\Delta t` inside the URDF's velocity limits by
construction. The samples are then interpolated by a
:class:`~hmpc_pin.tasks.trajectory.JointTrajectory` (cubic spline).

Every sample's residual — position :math:`\\|p(q_k) - p^*(t_k)\\|` [m] and orientation
:math:`\\|\\log(R^{*T}(t_k) R(q_k))\\|` [rad], from Pinocchio's forward kinematics — is
checked: above the tolerance the pose cannot be reached (outside the workspace, or only
past a joint limit or faster than the velocity limits), and a
:class:`~hmpc_pin.exceptions.KinematicsError` names the time, the target and the residual.

Orientations are unit quaternions :math:`(x, y, z, w)`, scalar last (Pinocchio's/Eigen's
``coeffs()`` order), in the world frame.

``pin-pink`` is in the extra ``hmpc_pin[tasks]``; without it an
:class:`~hmpc_pin.exceptions.ExtraError` names the extra.
"""

from __future__ import annotations

import difflib
import warnings
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..exceptions import ExtraError, KinematicsError, LimitError
from ..model.robot import Robot
from .base import FloatArray, Pair, SamplingForm, samples_otherwise
from .trajectory import JointTrajectory

__all__ = [
    "CirclePath",
    "LinePath",
    "PoseReference",
    "PoseWaypoints",
    "check_frame",
    "frame_pose",
    "plane_axes",
    "quat_series",
    "quat_to_matrix",
    "rotation_angle",
    "solve_path_ik",
]

#: Order of the quaternion components everywhere in this package.
QUATERNION_ORDER = "x, y, z, w (scalar last)"


def quat_to_matrix(quat) -> FloatArray:
    """Rotation matrix of the unit quaternion ``(x, y, z, w)`` (normalised here).

    Raises:
        KinematicsError: Not 4 finite numbers of non-zero norm.
    """
    q = np.asarray(quat, dtype=float)
    if q.shape != (4,) or not np.all(np.isfinite(q)) or np.linalg.norm(q) < 1e-9:
        raise KinematicsError(
            f"orientation {q.tolist()} is not a quaternion",
            value=q,
            expected=f"4 finite numbers ({QUATERNION_ORDER}) of non-zero norm",
        )
    x, y, z, w = q / np.linalg.norm(q)
    return pin.Quaternion(w, x, y, z).toRotationMatrix()


def matrix_to_quat(R) -> FloatArray:
    """The unit quaternion ``(x, y, z, w)`` of ``R``, with ``w >= 0``."""
    coeffs = np.array(pin.Quaternion(np.asarray(R, dtype=float)).coeffs(), dtype=float)
    return -coeffs if coeffs[3] < 0 else coeffs


def quat_series(rotations, like=None) -> FloatArray:
    """Unit quaternions ``(x, y, z, w)`` of a stack of rotations (m, 3, 3), continuous in
    sign: :math:`q` and :math:`-q` are the same rotation, so each is chosen in the
    hemisphere of its predecessor (the first with ``w >= 0``), or, with ``like`` (m, 4),
    in the hemisphere of ``like``'s row (the measured orientation next to its target).
    A path through a half turn then has no jump of :math:`|\\Delta q| = 2`."""
    quats = np.array([matrix_to_quat(R) for R in rotations]).reshape(-1, 4)
    if like is not None:
        flip = np.sum(quats * np.asarray(like, dtype=float), axis=1) < 0
        quats[flip] *= -1.0
        return quats
    for k in range(1, len(quats)):
        if np.dot(quats[k], quats[k - 1]) < 0:
            quats[k] *= -1.0
    return quats


def rotation_angle(R_ref, R) -> FloatArray:
    """Angle [rad] of :math:`R_{ref}^T R` for stacks (m, 3, 3): :math:`\\|\\log R_{ref}^T R\\|`."""
    rel = np.einsum("mji,mjk->mik", np.asarray(R_ref), np.asarray(R))
    cos = np.clip((np.trace(rel, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
    return np.arccos(cos)


def check_frame(robot: Robot, frame: str) -> int:
    """The id of ``frame`` in the robot's model.

    Raises:
        KinematicsError: No such frame; the message lists the closest names.
    """
    names = [f.name for f in robot.model.frames]
    if not isinstance(frame, str) or not robot.model.existFrame(frame):
        close = difflib.get_close_matches(str(frame), names, n=4, cutoff=0.3)
        hint = f"closest: {', '.join(map(repr, close))}" if close else f"frames: {names}"
        raise KinematicsError(
            f"frame {frame!r} is not in robot {robot.name!r} ({hint}); "
            f"the tool frame is {robot.tool_frame!r}",
            value=frame,
            expected="a frame name of the robot's model",
        )
    return robot.model.getFrameId(frame)


def frame_pose(robot: Robot, frame: str, qs) -> tuple[FloatArray, FloatArray]:
    """Positions (m, 3) [m] and rotations (m, 3, 3) of ``frame`` at joint vectors ``qs``
    (m, n), by Pinocchio's forward kinematics (own data, the robot's is untouched)."""
    fid = check_frame(robot, frame)
    model, data = robot.model, robot.model.createData()
    qs = np.atleast_2d(np.asarray(qs, dtype=float))
    pos, rot = np.empty((len(qs), 3)), np.empty((len(qs), 3, 3))
    for k, q in enumerate(qs):
        pin.framesForwardKinematics(model, data, q)
        pos[k] = data.oMf[fid].translation
        rot[k] = data.oMf[fid].rotation
    return pos, rot


def _min_jerk(s):
    s = np.clip(s, 0.0, 1.0)
    return s**3 * (10.0 + s * (-15.0 + 6.0 * s))


@dataclass(frozen=True)
class PoseWaypoints:
    """Timed SE(3) waypoints; between two, a minimum-jerk blend (position on the segment,
    rotation along the geodesic :math:`R_0\\exp(\\sigma\\log R_0^T R_1)`), at rest at each
    waypoint; the first pose held before, the last after.

    Attributes:
        times: (P,) [s], strictly increasing. positions: (P, 3) [m]. rotations: (P, 3, 3).
    """

    times: FloatArray
    positions: FloatArray
    rotations: FloatArray

    def poses(self, times) -> tuple[FloatArray, FloatArray]:
        """Positions (m, 3) [m] and rotations (m, 3, 3) at ``times`` (m,) [s]."""
        t = np.asarray(times, dtype=float).reshape(-1)
        k = np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, len(self.times) - 2)
        h = self.times[k + 1] - self.times[k]
        sigma = _min_jerk((t - self.times[k]) / h)
        p0, p1 = self.positions[k], self.positions[k + 1]
        pos = p0 + sigma[:, None] * (p1 - p0)
        rot = np.empty((t.size, 3, 3))
        for i in range(t.size):
            R0, R1 = self.rotations[k[i]], self.rotations[k[i] + 1]
            rot[i] = R0 @ pin.exp3(sigma[i] * pin.log3(R0.T @ R1))
        return pos, rot


@dataclass(frozen=True)
class LinePath:
    """A straight line from ``start`` to ``end`` [m] in ``duration`` [s] from ``t_start``
    [s] (minimum-jerk timing, at rest at both ends), orientation ``rotation`` held."""

    start: FloatArray
    end: FloatArray
    t_start: float
    duration: float
    rotation: FloatArray

    def poses(self, times) -> tuple[FloatArray, FloatArray]:
        """Positions (m, 3) [m] and rotations (m, 3, 3) at ``times`` (m,) [s]."""
        t = np.asarray(times, dtype=float).reshape(-1)
        sigma = _min_jerk((t - self.t_start) / self.duration)
        pos = self.start + sigma[:, None] * (self.end - self.start)
        return pos, np.broadcast_to(self.rotation, (t.size, 3, 3)).copy()


def plane_axes(plane) -> tuple[FloatArray, FloatArray]:
    """Two orthonormal in-plane axes (u, v) of ``"xy"``, ``"xz"``, ``"yz"`` or a normal (3,).

    Raises:
        KinematicsError: Another name, or a zero or non-finite normal.
    """
    named = {
        "xy": ((1, 0, 0), (0, 1, 0)),
        "xz": ((1, 0, 0), (0, 0, 1)),
        "yz": ((0, 1, 0), (0, 0, 1)),
    }
    if isinstance(plane, str):
        if plane not in named:
            raise KinematicsError(
                f"plane {plane!r} is not known",
                value=plane,
                expected="'xy', 'xz', 'yz' or a normal [nx, ny, nz]",
            )
        u, v = named[plane]
        return np.array(u, dtype=float), np.array(v, dtype=float)
    nrm = np.asarray(plane, dtype=float)
    if nrm.shape != (3,) or not np.all(np.isfinite(nrm)) or np.linalg.norm(nrm) < 1e-12:
        raise KinematicsError(
            f"plane normal {nrm.tolist()} is not a direction",
            value=nrm,
            expected="3 finite numbers, not all zero",
        )
    nrm = nrm / np.linalg.norm(nrm)
    seed = np.eye(3)[int(np.argmin(np.abs(nrm)))]
    u = np.cross(nrm, seed)
    u /= np.linalg.norm(u)
    return u, np.cross(nrm, u)


@dataclass(frozen=True)
class CirclePath:
    """:math:`p^*(t) = c + r(\\cos\\theta\\,u + \\sin\\theta\\,v)`, orientation ``rotation``
    held; u, v span the plane. The angle starts at rest when ``ramp`` :math:`T_r > 0`:

    .. math::

        \\theta(t) = 2\\pi f\\,T_r\\,(2.5x^4 - 3x^5 + x^6),\\ x = \\tfrac{t - t_0}{T_r} \\le 1;
        \\qquad \\theta(t) = 2\\pi f\\,(t - t_0 - T_r/2) \\text{ after,}

    the angular speed rising from 0 to :math:`2\\pi f` along the minimum-jerk profile
    :math:`10x^3 - 15x^4 + 6x^5` (C²); with :math:`T_r = 0`, :math:`\\theta = 2\\pi f(t - t_0)`.

    Attributes:
        center: c [m]. radius: r [m]. frequency: f [Hz]. u, v: in-plane unit axes.
        rotation: (3, 3). t_start: t₀ [s] (before it the start point is held).
        ramp: :math:`T_r` [s], 0 for none.
    """

    center: FloatArray
    radius: float
    frequency: float
    u: FloatArray
    v: FloatArray
    rotation: FloatArray
    t_start: float = 0.0
    ramp: float = 0.0

    def angle(self, times) -> FloatArray:
        """:math:`\\theta(t)` [rad] at ``times`` (m,) [s]."""
        tau = np.maximum(np.asarray(times, dtype=float).reshape(-1) - self.t_start, 0.0)
        w = 2.0 * np.pi * self.frequency
        if self.ramp <= 0:
            return w * tau
        x = np.minimum(tau / self.ramp, 1.0)
        rising = w * self.ramp * x**4 * (2.5 + x * (-3.0 + x))
        return np.where(tau < self.ramp, rising, w * (tau - self.ramp / 2.0))

    def poses(self, times) -> tuple[FloatArray, FloatArray]:
        """Positions (m, 3) [m] and rotations (m, 3, 3) at ``times`` (m,) [s]."""
        theta = self.angle(times)
        pos = self.center + self.radius * (
            np.cos(theta)[:, None] * self.u + np.sin(theta)[:, None] * self.v
        )
        return pos, np.broadcast_to(self.rotation, (theta.size, 3, 3)).copy()


def _pink():
    try:
        import pink
        import qpsolvers
    except ImportError as exc:
        raise ExtraError("tasks", "end-effector tasks (pink's differential IK)") from exc
    solver = "proxqp" if "proxqp" in qpsolvers.available_solvers else None
    if solver is None:
        raise KinematicsError(
            "pose tasks solve pink's QP with ProxQP, which qpsolvers does not find; "
            "pip install 'qpsolvers[proxqp]'",
            value=qpsolvers.available_solvers,
            expected="'proxqp' among qpsolvers.available_solvers",
        )
    return pink, solver


def _describe(pos, rot) -> str:
    return f"position {np.round(pos, 4).tolist()} m, orientation (xyzw) " + str(
        np.round(matrix_to_quat(rot), 4).tolist()
    )


def solve_path_ik(
    robot: Robot,
    frame: str,
    path,
    times,
    q_init,
    *,
    posture_cost: float = 1e-3,
    position_tol: float = 1e-4,
    orientation_tol: float = 1e-3,
    start_iterations: int = 500,
) -> FloatArray:
    """Joint positions (K, n) that put ``frame`` on ``path`` at ``times`` (module doc).

    The first sample is solved from ``q_init`` by up to ``start_iterations`` pink steps
    (joint position limits only: the start of the run is not a motion); each next one by one
    step from the previous, under the position and velocity limits.

    Args:
        robot: The controller's model.
        frame: Frame name (:func:`check_frame`).
        path: An object with ``poses(times) -> (positions (m, 3), rotations (m, 3, 3))``.
        times: Sample times (K,) [s], uniformly spaced, K >= 2.
        q_init: Initial guess and posture target [rad], inside the position limits.
        posture_cost: :math:`w_p`, relative to the frame task's cost 1.
        position_tol, orientation_tol: Largest residual [m], [rad] accepted.

    Raises:
        KinematicsError: Unknown frame; a pose whose residual exceeds the tolerance
            (named with its time, the target and the residual).
        ExtraError: pink is not installed (extra ``tasks``).
        LimitError: ``q_init`` outside the position limits.
    """
    pink, solver = _pink()
    from pink.limits import ConfigurationLimit, VelocityLimit
    from pink.tasks import FrameTask, PostureTask

    check_frame(robot, frame)
    times = np.asarray(times, dtype=float)
    dt = float(times[1] - times[0])
    q = robot.check_vector("q_init", q_init).copy()
    ranged = robot.lower < robot.upper  # a 0/0 URDF range means no limit (pink skips it too)
    for i in np.flatnonzero(ranged & ((q < robot.lower) | (q > robot.upper))):
        raise LimitError(
            "pose task q_init",
            robot.joint_names[i],
            None,
            q[i],
            robot.lower[i],
            robot.upper[i],
            "give q_init inside the limits",
        )
    model = robot.model.copy()  # pink attaches its limit objects to the model it is given
    targets_p, targets_R = path.poses(times)
    config = pink.Configuration(model, model.createData(), q)
    task = FrameTask(frame, position_cost=1.0, orientation_cost=1.0)
    posture = PostureTask(cost=posture_cost)
    posture.set_target(q)
    tasks = [task, posture]
    position_limit = ConfigurationLimit(model)
    both_limits = [position_limit, VelocityLimit(model)]
    out = np.empty((times.size, robot.nq))
    fid = model.getFrameId(frame)
    for k in range(times.size):
        target = pin.SE3(targets_R[k], targets_p[k])
        task.set_target(target)
        steps, limits = (start_iterations, [position_limit]) if k == 0 else (1, both_limits)
        for _ in range(steps):
            v = pink.solve_ik(config, tasks, dt, solver=solver, limits=limits, damping=1e-12)
            config.integrate_inplace(v, dt)
            if k == 0:
                err = pin.log6(target.actInv(config.data.oMf[fid])).vector
                if np.linalg.norm(err) < 1e-10:
                    break
        placement = config.data.oMf[fid]
        e_pos = float(np.linalg.norm(placement.translation - targets_p[k]))
        e_rot = float(np.linalg.norm(pin.log3(targets_R[k].T @ placement.rotation)))
        if e_pos > position_tol or e_rot > orientation_tol:
            raise KinematicsError(
                f"frame {frame!r}: the pose at t={times[k]:.6g} s "
                f"({_describe(targets_p[k], targets_R[k])}) cannot be reached: residual "
                f"{e_pos:.3g} m, {e_rot:.3g} rad after inverse kinematics within the joint "
                "position and velocity limits; move the path into the workspace, slow it "
                "down or change q_init",
                value=(targets_p[k], targets_R[k]),
                expected=f"a residual <= {position_tol:g} m and {orientation_tol:g} rad",
            )
        out[k] = config.q
    return out


class PoseReference:
    """The joint reference of an end-effector task: the IK solution's
    :class:`~hmpc_pin.tasks.trajectory.JointTrajectory` (sampled by the controllers) and the
    task-space target it came from (for the task-space results and figures).

    Attributes:
        frame: The frame name. path: The target path (``poses(times)``).
        trajectory: The joint trajectory. n: Number of joints.
    """

    def __init__(self, robot: Robot, frame: str, path, trajectory: JointTrajectory):
        self.frame = frame
        self.path = path
        self.trajectory = trajectory
        self.n = trajectory.n
        self.robot = robot
        self.sample_many = trajectory.sample_many  # the hot path: no extra call
        self.acceleration = trajectory.acceleration

    @classmethod
    def solve(
        cls,
        robot: Robot,
        frame: str,
        path,
        t_end: float,
        q_init,
        *,
        dt: float = 0.01,
        t_start: float = 0.0,
        **ik_options,
    ) -> PoseReference:
        """Solve ``path`` over [t_start, t_end] every ``dt`` [s] (:func:`solve_path_ik`)."""
        k = max(2, int(np.ceil((t_end - t_start) / dt - 1e-9)) + 1)
        times = t_start + dt * np.arange(k)
        qs = solve_path_ik(robot, frame, path, times, q_init, **ik_options)
        trajectory = JointTrajectory(
            times,
            qs,
            joint_names=robot.joint_names,
            boundary="not-a-knot",
            source=f"pose task of frame {frame!r}",
        )
        return cls(robot, frame, path, trajectory)

    def sample(self, t: float) -> Pair:
        """Joint position [rad] and velocity [rad/s] at ``t`` [s]."""
        return self.trajectory.sample(t)

    def compiled_sampling(self) -> SamplingForm | None:
        """The joint trajectory's form for the compiled step (:mod:`hmpc_pin.tasks.base`);
        ``None`` for a subclass that samples otherwise (it overrides ``sample`` or
        ``sample_many``, :func:`~hmpc_pin.tasks.base.samples_otherwise`)."""
        if samples_otherwise(type(self), PoseReference) or self.sample_many != (
            self.trajectory.sample_many
        ):
            return None
        return self.trajectory.compiled_sampling()

    def native_form(self) -> tuple | None:
        """Deprecated since 0.3: :meth:`compiled_sampling` (typed) as the tuple of 0.3."""
        warnings.warn(
            "native_form() is deprecated since 0.3; call compiled_sampling()",
            DeprecationWarning,
            stacklevel=2,
        )
        form = self.compiled_sampling()
        return None if form is None else form.as_tuple()

    def target(self, times) -> tuple[FloatArray, FloatArray]:
        """Target positions (m, 3) [m] and quaternions (m, 4) ``(x, y, z, w)`` at ``times``
        (continuous in sign along the path: :func:`quat_series`)."""
        pos, rot = self.path.poses(times)
        return pos, quat_series(rot)

    def __repr__(self) -> str:
        return f"PoseReference(frame={self.frame!r}, path={type(self.path).__name__}, " + (
            f"{self.trajectory!r})"
        )
