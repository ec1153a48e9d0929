"""Build every part of an experiment from its :class:`~hmpc_pin.config.ExperimentConfig`; run it."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .config import ExperimentConfig
from .controller import HierarchicalMPC
from .disturbances import CoulombViscousFriction, Disturbance, GaussianPulse, ZeroDisturbance
from .references import SineReference
from .robot import Robot, load_robot
from .simulate import Result, simulate

__all__ = ["Experiment", "build_reference", "run_experiment"]


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


@dataclass
class Experiment:
    """The objects of one experiment, built from its config.

    Attributes:
        config: The validated config.
        robot: The controller's model.
        plant: The plant's model (a separate ``pin.Model``; another URDF if configured).
        controller: The :class:`HierarchicalMPC`.
        reference: The joint reference.
        disturbance: The plant disturbance ``d(t, q, dq)``.
        q0, dq0: Initial state.
    """

    config: ExperimentConfig
    robot: Robot
    plant: Robot
    controller: HierarchicalMPC
    reference: object
    disturbance: Disturbance
    q0: np.ndarray
    dq0: np.ndarray

    @classmethod
    def from_config(cls, config: ExperimentConfig, *, observer: bool | None = None) -> Experiment:
        """Build the experiment; ``observer`` overrides ``controller.observer.enabled``."""
        if observer is not None:
            obs = replace(config.controller.observer, enabled=observer)
            config = replace(config, controller=replace(config.controller, observer=obs))
        robot = load_robot(config.robot.urdf, gravity=config.robot.gravity)
        n = robot.nq
        config.check_dimensions(n)
        pc = config.plant
        plant_gravity = pc.gravity if pc.gravity is not None else config.robot.gravity
        plant = (
            load_robot(pc.urdf, gravity=plant_gravity)
            if pc.urdf is not None
            else load_robot(config.robot.urdf, gravity=plant_gravity)
        )
        if plant.nq != n:
            from .exceptions import ConfigError

            raise ConfigError(
                "plant.urdf",
                f"the plant has {plant.nq} joints but the robot has {n}; use the same arm",
            )
        reference = build_reference(config, robot)
        dc = config.disturbance
        disturbance: Disturbance = ZeroDisturbance(n)
        if dc.friction is not None:
            disturbance = disturbance + CoulombViscousFriction(
                np.broadcast_to(dc.friction.viscous, (n,)),
                np.broadcast_to(dc.friction.coulomb, (n,)),
            )
        if dc.pulse is not None:
            disturbance = disturbance + GaussianPulse(
                np.broadcast_to(dc.pulse.amplitude, (n,)),
                np.broadcast_to(dc.pulse.center, (n,)),
                np.broadcast_to(dc.pulse.sigma, (n,)),
            )
        controller = HierarchicalMPC(robot, config.controller)
        return cls(
            config=config,
            robot=robot,
            plant=plant,
            controller=controller,
            reference=reference,
            disturbance=disturbance,
            q0=(
                reference.sample(0.0)[0]
                if config.simulation.q0 is None
                else config.vector("simulation.q0", n)
            ),
            dq0=config.vector("simulation.dq0", n),
        )

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
            on_step=on_step,
            meta={
                "experiment": cfg.name,
                "config": str(cfg.source) if cfg.source else None,
                "urdf": str(cfg.robot.urdf),
                "gravity": cfg.robot.gravity,
                "observer": cfg.controller.observer.enabled,
                "Ts": cfg.controller.Ts,
                "N": cfg.controller.N,
                "Nc": cfg.controller.Nc,
            },
        )


def run_experiment(
    config: ExperimentConfig, *, observer: bool | None = None, duration: float | None = None
) -> Result:
    """Build and run ``config``; ``observer=False`` runs the baseline without NDO."""
    return Experiment.from_config(config, observer=observer).run(duration)
