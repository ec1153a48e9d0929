"""rclpy brought up for one node: the extra checked, discovery limited, no signal handler,
the executor spinning in a background thread.

rclpy installs its own SIGINT handler (which shuts the context down); the nodes here
start rclpy without it, so that Ctrl-C reaches the real-time loop's safe stop.
"""

from __future__ import annotations

import os
import threading
from types import ModuleType

from ..exceptions import ConfigError, ExtraError

__all__ = ["RosNode", "discovery_range", "import_ros"]


def import_ros(needed_for: str) -> dict[str, ModuleType]:
    """rclpy and the message packages, or :class:`~hmpc_pin.exceptions.ExtraError` naming
    the extra ``ros`` (a ROS 2 installation's rclpy, sourced, works the same)."""
    try:
        import rclpy
        import rclpy.executors
        import rclpy.qos
        import rclpy.signals
        from sensor_msgs import msg as sensor_msgs
        from std_msgs import msg as std_msgs
        from trajectory_msgs import msg as trajectory_msgs
    except ImportError as exc:
        raise ExtraError("ros", f"{needed_for} (rclpy and the message packages: {exc})") from exc
    return {"rclpy": rclpy, "sensor_msgs": sensor_msgs, "std_msgs": std_msgs,
            "trajectory_msgs": trajectory_msgs}  # fmt: skip


def discovery_range(configured: str | None, environ=os.environ) -> str:
    """The ``ROS_AUTOMATIC_DISCOVERY_RANGE`` to run with: ``[ros] discovery`` if given,
    else the environment's, else ``LOCALHOST``."""
    from ..experiment.config.ros import DISCOVERY_RANGES

    if configured is not None:
        return DISCOVERY_RANGES[configured]
    value = environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "")
    return value if value else "LOCALHOST"


class RosNode:
    """One rclpy context and node, its executor spun by a daemon thread.

    Args:
        name: Node name.
        namespace: Node namespace (``""``: the root).
        discovery: ``ROS_AUTOMATIC_DISCOVERY_RANGE`` set before rclpy starts.
        needed_for: What needs rclpy (for the missing-extra message).

    Attributes:
        node: The ``rclpy.node.Node``.
        msgs: The modules of :func:`import_ros`.
    """

    def __init__(self, name: str, namespace: str, discovery: str, needed_for: str):
        self.msgs = import_ros(needed_for)
        rclpy = self.msgs["rclpy"]
        os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = discovery
        self.context = rclpy.context.Context()
        rclpy.init(context=self.context,
                   signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)  # fmt: skip
        try:
            self.node = rclpy.create_node(name, namespace=namespace or None,
                                          context=self.context)  # fmt: skip
        except Exception as exc:  # rclpy's InvalidNodeNameException, ...
            self.context.try_shutdown()
            raise ConfigError("ros.node", f"rclpy refused the node {name!r} in namespace "
                              f"{namespace!r}: {exc}") from None  # fmt: skip
        self.executor = rclpy.executors.SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._thread: threading.Thread | None = None
        self._closed = False

    def qos(self, depth: int = 10, reliable: bool = True):
        """A keep-last QoS profile (best effort subscribes to both kinds of publisher)."""
        q = self.msgs["rclpy"].qos
        policy = q.ReliabilityPolicy
        return q.QoSProfile(
            depth=depth, reliability=policy.RELIABLE if reliable else policy.BEST_EFFORT
        )

    def topic(self, name: str) -> str:
        """``name`` resolved as the node resolves it (``~/x`` under the node's name)."""
        try:
            return self.node.resolve_topic_name(name)
        except Exception:  # an rclpy without resolve_topic_name
            if name.startswith("~/"):
                return self.node.get_fully_qualified_name() + name[1:]
            if name.startswith("/"):
                return name
            ns = self.node.get_namespace().rstrip("/")
            return f"{ns}/{name}"

    def start(self) -> None:
        """Spin the executor in a daemon thread (callbacks run there)."""
        self._thread = threading.Thread(target=self._spin, name="hmpc-pin-ros", daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        ExternalShutdown = self.msgs["rclpy"].executors.ExternalShutdownException
        try:
            self.executor.spin()
        except ExternalShutdown:
            pass
        except Exception:
            if not self._closed:
                raise

    def close(self) -> None:
        """Stop spinning, destroy the node, shut the context down (idempotent)."""
        if self._closed:
            return
        self._closed = True
        self.executor.shutdown(timeout_sec=1.0)
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        self.node.destroy_node()
        self.context.try_shutdown()
