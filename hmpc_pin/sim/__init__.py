"""Simulation: disturbances, plants (one protocol, :mod:`~hmpc_pin.sim.plants`), the arm's
interface as drivers deliver it (:mod:`~hmpc_pin.sim.sensing`), the closed loop, results."""

from .disturbances import (
    CoulombViscousFriction,
    Disturbance,
    GaussianPulse,
    Periodic,
    SumDisturbance,
    ZeroDisturbance,
    as_disturbance,
)
from .mujoco import MuJoCoPlant
from .mujoco_settings import MuJoCoSettings, Obstacle
from .plants import PLANTS, EulerPlant, Plant, RK4Plant
from .result import RESULT_ARRAYS, Result
from .sensing import SensedController, Sensing
from .simulate import simulate

__all__ = [
    "PLANTS",
    "RESULT_ARRAYS",
    "CoulombViscousFriction",
    "Disturbance",
    "EulerPlant",
    "GaussianPulse",
    "MuJoCoPlant",
    "MuJoCoSettings",
    "Obstacle",
    "Periodic",
    "Plant",
    "RK4Plant",
    "Result",
    "SensedController",
    "Sensing",
    "SumDisturbance",
    "ZeroDisturbance",
    "as_disturbance",
    "simulate",
]
