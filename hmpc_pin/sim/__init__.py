"""Simulation: disturbances, plants (one protocol, :mod:`~hmpc_pin.sim.plants`), the closed
loop, results."""

from .disturbances import (
    CoulombViscousFriction,
    Disturbance,
    GaussianPulse,
    Periodic,
    SumDisturbance,
    ZeroDisturbance,
    as_disturbance,
)
from .mujoco import MuJoCoPlant, MuJoCoSettings, Obstacle
from .plants import PLANTS, EulerPlant, Plant, RK4Plant
from .result import RESULT_ARRAYS, Result
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
    "SumDisturbance",
    "ZeroDisturbance",
    "as_disturbance",
    "simulate",
]
