"""The plant of an experiment: ``[plant]`` and ``[disturbance]`` → the simulated arm (the
Pinocchio RK4 or Euler plant, or MuJoCo) with its disturbance and effort limits."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..exceptions import (
    ConfigError,
)
from ..model.robot import Robot, damping_time_constants
from ..sim.disturbances import CoulombViscousFriction, Disturbance, GaussianPulse, ZeroDisturbance
from ..sim.engines import engine_spec
from ..sim.mujoco_settings import MuJoCoSettings, Obstacle
from ..sim.plants import PLANTS, Plant, RK4Plant, choose_step
from .config import (
    ExperimentConfig,
    PlantConfig,
)

__all__ = [
    "DAMPING_STEP_LIMIT",
    "PILOT_DURATION",
    "build_disturbance",
    "check_plant_damping",
    "damping_rates",
    "mujoco_settings",
    "pinocchio_plant",
    "plant_effort_limit",
    "plant_step",
]

#: Periods along the run whose error ``[plant] tolerance`` checks (evenly spaced).
CALIBRATION_PERIODS = 64
#: The stretch of the run's start [s] whose error ``[plant] tolerance`` also checks.
PILOT_DURATION = 1.0


def plant_effort_limit(config: ExperimentConfig, plant: Robot) -> np.ndarray | None:
    """The plant's effort limits [N·m]: ``plant.effort_limit``, else the plant URDF's (a
    value <= 0 means none); ``None`` when ``plant.saturate`` is false."""
    pc = config.plant
    if not pc.saturate:
        return None
    if pc.effort_limit is not None:
        return config.vector("plant.effort_limit", plant.nq)
    eff = plant.effort_limit
    return np.where(eff > 0, eff, np.inf)


def mujoco_settings(pc: PlantConfig, n: int) -> MuJoCoSettings:
    """:class:`.MuJoCoSettings` of ``[plant.mujoco]`` for ``n`` joints."""
    mc = pc.mujoco
    if mc is None:
        raise ConfigError("plant.mujoco", "only with plant.engine = 'mujoco'")
    ob = mc.obstacle
    per_joint = {}
    for name in ("frictionloss", "damping", "armature"):
        value = getattr(mc, name)
        if value.ndim == 1 and value.shape != (n,):
            raise ConfigError(
                f"plant.mujoco.{name}",
                f"has {value.shape[0]} entries but the robot has {n} "
                f"joints; give {n} values or one value for all joints",
            )
        per_joint[name] = tuple(np.broadcast_to(value, (n,)).tolist())
    return MuJoCoSettings(
        integrator=mc.integrator,
        import_urdf_dynamics=pc.joint_dynamics,
        friction_timeconst=mc.friction_timeconst,
        geometry=mc.geometry,
        obstacle=None
        if ob is None
        else Obstacle(
            tuple(ob.position.tolist()),
            tuple(ob.size.tolist()),
            ob.friction,
            tuple(ob.solref.tolist()),
        ),
        **per_joint,
    )


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


#: The largest plant step × damping rate h·b_j·(M⁻¹)_jj an explicit integrator is given:
#: RK4 is stable on x' = −λx up to hλ = 2.785, explicit Euler up to 2 (half of each, for
#: the posture-dependent M(q)).
DAMPING_STEP_LIMIT = {"rk4": 1.39, "euler": 1.0}


def damping_rates(robot: Robot, q: np.ndarray) -> np.ndarray:
    """Per joint the rate λ_j = b_j (M(q)⁻¹)_jj [1/s] at which the URDF's joint damping
    b_j [N·m·s/rad] slows joint j at ``q`` (0 without damping): the inverse of
    :func:`~hmpc_pin.model.robot.damping_time_constants`."""
    return 1.0 / damping_time_constants(robot, q)


def check_plant_damping(pc: PlantConfig, robot: Robot, q: np.ndarray) -> None:
    """Refuse a plant step too long for the URDF's joint damping (the explicit integrator
    would diverge at once).

    Raises:
        ConfigError: ``plant.dt`` × λ_j (:func:`damping_rates` at ``q``) above
            :data:`DAMPING_STEP_LIMIT`, naming the joint, its time constant 1/λ_j and the
            step that would do.
    """
    if not engine_spec(pc.engine).integrated or not pc.joint_dynamics or pc.dt is None:
        return
    limit = DAMPING_STEP_LIMIT.get(pc.integrator)
    lam = damping_rates(robot, q)
    if limit is None or pc.dt * lam.max(initial=0.0) <= limit:
        return
    j = int(np.argmax(lam))
    raise ConfigError(
        "plant.dt",
        f"{pc.dt:g} s is too long for the URDF damping of joint {robot.joint_names[j]!r} "
        f"(time constant 1/(b (M^-1)_jj) = {1 / lam[j]:.3g} s): the {pc.integrator} plant "
        f"diverges; use [plant] dt <= {limit / lam[j]:.3g} s (dividing Ts), engine = "
        "'mujoco' (implicit damping), or [plant] joint_dynamics = false",
    )


def pinocchio_plant(
    pc: PlantConfig, robot: Robot, disturbance, Ts: float, dt: float | None = None
) -> Plant:
    """The Pinocchio plant of ``[plant]`` (its integrator, step and backend) on ``robot``,
    with the step ``dt`` [s] when given (else ``plant.dt``)."""
    dt = pc.dt if dt is None else dt
    if pc.integrator == "rk4":
        return RK4Plant(
            robot,
            disturbance,
            Ts,
            dt,
            backend=pc.backend,
            joint_dynamics=pc.joint_dynamics,
            coulomb=pc.coulomb,
        )
    return PLANTS[pc.integrator](robot, disturbance, Ts, dt, joint_dynamics=pc.joint_dynamics)


def calibration_samples(
    robot: Robot, reference, disturbance, Ts: float, duration: float, joint_dynamics: bool
) -> list[tuple[float, np.ndarray, np.ndarray, np.ndarray]]:
    """The periods ``[plant] tolerance`` checks: at :data:`CALIBRATION_PERIODS` instants
    :math:`t_k` evenly along the run, the reference's state and the torque that makes the
    plant follow it over the period, as a controller that tracks it and cancels the
    disturbance would send:

    .. math::

        \\tau_k = \\mathrm{RNEA}(r_k, \\dot r_k, (\\dot r_{k+1} - \\dot r_k)/T_s)
            + B\\dot r_k + F\\,\\mathrm{sgn}\\,\\dot r_k - d(t_k, r_k, \\dot r_k)

    (:math:`B, F` the URDF's joint damping and Coulomb friction when ``joint_dynamics``).

    Returns:
        ``(t_k, r_k, ṙ_k, τ_k)`` tuples [s, rad, rad/s, N·m].
    """
    K = max(1, round(duration / Ts))
    ks = np.unique(np.linspace(0, K - 1, min(CALIBRATION_PERIODS, K)).round().astype(int))
    t = ks * Ts
    q, dq = reference.sample_many(t)
    _, dq1 = reference.sample_many(t + Ts)
    n = robot.nq
    b = np.asarray(robot.joint_damping if joint_dynamics else np.zeros(n), dtype=float)
    f = np.asarray(robot.joint_friction if joint_dynamics else np.zeros(n), dtype=float)
    out = []
    for tk, qk, vk, vk1 in zip(t, q, dq, dq1, strict=True):
        tau = robot.inverse_dynamics(qk, vk, (vk1 - vk) / Ts) + b * vk + f * np.sign(vk)
        if disturbance is not None:
            tau = tau - np.asarray(disturbance(float(tk), qk.copy(), vk.copy()), dtype=float)
        out.append((float(tk), qk.copy(), vk.copy(), tau))
    return out


def _pilot_error(pilot, h: float) -> float:
    """max |q_h − q_{h/2}| [rad] of the run's start (inf where either diverges)."""
    a, b = pilot(h), pilot(h / 2)
    if a is None or b is None or a.shape != b.shape:
        return np.inf
    with np.errstate(all="ignore"):
        err = float(np.abs(a - b).max(initial=0.0))
    return err if np.isfinite(err) else np.inf


def _damping_divisions(pc: PlantConfig, robot: Robot, q: np.ndarray, Ts: float) -> int:
    """The fewest steps per period :func:`check_plant_damping` accepts at ``q`` (1 without
    URDF damping): the tolerance's search starts there, not at a step it would refuse."""
    limit = DAMPING_STEP_LIMIT.get(pc.integrator)
    lam = damping_rates(robot, q).max(initial=0.0) if pc.joint_dynamics else 0.0
    if limit is None or lam <= 0.0:
        return 1
    return max(1, math.ceil(Ts * lam / limit * (1.0 + 1e-12)))


def plant_step(
    pc: PlantConfig,
    robot: Robot,
    disturbance,
    Ts: float,
    reference,
    duration: float,
    pilot=None,
) -> float:
    """The plant's step [s]: ``plant.dt``, or with ``plant.tolerance`` the largest
    :math:`T_s/m` within it (:func:`~hmpc_pin.sim.plants.choose_step` on
    :func:`calibration_samples` of ``reference`` over ``duration`` [s], and
    ``pilot(plant)``: the positions [rad] of the run's start on ``plant``, whose difference
    between the steps ``h`` and ``h/2`` is held to the tolerance too; ``None``: none).

    Raises:
        ConfigError: No step reaches the tolerance, or the step chosen is too long for the
            URDF's damping (:func:`check_plant_damping`).
    """
    if pc.tolerance is None:
        return pc.dt
    samples = calibration_samples(robot, reference, disturbance, Ts, duration, pc.joint_dynamics)
    plants: dict[float, Plant] = {}
    runs: dict[float, np.ndarray | None] = {}

    def plant_of(h: float) -> Plant:  # one plant per step (h/2 is the next h's)
        key = round(Ts / h, 6)
        if key not in plants:
            plants[key] = pinocchio_plant(pc, robot, disturbance, Ts, h)
        return plants[key]

    def run_of(h: float) -> np.ndarray | None:
        key = round(Ts / h, 6)
        if key not in runs:
            runs[key] = pilot(plant_of(h))
        return runs[key]

    h, _ = choose_step(
        plant_of,
        Ts,
        samples,
        pc.tolerance,
        periods=max(1, round(duration / Ts)),
        pilot=None if pilot is None else lambda h: _pilot_error(run_of, h),
        min_divisions=_damping_divisions(pc, robot, samples[0][1], Ts),
    )
    check_plant_damping(replace(pc, dt=h, tolerance=None), robot, samples[0][1])
    return h


#: The name of :func:`plant_effort_limit` before version 0.3.
_effort_limit = plant_effort_limit
