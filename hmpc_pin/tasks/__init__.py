"""Tasks: the references the controllers track (one protocol, :mod:`~hmpc_pin.tasks.base`).

Joint space: the paper's sine, a quintic move, a trajectory through timed samples or from a
file (:mod:`.trajectory`), joint waypoints retimed by TOPP-RA (:mod:`.waypoints`). Task
space: a frame's SE(3) path solved by pink's differential IK (:mod:`.pose`; the extra
``hmpc_pin[tasks]``).
"""

from .base import Reference, as_reference, check_limits, sample_horizon
from .pose import CirclePath, LinePath, PoseReference, PoseWaypoints, solve_path_ik
from .quintic import QuinticReference
from .sine import SineReference
from .trajectory import JointTrajectory, load_trajectory
from .waypoints import retime_waypoints

__all__ = [
    "CirclePath",
    "JointTrajectory",
    "LinePath",
    "PoseReference",
    "PoseWaypoints",
    "QuinticReference",
    "Reference",
    "SineReference",
    "as_reference",
    "check_limits",
    "load_trajectory",
    "retime_waypoints",
    "sample_horizon",
    "solve_path_ik",
]
