"""``hmpc-pin ros-arm``: run the config's plant as a ROS 2 node (joint states out, efforts in;
extra: ros). Its arguments (``add_arguments``) and its entry point (``main``).
"""

from __future__ import annotations

from ..common import (
    EXIT_INTERRUPTED,
    EXIT_OK,
    checked_duration,
    read_config,
    ros_config,
)

__all__ = ["add_arguments", "main"]


def add_arguments(arm) -> None:
    """``hmpc-pin ros-arm`` (:mod:`hmpc_pin.apps.ros`)."""
    from ..ros import ros_arm_arguments

    ros_arm_arguments(arm)


def main(args) -> int:
    """``hmpc-pin ros-arm``: the config's plant as a ROS 2 node (:mod:`hmpc_pin.apps.ros`)."""
    from ...ros.node import import_ros
    from ..ros import run_ros_arm

    import_ros("hmpc-pin ros-arm")
    checked_duration(args.duration)
    config = ros_config(args, read_config(args.config))
    counts = run_ros_arm(config, args.duration, args.ros_args, args.real_time_factor)
    return EXIT_INTERRUPTED if counts["interrupted"] else EXIT_OK
