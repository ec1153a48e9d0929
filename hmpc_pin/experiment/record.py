"""The run record of an experiment: the metadata stored with a run
(:func:`~hmpc_pin.experiment.record.run_meta`, what replay and ``hmpc-pin identify`` need),
the plant's engine and its measurements added to a result
(:func:`~hmpc_pin.experiment.record.record_plant`), and the position limits the metrics
measure excursions against (:func:`~hmpc_pin.experiment.record.recorded_limits`).
"""

from __future__ import annotations

import numpy as np

from ..controllers.base import Controller
from ..controllers.wrappers import CollisionReaction
from ..identification.observer_model import ObserverModel
from ..model.robot import Robot
from ..sim.mujoco import MuJoCoPlant
from ..sim.plants import Plant
from ..sim.result import Result
from .config import ExperimentConfig
from .controllers import mpc_settings, uses_observer

__all__ = ["identification_meta", "record_plant", "recorded_limits", "run_meta"]


def recorded_limits(robot: Robot) -> dict[str, list[float]]:
    """The URDF position limits [rad or m] the metrics measure excursions against.

    Args:
        robot: The controller's model.

    Returns:
        ``{"lower": [...], "upper": [...]}``; a zero or inverted range (double_pendulum's
        0/0: no range given) is recorded as ±inf.
    """
    lo, hi = robot.lower, robot.upper
    ok = lo < hi
    return {
        "lower": np.where(ok, lo, -np.inf).tolist(),
        "upper": np.where(ok, hi, np.inf).tolist(),
    }


def run_meta(config: ExperimentConfig, robot: Robot, controller: Controller) -> dict:
    """The metadata stored with a run of an experiment (replay needs the URDF).

    Args:
        config: The experiment's validated config.
        robot: The controller's model.
        controller: The controller that runs (its compensation's observer is recorded).

    Returns:
        The experiment's name, config file, URDF, joints, limits, gravity, controller and
        its periods, and :func:`identification_meta`.
    """
    return {
        "experiment": config.name,
        "config": str(config.source) if config.source else None,
        "urdf": str(robot.source),
        "locked_joints": robot.locked_joints,
        "joint_kinds": list(robot.joint_kinds),
        "limits": recorded_limits(robot),
        "gravity": config.robot.gravity,
        "controller": config.controller.label,
        "observer": uses_observer(config.controller),
        "Ts": config.controller.Ts,
        "N": config.controller.N,
        "Nc": config.controller.Nc,
        "state_bound": config.simulation.state_bound,
        **identification_meta(config, robot, controller),
    }


def identification_meta(config: ExperimentConfig, robot: Robot, controller: Controller) -> dict:
    """What ``hmpc-pin identify`` needs of the controller: the observer (its regressors
    are passed through its dynamics) and the friction fed forward (added back to its
    estimate).

    Args:
        config: The experiment's validated config.
        robot: The controller's model.
        controller: The controller that runs.

    Returns:
        ``observer_model`` (the observer that runs: its matrix cY or K_O, Ts, Euler) and
        ``friction_feedforward`` (viscous [N·m·s/rad], coulomb [N·m], smoothing [rad/s]),
        each where it applies.
    """
    cc, n = config.controller, robot.nq
    out: dict = {}
    model = ObserverModel.of(
        getattr(controller, "compensation", None),
        model_at=mpc_settings(cc, n).model_at,
    )
    if model is not None:
        out["observer_model"] = model.record()
    if cc.friction is not None:
        out["friction_feedforward"] = {
            "viscous": config.vector("controller.friction.viscous", n).tolist(),
            "coulomb": config.vector("controller.friction.coulomb", n).tolist(),
            "smoothing": cc.friction.smoothing,
        }
    return out


def record_plant(
    config: ExperimentConfig, robot: Robot, controller: Controller, plant: Plant, result: Result
) -> Result:
    """Add the plant's engine and what it measured to ``result``.

    Args:
        config: The experiment's validated config.
        robot: The controller's model.
        controller: The controller that ran (a collision watch records its flag).
        plant: The plant that ran.
        result: The run's result, completed in place.

    Returns:
        ``result``, with the engine and its version (a Pinocchio plant's step [s] and
        Coulomb law: ``plant_step``, chosen by ``plant.tolerance`` where given, and
        ``coulomb``), the MuJoCo contact force [N·m] and first contact [s], the friction
        fed forward [N·m] and the collision flag.
    """
    pc = config.plant
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
            result.meta["first_contact"] = float(result.t[touching[0]]) if touching.size else None
    else:
        import pinocchio

        result.meta["engine_version"] = pinocchio.__version__
    fm = config.controller.friction
    if fm is not None:
        n = robot.nq
        a = config.vector("controller.friction.viscous", n)
        b = config.vector("controller.friction.coulomb", n)
        # the model's torque at the recorded velocity (the observer's target is d + it)
        sign = np.tanh(result.dq / fm.smoothing) if fm.smoothing > 0 else np.sign(result.dq)
        result.extra["friction_feedforward"] = a * result.dq + b * sign
    if isinstance(controller, CollisionReaction):
        c = controller
        result.meta["collision"] = {
            "detected_at": c.detected_at,
            "joint": None if c.joint is None else robot.joint_names[c.joint],
            "reaction": c.reaction,
            "threshold": c.threshold.tolist(),
        }
    return result
