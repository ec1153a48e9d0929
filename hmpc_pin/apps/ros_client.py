"""``hmpc-pin ros-trajectory``, ``ros-lifecycle`` and ``ros-params``: the controller node of
``hmpc-pin ros`` driven from the command line with rclpy alone
(:mod:`hmpc_pin.ros.client`), for an installation without a sourced ROS 2 (no ``ros2``
command): a new reference, lifecycle transitions, the parameters.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from ..exceptions import ConfigError

__all__ = [
    "lifecycle_arguments",
    "params_arguments",
    "run_lifecycle",
    "run_params",
    "run_trajectory",
    "trajectory_arguments",
]

DEFAULT_NODE = "/hmpc_pin_controller"


def _node_option(parser) -> None:
    parser.add_argument(
        "--node",
        default=DEFAULT_NODE,
        metavar="NAME",
        help=f"the controller node, with its namespace [{DEFAULT_NODE}]",
    )
    parser.add_argument(
        "--timeout",
        type=float,
        default=10.0,
        metavar="S",
        help="wait this long [s] for the node and each answer [10]",
    )


def _timeout(value: float) -> float:
    if not (math.isfinite(value) and value > 0):
        raise ConfigError("--timeout", f"expected a time [s] > 0, got {value!r}")
    return value


def trajectory_arguments(p) -> None:
    """``ros-trajectory``'s description and arguments."""
    p.description = (
        "Send a new reference to the controller of `hmpc-pin ros CONFIG` as a "
        "trajectory_msgs/JointTrajectory on its ~/joint_trajectory (what `ros2 topic pub` "
        "does, with rclpy alone): one point reached --in seconds from now (--to), or the "
        "points of a trajectory file (--file). The node checks it against the limits and "
        "logs whether it accepted it."
    )
    p.add_argument("config", type=Path, help="the controller's experiment TOML (joints, node)")
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument(
        "--to",
        metavar="Q1,Q2,...",
        help="joint positions [rad], one per controlled joint in the robot's order",
    )
    what.add_argument(
        "--file",
        type=Path,
        metavar="FILE",
        help="a trajectory file (.csv: t, one column per joint [, dq_<joint>]; or .npz), "
        "its times from its first",
    )
    p.add_argument(
        "--in",
        dest="seconds",
        type=float,
        default=2.0,
        metavar="S",
        help="with --to: reach the point S seconds after the message arrives [2]",
    )
    p.add_argument(
        "--namespace", metavar="NS", help="the nodes' namespace (overrides ros.namespace)"
    )
    p.add_argument(
        "--timeout", type=float, default=10.0, metavar="S", help="wait for the node [s] [10]"
    )


def lifecycle_arguments(p) -> None:
    """``ros-lifecycle``'s description and arguments."""
    from ..ros.client import TRANSITIONS

    p.description = (
        "Change the lifecycle state of the controller node of `hmpc-pin ros` (what "
        "`ros2 lifecycle set` and `ros2 lifecycle get` do, with rclpy alone): deactivate "
        "runs its stop sequence and ends its run (exit 130); configure and activate start "
        "a node started with [ros] autostart = false. Exit 0 when the node is in the "
        "transition's goal state, 1 when not."
    )
    p.add_argument(
        "transition",
        choices=[*TRANSITIONS, "get"],
        help="the transition, or `get`: print the node's state",
    )
    _node_option(p)


def params_arguments(p) -> None:
    """``ros-params``' description and arguments."""
    p.description = (
        "Print the parameters of the controller node of `hmpc-pin ros` (`name = value`, "
        "one a line; what `ros2 param list` and `ros2 param get` do, with rclpy alone): "
        "the config's [ros] and [realtime] keys as the node runs them, read-only."
    )
    p.add_argument("names", nargs="*", metavar="NAME", help="only these parameters [all]")
    _node_option(p)


def _topic(ns: str, node: str, name: str) -> str:
    """``name`` resolved as the node resolves it."""
    if name.startswith("~/"):
        return f"{ns.rstrip('/')}/{node}/{name[2:]}"
    if name.startswith("/"):
        return name
    return f"{ns.rstrip('/')}/{name}"


def run_trajectory(args, config) -> int:
    """``ros-trajectory`` (``config`` loaded by the command line)."""
    from ..experiment.build import load_robot_config
    from ..ros.client import RosClient
    from ..tasks.trajectory import load_trajectory
    from .ros import with_namespace

    timeout = _timeout(args.timeout)
    config = with_namespace(config, args.namespace)
    names = list(load_robot_config(config.robot).joint_names)
    if args.to is not None:
        try:
            q = np.array([float(x) for x in args.to.split(",")])
        except ValueError:
            q = np.array([math.nan])
        if q.shape != (len(names),) or not np.isfinite(q).all():
            raise ConfigError(
                "--to",
                f"expected {len(names)} finite positions [rad] separated by commas, in the "
                f"order {names}; got {args.to!r}",
            )
        if not (math.isfinite(args.seconds) and args.seconds > 0):
            raise ConfigError("--in", f"expected a time [s] > 0, got {args.seconds!r}")
        times, positions, velocities = np.array([args.seconds]), q[None, :], None
    else:
        traj = load_trajectory(args.file, names)  # bad file: one line, exit 2
        times = traj.times - traj.times[0]
        positions, velocities = traj.q_samples, traj.dq_samples
    rc = config.ros
    topic = _topic(rc.namespace, rc.node, rc.joint_trajectory)
    node = f"{rc.namespace.rstrip('/')}/{rc.node}"
    with RosClient(node, timeout, "hmpc-pin ros-trajectory") as c:
        c.send_trajectory(names, times, positions, velocities, topic=topic)
    print(
        f"sent a trajectory of {len(times)} points ({float(times[-1]):g} s) to {topic}; the "
        "node logs whether it accepted it (and records it in its run file)"
    )
    return 0


def run_lifecycle(args) -> int:
    """``ros-lifecycle``."""
    from ..ros.client import RosClient

    with RosClient(args.node, _timeout(args.timeout), "hmpc-pin ros-lifecycle") as c:
        if args.transition == "get":
            state = c.state()
            if state is None:
                print(f"error: {c.target}: no answer to get_state", file=sys.stderr)
                return 1
            print(state)
            return 0
        done, line = c.transition(args.transition)
    print(line, file=sys.stdout if done else sys.stderr)
    return 0 if done else 1


def run_params(args) -> int:
    """``ros-params``."""
    from ..ros.client import RosClient

    with RosClient(args.node, _timeout(args.timeout), "hmpc-pin ros-params") as c:
        values = c.parameters(args.names)
    for name, value in values.items():
        print(f"{name} = {value!r}")
    return 0
