"""Build every part of an experiment from its :class:`~hmpc_pin.config.ExperimentConfig`; run it."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .config import ExperimentConfig
from .controller import make_controller
from .disturbances import CoulombViscousFriction, Disturbance, GaussianPulse, ZeroDisturbance
from .exceptions import ConfigError, LimitError
from .references import SineReference, check_limits
from .robot import Robot, load_robot
from .simulate import Result, simulate

__all__ = [
    "Experiment",
    "build_disturbance",
    "build_reference",
    "run_experiment",
    "uses_observer",
    "with_controller",
]


def build_reference(config: ExperimentConfig, robot: Robot):
    """The joint reference of ``config``: the sine of Eq 31 or the Section 5.4 motion.

    For ``kind = "cartesian"`` both tool poses are solved by inverse kinematics
    inside the joint limits (the goal on the branch closest to the start) and
    joined by a quintic. Raises :class:`~hmpc_pin.kinematics.KinematicsError`
    naming the pose when one is unreachable.
    """
    n = robot.nq
    rc = config.reference
    if rc.kind == "cartesian":
        from .kinematics import solve_pose
        from .references import QuinticReference

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


def build_disturbance(config: ExperimentConfig, robot: Robot, q0: np.ndarray) -> Disturbance:
    """The plant disturbance of ``config`` (Eq 32–34); with ``scale = "inertia"`` each
    joint's coefficients are multiplied by :math:`M_{ii}(q_0)` of the controller's model."""
    n = robot.nq
    dc = config.disturbance
    k = np.diag(robot.mass_matrix(q0)).copy() if dc.scale == "inertia" else np.ones(n)
    disturbance: Disturbance = ZeroDisturbance(n)
    if dc.friction is not None:
        disturbance = disturbance + CoulombViscousFriction(
            k * np.broadcast_to(dc.friction.viscous, (n,)),
            k * np.broadcast_to(dc.friction.coulomb, (n,)),
        )
    if dc.pulse is not None:
        disturbance = disturbance + GaussianPulse(
            k * np.broadcast_to(dc.pulse.amplitude, (n,)),
            np.broadcast_to(dc.pulse.center, (n,)),
            np.broadcast_to(dc.pulse.sigma, (n,)),
        )
    return disturbance


def uses_observer(controller) -> bool:
    """Whether the controller of this :class:`~hmpc_pin.config.ControllerConfig` has an observer."""
    return controller.kind == "hmpc-momentum" or (
        controller.kind == "hmpc" and controller.observer.enabled
    )


def with_controller(
    config: ExperimentConfig, kind: str | None = None, observer: bool | None = None
) -> ExperimentConfig:
    """``config`` with ``controller.kind`` and/or ``controller.observer.enabled`` replaced.

    ``observer=False`` turns ``hmpc-momentum`` into ``hmpc-none`` (the momentum
    observer has no off switch of its own); ``observer=True`` turns ``hmpc-none``
    into ``hmpc``.
    """
    cc = config.controller
    if kind is not None:
        cc = replace(cc, kind=kind)
    if observer is not None:
        cc = replace(cc, observer=replace(cc.observer, enabled=observer))
        if not observer and cc.kind == "hmpc-momentum":
            cc = replace(cc, kind="hmpc-none")
        elif observer and cc.kind == "hmpc-none":
            cc = replace(cc, kind="hmpc")
    return config if cc is config.controller else replace(config, controller=cc)


@dataclass
class Experiment:
    """The objects of one experiment, built from its config.

    Attributes:
        config: The validated config.
        robot: The controller's model.
        plant: The plant's model (a separate ``pin.Model``; another URDF if configured).
        controller: The controller named by ``config.controller.kind``
            (:func:`~hmpc_pin.controller.make_controller`).
        reference: The joint reference.
        disturbance: The plant disturbance ``d(t, q, dq)``.
        q0, dq0: Initial state.
    """

    config: ExperimentConfig
    robot: Robot
    plant: Robot
    controller: object
    reference: object
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
            observer: Overrides ``controller.observer.enabled`` (``False`` on an
                ``hmpc-momentum`` config gives ``hmpc-none``).
            controller: Overrides ``controller.kind`` (one of
                :data:`~hmpc_pin.config.CONTROLLER_KINDS`); applied before ``observer``.

        Raises:
            LimitError: The initial state or the reference (sampled at every control
                instant of the run and its last horizon) leaves the joint limits.
        """
        config = with_controller(config, controller, observer)
        rc = config.robot
        robot = rc.load()
        n = robot.nq
        config.check_dimensions(n)
        pc = config.plant
        plant_gravity = pc.gravity if pc.gravity is not None else rc.gravity
        plant = (
            load_robot(pc.urdf, gravity=plant_gravity, locked_joints=rc.locked_joints)
            if pc.urdf is not None
            else rc.load(gravity=plant_gravity)
        )
        if plant.nq != n:
            raise ConfigError(
                "plant.urdf",
                f"the plant has {plant.nq} joints but the robot has {n}; use the same arm",
            )
        reference = build_reference(config, robot)
        q0 = (
            reference.sample(0.0)[0]
            if config.simulation.q0 is None
            else config.vector("simulation.q0", n)
        )
        controller = make_controller(robot, config.controller)
        limits = config.controller.constraints.limits(robot)
        if limits is not None:
            lower, upper, _ = limits
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
        pc = self.config.plant
        if not pc.saturate:
            return None
        if pc.effort_limit is not None:
            return self.config.vector("plant.effort_limit", self.robot.nq)
        eff = self.plant.effort_limit
        return np.where(eff > 0, eff, np.inf)

    def run(self, duration: float | None = None, on_step=None) -> Result:
        """Simulate the closed loop for ``duration`` [s] (default: the config's).

        ``on_step(t, q, q_ref)`` is called at every control instant (live view).
        """
        cfg = self.config
        return simulate(
            self.robot,
            self.controller,
            self.reference,
            self.disturbance,
            duration=cfg.simulation.duration if duration is None else duration,
            q0=self.q0,
            dq0=self.dq0,
            plant=self.plant,
            dt=cfg.plant.dt,
            integrator=cfg.plant.integrator,
            effort_limit=self.effort_limit,
            state_bound=cfg.simulation.state_bound,
            on_step=on_step,
            meta={
                "experiment": cfg.name,
                "config": str(cfg.source) if cfg.source else None,
                "urdf": self.robot.source,
                "locked_joints": self.robot.locked_joints,
                "limits": {
                    "lower": self.robot.lower.tolist(),
                    "upper": self.robot.upper.tolist(),
                },
                "gravity": cfg.robot.gravity,
                "controller": cfg.controller.kind,
                "observer": uses_observer(cfg.controller),
                "Ts": cfg.controller.Ts,
                "N": cfg.controller.N,
                "Nc": cfg.controller.Nc,
                "state_bound": cfg.simulation.state_bound,
            },
        )


def run_experiment(
    config: ExperimentConfig, *, observer: bool | None = None, duration: float | None = None
) -> Result:
    """Build and run ``config``; ``observer=False`` runs the baseline without NDO."""
    return Experiment.from_config(config, observer=observer).run(duration)
