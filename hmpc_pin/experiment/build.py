"""The one place where a config becomes objects: robot, controller × compensation,
reference, disturbance, plant (``ARCHITECTURE``: names in a config → objects here only).

The algorithms below (controllers, compensations, plants, references) take their own
small settings or plain arguments and never see the TOML schema; every check that needs
the robot (vector lengths, limits, the initial state) is made here, before a run.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace

import numpy as np

from ..controllers.base import Controller
from ..controllers.computed_torque import ComputedTorque
from ..controllers.hierarchical import HierarchicalMPC
from ..controllers.wrappers import CollisionReaction
from ..exceptions import (
    ConfigError,
    InterfaceError,
    LimitError,
    SimulationError,
    ValidityWarning,
)
from ..model.robot import Robot, load_robot
from ..realtime.loop import LoopSettings
from ..realtime.safety import SafeTorque, SafetySettings
from ..sim.disturbances import CoulombViscousFriction, Disturbance, GaussianPulse, ZeroDisturbance
from ..sim.mujoco import MuJoCoPlant, MuJoCoSettings, Obstacle
from ..sim.plants import PLANTS, Plant, RK4Plant
from ..sim.result import Result
from ..sim.simulate import simulate
from ..tasks.base import Reference, check_limits
from ..tasks.pose import (
    QUATERNION_ORDER,
    CirclePath,
    LinePath,
    PoseReference,
    PoseWaypoints,
    check_frame,
    frame_pose,
    matrix_to_quat,
    plane_axes,
    quat_to_matrix,
)
from ..tasks.quintic import QuinticReference
from ..tasks.sine import SineReference
from ..tasks.trajectory import JointTrajectory, load_trajectory
from ..tasks.waypoints import retime_waypoints
from .combos import HMPC_ONLY, TABLES, applies
from .controllers import _limits, controller_parts, make_compensation, mpc_settings
from .schema import (
    DEFAULT_COMPENSATION,
    OBSERVERS,
    ControllerConfig,
    ExperimentConfig,
    PlantConfig,
    RobotConfig,
    parse_combination,
)

__all__ = [
    "Experiment",
    "build_disturbance",
    "build_reference",
    "build_task_reference",
    "check_trajectory_limits",
    "load_robot_config",
    "make_arm_plant",
    "make_compensation",
    "make_controller",
    "mpc_settings",
    "mujoco_settings",
    "realtime_parts",
    "run_experiment",
    "task_space",
    "uses_observer",
    "warn_validity",
    "with_controller",
]


def load_robot_config(rc: RobotConfig, gravity: float | None = None) -> Robot:
    """The robot of ``[robot]`` (optionally with another gravity [m/s²])."""
    g = rc.gravity if gravity is None else gravity
    return load_robot(rc.source, gravity=g, locked_joints=rc.locked_joints)


def _effort_limit(config: ExperimentConfig, plant: Robot) -> np.ndarray | None:
    """The plant's effort limits [N·m]: ``plant.effort_limit``, else the plant URDF's (a
    value <= 0 means none); ``None`` when ``plant.saturate`` is false."""
    pc = config.plant
    if not pc.saturate:
        return None
    if pc.effort_limit is not None:
        return config.vector("plant.effort_limit", plant.nq)
    eff = plant.effort_limit
    return np.where(eff > 0, eff, np.inf)


def make_controller(
    robot: Robot, config: ControllerConfig | ExperimentConfig | None = None
) -> Controller:
    """The controller × compensation of ``config`` (README, "Controllers").

    ``config`` is a :class:`~hmpc_pin.experiment.schema.ControllerConfig`, a whole
    :class:`~hmpc_pin.experiment.schema.ExperimentConfig` (its ``controller`` table is
    used) or ``None`` (the defaults). ``hmpc`` gives a
    :class:`~hmpc_pin.controllers.hierarchical.HierarchicalMPC`, ``computed-torque*`` a
    :class:`~hmpc_pin.controllers.computed_torque.ComputedTorque`; each holds the
    compensation of :func:`make_compensation`.

    Raises:
        InterfaceError: ``config`` is neither (e.g. a dict or a file path).
    """
    if isinstance(config, ExperimentConfig):
        config = config.controller
    if config is not None and not isinstance(config, ControllerConfig):
        raise InterfaceError(
            config,
            "a ControllerConfig or an ExperimentConfig",
            "load a TOML file with load_config(path) and pass the result (or its .controller)",
        )
    cc = config if config is not None else ControllerConfig()
    if cc.kind == "hmpc":
        settings, compensation, limits = controller_parts(robot, cc)
        return HierarchicalMPC(robot, settings, compensation, limits=limits)
    gains, compensation = controller_parts(robot, cc)
    return ComputedTorque(robot, gains, compensation)


def warn_validity(robot: Robot, cc: ControllerConfig) -> None:
    """Warn (:class:`~hmpc_pin.exceptions.ValidityWarning`) when the compensation of ``cc``
    is used outside the arms it is proven for: Chen's :math:`Y` (Eq 28–30) on an arm that
    is not a planar serial chain (:meth:`~hmpc_pin.model.robot.Robot.is_planar_chain`)."""
    if cc.compensation == "chen" and not robot.is_planar_chain():
        warnings.warn(
            f"compensation 'chen' (Chen's observer, Eq 28-30) is proven for planar serial "
            f"arms only, and robot {robot.name!r} is not one; use compensation = 'general' "
            "(Y = I, valid on any arm for gain c above general_gain_bound) or 'momentum'",
            ValidityWarning,
            stacklevel=3,
        )


def mujoco_settings(pc: PlantConfig, n: int) -> MuJoCoSettings:
    """:class:`~hmpc_pin.sim.mujoco.MuJoCoSettings` of ``[plant.mujoco]`` for ``n`` joints."""
    mc = pc.mujoco
    if mc is None:
        raise ConfigError("plant.mujoco", "only with plant.engine = 'mujoco'")
    ob = mc.obstacle
    per_joint = {}
    for name in ("frictionloss", "damping", "armature"):
        value = getattr(mc, name)
        if value.ndim == 1 and value.shape != (n,):
            raise ConfigError(
                f"plant.mujoco.{name}", f"has {value.shape[0]} entries but the robot has {n} "
                f"joints; give {n} values or one value for all joints",
            )  # fmt: skip
        per_joint[name] = tuple(np.broadcast_to(value, (n,)).tolist())
    return MuJoCoSettings(
        integrator=mc.integrator,
        import_urdf_dynamics=mc.import_urdf_dynamics,
        geometry=mc.geometry,
        obstacle=None if ob is None else Obstacle(
            tuple(ob.position.tolist()), tuple(ob.size.tolist()), ob.friction,
            tuple(ob.solref.tolist()),
        ),
        **per_joint,
    )  # fmt: skip


def uses_observer(cc: ControllerConfig) -> bool:
    """Whether the compensation of ``cc`` is an observer (chen, general, momentum)."""
    return cc.compensation in OBSERVERS


def with_controller(
    config: ExperimentConfig,
    kind: str | None = None,
    observer: bool | None = None,
    *,
    compensation: str | None = None,
) -> ExperimentConfig:
    """``config`` with another controller and/or compensation; tables that no longer
    apply are dropped, the others kept.

    Args:
        config: The experiment.
        kind: ``"controller+compensation"``, a 0.1 name (``"hmpc-ism"``) or a bare
            controller (which keeps the config's compensation if it has the same
            controller, else takes the controller's default).
        observer: ``False``: no compensation (``compensation = "none"``, the "no NDO"
            baseline); ``True``: the config's observer, or Chen's NDO.
        compensation: A compensation name; overrides the one ``kind`` implies.
    """
    cc = config.controller
    controller, comp = (cc.kind, None) if kind is None else parse_combination(kind)
    if comp is None:
        comp = cc.compensation if controller == cc.kind else DEFAULT_COMPENSATION[controller]
    if compensation is not None:
        comp = compensation
    if observer is False:
        comp = "none"
    elif observer is True and comp not in OBSERVERS:
        comp = cc.compensation if cc.compensation in OBSERVERS else "chen"
    keep = {name: (getattr(cc, name) if applies(name, controller, comp) else None)
            for name in TABLES}  # fmt: skip
    if keep["ism"] is not None and comp == "ism":
        keep["ism"] = replace(keep["ism"], boundary_layer=None)
    if keep["computed_torque"] is not None and controller == "computed-torque":
        keep["computed_torque"] = replace(keep["computed_torque"], ki=None)
    hmpc_only = {name: (getattr(cc, name) if applies(name, controller, comp) else None)
                 for name in HMPC_ONLY}  # fmt: skip
    new = replace(cc, kind=controller, compensation=comp, **keep, **hmpc_only)
    return (
        config
        if (new.kind, new.compensation) == (cc.kind, cc.compensation)
        and all(getattr(new, k) is getattr(cc, k) for k in keep)
        else replace(config, controller=new)
    )


def build_reference(config: ExperimentConfig, robot: Robot) -> Reference:
    """The joint reference of ``config``: the sine of Eq 31 or the Section 5.4 motion.

    For ``kind = "cartesian"`` both tool poses are solved by inverse kinematics
    inside the joint limits (the goal on the branch closest to the start) and
    joined by a quintic. Raises :class:`~hmpc_pin.kinematics.KinematicsError`
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
    trajectory: JointTrajectory, robot: Robot, lower: np.ndarray, upper: np.ndarray,
    what: str = "reference", hint: str | None = None,
) -> None:  # fmt: skip
    """Check a joint trajectory against position and (URDF) velocity limits at its samples
    and 10 points per segment between them.

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
        raise LimitError(what, names[i], float(fine[k]), float(q[k, i]), lower[i], upper[i],
                         hint)  # fmt: skip
    vmax = np.where(robot.velocity_limit > 0, robot.velocity_limit, np.inf)
    bad = np.abs(dq) > vmax * (1 + 1e-9)
    if bad.any():
        k, i = np.argwhere(bad)[0]
        raise LimitError(f"{what} velocity", names[i], float(fine[k]), float(dq[k, i]),
                         -vmax[i], vmax[i], hint)  # fmt: skip


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
    """The reference of ``kind = "trajectory" | "waypoints" | "pose"`` (README, "Tasks"),
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
            trajectory, robot, lower, upper, f"reference ({rc.trajectory.file.name})",
            "change the file: slower (velocity limits: the URDF's) or inside the position "
            "limits (the URDF's or controller.constraints.lower/upper)",
        )  # fmt: skip
        return trajectory
    if rc.kind == "waypoints":
        wc = rc.waypoints
        n = robot.nq
        for p, point in enumerate(wc.points):
            for i in np.flatnonzero((point < lower) | (point > upper)):
                raise LimitError(f"waypoint {p}", names[i], None, point[i], lower[i], upper[i],
                                 "move the waypoint (reference.waypoints.points) inside the "
                                 "limits")  # fmt: skip
        vmax = (
            config.vector("reference.waypoints.velocity_limit", n)
            if wc.velocity_limit is not None
            else robot.velocity_limit
        )
        trajectory = retime_waypoints(
            wc.points, vmax, config.vector("reference.waypoints.acceleration_limit", n),
            t_start=wc.t_start, dt=config.controller.Ts, joint_names=names,
        )  # fmt: skip
        check_trajectory_limits(
            trajectory, robot, lower, upper, "waypoint path",
            "the spline through the waypoints overshoots: add a waypoint or move them away "
            "from the limit",
        )  # fmt: skip
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
        raise LimitError("reference.pose.q_init", names[i], None, q_init[i], lower[i], upper[i],
                         "give reference.pose.q_init inside the limits")  # fmt: skip
    cc = config.controller
    t_end = config.simulation.duration + (cc.N + 2) * cc.Ts
    reference = PoseReference.solve(
        robot, frame, _pose_path(pc, robot, q_init), t_end, q_init, dt=pc.dt,
        posture_cost=pc.posture_cost,
    )  # fmt: skip
    check_trajectory_limits(
        reference.trajectory, robot, lower, upper, f"pose task ({frame})",
        "the spline through the IK samples leaves a limit: lower reference.pose.dt or move "
        "the path away from the limits",
    )  # fmt: skip
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
    result.ee_quat = np.array([matrix_to_quat(R) for R in rot])
    result.ee_quat_ref = quat_ref
    result.meta["task"] = {"frame": reference.frame, "quaternion": QUATERNION_ORDER}
    return result


def build_disturbance(config: ExperimentConfig, robot: Robot, q0: np.ndarray) -> Disturbance:
    """The plant disturbance of ``config`` (Eq 32–34); with ``scale = "inertia"`` each
    joint's coefficients are multiplied by :math:`M_{ii}(q_0)` of the controller's model."""
    n = robot.nq
    dc = config.disturbance
    k = np.diag(robot.mass_matrix(q0)).copy() if dc.scale == "inertia" else np.ones(n)
    disturbance: Disturbance = ZeroDisturbance(n)
    if dc.friction is not None:
        sign = -1.0 if dc.friction.sign == "literal" else 1.0  # literal: d = +(a q̇ + b sgn q̇)
        disturbance = disturbance + CoulombViscousFriction(
            sign * k * np.broadcast_to(dc.friction.viscous, (n,)),
            sign * k * np.broadcast_to(dc.friction.coulomb, (n,)),
        )
    if dc.pulse is not None:
        disturbance = disturbance + GaussianPulse(
            k * np.broadcast_to(dc.pulse.amplitude, (n,)),
            np.broadcast_to(dc.pulse.center, (n,)),
            np.broadcast_to(dc.pulse.sigma, (n,)),
        )
    return disturbance


@dataclass
class Experiment:
    """The objects of one experiment, built from its config.

    Attributes:
        config: The validated config.
        robot: The controller's model.
        plant: The plant's model (a separate ``pin.Model``; another URDF if configured).
        controller: The controller × compensation of ``config.controller``
            (:func:`make_controller`).
        reference: The joint reference.
        disturbance: The plant disturbance ``d(t, q, dq)``.
        q0, dq0: Initial state.
    """

    config: ExperimentConfig
    robot: Robot
    plant: Robot
    controller: Controller
    reference: Reference
    disturbance: Disturbance
    q0: np.ndarray
    dq0: np.ndarray

    @classmethod
    def from_config(
        cls,
        config: ExperimentConfig,
        *,
        observer: bool | None = None,
        controller: str | None = None,
    ) -> Experiment:
        """Build the experiment.

        Args:
            config: The validated config.
            observer: ``False`` runs without compensation, ``True`` with an observer
                (:func:`with_controller`).
            controller: Another controller × compensation (:func:`with_controller`);
                applied before ``observer``.

        Raises:
            LimitError: The initial state or the reference (sampled at every control
                instant of the run and its last horizon) leaves the joint limits.
        """
        try:
            return cls._build(config, observer=observer, controller=controller)
        except ConfigError as exc:  # name the file the bad value came from
            if exc.source is None and config.source is not None:
                raise ConfigError(exc.key, exc.message, source=str(config.source)) from None
            raise

    @classmethod
    def _build(
        cls, config: ExperimentConfig, *, observer: bool | None, controller: str | None
    ) -> Experiment:
        config = with_controller(config, controller, observer)
        rc = config.robot
        robot = load_robot_config(rc)
        n = robot.nq
        config.check_dimensions(n)
        if config.plant.effort_limit is not None:
            config.vector("plant.effort_limit", n)
        pc = config.plant
        plant_gravity = pc.gravity if pc.gravity is not None else rc.gravity
        plant = (
            load_robot(pc.urdf, gravity=plant_gravity, locked_joints=rc.locked_joints)
            if pc.urdf is not None
            else load_robot_config(rc, gravity=plant_gravity)
        )
        if plant.nq != n:
            raise ConfigError(
                "plant.urdf",
                f"the plant has {plant.nq} joints but the robot has {n}; use the same arm",
            )
        if pc.engine == "mujoco":  # compiles the URDF (and checks timestep | Ts) before a run
            MuJoCoPlant(plant, None, config.controller.Ts, pc.mujoco.timestep,
                        mujoco_settings(pc, n))  # fmt: skip
        else:
            pinocchio_plant(pc, plant, None, config.controller.Ts)  # checks dt | Ts
        reference = build_reference(config, robot)
        q0 = (
            reference.sample(0.0)[0]
            if config.simulation.q0 is None
            else config.vector("simulation.q0", n)
        )
        robot.check_mass_matrix(q0)
        warn_validity(robot, config.controller)
        controller = make_controller(robot, config.controller)
        # The compensation is fed the torque the plant applies (clipped), not the commanded one.
        controller.effort_limit = _effort_limit(config, plant)
        if config.collision is not None and uses_observer(config.controller):
            controller = CollisionReaction(
                controller, config.vector("collision.threshold", n), config.collision.reaction
            )
        limits = _limits(config.controller, robot) if config.controller.kind == "hmpc" else None
        if limits is not None:
            lower, upper = limits.lower, limits.upper
            for i in np.flatnonzero((q0 < lower - 1e-9) | (q0 > upper + 1e-9)):
                raise LimitError(
                    "initial position (simulation.q0)", robot.joint_names[i], None, q0[i],
                    lower[i], upper[i],
                )  # fmt: skip
            cc = config.controller
            times = cc.Ts * np.arange(round(config.simulation.duration / cc.Ts) + cc.N + 1)
            check_limits(reference, lower, upper, times, robot.joint_names)
        return cls(
            config=config,
            robot=robot,
            plant=plant,
            controller=controller,
            reference=reference,
            disturbance=build_disturbance(config, robot, q0),
            q0=q0,
            dq0=config.vector("simulation.dq0", n),
        )

    @property
    def effort_limit(self) -> np.ndarray | None:
        """The plant's effort limits [N·m] (config override, else the plant URDF's; a
        URDF value <= 0 means none), or ``None`` when ``plant.saturate`` is false."""
        return _effort_limit(self.config, self.plant)

    def run(self, duration: float | None = None, on_step=None) -> Result:
        """Simulate the closed loop for ``duration`` [s] (default: the config's).

        ``on_step(t, q, q_ref)`` is called at every control instant (live view). The
        result's ``meta`` records the plant's engine and version (and, with a collision
        watch, the flag); on MuJoCo with an obstacle ``extra["contact_force"]`` holds the
        generalized contact force [N·m] at each instant (of the last MuJoCo step before
        it) and ``meta["first_contact"]`` the first instant it is not zero.
        """
        plant = self.make_plant()
        try:
            result = self._simulate(plant, duration, on_step)
        except SimulationError as exc:
            if exc.result is not None:
                self._record_plant(plant, exc.result)
                task_space(self.reference, self.robot, exc.result)
            raise
        return task_space(self.reference, self.robot, self._record_plant(plant, result))

    def _record_plant(self, plant: Plant, result: Result) -> Result:
        """Add the engine, the MuJoCo contact force and the collision flag to ``result``."""
        pc = self.config.plant
        result.meta["engine"] = pc.engine
        if isinstance(plant, MuJoCoPlant):
            result.meta["engine_version"] = plant.version
            ob = plant.settings.obstacle
            if ob is not None:  # (without an obstacle MuJoCo's contacts are off)
                result.meta["obstacle"] = {"position": list(ob.position), "size": list(ob.size)}
                contact = np.array(plant.history[: len(result.t)])
                result.extra["contact_force"] = contact
                touching = np.flatnonzero(np.abs(contact).max(axis=1) > 0)
                result.meta["first_contact"] = (
                    float(result.t[touching[0]]) if touching.size else None
                )
        else:
            import pinocchio

            result.meta["engine_version"] = pinocchio.__version__
        if isinstance(self.controller, CollisionReaction):
            c = self.controller
            result.meta["collision"] = {
                "detected_at": c.detected_at,
                "joint": None if c.joint is None else self.robot.joint_names[c.joint],
                "reaction": c.reaction,
                "threshold": c.threshold.tolist(),
            }
        return result

    def _simulate(self, plant: Plant, duration: float | None, on_step) -> Result:
        cfg = self.config
        return simulate(
            self.robot,
            self.controller,
            self.reference,
            duration=cfg.simulation.duration if duration is None else duration,
            q0=self.q0,
            dq0=self.dq0,
            plant=plant,
            effort_limit=self.effort_limit,
            state_bound=cfg.simulation.state_bound,
            on_step=on_step,
            meta=self.meta(),
        )

    def meta(self) -> dict:
        """The metadata stored with a run of this experiment (replay needs the URDF)."""
        cfg = self.config
        return {
            "experiment": cfg.name,
            "config": str(cfg.source) if cfg.source else None,
            "urdf": str(self.robot.source),
            "locked_joints": self.robot.locked_joints,
            "joint_kinds": list(self.robot.joint_kinds),
            "limits": self._recorded_limits(),
            "gravity": cfg.robot.gravity,
            "controller": cfg.controller.label,
            "observer": uses_observer(cfg.controller),
            "Ts": cfg.controller.Ts,
            "N": cfg.controller.N,
            "Nc": cfg.controller.Nc,
            "state_bound": cfg.simulation.state_bound,
        }

    def _recorded_limits(self) -> dict[str, list[float]]:
        """The URDF position limits the metrics measure excursions against; a zero or
        inverted range (double_pendulum's 0/0: no range given) is recorded as ±inf."""
        lo, hi = self.robot.lower, self.robot.upper
        ok = lo < hi
        return {
            "lower": np.where(ok, lo, -np.inf).tolist(),
            "upper": np.where(ok, hi, np.inf).tolist(),
        }

    @property
    def obstacle(self) -> dict | None:
        """The MuJoCo scene's box as ``{"position", "size"}`` [m] (for a view), or ``None``."""
        mc = self.config.plant.mujoco
        if mc is None or mc.obstacle is None:
            return None
        return {"position": mc.obstacle.position.tolist(), "size": mc.obstacle.size.tolist()}

    def make_plant(self, Ts: float | None = None) -> Plant:
        """A new plant of ``[plant]`` (its integrator, step and this experiment's
        disturbance) on the plant model, advanced by ``Ts`` [s] per call (default: the
        controller's period; a real-time arm's is the interface period)."""
        pc = self.config.plant
        Ts = self.controller.Ts if Ts is None else Ts
        if pc.engine == "mujoco":
            return MuJoCoPlant(
                self.plant, self.disturbance, Ts, pc.mujoco.timestep,
                mujoco_settings(pc, self.robot.nq),
            )  # fmt: skip
        return pinocchio_plant(pc, self.plant, self.disturbance, Ts)


def pinocchio_plant(pc: PlantConfig, robot: Robot, disturbance, Ts: float) -> Plant:
    """The Pinocchio plant of ``[plant]`` (its integrator, step and backend) on ``robot``."""
    if pc.integrator == "rk4":
        return RK4Plant(robot, disturbance, Ts, pc.dt, backend=pc.backend)
    return PLANTS[pc.integrator](robot, disturbance, Ts, pc.dt)


def make_arm_plant(config: ExperimentConfig) -> Plant:
    """The plant of ``config`` advanced one interface period ``1/realtime.rate`` per call:
    the arm of ``hmpc-pin realtime``, built in the arm's own process (so a module-level
    function of the config alone, picklable)."""
    return Experiment.from_config(config).make_plant(1.0 / config.realtime.rate)


def realtime_parts(experiment: Experiment) -> tuple[LoopSettings, SafetySettings, SafeTorque]:
    """The loop settings, safety settings and safe torque of ``[realtime]``.

    Raises:
        ConfigError: The rate does not divide the controller period, or ``plant.dt``
            does not divide the interface period.
    """
    cfg = experiment.config
    rc, robot = cfg.realtime, experiment.robot
    n = robot.nq
    loop = LoopSettings(rate=rc.rate, duration=cfg.simulation.duration, gc_handling=rc.gc,
                        gc_slack=rc.gc_slack, spin=rc.spin)  # fmt: skip
    loop.decimation(cfg.controller.Ts)
    experiment.make_plant(loop.period)  # checks that the plant's step divides the period
    if rc.limits:
        vel = np.where(robot.velocity_limit > 0, robot.velocity_limit * rc.scale, np.inf)
        lim = experiment._recorded_limits()  # a URDF without a range: no position bound
        lower, upper = np.asarray(lim["lower"]), np.asarray(lim["upper"])
        safety = SafetySettings(lower - rc.margin, upper + rc.margin, vel,
                                max_misses=rc.max_misses, watchdog=rc.watchdog,
                                hold=rc.hold)  # fmt: skip
    else:
        safety = SafetySettings.unlimited(n, max_misses=rc.max_misses, watchdog=rc.watchdog,
                                          hold=rc.hold)  # fmt: skip
    safe = SafeTorque(robot, cfg.vector("realtime.damping", n), gravity=rc.gravity)
    return loop, safety, safe


def run_experiment(
    config: ExperimentConfig, *, observer: bool | None = None, duration: float | None = None
) -> Result:
    """Build and run ``config``; ``observer=False`` runs the baseline without NDO."""
    return Experiment.from_config(config, observer=observer).run(duration)
