"""rclpy brought up for one node: the extra checked, discovery limited, no signal handler,
messages taken in the caller's thread.

rclpy installs its own SIGINT handler (which shuts the context down); the nodes here
start rclpy without it, so that Ctrl-C reaches the real-time loop's safe stop.

No executor: the loop waits on a wait set of its subscriptions and takes the messages
itself (:meth:`RosNode.take`, :meth:`RosNode.waiter`), in its own thread. rclpy's Python
executor costs hundreds of µs per callback and, spun in a second thread, hands the GIL
back and forth at every state; taken directly a state costs tens of µs.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from types import ModuleType

from ..exceptions import ConfigError, ExtraError

__all__ = ["RosNode", "discovery_range", "import_ros"]


def import_ros(needed_for: str) -> dict[str, ModuleType]:
    """rclpy and the message packages, or :class:`~hmpc_pin.exceptions.ExtraError` naming
    the extra ``ros`` (a ROS 2 installation's rclpy, sourced, works the same)."""
    try:
        import rclpy
        import rclpy.impl.implementation_singleton
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
    """One rclpy context and node; messages taken by the caller (module doc).

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

    def subscribe(self, msg_type, topic: str, qos):
        """A subscription whose messages are taken with :meth:`take` (no callback)."""
        return self.node.create_subscription(msg_type, topic, _never, qos)

    @staticmethod
    def take(sub) -> list:
        """The messages waiting on ``sub``, oldest first (does not block)."""
        out = []
        with sub.handle:
            while (taken := sub.handle.take_message(sub.msg_type, sub.raw)) is not None:
                out.append(taken[0])
        return out

    def waiter(self, subs) -> Callable[[float], None]:
        """``wait(timeout)``: block until one of ``subs`` has a message or ``timeout`` [s]
        (the GIL released meanwhile)."""
        impl = self.msgs["rclpy"].impl.implementation_singleton.rclpy_implementation
        wait_set = impl.WaitSet(len(subs), 0, 0, 0, 0, 0, self.context.handle)
        handles = [sub.handle for sub in subs]

        def wait(timeout: float) -> None:
            wait_set.clear_entities()
            for handle in handles:
                wait_set.add_subscription(handle)
            wait_set.wait(max(0, int(timeout * 1e9)))

        return wait

    def close(self) -> None:
        """Stop spinning, destroy the node, shut the context down (idempotent)."""
        if self._closed:
            return
        self._closed = True
        self.node.destroy_node()
        self.context.try_shutdown()


def _never(msg) -> None:  # pragma: no cover - messages are taken, never dispatched
    """The callback rclpy requires of a subscription; no executor calls it."""
