"""Controllers: inverse dynamics × an outer loop × a compensation (one protocol,
:mod:`~hmpc_pin.controllers.base`).

The controllers by name: :mod:`hmpc_pin.controllers.registry`."""

from .base import Controller, ControllerWrapper
from .computed_torque import ComputedTorque, CTSettings
from .hierarchical import HierarchicalMPC, MPCSettings, state_limits
from .wrappers import MeasuredController, TimedController

__all__ = [
    "CTSettings",
    "ComputedTorque",
    "Controller",
    "ControllerWrapper",
    "HierarchicalMPC",
    "MPCSettings",
    "MeasuredController",
    "TimedController",
    "state_limits",
]
