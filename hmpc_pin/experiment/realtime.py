"""The real-time assembly of an experiment: the loop settings, the safety settings and the safe
torque of ``[realtime]`` (:func:`~hmpc_pin.experiment.realtime.realtime_parts`, what
``hmpc-pin realtime``, ``hmpc-pin ros`` and ``hmpc-pin franka`` build), and the brake that
stops the arm (:func:`~hmpc_pin.experiment.realtime.brake_settings`,
:func:`~hmpc_pin.experiment.realtime.minimum_brake_time`).
"""

from __future__ import annotations

import math
import warnings
from typing import Protocol

import numpy as np

from ..exceptions import ConfigError, ValidityWarning
from ..model.robot import Robot
from ..realtime.loop import LoopSettings
from ..realtime.safety import SafeTorque, SafetySettings, brake_time_constant
from ..sim.plants import Plant
from .config import ExperimentConfig
from .record import recorded_limits

__all__ = ["brake_settings", "minimum_brake_time", "realtime_parts"]


class Assembled(Protocol):
    """What :func:`realtime_parts` reads of an experiment
    (:class:`~hmpc_pin.experiment.build.Experiment` is one)."""

    config: ExperimentConfig
    robot: Robot
    q0: np.ndarray

    @property
    def effort_limit(self) -> np.ndarray | None:
        """The plant's effort limits [N·m], or ``None``."""

    def make_plant(self, Ts: float | None = None) -> Plant:
        """A new plant advanced by ``Ts`` [s] per call."""


def realtime_parts(
    experiment: Assembled, rate: float | None = None, *, plant: bool = True
) -> tuple[LoopSettings, SafetySettings, SafeTorque]:
    """The loop settings, safety settings and safe torque of ``[realtime]``.

    Args:
        experiment: The experiment (:class:`~hmpc_pin.experiment.build.Experiment`).
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
        lim = recorded_limits(robot)  # a URDF without a range: no position bound
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
