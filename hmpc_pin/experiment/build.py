"""Where a config becomes objects: robot, controller × compensation, reference, disturbance,
plant (names in a config → objects in this layer only), split by what is built:
:mod:`~hmpc_pin.experiment.controllers` (the controller's settings, compensation and limits),
:mod:`~hmpc_pin.experiment.references` (the reference),
:mod:`~hmpc_pin.experiment.plants` (the plant and its disturbance), and here the
:class:`Experiment` that holds them and runs them.

The algorithms below (controllers, compensations, plants, references) take their own
small settings or plain arguments and never see the TOML schema; every check that needs
the robot (vector lengths, limits, the initial state) is made here, before a run.
"""

from __future__ import annotations

import contextlib
import math
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..checks import run_memory
from ..compensation.base import warn_chen_validity
from ..compensation.observers import DEFAULT_DESIGN
from ..compensation.registry import compensation_spec
from ..controllers.base import Controller
from ..controllers.hierarchical import warn_fast_damping
from ..controllers.registry import controller_spec
from ..controllers.wrappers import CollisionReaction, FrictionFeedforward
from ..exceptions import (
    ConfigError,
    InterfaceError,
    LimitError,
    SimulationError,
    ValidityWarning,
)
from ..identification.observer_model import ObserverModel
from ..model.robot import Robot, load_robot
from ..realtime.loop import LoopSettings
from ..realtime.safety import SafeTorque, SafetySettings, brake_time_constant
from ..sim.disturbances import Disturbance
from ..sim.engines import engine_spec
from ..sim.mujoco import MuJoCoPlant
from ..sim.plants import Plant
from ..sim.result import Result
from ..sim.simulate import simulate
from ..tasks.base import Reference, check_limits
from .combos import HMPC_ONLY, OBSERVERS, TABLES, applies
from .config import (
    ControllerConfig,
    ExperimentConfig,
    RobotConfig,
    parse_combination,
)
from .controllers import controller_limits, controller_parts, make_compensation, mpc_settings
from .plants import (
    PILOT_DURATION,
    build_disturbance,
    check_plant_damping,
    mujoco_settings,
    pinocchio_plant,
    plant_effort_limit,
    plant_step,
)
from .references import build_reference, build_task_reference, check_trajectory_limits, task_space

__all__ = [
    "Experiment",
    "build_disturbance",
    "build_reference",
    "build_task_reference",
    "check_friction_sources",
    "check_trajectory_limits",
    "load_robot_config",
    "make_arm_plant",
    "make_compensation",
    "make_controller",
    "mpc_settings",
    "mujoco_settings",
    "realtime_parts",
    "reuse_robots",
    "run_experiment",
    "task_space",
    "uses_observer",
    "warn_bandwidth",
    "warn_validity",
    "with_controller",
]


#: Robots loaded while :func:`reuse_robots` is on, by source (with the file's size and
#: modification time), gravity and locked joints.
_ROBOTS: dict[tuple, Robot] = {}
_REUSE = [False]


@contextlib.contextmanager
def reuse_robots() -> Iterator[None]:
    """Within this context :func:`load_robot_config` returns a copy of a robot it loaded
    before from the same unchanged file, gravity and locked joints, instead of parsing the
    URDF again (many runs of one config in one process: the sweep's workers). The file's
    checks and warnings come with its first load only."""
    before, _REUSE[0] = _REUSE[0], True
    try:
        yield
    finally:
        _REUSE[0] = before


def load_robot_config(rc: RobotConfig, gravity: float | None = None) -> Robot:
    """The robot of ``[robot]`` (optionally with another gravity [m/s²])."""
    g = rc.gravity if gravity is None else gravity
    if not _REUSE[0]:
        return _with_armature(load_robot(rc.source, gravity=g, locked_joints=rc.locked_joints), rc)
    path = Path(rc.source)
    stamp = (path.stat().st_size, path.stat().st_mtime_ns) if path.is_file() else None
    locked = tuple(sorted((rc.locked_joints or {}).items()))
    key = (str(rc.source), stamp, float(g), locked)
    robot = _ROBOTS.get(key)
    if robot is None:
        if len(_ROBOTS) >= 16:
            _ROBOTS.clear()
        robot = _ROBOTS[key] = load_robot(rc.source, gravity=g, locked_joints=rc.locked_joints)
    return _with_armature(robot.copy(), rc)


def _with_armature(robot: Robot, rc: RobotConfig) -> Robot:
    """``robot`` with ``[robot] armature`` [kg·m²] on its joints' diagonal (Pinocchio's
    ``model.armature``, which ``crba`` adds to M(q)).

    Raises:
        ConfigError: Neither one value nor one per joint.
    """
    if rc.armature is None:
        return robot
    arm = np.asarray(rc.armature, dtype=float)
    n = robot.nq
    if arm.ndim == 1 and arm.size != n:
        raise ConfigError(
            "robot.armature", f"expected one value or {n} (one per joint), got {arm.size}"
        )
    robot.model.armature[:] = np.broadcast_to(arm, (robot.model.nv,))
    return robot


def make_controller(
    robot: Robot,
    config: ControllerConfig | ExperimentConfig | None = None,
    *,
    posture: np.ndarray | None = None,
) -> Controller:
    """The controller × compensation of ``config`` (docs, "Controllers").

    ``posture`` [rad] is where an observer bandwidth is made exact (the run's start; default
    :func:`~hmpc_pin.experiment.controllers.bandwidth_posture`).

    ``config`` is a :class:`~hmpc_pin.experiment.config.controller.ControllerConfig`, a whole
    :class:`~hmpc_pin.experiment.config.experiment.ExperimentConfig` (its ``controller`` table is
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
    return controller_spec(cc.kind).cls(robot, *controller_parts(robot, cc, posture))


def warn_validity(robot: Robot, cc: ControllerConfig, posture: np.ndarray | None = None) -> None:
    """Warn (:class:`~hmpc_pin.exceptions.ValidityWarning`) when the compensation of ``cc``
    is used outside the arms it is proven for: Chen's :math:`Y` (Eq 28–30) on an arm that
    is not a planar serial chain (:meth:`~hmpc_pin.model.robot.Robot.is_planar_chain`).

    The controllers warn the same when built
    (:func:`~hmpc_pin.compensation.base.check_compensation`); this is kept for callers
    that check a config without building its controller."""
    warn_chen_validity(robot, cc.compensation, stacklevel=3)
    warn_bandwidth(robot, cc, posture)


def check_friction_sources(robot: Robot, cc: ControllerConfig) -> None:
    """Refuse a friction compensated twice: ``[controller.friction]`` (an identified
    model, fed forward) on an arm whose URDF declares ``<dynamics damping friction>`` that
    the hierarchical MPC already compensates (``[controller] joint_dynamics``).

    Raises:
        ConfigError: Both apply; names the joints whose URDF declares joint dynamics.
    """
    if cc.friction is None or not controller_spec(cc.kind).mpc or not cc.joint_dynamics:
        return
    declared = np.flatnonzero((robot.joint_damping != 0) | (robot.joint_friction != 0))
    if declared.size:
        names = ", ".join(robot.joint_names[i] for i in declared)
        raise ConfigError(
            "controller.friction",
            f"the URDF already declares <dynamics> on joints {names}, which [controller] "
            "joint_dynamics = true compensates; give one friction model: set [controller] "
            "joint_dynamics = false to use [controller.friction] instead, or remove "
            "[controller.friction]",
        )


def warn_bandwidth(robot: Robot, cc: ControllerConfig, posture: np.ndarray | None = None) -> None:
    """Warn (:class:`~hmpc_pin.exceptions.ValidityWarning`) when an observer given as a
    bandwidth breaks the rule of :mod:`hmpc_pin.compensation.bandwidth` for ``cc.Ts`` and
    ``cc.latency`` at ``posture`` [rad] (naming the joints)."""
    obs = cc.observer
    if obs is not None and obs.bandwidth is not None:
        from ..compensation.bandwidth import check_bandwidth
        from .controllers import observer_bandwidth

        check_bandwidth(
            observer_bandwidth(robot, cc, posture),
            cc.Ts,
            cc.latency or 0.0,
            robot.joint_names,
            explicit=obs.discretization == "explicit",
        )


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
        comp = (
            cc.compensation
            if controller == cc.kind
            else controller_spec(controller).default_compensation
        )
    if compensation is not None:
        comp = compensation
    if observer is False:
        comp = "none"
    elif observer is True and comp not in OBSERVERS:
        comp = cc.compensation if cc.compensation in OBSERVERS else DEFAULT_DESIGN
    keep = {
        name: (getattr(cc, name) if applies(name, controller, comp) else None) for name in TABLES
    }
    if keep["ism"] is not None and not compensation_spec(comp).boundary_layer:
        keep["ism"] = replace(keep["ism"], boundary_layer=None)
    if keep["computed_torque"] is not None and not controller_spec(controller).pid:
        keep["computed_torque"] = replace(keep["computed_torque"], ki=None)
    hmpc_only = {
        name: (getattr(cc, name) if applies(name, controller, comp) else None) for name in HMPC_ONLY
    }
    new = replace(cc, kind=controller, compensation=comp, **keep, **hmpc_only)
    return (
        config
        if (new.kind, new.compensation) == (cc.kind, cc.compensation)
        and all(getattr(new, k) is getattr(cc, k) for k in keep)
        else replace(config, controller=new)
    )


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
        run_memory("simulation.duration", config.simulation.duration, config.controller.Ts, n)
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
        if not engine_spec(pc.engine).integrated:  # MuJoCo compiles the URDF (checks timestep | Ts)
            MuJoCoPlant(
                plant, None, config.controller.Ts, pc.mujoco.timestep, mujoco_settings(pc, n)
            )
        elif pc.tolerance is None:
            pinocchio_plant(pc, plant, None, config.controller.Ts)  # checks dt | Ts
        reference = build_reference(config, robot)
        q0 = (
            reference.sample(0.0)[0]
            if config.simulation.q0 is None
            else config.vector("simulation.q0", n)
        )
        robot.check_mass_matrix(q0)
        check_plant_damping(pc, plant, q0)  # the plant's step against the URDF damping
        cc = config.controller
        mpc = controller_spec(cc.kind).mpc
        if mpc and not cc.joint_dynamics and config.plant.joint_dynamics:
            warn_fast_damping(plant, cc.Ts)  # the simulated arm has them, uncompensated
        check_friction_sources(robot, cc)
        controller = make_controller(robot, cc, posture=q0)  # warns as warn_validity
        warn_bandwidth(robot, cc, q0)
        # The compensation is fed the torque the plant applies (clipped), not the commanded one.
        controller.effort_limit = plant_effort_limit(config, plant)
        fm = config.controller.friction
        if fm is not None:  # the friction model, fed forward around the controller
            controller = FrictionFeedforward(
                controller,
                config.vector("controller.friction.viscous", n),
                config.vector("controller.friction.coulomb", n),
                fm.smoothing,
            )
        if config.collision is not None and uses_observer(config.controller):
            controller = CollisionReaction(
                controller, config.vector("collision.threshold", n), config.collision.reaction
            )
        limits = controller_limits(config.controller, robot)
        if limits is not None:
            lower, upper = limits.lower, limits.upper
            for i in np.flatnonzero((q0 < lower - 1e-9) | (q0 > upper + 1e-9)):
                raise LimitError(
                    "initial position (simulation.q0)",
                    robot.joint_names[i],
                    None,
                    q0[i],
                    lower[i],
                    upper[i],
                )
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
        return plant_effort_limit(self.config, self.plant)

    def run(
        self, duration: float | None = None, on_step=None, loop: str | None = None, progress=None
    ) -> Result:
        """Simulate the closed loop for ``duration`` [s] (default: the config's).

        ``loop`` is deprecated and has no effect (:func:`~hmpc_pin.sim.simulate.simulate`:
        every run goes through the compiled loop).

        ``on_step(t, q, q_ref)`` is called at every control instant (live view),
        ``progress(k, K)`` after each chunk of control periods (a progress bar). The
        result's ``meta`` records the plant's engine and version (and, with a collision
        watch, the flag); on MuJoCo with an obstacle ``extra["contact_force"]`` holds the
        generalized contact force [N·m] at each instant (of the last MuJoCo step before
        it) and ``meta["first_contact"]`` the first instant it is not zero.
        """
        plant = self.make_plant()
        try:
            result = self._simulate(plant, duration, on_step, loop, progress)
        except SimulationError as exc:
            if exc.result is not None:
                self._record_plant(plant, exc.result)
                task_space(self.reference, self.robot, exc.result)
            raise
        return task_space(self.reference, self.robot, self._record_plant(plant, result))

    def _record_plant(self, plant: Plant, result: Result) -> Result:
        """Add the engine (a Pinocchio plant's step [s] and Coulomb law: ``plant_step``,
        chosen by ``plant.tolerance`` where given, and ``coulomb``), the MuJoCo contact force
        and the collision flag to ``result``."""
        pc = self.config.plant
        result.meta["engine"] = pc.engine
        if not isinstance(plant, MuJoCoPlant):
            result.meta["plant_step"] = float(plant.h)
            result.meta["coulomb"] = getattr(plant, "coulomb", "sign")
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
        fm = self.config.controller.friction
        if fm is not None:
            n = self.robot.nq
            a = self.config.vector("controller.friction.viscous", n)
            b = self.config.vector("controller.friction.coulomb", n)
            # the model's torque at the recorded velocity (the observer's target is d + it)
            sign = np.tanh(result.dq / fm.smoothing) if fm.smoothing > 0 else np.sign(result.dq)
            result.extra["friction_feedforward"] = a * result.dq + b * sign
        if isinstance(self.controller, CollisionReaction):
            c = self.controller
            result.meta["collision"] = {
                "detected_at": c.detected_at,
                "joint": None if c.joint is None else self.robot.joint_names[c.joint],
                "reaction": c.reaction,
                "threshold": c.threshold.tolist(),
            }
        return result

    def _simulate(
        self, plant: Plant, duration: float | None, on_step, loop: str | None = None, progress=None
    ) -> Result:
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
            loop=loop,
            progress=progress,
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
            **self._identification_meta(),
        }

    def _identification_meta(self) -> dict:
        """What ``hmpc-pin identify`` needs of the controller: the observer (its
        regressors are passed through its dynamics) and the friction fed forward (added
        back to its estimate)."""
        cc, n = self.config.controller, self.robot.nq
        out: dict = {}
        model = ObserverModel.of(
            getattr(self.controller, "compensation", None),
            model_at=mpc_settings(cc, n).model_at,
        )
        if model is not None:  # the observer that runs: its matrix (cY or K_O), Ts, Euler
            out["observer_model"] = model.record()
        if cc.friction is not None:
            out["friction_feedforward"] = {
                "viscous": self.config.vector("controller.friction.viscous", n).tolist(),
                "coulomb": self.config.vector("controller.friction.coulomb", n).tolist(),
                "smoothing": cc.friction.smoothing,
            }
        return out

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
        controller's period; a real-time arm's is the interface period). With
        ``plant.tolerance`` its step is chosen by the first plant of each period
        (:func:`~hmpc_pin.experiment.plants.plant_step`), then kept for the experiment."""
        pc = self.config.plant
        Ts = self.controller.Ts if Ts is None else Ts
        if not engine_spec(pc.engine).integrated:
            return MuJoCoPlant(
                self.plant,
                self.disturbance,
                Ts,
                pc.mujoco.timestep,
                mujoco_settings(pc, self.robot.nq),
            )
        steps = self.__dict__.setdefault("_plant_steps", {})
        if Ts not in steps:
            steps[Ts] = self._plant_step(Ts)
        return pinocchio_plant(pc, self.plant, self.disturbance, Ts, steps[Ts])

    def _plant_step(self, Ts: float) -> float:
        """The step of the plant advanced by ``Ts`` (:func:`plant_step`): with a tolerance,
        checked along the reference and, at the controller's period, on the closed loop's
        first :data:`PILOT_DURATION` (its start, off the reference if ``q0`` is)."""
        pc = self.config.plant
        duration = self.config.simulation.duration
        pilot = None
        if pc.tolerance is not None and math.isclose(Ts, self.controller.Ts):
            window = min(duration, PILOT_DURATION)

            def pilot(plant: Plant) -> np.ndarray | None:
                try:
                    return self._simulate(plant, window, None).q
                except SimulationError:
                    return None

        return plant_step(pc, self.plant, self.disturbance, Ts, self.reference, duration, pilot)


def make_arm_plant(config: ExperimentConfig) -> Plant:
    """The plant of ``config`` advanced one interface period ``1/realtime.rate`` per call:
    the arm of ``hmpc-pin realtime``, built in the arm's own process (so a module-level
    function of the config alone, picklable)."""
    return Experiment.from_config(config).make_plant(1.0 / config.realtime.rate)


def realtime_parts(
    experiment: Experiment, rate: float | None = None, *, plant: bool = True
) -> tuple[LoopSettings, SafetySettings, SafeTorque]:
    """The loop settings, safety settings and safe torque of ``[realtime]``.

    Args:
        experiment: The experiment.
        rate: The interface rate [Hz] (default ``realtime.rate``; the ROS commands pass
            ``ros.rate``).
        plant: Check that ``plant.dt`` divides the interface period (``False`` where
            the arm is not this experiment's plant: a ROS driver).

    Raises:
        ConfigError: The rate does not divide the controller period, ``plant.dt`` does
            not divide the interface period, or ``brake_time`` is below
            :func:`minimum_brake_time` at that period.
    """
    cfg = experiment.config
    rc, robot = cfg.realtime, experiment.robot
    n = robot.nq
    loop = LoopSettings(
        rate=rc.rate if rate is None else rate,
        duration=cfg.simulation.duration,
        gc_handling=rc.gc,
        gc_slack=rc.gc_slack,
        spin=rc.spin,
        warm_up=rc.warm_up,
    )
    loop.decimation(cfg.controller.Ts)
    if plant:
        experiment.make_plant(loop.period)  # checks that the plant's step divides the period
    if rc.limits:
        vel = np.where(robot.velocity_limit > 0, robot.velocity_limit * rc.scale, np.inf)
        lim = experiment._recorded_limits()  # a URDF without a range: no position bound
        lower, upper = np.asarray(lim["lower"]), np.asarray(lim["upper"])
        safety = SafetySettings(
            lower - rc.margin,
            upper + rc.margin,
            vel,
            max_misses=rc.max_misses,
            watchdog=rc.watchdog,
            hold=rc.hold,
            brake_speed=rc.brake_speed,
        )
    else:
        safety = SafetySettings.unlimited(
            n,
            max_misses=rc.max_misses,
            watchdog=rc.watchdog,
            hold=rc.hold,
            brake_speed=rc.brake_speed,
        )
    damping, brake = brake_settings(cfg, loop.period)
    if damping is not None:
        damping = cfg.vector("realtime.damping", n)
        _warn_weak_damping(
            robot.mass_matrix(experiment.q0), damping, rc.hold, minimum_brake_time(cfg, loop.period)
        )
    safe = SafeTorque(
        robot,
        damping if damping is not None else 0.0,
        rc.gravity is not False,
        effort_limit=experiment.effort_limit,
        brake_time=brake,
    )
    return loop, safety, safe


def minimum_brake_time(config: ExperimentConfig, period: float) -> float:
    """The shortest inertia brake time [s] that slows the arm without overshoot at the
    interface ``period`` [s] P.

    A command acts ``d`` periods after the state it was computed from (one for the arm to
    take it, plus the declared ``[controller] latency`` L rounded up to periods), so the
    brake's speed follows :math:`v_{k+1} = v_k - (P/T_b)\\,v_{k-d}`; it decays without
    oscillating when :math:`P/T_b \\le d^d/(d+1)^{d+1}`, which :math:`T_b \\ge e\\,(d+1)P`
    guarantees: :math:`d = 1 + \\lceil L/P \\rceil`.
    """
    latency = config.controller.latency or 0.0
    d = 1 + math.ceil(latency / period - 1e-9)
    return math.e * (d + 1) * period


def brake_settings(
    config: ExperimentConfig, period: float
) -> tuple[np.ndarray | None, float | None]:
    """``(damping, brake_time)`` of the safe torque at the interface ``period`` [s]: the
    diagonal ``[realtime] damping`` [N·m·s/rad] if given, else the inertia brake's time [s]
    (``[realtime] brake_time``, default ``hold``/6, at least :func:`minimum_brake_time`).

    Raises:
        ConfigError: ``brake_time`` below :func:`minimum_brake_time` at this period.
    """
    rc = config.realtime
    if rc.damping is not None:
        return np.asarray(rc.damping, dtype=float), None
    shortest = minimum_brake_time(config, period)
    if rc.brake_time is None:
        return None, max(rc.hold / 6.0, shortest)
    if rc.brake_time < shortest:
        raise ConfigError(
            "realtime.brake_time",
            f"is {rc.brake_time:g} s, below {shortest:.3g} s = e·(d+1)·P for the interface "
            f"period P = {period:g} s and a command acting d = "
            f"{round(shortest / (math.e * period)) - 1} periods after its state (one, plus "
            "[controller] latency): a shorter brake overshoots and oscillates. Give at least "
            f"{shortest:.3g} s, or a higher interface rate (its period sets the minimum)",
        )
    return None, float(rc.brake_time)


def _warn_weak_damping(M: np.ndarray, damping: np.ndarray, hold: float, shortest: float) -> None:
    """Warn when the diagonal damping cannot slow the arm within ``hold`` [s]."""
    if hold <= 0:
        return  # no brake after the first safe torque: nothing to slow
    d = np.broadcast_to(damping, (M.shape[0],))
    slowest = brake_time_constant(M, d)
    if slowest <= hold / 3.0:
        return
    advice = (
        f"Set realtime.brake_time = {max(hold / 6, shortest):.3g} (brakes with "
        "M(q)/brake_time: every joint alike)"
    )
    if np.isfinite(slowest):
        what = (
            f"slows this arm's slowest motion with a time constant of {slowest:.3g} s (its "
            f"inertia at the start posture): after hold = {hold:g} s it still moves at "
            f"{100 * np.exp(-hold / slowest):.0f} % of its speed at the stop"
        )
        advice += f", or damping above {3.0 * slowest / hold * float(d.max()):.3g} N·m·s/rad"
    else:
        what = "leaves a joint with damping 0 unbraked: it keeps its speed at the stop"
    warnings.warn(f"realtime.damping: the brake {what}. {advice}", ValidityWarning, stacklevel=3)


def run_experiment(
    config: ExperimentConfig, *, observer: bool | None = None, duration: float | None = None
) -> Result:
    """Build and run ``config``; ``observer=False`` runs the baseline without NDO."""
    return Experiment.from_config(config, observer=observer).run(duration)
