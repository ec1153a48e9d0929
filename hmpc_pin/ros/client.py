"""The controller node from another process, with rclpy alone (no ``ros2`` command, no
sourced ROS 2): send a new reference, change its lifecycle state, read its parameters.

What ``ros2 topic pub``, ``ros2 lifecycle set`` and ``ros2 param list`` do for the node of
``hmpc-pin ros``, for an installation that has the extra ``ros`` (rclpy and the message
packages as wheels) but no ROS 2 command line. Each call starts its own rclpy context (no
signal handler), waits for the node's topic or service to be discovered, and returns one
answer.

A service's answer can be lost while DDS still matches its response writer to a client
just made (ROS 2's service-discovery race, likelier with more participants on the
graph): :meth:`RosClient.transition` therefore asks the node's state when a transition
gets no answer in time, and reports the transition done if the node is in its goal state.
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence

import numpy as np

from ..exceptions import ArmError, ConfigError
from .node import discovery_range, import_ros

__all__ = ["TRANSITIONS", "RosClient"]

#: The lifecycle transitions a user asks for, and the state each leads to.
TRANSITIONS = {
    "configure": "inactive",
    "activate": "active",
    "deactivate": "inactive",
    "cleanup": "unconfigured",
    "shutdown": "finalized",
}


class RosClient:
    """A short-lived rclpy node that talks to the controller node ``node``.

    Args:
        node: The controller's fully qualified name (``/hmpc_pin_controller``, with its
            namespace: ``/arm1/hmpc_pin_controller``).
        timeout: How long [s] to wait for discovery and for each answer.
        needed_for: What needs rclpy (for the missing-extra message).
    """

    def __init__(self, node: str, timeout: float = 10.0, needed_for: str = "hmpc-pin ros"):
        self.msgs = import_ros(needed_for)
        rclpy = self.msgs["rclpy"]
        os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = discovery_range(None)
        self.target = node if node.startswith("/") else "/" + node
        self.timeout = float(timeout)
        self.context = rclpy.context.Context()
        rclpy.init(
            context=self.context, signal_handler_options=rclpy.signals.SignalHandlerOptions.NO
        )
        self.node = rclpy.create_node(f"hmpc_pin_client_{os.getpid()}", context=self.context)
        from rclpy.executors import SingleThreadedExecutor

        self._executor = SingleThreadedExecutor(context=self.context)
        self._executor.add_node(self.node)

    def __enter__(self) -> RosClient:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Destroy the node, shut the context down."""
        self._executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        self.context.try_shutdown()

    # ---------------------------------------------------------------- services
    def _call(self, srv_type, name: str, request):
        """``request`` to the service ``name`` of the node; ``None``: no answer in time.

        Raises:
            ArmError: The service was not discovered within the timeout.
        """
        client = self.node.create_client(srv_type, f"{self.target}/{name}")
        if not client.wait_for_service(timeout_sec=self.timeout):
            raise ArmError(
                f"no service {self.target}/{name} within {self.timeout:g} s: is `hmpc-pin "
                "ros` running, with this node name and namespace, on this host (or in "
                "ROS_AUTOMATIC_DISCOVERY_RANGE)?"
            )
        future = client.call_async(request)
        self._executor.spin_until_future_complete(future, timeout_sec=self.timeout)
        return future.result() if future.done() else None

    def state(self) -> str | None:
        """The node's lifecycle state (``unconfigured``, ``inactive``, ``active``,
        ``finalized``); ``None``: no answer."""
        from lifecycle_msgs.srv import GetState

        res = self._call(GetState, "get_state", GetState.Request())
        return None if res is None else str(res.current_state.label)

    def transition(self, name: str) -> tuple[bool, str]:
        """Ask for the lifecycle transition ``name`` (a key of :data:`TRANSITIONS`).

        Returns:
            ``(done, line)``: whether the node is now in the transition's goal state, and
            one line saying so (or why not).
        """
        from lifecycle_msgs.msg import Transition
        from lifecycle_msgs.srv import ChangeState

        goal = TRANSITIONS[name]
        req = ChangeState.Request()
        req.transition.id = getattr(Transition, f"TRANSITION_{name.upper()}")
        if name == "shutdown":  # from whichever state the node is in
            now = self.state()
            which = {"unconfigured": "UNCONFIGURED", "inactive": "INACTIVE"}.get(
                now or "", "ACTIVE"
            )
            req.transition.id = getattr(Transition, f"TRANSITION_{which}_SHUTDOWN")
        res = self._call(ChangeState, "change_state", req)
        if res is not None and res.success:
            return True, f"{self.target}: {name} done, now {goal}"
        now = self.state()  # an answer lost, or refused: what the node says now
        if now == goal:
            return True, f"{self.target}: {name} done, now {goal}"
        why = "no answer" if res is None else "refused"
        return False, (
            f"{self.target}: {name} {why} (the node is {now or 'not answering'}; "
            f"{name} leads to {goal})"
        )

    def parameters(self, names: Sequence[str] = ()) -> dict:
        """``{name: value}`` of the node's parameters (all of them without ``names``).

        Raises:
            ArmError: No answer within the timeout.
            ConfigError: A name the node does not have (named).
        """
        from rcl_interfaces.srv import GetParameters, ListParameters

        res = self._call(ListParameters, "list_parameters", ListParameters.Request())
        if res is None:
            raise ArmError(f"{self.target}: no answer to list_parameters")
        known = sorted(res.result.names)
        unknown = [x for x in names if x not in known]
        if unknown:
            raise ConfigError(
                unknown[0], f"{self.target} has no such parameter; it has {', '.join(known)}"
            )
        names = list(names) or known
        req = GetParameters.Request()
        req.names = names
        res = self._call(GetParameters, "get_parameters", req)
        if res is None or len(res.values) != len(names):
            raise ArmError(f"{self.target}: no answer to get_parameters")
        return {name: _value(v) for name, v in zip(names, res.values, strict=True)}

    # ---------------------------------------------------------------- topics
    def send_trajectory(
        self, joint_names: Sequence[str], times, positions, velocities=None, topic=None
    ) -> str:
        """Publish a ``trajectory_msgs/JointTrajectory`` to the node's
        ``~/joint_trajectory`` (or ``topic``) once a subscriber is matched, and wait until
        it is delivered.

        Args:
            joint_names: The joints, in the order of the columns.
            times: ``time_from_start`` of each point [s], (m,).
            positions: (m, n) [rad]. velocities: (m, n) [rad/s] or ``None``.

        Returns:
            The topic it was sent on.

        Raises:
            ArmError: No subscriber within the timeout.
        """
        msgs = self.msgs["trajectory_msgs"]
        topic = topic or f"{self.target}/joint_trajectory"
        pub = self.node.create_publisher(msgs.JointTrajectory, topic, 10)
        end = time.monotonic() + self.timeout
        while pub.get_subscription_count() == 0:
            if time.monotonic() > end:
                raise ArmError(
                    f"no subscriber on {topic} within {self.timeout:g} s: is `hmpc-pin ros` "
                    "running, with this node name and namespace?"
                )
            time.sleep(0.05)
        time.sleep(0.3)  # (discovery completes both ways: the first message is not lost)
        msg = msgs.JointTrajectory()
        msg.joint_names = list(joint_names)
        q = np.atleast_2d(np.asarray(positions, dtype=float))
        dq = None if velocities is None else np.atleast_2d(np.asarray(velocities, dtype=float))
        points = []
        for k, t in enumerate(np.atleast_1d(np.asarray(times, dtype=float))):
            p = msgs.JointTrajectoryPoint()
            p.positions = [float(x) for x in q[k]]
            if dq is not None:
                p.velocities = [float(x) for x in dq[k]]
            ns = round(float(t) * 1e9)
            p.time_from_start.sec, p.time_from_start.nanosec = divmod(ns, 1_000_000_000)
            points.append(p)
        msg.points = points
        pub.publish(msg)
        pub.wait_for_all_acked(self.msgs["rclpy"].duration.Duration(seconds=self.timeout))
        return topic


def _value(v):
    """An ``rcl_interfaces/ParameterValue`` as a Python value."""
    kinds = {
        1: "bool_value",
        2: "integer_value",
        3: "double_value",
        4: "string_value",
        5: "byte_array_value",
        6: "bool_array_value",
        7: "integer_array_value",
        8: "double_array_value",
        9: "string_array_value",
    }
    value = getattr(v, kinds[v.type])
    return list(value) if v.type >= 5 else value
