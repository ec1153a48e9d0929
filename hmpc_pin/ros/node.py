"""rclpy brought up for one node: the extra checked, discovery limited, the middleware's
settings applied where the user has not set them (:mod:`.middleware`), no signal handler,
messages taken in the caller's thread.

rclpy installs its own SIGINT handler (which shuts the context down); the nodes here
start rclpy without it, so that Ctrl-C reaches the real-time loop's safe stop.

No executor: the loop waits on a wait set of its subscriptions and takes the messages
itself (:meth:`RosNode.take`, :meth:`RosNode.waiter`), in its own thread. rclpy's Python
executor costs hundreds of µs per callback and, spun in a second thread, hands the GIL
back and forth at every state; taken directly a state costs tens of µs.
"""

from __future__ import annotations

import contextlib
import os
import threading
from collections.abc import Callable
from types import ModuleType

from ..exceptions import ConfigError, ExtraError
from .middleware import apply_middleware_defaults

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
    return {
        "rclpy": rclpy,
        "sensor_msgs": sensor_msgs,
        "std_msgs": std_msgs,
        "trajectory_msgs": trajectory_msgs,
    }


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

    The node is a lifecycle node (``rclpy.lifecycle``; its ``change_state`` and
    ``get_state`` services answered once :meth:`serve` runs): it configures and activates
    itself at :meth:`serve`, or waits for an orchestrator to (``serve(activate=False)``,
    :meth:`wait_active`); ``deactivate`` (or ``shutdown``) from an orchestrator calls
    the function given to :meth:`on_deactivate` (the controller's stop sequence) and
    returns when it has run. Parameters given here are declared read-only with the
    config's values (``ros2 param list``); a ``--ros-args -p`` override of one of them
    that differs from the config is refused (set it in the config file).

    Args:
        name: Node name.
        namespace: Node namespace (``""``: the root).
        discovery: ``ROS_AUTOMATIC_DISCOVERY_RANGE`` set before rclpy starts.
        needed_for: What needs rclpy (for the missing-extra message).
        ros_args: Arguments after ``--ros-args`` (remaps ``-r``, ``__ns``, ``__node``,
            ``-p use_sim_time:=true``, ...), given to rclpy.
        parameters: ``{name: value}`` declared read-only on the node.

    Attributes:
        node: The ``rclpy`` node.
        msgs: The modules of :func:`import_ros`.
        middleware: The environment variables set before rclpy started
            (:func:`~hmpc_pin.ros.middleware.apply_middleware_defaults`; those the user
            had set are not in it).
    """

    def __init__(
        self,
        name: str,
        namespace: str,
        discovery: str,
        needed_for: str,
        ros_args: list[str] | None = None,
        parameters: dict | None = None,
    ):
        self.msgs = import_ros(needed_for)
        rclpy = self.msgs["rclpy"]
        os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = discovery
        self.middleware = apply_middleware_defaults(os.environ)
        self.context = rclpy.context.Context()
        args = ["hmpc-pin", "--ros-args", *ros_args] if ros_args else None
        try:
            rclpy.init(
                args=args,
                context=self.context,
                signal_handler_options=rclpy.signals.SignalHandlerOptions.NO,
            )
        except Exception as exc:  # rcl's RCLInvalidROSArgsError, ...
            raise ConfigError(
                "--ros-args",
                f"rclpy refused {ros_args} ({exc}); expected ROS 2 "
                "arguments such as -r from:=to, -r __ns:=/arm1, -p "
                "use_sim_time:=true",
            ) from None
        self._deactivate: tuple[Callable, tuple] | None = None
        self._active = threading.Event()  # set on activate (and on a shutdown before it)
        self._shut_down = False
        self._transition_lock = threading.Lock()  # on_deactivate against the transition
        #: Whether the node was deactivated or shut down (the run does not start again).
        self.deactivated = False
        self._executor = None
        self._thread = None
        try:
            self.node = _lifecycle_node(self, name, namespace)
        except Exception as exc:  # rclpy's InvalidNodeNameException, ...
            self.context.try_shutdown()
            raise ConfigError(
                "ros.node", f"rclpy refused the node {name!r} in namespace {namespace!r}: {exc}"
            ) from None
        self._closed = False
        from rclpy.callback_groups import CallbackGroup

        class _Manual(CallbackGroup):
            """Subscriptions whose messages the caller takes: never an executor's."""

            def can_execute(self, entity) -> bool:
                return False

            def beginning_execution(self, entity) -> bool:
                return False

            def ending_execution(self, entity) -> None:
                pass

        self._manual = _Manual()
        if parameters:
            self._declare(parameters)
            self._refuse_undeclared(parameters)

    def _declare(self, parameters: dict) -> None:
        from rcl_interfaces.msg import ParameterDescriptor

        for key, value in parameters.items():
            try:
                got = self.node.declare_parameter(
                    key, value, ParameterDescriptor(read_only=True, description="from the config")
                ).value
            except Exception as exc:  # an override of another type (rclpy's exceptions)
                self.close()
                raise ConfigError(
                    key,
                    f"--ros-args sets it to a value of another type than "
                    f"the config's {value!r} ({exc}); set it in the config "
                    "file",
                ) from None
            if got != value and not (isinstance(value, list) and list(got) == value):
                self.close()
                raise ConfigError(
                    key,
                    f"--ros-args sets {got!r} but the config has {value!r}; the node's "
                    "parameters mirror the config: set it in the config file",
                )

    def _refuse_undeclared(self, parameters: dict) -> None:
        """A ``--ros-args -p`` of a name in one of the declared tables (``ros.*``,
        ``realtime.*``, ...) that is not declared would be ignored by rclpy: refuse it."""
        tables = {key.split(".")[0] for key in parameters if "." in key}
        overrides = getattr(self.node, "_parameter_overrides", None) or {}
        for name in overrides:
            if name not in parameters and name.split(".")[0] in tables:
                self.close()
                raise ConfigError(
                    name,
                    "--ros-args sets it, but the node has no such parameter (its "
                    "parameters mirror the config: `ros2 param list` shows them); set the "
                    "config file's key instead",
                )

    def serve(self, activate: bool = True) -> None:
        """Answer the node's services (parameters, lifecycle, ``/clock`` with
        ``use_sim_time``) in a thread of their own; the subscriptions of :meth:`subscribe`
        stay the caller's.

        Args:
            activate: Configure and activate the lifecycle node now (``False``: it stays
                unconfigured until an orchestrator configures and activates it;
                :meth:`wait_active` waits for that).
        """
        from rclpy.executors import SingleThreadedExecutor

        if activate:
            self.node.trigger_configure()
            self.node.trigger_activate()
        self._executor = SingleThreadedExecutor(context=self.context)
        self._executor.add_node(self.node)
        self._thread = threading.Thread(target=self._spin, name="ros_services", daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        with contextlib.suppress(Exception):  # the context shut down under it
            self._executor.spin()  # type: ignore[union-attr]

    def wait_active(self) -> bool:
        """Block until the node is activated (True) or shut down before (False); Ctrl-C
        raises ``KeyboardInterrupt`` meanwhile."""
        while not self._active.wait(0.1):
            pass
        return not self._shut_down

    def on_deactivate(self, stop: Callable, *args) -> None:
        """Call ``stop(*args)`` when the node is deactivated or shut down (from the
        services' thread); it returns when the stop sequence has run. Deactivated
        already (before this call): ``stop(*args)`` is called now."""
        with self._transition_lock:
            fire = self.deactivated
            self._deactivate = None if fire else (stop, args)
        if fire:
            stop(*args)

    def _transition_stop(self) -> None:
        with self._transition_lock:
            self.deactivated = True
            pending, self._deactivate = self._deactivate, None
        if pending is not None:
            stop, args = pending
            stop(*args)

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

    def subscribe(self, msg_type, topic: str, qos, raw: bool = False):
        """A subscription whose messages are taken with :meth:`take` (no callback; no
        executor takes them); ``raw``: taken as their serialized bytes (CDR, no
        conversion to a Python message)."""
        return self.node.create_subscription(
            msg_type, topic, _never, qos, callback_group=self._manual, raw=raw
        )

    @staticmethod
    def take(sub) -> list:
        """The messages waiting on ``sub``, oldest first (does not block)."""
        out = []
        with sub.handle:
            while (taken := sub.handle.take_message(sub.msg_type, sub.raw)) is not None:
                out.append(taken[0])
        return out

    @staticmethod
    def take_with_time(sub) -> list:
        """``(message, received [s])`` for each message waiting on ``sub``, oldest first:
        ``received`` is the middleware's reception time on the system clock (0 where the
        middleware does not give it)."""
        out = []
        with sub.handle:
            while (taken := sub.handle.take_message(sub.msg_type, sub.raw)) is not None:
                msg, info = taken
                received = info.get("received_timestamp", 0) if isinstance(info, dict) else 0
                out.append((msg, 1e-9 * received))
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
        self._deactivate = None
        if self._executor is not None:
            self._executor.shutdown(timeout_sec=5.0)
        if self._thread is not None:
            # the services' thread ends once the callback in flight has returned and its
            # answer is sent (deactivate's, after the stop sequence it waited for): the node
            # is destroyed only then (destroyed under it, the transition fails to complete
            # and the orchestrator gets no answer)
            self._thread.join(timeout=5.0)
        self.node.destroy_node()
        self.context.try_shutdown()


def _lifecycle_node(owner: RosNode, name: str, namespace: str):
    """A ``rclpy.lifecycle.LifecycleNode`` whose deactivate and shutdown run the owner's
    stop (:meth:`RosNode.on_deactivate`)."""
    from rclpy.lifecycle import LifecycleNode, TransitionCallbackReturn

    class _Node(LifecycleNode):
        def on_activate(self, state):
            if owner.deactivated:  # the run has stopped: it does not start again
                return TransitionCallbackReturn.FAILURE
            owner._active.set()
            return super().on_activate(state)

        def on_deactivate(self, state):
            owner._transition_stop()
            return TransitionCallbackReturn.SUCCESS

        def on_shutdown(self, state):
            owner._shut_down = not owner._active.is_set()
            owner._active.set()
            owner._transition_stop()
            return TransitionCallbackReturn.SUCCESS

    return _Node(name, namespace=namespace or None, context=owner.context)


def _never(msg) -> None:  # pragma: no cover - messages are taken, never dispatched
    """The callback rclpy requires of a subscription; no executor calls it."""
