"""An arm as ros2_control exposes it, seen by the real-time loop: a
:class:`~hmpc_pin.realtime.interface.PacedInterface` over two topics.

* states: ``sensor_msgs/JointState`` on ``/joint_states`` (joint_state_broadcaster),
  matched to the robot's joints by name (any order, extra joints ignored); a message
  without velocities is read as non-finite (a fault: the controller needs q̇);
* torque: ``std_msgs/Float64MultiArray`` on ``/effort_controller/commands``
  (effort_controllers' JointGroupEffortController), in the robot's joint order.

Stamps are the messages' ``header.stamp`` on the system clock, shifted to start near 0;
a driver that leaves the stamp at zero, or stamps on another clock (simulated time,
more than 1 s from the wall when the first state arrives), is timed from each state's
arrival instead (``stamps`` says which).
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np

from ..exceptions import ArmError
from .node import RosNode

__all__ = ["RosArmInterface"]


class RosArmInterface:
    """Joint states in, effort commands out (module doc); paces the loop.

    Args:
        ros: The controller's :class:`~hmpc_pin.ros.node.RosNode`; its messages are taken
            in :meth:`wait`, in the loop's thread.
        joint_names: The robot's joints, in the order of ``q`` and of the command.
        period: The interface period [s] the arm publishes at.
        joint_states, commands: Topic names.
        start_timeout: How long [s] :meth:`start` waits for the first state.

    Attributes:
        stamps: ``"header"`` or ``"arrival"`` (module doc), set by :meth:`start`.
        received: Joint-state messages received.
        published: Commands published.
    """

    def __init__(
        self,
        ros: RosNode,
        joint_names: Sequence[str],
        period: float,
        joint_states: str,
        commands: str,
        start_timeout: float = 10.0,
    ):
        self.ros = ros
        self.names = tuple(joint_names)
        self.nq = n = len(self.names)
        self.period = float(period)
        self.start_timeout = start_timeout
        self.joint_states_topic = ros.topic(joint_states)
        self.commands_topic = ros.topic(commands)
        std = ros.msgs["std_msgs"]
        self._cmd = std.Float64MultiArray()
        self._pub = ros.node.create_publisher(std.Float64MultiArray, commands, ros.qos(10))
        self._sub = ros.subscribe(ros.msgs["sensor_msgs"].JointState, joint_states,
                                  ros.qos(1, reliable=False))  # the newest state only  # fmt: skip
        self._others: list[tuple[object, object]] = []
        self._wait = ros.waiter([self._sub])
        self._arrived = 0
        self._latest: tuple[float, np.ndarray, np.ndarray] | None = None
        self._seen_names: list[str] | None = None
        self._index: np.ndarray | None = None
        self._missing: list[str] = []
        self._origin = 0.0
        self._arrival = False
        self.stamps = "header"
        self.received = 0
        self.published = 0
        self._stamp = 0.0
        self._q, self._dq = np.zeros(n), np.zeros(n)

    def add_subscription(self, msg_type, topic: str, callback, qos) -> str:
        """Take ``topic``'s messages in :meth:`wait` too, calling ``callback(msg)`` in the
        loop's thread (between states); returns the resolved topic name."""
        sub = self.ros.subscribe(msg_type, topic, qos)
        self._others.append((sub, callback))
        self._wait = self.ros.waiter([self._sub] + [s for s, _ in self._others])
        return self.ros.topic(topic)

    def _poll(self) -> None:
        """Take what has arrived: the states (newest last), then the other topics."""
        take = self.ros.take
        for msg in take(self._sub):
            self._on_state(msg)
        for sub, callback in self._others:
            for msg in take(sub):
                callback(msg)

    def _on_state(self, msg) -> None:
        now = time.time()
        names = msg.name
        if names != self._seen_names:
            self._seen_names = list(names)
            where = {name: i for i, name in enumerate(names)}
            self._missing = [name for name in self.names if name not in where]
            self._index = None if self._missing else np.array([where[x] for x in self.names])
        n = self.nq
        if self._index is None:
            q = dq = np.full(n, np.nan)
        else:
            pos = np.asarray(msg.position, dtype=float)
            vel = np.asarray(msg.velocity, dtype=float)
            q = pos[self._index] if pos.size == len(names) else np.full(n, np.nan)
            dq = vel[self._index] if vel.size == len(names) else np.full(n, np.nan)
        st = msg.header.stamp
        stamp = st.sec + 1e-9 * st.nanosec
        if self.received == 0:
            # the first state decides the time base (module doc)
            self._arrival = stamp == 0.0 or abs(stamp - now) > 1.0
            self.stamps = "arrival" if self._arrival else "header"
            self._origin = float(int(now))
        stamp = (now if self._arrival or stamp == 0.0 else stamp) - self._origin
        if self._latest is not None:  # periods since the previous state (>= 1)
            self._arrived += max(1, round((stamp - self._latest[0]) / self.period))
        else:
            self._arrived += 1
        self._latest = (stamp, q, dq)
        self.received += 1

    # -------------------------------------------------------------- the loop's side
    def start(self) -> None:
        """Wait for the first state (spinning the node in this thread): its joints must
        cover the robot's.

        Raises:
            ArmError: No state within ``start_timeout``, or one without some of
                the robot's joints or without positions and velocities for each.
        """
        end = time.monotonic() + self.start_timeout
        while self._latest is None and time.monotonic() < end:
            self._wait(min(0.1, max(0.0, end - time.monotonic())))
            self._poll()
        if self._latest is None:
            raise ArmError(
                f"no sensor_msgs/JointState on {self.joint_states_topic} within "
                f"{self.start_timeout:g} s (ros.start_timeout); start the arm's driver "
                "(or `hmpc-pin ros-arm CONFIG`) and check ros.joint_states and the "
                "namespace"
            )
        if self._missing:
            raise ArmError(
                f"the joint states on {self.joint_states_topic} name "
                f"{self._seen_names} but not the robot's joints {self._missing}; "
                "expected every controlled joint (lock the others in [robot])"
            )
        _, q, dq = self._latest  # type: ignore[misc]
        if not (np.isfinite(q).all() and np.isfinite(dq).all()):
            raise ArmError(
                f"the joint states on {self.joint_states_topic} carry no finite position "
                "and velocity for every joint; the controller needs both"
            )
        self.wait(0.0)

    def clock(self) -> float:
        """Now [s] on the stamps' clock (the system clock shifted as the stamps are)."""
        return time.time() - self._origin

    def wait(self, timeout: float) -> int:
        """Block until a new state arrives or ``timeout`` [s] (messages of the other
        subscriptions are handled here too); take the newest and return how many
        interface periods its stamp is after the previous one taken."""
        self._poll()
        if not self._arrived:
            end = time.monotonic() + timeout
            while not self._arrived and (remaining := end - time.monotonic()) > 0:
                self._wait(remaining)
                self._poll()
        count, self._arrived = self._arrived, 0
        if count:
            self._stamp, q, dq = self._latest  # type: ignore[misc]
            self._q[:] = q
            self._dq[:] = dq
        return count

    def read(self) -> tuple[float, np.ndarray, np.ndarray]:
        """The state taken by the last :meth:`wait`: ``(stamp [s], q, dq)``."""
        return self._stamp, self._q, self._dq

    def write(self, tau: np.ndarray) -> None:
        """Publish ``tau`` [N·m] on the command topic (robot joint order)."""
        self._cmd.data = np.asarray(tau, dtype=float).tolist()
        self._pub.publish(self._cmd)
        self.published += 1

    def close(self) -> None:
        """Stop the node (idempotent)."""
        self.ros.close()
