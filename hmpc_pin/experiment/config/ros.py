"""``[ros]``: the ROS 2 nodes of ``hmpc-pin ros`` and ``hmpc-pin ros-arm``."""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass

from ...exceptions import ConfigError
from ._fields import _bool, _choice, _float, _int, _set

#: ``[ros] gravity``: who compensates gravity (the guide "ROS 2" has a table per arm).
GRAVITY = ("controller", "arm")
#: ``[ros] qos_reliability`` values.
RELIABILITY = ("reliable", "best_effort")
#: ``[ros] external_torque_type`` values; ``"float64_multi_array"`` is deprecated.
EXTERNAL_TORQUE_TYPES = ("joint_state", "float64_multi_array")

#: ``[ros] discovery`` values and the ``ROS_AUTOMATIC_DISCOVERY_RANGE`` each sets.
DISCOVERY_RANGES = {
    "localhost": "LOCALHOST",
    "subnet": "SUBNET",
    "off": "OFF",
    "system_default": "SYSTEM_DEFAULT",
}

# A ROS 2 topic name: tokens of letters, digits, underscores separated by "/", optionally
# absolute ("/...") or private ("~/..."); a token does not start with a digit.
_TOPIC = re.compile(r"^(~/|/)?[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*$")
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_NAMESPACE = re.compile(r"^(/[A-Za-z_][A-Za-z0-9_]*)*$")


def check_namespace(key: str, value) -> str:
    """A ROS namespace: ``""`` or ``/a/b``, each token a name (``"a/b"`` is read as
    ``"/a/b"``)."""
    if not isinstance(value, str):
        raise ConfigError(key, f"expected a string, got {type(value).__name__} {value!r}")
    ns = value if value in ("", "/") or value.startswith("/") else "/" + value
    ns = "" if ns == "/" else ns.rstrip("/") if len(ns) > 1 else ns
    if not _NAMESPACE.match(ns):
        raise ConfigError(
            key,
            f"expected a ROS namespace such as '/arm1' (letters, digits, "
            f"underscores between '/'), got {value!r}",
        )
    return ns


@dataclass(frozen=True, eq=False)
class RosConfig:
    """The ROS 2 interface: topics as ros2_control exposes an arm, and the interface rate.

    The controller node subscribes to ``joint_states`` (``sensor_msgs/JointState``, as
    ros2_control's joint_state_broadcaster publishes) and publishes the torque on
    ``commands`` (``std_msgs/Float64MultiArray``, as effort_controllers'
    JointGroupEffortController takes it, in the robot's joint order). Relative names are
    resolved in the node's namespace (the defaults: ``/joint_states`` and
    ``/effort_controller/commands`` at the root, ``/arm1/joint_states`` ... under
    ``namespace = "/arm1"``, as ros2_control's controllers resolve theirs), ``~/`` names
    under the node's own name, names starting with ``/`` as they are.

    Attributes:
        joint_states: Topic of the measured state (``sensor_msgs/JointState``).
        commands: Topic of the effort command [N·m] (``std_msgs/Float64MultiArray``).
        joint_trajectory: Topic of new references (``trajectory_msgs/JointTrajectory``).
        external_torque: Topic of the disturbance estimate d̂ [N·m], published at every
            controller step as ``sensor_msgs/JointState`` (``header.stamp`` the state's
            stamp, ``name`` the joints, ``effort`` d̂).
        external_torque_type: ``"joint_state"`` (default) or ``"float64_multi_array"``
            (the message of earlier versions, ``std_msgs/Float64MultiArray`` without
            stamp or names; deprecated).
        collision: Topic of the collision flag (``std_msgs/Bool``), published at every
            controller step when ``[collision]`` is set.
        node: Name of the controller node.
        arm_node: Name of the arm node of ``hmpc-pin ros-arm``.
        namespace: Namespace of both nodes (``""``: the root; ``--namespace`` overrides).
        rate: Interface rate [Hz]: ``ros-arm`` publishes a state every ``1/rate`` s, the
            controller answers each; ``1/rate`` must divide ``controller.Ts`` (and be a
            whole number of ``plant.dt`` for ``ros-arm``). ``[realtime] rate`` does not
            apply to the ROS commands.
        discovery: ``"localhost"``, ``"subnet"``, ``"off"`` or ``"system_default"``: the
            ``ROS_AUTOMATIC_DISCOVERY_RANGE`` the commands set. Not given: the
            environment's value if set, else ``"localhost"`` (the controller and the
            arm's driver normally share a machine).
        start_timeout: How long [s] the controller waits for the first joint state.
        gravity: Who compensates gravity. ``"controller"`` (default): every command
            includes G(q) (ros2_control's effort interfaces on UR, simulated arms, the
            mock). ``"arm"``: the arm adds G(q) itself (Franka FCI, KUKA FRI torque
            overlay): no command includes it, and the held-safe command after a stop is
            zero.
        autostart: ``true`` (default): the controller node configures and activates
            itself. ``false``: it starts unconfigured, publishes nothing and waits for an
            orchestrator (a launch file's lifecycle manager, ``ros2 lifecycle set``) to
            configure and activate it; the run then starts. A deactivate ends the run
            (stop sequence, exit 130); the node does not activate again.
        qos_depth: History depth of every subscription and publisher (ros2_control's
            default: 10, ``SystemDefaultsQoS``). The joint states are all taken (merged by
            joint name), the newest answered.
        qos_reliability: ``"reliable"`` (ros2_control's default) or ``"best_effort"``:
            the trajectory messages and the published estimates. The commands are
            always published reliable (a best-effort publisher would reach no reliable
            effort controller; a reliable one reaches both kinds), and the joint states
            always subscribed best effort (it matches a reliable publisher too, and the
            arm's driver never waits for, or resends to, the controller).
    """

    joint_states: str = "joint_states"
    commands: str = "effort_controller/commands"
    joint_trajectory: str = "~/joint_trajectory"
    external_torque: str = "~/external_torque"
    collision: str = "~/collision"
    node: str = "hmpc_pin_controller"
    arm_node: str = "hmpc_pin_arm"
    namespace: str = ""
    rate: float = 1000.0
    discovery: str | None = None
    start_timeout: float = 10.0
    gravity: str = "controller"
    autostart: bool = True
    qos_depth: int = 10
    qos_reliability: str = "reliable"
    external_torque_type: str = "joint_state"

    def __post_init__(self):
        for key in ("joint_states", "commands", "joint_trajectory", "external_torque", "collision"):
            value = getattr(self, key)
            if not (isinstance(value, str) and _TOPIC.match(value)):
                raise ConfigError(
                    key,
                    f"expected a ROS topic name such as 'joint_states' or '~/{key}', got {value!r}",
                )
        for key in ("node", "arm_node"):
            value = getattr(self, key)
            if not (isinstance(value, str) and _NAME.match(value)):
                raise ConfigError(
                    key,
                    f"expected a node name (letters, digits, underscores, "
                    f"not starting with a digit), got {value!r}",
                )
        if self.node == self.arm_node:
            raise ConfigError(
                "arm_node",
                f"is the controller's name {self.node!r} too; give the two nodes different names",
            )
        _set(self, "namespace", check_namespace("namespace", self.namespace))
        _set(self, "rate", _float("rate", self.rate, positive=True))
        _set(self, "start_timeout", _float("start_timeout", self.start_timeout, positive=True))
        _set(self, "gravity", _choice("gravity", self.gravity, GRAVITY))
        _set(self, "autostart", _bool("autostart", self.autostart))
        _set(self, "qos_depth", _int("qos_depth", self.qos_depth, minimum=1))
        _set(self, "qos_reliability", _choice("qos_reliability", self.qos_reliability, RELIABILITY))
        _set(
            self,
            "external_torque_type",
            _choice("external_torque_type", self.external_torque_type, EXTERNAL_TORQUE_TYPES),
        )
        if self.external_torque_type == "float64_multi_array":
            warnings.warn(
                "ros.external_torque_type = 'float64_multi_array' is deprecated: the "
                "disturbance estimate is published as sensor_msgs/JointState (stamped, with "
                "joint names, d̂ in effort); drop the key once the subscribers read it",
                DeprecationWarning,
                stacklevel=2,
            )
        if self.discovery is not None and self.discovery not in DISCOVERY_RANGES:
            raise ConfigError(
                "discovery", f"expected one of {tuple(DISCOVERY_RANGES)}, got {self.discovery!r}"
            )

    @property
    def period(self) -> float:
        """Interface period ``1/rate`` [s]."""
        return 1.0 / self.rate
