"""The ``--ros-args`` of ``hmpc-pin ros``, read before rclpy starts (no ROS needed).

rclpy takes ``-p name:=value`` for a parameter the node never declares without a word
(the value is kept as an override nobody reads), and the node's name and namespace can be
remapped (``-r __node:=name``, ``-r __ns:=/ns``). This module reads those arguments as
rcl does, so that the command refuses a parameter the node does not have (listing the
ones it has) and names the node as it will be named.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..exceptions import ConfigError

__all__ = ["RCLPY_PARAMETERS", "RosArgs", "check_parameters", "parse_ros_args"]

#: Parameters every rclpy node has (``ros2 param list`` on any node), besides its own.
RCLPY_PARAMETERS = ("use_sim_time", "start_type_description_service")
#: Prefixes of parameters rclpy reads itself (QoS overrides of a topic).
RCLPY_PREFIXES = ("qos_overrides.",)

_PARAM = ("-p", "--param")
_REMAP = ("-r", "--remap")
#: Flags of rcl that take one value (skipped).
_WITH_VALUE = ("--params-file", "--log-level", "--log-config-file", "-e", "--enclave")


@dataclass
class RosArgs:
    """What ``--ros-args`` sets that the command must know before rclpy starts.

    Attributes:
        parameters: ``-p`` overrides, name → value text (a node-targeted
            ``-p node:name:=v`` under its name when it targets ``node``).
        node: The name of a ``-r __node:=...`` remap, or ``None``.
        namespace: The namespace of a ``-r __ns:=...`` remap, or ``None``.
    """

    parameters: dict[str, str] = field(default_factory=dict)
    node: str | None = None
    namespace: str | None = None


def _split(rule: str, flag: str, node: str) -> tuple[str, str] | None:
    """``name:=value`` of a rule (``None`` if it targets another node than ``node``)."""
    if ":=" not in rule:
        raise ConfigError(
            "--ros-args", f"{flag} {rule!r}: expected name:=value (e.g. -p use_sim_time:=true)"
        )
    name, value = rule.split(":=", 1)
    if ":" in name:  # node-targeted: node:name:=value
        target, name = name.split(":", 1)
        if target != node:
            return None
    return name, value


def parse_ros_args(args: list[str] | None, node: str) -> RosArgs:
    """Read the parameters and the node's name and namespace remaps of ``args`` (the
    arguments after ``--ros-args``) for the node named ``node``.

    Raises:
        ConfigError: (``--ros-args``) a ``-p``/``-r`` without its ``name:=value``.
    """
    out = RosArgs()
    args = list(args or [])
    i = 0
    while i < len(args):
        flag = args[i]
        if flag in _PARAM + _REMAP:
            if i + 1 >= len(args):
                raise ConfigError("--ros-args", f"{flag} without its name:=value")
            rule = _split(args[i + 1], flag, node)
            if rule is not None:
                name, value = rule
                if flag in _PARAM:
                    out.parameters[name] = value
                elif name == "__node":
                    out.node = value
                elif name == "__ns":
                    out.namespace = value
            i += 2
        elif flag in _WITH_VALUE:
            i += 2
        else:
            i += 1
    return out


def check_parameters(given: dict[str, str], declared) -> None:
    """Refuse a ``-p`` of a parameter the node does not declare (nor rclpy reads).

    Args:
        given: :attr:`RosArgs.parameters`.
        declared: The node's parameter names.

    Raises:
        ConfigError: (``--ros-args``) naming the parameter and listing the node's.
    """
    known = set(declared) | set(RCLPY_PARAMETERS)
    for name in given:
        if name in known or name.startswith(RCLPY_PREFIXES):
            continue
        raise ConfigError(
            "--ros-args",
            f"-p {name}: the node has no such parameter; its parameters are "
            f"{', '.join(sorted(known))} (and qos_overrides.*); those of the config are "
            "read-only: set the config file's key instead",
        )
