"""An arm as ros2_control exposes it, seen by the real-time loop: a
:class:`~hmpc_pin.realtime.interface.PacedInterface` over two topics.

* states: ``sensor_msgs/JointState`` on ``/joint_states`` (joint_state_broadcaster),
  **merged by joint name**: each message updates the controlled joints it names (any
  order; other joints ignored); a message that names none of them (a gripper's driver, a
  second broadcaster, joint_state_publisher) is ignored and is not a period; a state is
  complete — one period — when every controlled joint has been updated since the last
  one (one message from a broadcaster that publishes them all). A message without
  positions or velocities for its joints gives non-finite values (a fault: the controller
  needs both);
* torque: ``std_msgs/Float64MultiArray`` on ``/effort_controller/commands``
  (effort_controllers' JointGroupEffortController), in the robot's joint order.

The states are taken serialized and read from their CDR bytes (:mod:`.cdr`; rclpy's
deserialisation for any other encoding): no Python message is built per state.

Time: stamps are the messages' ``header.stamp`` on the system clock, shifted to start
near 0; a driver that leaves the stamp at zero, or stamps on another clock (more than 1 s
from the wall when the first state arrives), is timed from each state's arrival instead
(``stamps`` says which: ``"header"``, ``"arrival"``).

**Simulated time** (the node's ``use_sim_time`` parameter, ``--ros-args -p
use_sim_time:=true``): the loop runs on the simulator's clock. The interface takes
``/clock`` (``rosgraph_msgs/Clock``) itself, with the states, and :meth:`~RosArmInterface.clock`
is the newest ``/clock`` time; the states are timed by their ``header.stamp`` on that
clock (``stamps = "simulated"``; a zero stamp: the ``/clock`` time it arrived at), each
state's arrival is its stamp (the simulator publishes the period's ``/clock`` and its
state together), and a state not answered before ``/clock`` has moved a period past it is
overdue. The periods counted, the run's duration and its latencies are then simulated
time, whatever the real-time factor (latencies quantised to ``/clock``'s period); the
watchdog stays wall-clock time (a simulator that stops publishing is gone).

Each state also has its **arrival** time (the middleware's reception time stamp, else
the time it was taken), on the same clock: the loop's deadline for a state is its
arrival plus a period, so a constant transport delay is no miss; the stamp-to-command
latency is measured apart (``stats["measured_latency"]``).
:meth:`RosArmInterface.wait` returns the periods elapsed by the stamps (the loop's time
follows the arm's) and sets ``overdue``, the states among them the loop failed to
answer in time (taken more than a period after they arrived); a burst after a stall of
the arm is not the loop's miss.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Sequence

import numpy as np

from ..exceptions import ArmError
from .cdr import JointStateReader
from .node import RosNode

__all__ = ["JointStateMerger", "RosArmInterface"]


class JointStateMerger:
    """Joint states merged by name into the robot's order (module doc); no rclpy needed.

    Args:
        joint_names: The controlled joints, in the order of ``q``.

    Attributes:
        q, dq: The merged state [rad, rad/s], (n,) (NaN until a joint is named).
        seen: Whether each joint has been named at least once.
        ignored: Messages that named none of the controlled joints.
    """

    def __init__(self, joint_names: Sequence[str]):
        self.names = tuple(joint_names)
        n = len(self.names)
        self.q, self.dq = np.full(n, np.nan), np.full(n, np.nan)
        self.seen = np.zeros(n, dtype=bool)
        self._fresh = np.zeros(n, dtype=bool)
        self._key: list[str] | None = None
        self._src = self._dst = np.zeros(0, dtype=int)
        self.other_names: list[str] = []
        self.ignored = 0

    def add(self, names, position, velocity) -> bool:
        """Merge one message; True when it completes a state (every controlled joint
        updated since the last complete one)."""
        if names != self._key:
            self._key = list(names)
            where = {name: i for i, name in enumerate(self._key)}
            pairs = [(where[x], j) for j, x in enumerate(self.names) if x in where]
            self._src = np.array([a for a, _ in pairs], dtype=int)
            self._dst = np.array([b for _, b in pairs], dtype=int)
        if self._dst.size == 0:
            self.ignored += 1
            self.other_names = list(names)
            return False
        m = len(self._key)
        pos = np.asarray(position, dtype=float)
        vel = np.asarray(velocity, dtype=float)
        self.q[self._dst] = pos[self._src] if pos.size == m else np.nan
        self.dq[self._dst] = vel[self._src] if vel.size == m else np.nan
        self.seen[self._dst] = True
        self._fresh[self._dst] = True
        if not self._fresh.all():
            return False
        self._fresh[:] = False
        return True

    @property
    def missing(self) -> list[str]:
        """The controlled joints no message has named yet."""
        return [x for x, s in zip(self.names, self.seen, strict=True) if not s]


class RosArmInterface:
    """Joint states in, effort commands out (module doc); paces the loop.

    Args:
        ros: The controller's :class:`~hmpc_pin.ros.node.RosNode`; its messages are taken
            in :meth:`wait`, in the loop's thread.
        joint_names: The robot's joints, in the order of ``q`` and of the command.
        period: The interface period [s] the arm publishes at.
        joint_states, commands: Topic names.
        start_timeout: How long [s] :meth:`start` waits for the first state.
        qos: The QoS profile whose depth the topics take (default: keep-last 10). The
            commands are always published reliable, whatever its reliability: a reliable
            publisher reaches a reliable subscriber (ros2_control's effort controller) and
            a best-effort one alike, where a best-effort publisher reaches no reliable
            controller. The joint states are subscribed best effort.

    Attributes:
        stamps: ``"header"``, ``"arrival"`` or ``"simulated"`` (module doc), set by
            :meth:`start`.
        sim_time: Whether the node runs on ``/clock`` (its ``use_sim_time``).
        gaps: Periods the stamps advanced by with no state for them (a state lost on
            the way, an arm slower than ``period``, a clock not the arm's). Periods
            whose states the subscription's full queue dropped (the loop too slow to
            take them) are not gaps: they count as ``overdue``.
        received: Complete joint states received (periods).
        published: Commands published.
        arrival: When the state taken by the last :meth:`wait` arrived [s], on
            :meth:`clock`.
        overdue: How many of the periods the last :meth:`wait` returned arrived more than
            a period before it (states not answered in time: misses).
    """

    def __init__(
        self,
        ros: RosNode,
        joint_names: Sequence[str],
        period: float,
        joint_states: str,
        commands: str,
        start_timeout: float = 10.0,
        qos=None,
    ):
        self.ros = ros
        self.names = tuple(joint_names)
        self.nq = n = len(self.names)
        self.period = float(period)
        self.start_timeout = start_timeout
        self.joint_states_topic = ros.topic(joint_states)
        self.commands_topic = ros.topic(commands)
        depth = getattr(qos, "depth", 10) if qos is not None else 10
        std = ros.msgs["std_msgs"]
        self._cmd = std.Float64MultiArray()
        self._pub = ros.node.create_publisher(
            std.Float64MultiArray, commands, ros.qos(depth, reliable=True)
        )
        # every state taken (merged by name), the newest answered; best effort (matches a
        # reliable publisher too): the arm's driver never waits for, or resends to, the
        # controller
        state_qos = ros.qos(depth, reliable=False)
        # taken serialized and read by JointStateReader (no Python message built per state)
        self._state_type = ros.msgs["sensor_msgs"].JointState
        self._sub = ros.subscribe(self._state_type, joint_states, state_qos, raw=True)
        self._read_state = JointStateReader()
        self._others: list[tuple[object, object]] = []
        self.sim_time = _uses_sim_time(ros.node)
        self._sim_now = math.nan  # the newest /clock time [s] (simulated time)
        self._clock_sub = None
        if self.sim_time:
            from rosgraph_msgs.msg import Clock

            self._clock_sub = ros.subscribe(Clock, "/clock", ros.qos(depth, reliable=False))
        self._wait = ros.waiter(self._subs())
        self._merge = JointStateMerger(self.names)
        self._arrivals: list[float] = []
        self._periods = 0
        self._latest: tuple[float, np.ndarray, np.ndarray, float] | None = None
        self._origin = 0.0
        self._arrival = False
        self._based = False
        self.stamps = "header"
        self.received = 0
        self.published = 0
        self.gaps = 0
        self._depth = depth
        self._overflowed = False
        self._dropped = 0  # periods whose state the full queue dropped (overdue)
        self.overdue = 0
        self.arrival = 0.0
        self._stamp = 0.0
        self._header_stamp = self._latest_header = self._taken_header = 0.0
        self._q, self._dq = np.zeros(n), np.zeros(n)

    @property
    def origin(self) -> float:
        """The loop clock's origin [s] on the stamps' clock (the system clock, or
        ``/clock`` under ``use_sim_time``): a whole second, set by the first complete
        state (0 before it). Stamps, arrivals and :meth:`clock` are relative to it."""
        return self._origin

    @property
    def ignored(self) -> int:
        """Messages that named none of the controlled joints (not periods)."""
        return self._merge.ignored

    def add_subscription(self, msg_type, topic: str, callback, qos) -> str:
        """Take ``topic``'s messages in :meth:`wait` too, calling ``callback(msg)`` in the
        loop's thread (between states); returns the resolved topic name."""
        sub = self.ros.subscribe(msg_type, topic, qos)
        self._others.append((sub, callback))
        self._wait = self.ros.waiter(self._subs())
        return self.ros.topic(topic)

    def _subs(self) -> list:
        """The subscriptions :meth:`wait` waits on."""
        clock = [] if self._clock_sub is None else [self._clock_sub]
        return [self._sub, *clock, *(s for s, _ in self._others)]

    def _take_clock(self) -> None:
        """Take the ``/clock`` messages waiting (simulated time): the newest is now."""
        for msg in self.ros.take(self._clock_sub):
            c = msg.clock
            self._sim_now = max(c.sec + 1e-9 * c.nanosec, self._sim_now_or(-math.inf))

    def _sim_now_or(self, default: float) -> float:
        return default if math.isnan(self._sim_now) else self._sim_now

    def _poll(self) -> None:
        """Take what has arrived: ``/clock`` (simulated time), the states (oldest first),
        then the other topics."""
        if self._clock_sub is not None:
            self._take_clock()
        msgs = self.ros.take_with_time(self._sub)
        # a full queue: older messages were dropped to make room, the periods before the
        # first state taken are the loop's own misses, not the arm's gaps
        self._overflowed = len(msgs) >= self._depth
        read = self._read_state
        for data, received in msgs:
            msg = read(data)
            if msg is None:  # not little-endian CDR: rclpy's deserialisation
                msg = _deserialize(data, self._state_type)
            self._on_state(msg, received)
        take = self.ros.take
        for sub, callback in self._others:
            for msg in take(sub):
                callback(msg)

    def _on_state(self, msg, received: float) -> None:
        """Merge one message; ``received`` [s] is its reception on the system clock (0:
        unknown, now)."""
        if not self._merge.add(msg.name, msg.position, msg.velocity):
            return
        st = msg.header.stamp
        stamp = st.sec + 1e-9 * st.nanosec
        self._header_stamp = stamp
        if self.sim_time:  # simulated time: the stamp (zero: the /clock it came at)
            now = self._sim_now_or(stamp) if stamp == 0.0 else stamp
            if not self._based:
                self._based = True
                self.stamps = "simulated"
                self._origin = float(int(now))
            arrival = stamp = now - self._origin
        else:
            now = time.time()
            if not self._based:
                # the first complete state decides the time base (module doc)
                self._based = True
                self._arrival = stamp == 0.0 or abs(stamp - now) > 1.0
                self.stamps = "arrival" if self._arrival else "header"
                self._origin = float(int(now))
            arrival = (received if 0.0 < received <= now + 1e-3 else now) - self._origin
            stamp = arrival if self._arrival or stamp == 0.0 else stamp - self._origin
        if self._latest is not None:  # periods since the previous state (>= 1)
            periods = max(1, round((stamp - self._latest[0]) / self.period))
            if self._overflowed:
                self._dropped += periods - 1
            else:
                self.gaps += periods - 1
            self._periods += periods
        else:
            self._periods += 1
        self._overflowed = False
        self._latest = (stamp, self._merge.q.copy(), self._merge.dq.copy(), arrival)
        self._latest_header = self._header_stamp or arrival + self._origin
        self._arrivals.append(arrival)
        self.received += 1

    # -------------------------------------------------------------- the loop's side
    def start(self) -> None:
        """Wait for the first complete state (spinning the node in this thread): the
        messages, merged by name, must cover the robot's joints; messages naming only
        other joints are ignored.

        Raises:
            ArmError: No complete state within ``start_timeout`` (none at all, only
                other joints, or some of the robot's joints never named), or one
                without finite positions and velocities.
        """
        end = time.monotonic() + self.start_timeout
        while self._latest is None and time.monotonic() < end:
            self._wait(min(0.1, max(0.0, end - time.monotonic())))
            self._poll()
        merge = self._merge
        if self._latest is None and merge.seen.any():
            raise ArmError(
                f"the joint states on {self.joint_states_topic} named the robot's joints "
                f"{[x for x, s in zip(self.names, merge.seen, strict=True) if s]} but never "
                f"{merge.missing} within {self.start_timeout:g} s (ros.start_timeout); "
                "expected every controlled joint (lock the others in [robot])"
            )
        if self._latest is None and merge.ignored:
            raise ArmError(
                f"the {merge.ignored} joint states on {self.joint_states_topic} within "
                f"{self.start_timeout:g} s name only other joints (last: "
                f"{merge.other_names}), none of the robot's {list(self.names)}; start the "
                "arm's joint_state_broadcaster, or check ros.joint_states and [robot]"
            )
        if self._latest is None:
            raise ArmError(
                f"no sensor_msgs/JointState on {self.joint_states_topic} within "
                f"{self.start_timeout:g} s (ros.start_timeout); start the arm's driver "
                "(or `hmpc-pin ros-arm CONFIG`) and check ros.joint_states and the "
                "namespace"
            )
        _, q, dq, _ = self._latest
        if not (np.isfinite(q).all() and np.isfinite(dq).all()):
            raise ArmError(
                f"the joint states on {self.joint_states_topic} carry no finite position "
                "and velocity for every joint; the controller needs both"
            )
        self.wait(0.0)

    def stamp_time(self) -> float:
        """The stamp [s] of the state taken last, on the arm's clock: the message's
        ``header.stamp`` (simulated time under ``use_sim_time``), or its arrival on the
        system clock if the stamp is zero."""
        return self._taken_header

    def clock(self) -> float:
        """Now [s] on the stamps' clock (the system clock shifted as the stamps are;
        under ``use_sim_time`` the newest ``/clock`` time, shifted alike)."""
        if self.sim_time:
            self._take_clock()
            return self._sim_now_or(self._stamp + self._origin) - self._origin
        return time.time() - self._origin

    def wait(self, timeout: float) -> int:
        """Block until a new complete state arrives or ``timeout`` [s] (messages of the
        other subscriptions are handled here too); take the newest and return how many
        interface periods its stamp is after the previous one taken. Sets
        ``arrival`` (the state's arrival, on :meth:`clock`) and ``overdue`` (the
        states taken with it that arrived more than a period ago: not answered in time)."""
        woke = self.clock()  # (taking a burst of messages is not the loop being late)
        self._poll()
        if not self._arrivals:
            end = time.monotonic() + timeout
            while not self._arrivals and (remaining := end - time.monotonic()) > 0:
                self._wait(remaining)
                woke = self.clock()
                self._poll()
        if not self._arrivals:
            self.overdue = 0
            return 0
        count, self._periods = self._periods, 0
        late = woke - self.period
        self.overdue = sum(1 for a in self._arrivals[:-1] if a < late) + self._dropped
        self._dropped = 0
        self._arrivals.clear()
        self._stamp, q, dq, self.arrival = self._latest  # type: ignore[misc]
        self._taken_header = self._latest_header
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

    #: How long [s] :meth:`close` waits for the arm's acknowledgement of the last command.
    ACK_TIMEOUT = 0.5

    def close(self) -> None:
        """Stop the node (idempotent), once the last command (the one the arm holds from
        now on: the stop sequence's G(q) or brake) is acknowledged by every reliable
        subscriber, or after :data:`ACK_TIMEOUT` -- destroyed at once, a command still in
        the middleware's send queue is lost and the arm holds the one before it."""
        pub = getattr(self, "_pub", None)
        if pub is not None:
            from rclpy.duration import Duration

            with contextlib.suppress(Exception):  # (a publisher already gone: nothing to wait)
                pub.wait_for_all_acked(Duration(nanoseconds=int(self.ACK_TIMEOUT * 1e9)))
        self.ros.close()


def _deserialize(data: bytes, msg_type):
    """``data`` as a ``msg_type`` message (rclpy's deserialisation, any encoding)."""
    from rclpy.serialization import deserialize_message

    return deserialize_message(data, msg_type)


def _uses_sim_time(node) -> bool:
    """The node's ``use_sim_time`` parameter (rclpy declares it on every node)."""
    try:
        return bool(node.get_parameter("use_sim_time").value)
    except Exception:  # an rclpy without it: the system clock
        return False
