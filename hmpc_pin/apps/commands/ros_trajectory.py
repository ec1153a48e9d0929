"""``hmpc-pin ros-trajectory``: send a new reference to the `ros` node's ~/joint_trajectory
(extra: ros). Its arguments (``add_arguments``) and its entry point (``main``).
"""

from __future__ import annotations

from ..common import read_config

__all__ = ["add_arguments", "main"]


def add_arguments(parser) -> None:
    """``hmpc-pin ros-trajectory`` (:mod:`hmpc_pin.apps.ros_client`)."""
    from ..ros_client import trajectory_arguments

    trajectory_arguments(parser)


def main(args) -> int:
    """``hmpc-pin ros-trajectory`` (:mod:`hmpc_pin.apps.ros_client`)."""
    from ...ros.node import import_ros
    from ..ros_client import run_trajectory

    import_ros("hmpc-pin ros-trajectory")
    return run_trajectory(args, read_config(args.config))
