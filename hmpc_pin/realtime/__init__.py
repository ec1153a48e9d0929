"""Real time: a controller at a fixed rate against an arm, deadlines measured, safe stops.

:class:`RobotInterface` is the arm (read the state with its stamp, write a torque,
close): :class:`PlantArm` in this process, :class:`ProcessArm` in a separate process in
wall-clock time, :class:`FrankaArm` a Franka FR3 or Panda over pylibfranka (FCI,
:mod:`.franka`; the older template :mod:`.driver_template` is superseded by it).
:class:`RealtimeLoop` runs any :class:`~hmpc_pin.controllers.base.Controller` against it
at absolute deadlines (or, against a :class:`PacedInterface` such as the ROS 2 arm of
:mod:`hmpc_pin.ros` or the Franka arm, answering each state the arm sends), records
latency and misses, and stops safely (:mod:`.safety`).
"""

from .franka import CommandFilter, FrankaArm
from .interface import PacedInterface, PlantArm, RobotInterface
from .loop import (
    LoopSettings,
    RealtimeLoop,
    RealtimeRun,
    fifo_priority,
    latency_stats,
    sleep_until,
)
from .process_arm import ProcessArm
from .safety import STOP_CAUSES, GravityByArm, SafeTorque, SafetySettings

__all__ = [
    "STOP_CAUSES",
    "CommandFilter",
    "FrankaArm",
    "GravityByArm",
    "LoopSettings",
    "PacedInterface",
    "PlantArm",
    "ProcessArm",
    "RealtimeLoop",
    "RealtimeRun",
    "RobotInterface",
    "SafeTorque",
    "SafetySettings",
    "fifo_priority",
    "latency_stats",
    "sleep_until",
]
