"""``hmpc-pin ros``: run the controller as a ROS 2 node against /joint_states (extra: ros). Its
arguments (``add_arguments``) and its entry point (``main``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..common import (
    add_force_option,
    add_inner_law_option,
    out_dir,
    read_config,
    realtime_files,
    refuse_earlier_files,
    report_realtime,
    ros_config,
    with_overrides,
)

if TYPE_CHECKING:
    from ...experiment.config import ExperimentConfig

__all__ = ["add_arguments", "main"]


def add_arguments(ros) -> None:
    """``hmpc-pin ros`` (:mod:`hmpc_pin.apps.ros`)."""
    from ..ros import ros_arguments

    ros_arguments(ros)
    add_inner_law_option(ros, "whole-step")
    add_force_option(ros)


def main(args) -> int:
    """``hmpc-pin ros``: the controller as a ROS 2 node (:mod:`hmpc_pin.apps.ros`)."""
    from ...experiment.inner_law import close_law
    from ...ros.node import import_ros
    from ..realtime import format_tracking
    from ..ros import build_ros, check_run_length, format_ros, run_ros

    import_ros("hmpc-pin ros")  # the extra, before anything else
    config = ros_config(args, with_overrides(read_config(args.config), False, args.duration))
    key = "--duration" if args.duration is not None else "simulation.duration"
    check_run_length(config.simulation.duration, config.ros.rate, key)
    namespace, node = _ros_node_name(config, args.ros_args)  # (checks its -p, before rclpy)
    # [ros] rate against Ts, the brake, [ros] gravity: bad input stops here, nothing written
    law = None if args.inner_law is None else config.realtime.inner_law  # (named the option)
    built = build_ros(config, law)  # built once, run below
    try:
        refuse_earlier_files(args.out, realtime_files(f"{config.name}_ros"), args.force)
        out = out_dir(args.out)
        print(
            f"{config.name}: {config.description} ({config.controller.label}) as ROS 2 node "
            f"{namespace}/{node} for {config.simulation.duration:g} s, "
            f"paced by {config.ros.joint_states} at {config.ros.rate:g} Hz",
            flush=True,
        )
        return report_realtime(
            lambda: run_ros(config, out, ros_args=args.ros_args, built=built),
            config,
            "published",
            format_ros,
            format_tracking,
        )
    finally:
        close_law(built[1][3])  # the threaded law's planner joined on every way out


def _ros_node_name(config: ExperimentConfig, ros_args: list[str] | None) -> tuple[str, str]:
    """The controller node's namespace and name as rclpy will set them (``-r __ns:=``,
    ``-r __node:=`` of ``--ros-args`` over ``[ros]``), once every ``-p`` of ``ros_args``
    is checked to name one of the node's parameters (:mod:`hmpc_pin.apps.ros_args`)."""
    from ..ros import config_parameters
    from ..ros_args import check_parameters, parse_ros_args

    given = parse_ros_args(ros_args, config.ros.node)
    check_parameters(given.parameters, config_parameters(config))
    namespace = config.ros.namespace if given.namespace is None else given.namespace
    return namespace.rstrip("/"), given.node or config.ros.node
