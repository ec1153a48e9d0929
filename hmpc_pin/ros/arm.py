"""A simulated arm as a ROS 2 node, with the topics and message types of ros2_control.

Every interface period :math:`T_a` (absolute deadlines on the system clock; a late wake
steps through every period it missed and publishes each state, so the arm's time follows
the wall and a state is published per period; under a real-time policy it busy-waits the
last stretch before each period, as the real-time loop does:
:class:`~hmpc_pin.realtime.pacing.Waker`) the node
advances its :class:`~hmpc_pin.sim.base.Plant` by one period with the latest effort
command held, then publishes ``sensor_msgs/JointState`` (name, position, velocity, the
applied effort; ``header.stamp`` the period's instant :math:`t_0 + kT_a` on the system
clock, the simulated measurement's time) as
joint_state_broadcaster does. Effort commands arrive as ``std_msgs/Float64MultiArray``
(JointGroupEffortController's input), one value per joint in the robot's order, and are
clipped to the effort limits; a command of the wrong length or with a non-finite value
is ignored and logged. Until the first command the arm holds still (on its brakes),
publishing its state.

**Joint stops.** With position limits (the URDF's) every period ends with the arm's hard
stops, as hardware's: a joint past its limit is put back on it and its velocity into the
limit zeroed (an inelastic stop; the velocity away from it kept), the plant reset to that
state.

**Simulated time** (``real_time_factor`` given): the node is a simulator. It publishes
``rosgraph_msgs/Clock`` on ``/clock`` each period, just before the state, and stamps the
states on that clock (from 0, :math:`kT_a`); a period takes :math:`T_a/f` of wall time for
a real-time factor :math:`f`. A late wake does not catch up (a simulator that cannot keep
its factor runs slower: its time is its own): the periods stay one per state and the
wall deadlines restart from the late wake (``late`` counts those wakes).

With ``[ros] gravity = "arm"`` the node is an arm that compensates gravity itself
(Franka's FCI, KUKA's FRI torque overlay): each period it applies the command plus
:math:`G(q)` of its own model at the period's start, that total clipped to the effort
limits (as the simulated plant clips its total), and publishes it as the effort; a zero
command then holds it.
"""

from __future__ import annotations

import time

import numpy as np

from ..realtime.loop import sleep_until
from ..realtime.pacing import Waker, realtime_policy, timer_slack
from ..sim.base import Plant
from .cdr import read_float64_array
from .node import RosNode

__all__ = ["RosArmNode"]


class RosArmNode:
    """The plant of an experiment behind ``/joint_states`` and the effort topic.

    Args:
        ros: Its :class:`~hmpc_pin.ros.node.RosNode`.
        plant: The arm's dynamics, advanced ``period`` per call.
        joint_names: The robot's joints (message order).
        q0, dq0: Initial state [rad, rad/s].
        period: Interface period [s].
        joint_states, commands: Topic names.
        effort_limit: Per-joint torque limit [N·m] (``None``: none), on the torque
            applied (with ``gravity``, the command plus G(q)).
        gravity: ``G(q)`` [N·m] the arm adds to each command itself (``None``: it adds
            nothing, the command is the torque).
        lower, upper: Joint position limits [rad], (n,) (``None``: no stops; ±inf: none
            on that joint), the joint stops (module doc).
        real_time_factor: Run on simulated time at this factor, publishing ``/clock``
            (module doc); ``None``: the system clock.

    Attributes:
        steps: Periods elapsed (a state published for each). late: Periods the node
            woke too late for (stepped and published late).
        stops: Periods that ended with a joint on its stop.
        commands: Commands applied. rejected: Commands ignored.
    """

    def __init__(
        self,
        ros: RosNode,
        plant: Plant,
        joint_names,
        q0,
        dq0,
        period: float,
        joint_states: str,
        commands: str,
        effort_limit=None,
        gravity=None,
        lower=None,
        upper=None,
        real_time_factor: float | None = None,
    ):
        self.ros, self.plant = ros, plant
        self.gravity = gravity
        self.names = list(joint_names)
        self.n = n = len(self.names)
        self.period = float(period)
        self.q, self.dq = np.array(q0, dtype=float), np.array(dq0, dtype=float)
        plant.reset(self.q, self.dq, 0.0)
        self.limit = None if effort_limit is None else np.asarray(effort_limit, dtype=float)
        self._cmd: np.ndarray | None = None
        self.tau = np.zeros(n)  # the torque applied (the command, plus G(q) with gravity)
        self._command = np.zeros(n)
        self.steps = self.late = self.commands = self.rejected = self.stops = 0
        inf = np.full(n, np.inf)
        self.lower = -inf if lower is None else np.asarray(lower, dtype=float)
        self.upper = inf if upper is None else np.asarray(upper, dtype=float)
        self._has_stops = bool(np.isfinite(self.lower).any() or np.isfinite(self.upper).any())
        self.real_time_factor = None if real_time_factor is None else float(real_time_factor)
        self._clock_pub = None
        if self.real_time_factor is not None:
            from rosgraph_msgs.msg import Clock

            self._clock_msg = Clock()
            self._clock_pub = ros.node.create_publisher(Clock, "/clock", ros.qos(10))
        sensor = ros.msgs["sensor_msgs"]
        self._msg = sensor.JointState()
        self._msg.name = self.names
        self._pub = ros.node.create_publisher(sensor.JointState, joint_states, ros.qos(10))
        # taken serialized, their values read from the bytes (hmpc_pin.ros.cdr)
        self._command_type = ros.msgs["std_msgs"].Float64MultiArray
        self._sub = ros.subscribe(self._command_type, commands, ros.qos(10), raw=True)
        self.commands_topic = ros.topic(commands)
        self.joint_states_topic = ros.topic(joint_states)
        self._stop = False
        self._started = False  # a command has come (before it: on the brakes)

    def _on_command(self, msg) -> None:
        """A ``Float64MultiArray`` command (its ``data``)."""
        self._on_values(msg.data)

    def _on_values(self, values) -> None:
        """A command's values [N·m]: kept if valid (module doc), else logged."""
        tau = np.asarray(values, dtype=float)
        if tau.shape != (self.n,) or not np.isfinite(tau).all():
            self.rejected += 1
            self.ros.node.get_logger().error(
                f"ignored an effort command of {tau.size} values {tau.tolist()} on "
                f"{self.commands_topic}; expected {self.n} finite values [N·m] in the order "
                f"{self.names}",
                throttle_duration_sec=1.0,
            )
            return
        self._cmd = tau

    def _publish(self, stamp: float) -> None:
        msg = self._msg
        ns = round(stamp * 1e9)
        if self._clock_pub is not None:  # the simulator's clock first, then its state
            c = self._clock_msg.clock
            c.sec, c.nanosec = divmod(ns, 1_000_000_000)
            self._clock_pub.publish(self._clock_msg)
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 1_000_000_000)
        msg.position = self.q.tolist()
        msg.velocity = self.dq.tolist()
        msg.effort = self.tau.tolist()
        self._pub.publish(msg)

    def _joint_stops(self) -> None:
        """The hard stops (module doc): q back on a limit it passed, the velocity into
        the limit zeroed; the plant reset to that state."""
        q, dq = self.q, self.dq
        below, above = q < self.lower, q > self.upper
        if not (below.any() or above.any()):
            return
        q, dq = q.copy(), dq.copy()
        q[below], q[above] = self.lower[below], self.upper[above]
        dq[below] = np.maximum(dq[below], 0.0)
        dq[above] = np.minimum(dq[above], 0.0)
        self.q, self.dq = q, dq
        self.plant.reset(q, dq, self.steps * self.period)
        self.stops += 1

    def stop(self) -> None:
        """Make :meth:`run` return at its next period (from another thread or a handler)."""
        self._stop = True

    def run(self, duration: float | None = None) -> None:
        """Publish and step until ``duration`` [s] (``None``: until :meth:`stop`):
        :math:`\\mathrm{round}(d/T_a)` periods, however late the node wakes (simulated
        seconds with a real-time factor)."""
        with timer_slack(1):  # a sleep ends on time, not up to 50 µs late (Linux)
            if self.real_time_factor is not None:
                self._run_simulated(duration)
            else:
                self._run_wall(duration)

    def _run_wall(self, duration: float | None) -> None:
        """:meth:`run` on the wall clock."""
        P = self.period
        clock = time.time
        # under a real-time policy, awake at each period's instant: sleep, then busy-wait
        # the stretch of the wake-ups' measured lateness (the real-time loop's Waker)
        waker = Waker(clock, P, spin=None if realtime_policy() else 0.0)
        t0 = clock()
        k = 0
        end = None if duration is None else round(duration / P)
        self._started = False
        self._publish(t0)
        while not self._stop and (end is None or k < end):
            k += 1
            waker.until(t0 + k * P)
            self._take_command()  # the newest valid command counts
            due = int((clock() - t0) / P)
            if end is not None:  # (a late wake near the end steps no period past it)
                due = min(due, end)
            if due > k:
                self.late += due - k
                k = due
            # (a late wake steps through the missed periods and publishes each: a state per
            # period, as a driver's, so that the controller counts the periods it missed)
            while self.steps < k:
                self._step()
                self._publish(t0 + self.steps * P)

    def _take_command(self) -> None:
        """The newest valid command since the last period, if any, held from now on."""
        for data in self.ros.take(self._sub):
            values = read_float64_array(data)
            if values is None:  # not little-endian CDR: rclpy's deserialisation
                from rclpy.serialization import deserialize_message

                values = deserialize_message(data, self._command_type).data
            self._on_values(values)
        cmd, self._cmd = self._cmd, None
        if cmd is None:
            return
        self._started = True
        self.commands += 1
        if self.limit is not None and self.gravity is None:
            np.clip(cmd, -self.limit, self.limit, out=self._command)
        else:  # (with gravity added by the arm, the total is clipped at each step)
            self._command[:] = cmd

    def _step(self) -> None:
        """One period with the command held (on the brakes before the first)."""
        if self._started:
            self.tau[:] = self._command
            if self.gravity is not None:
                self.tau += self.gravity(self.q)
                if self.limit is not None:  # the total joint torque is limited
                    np.clip(self.tau, -self.limit, self.limit, out=self.tau)
            self.q, self.dq = self.plant.advance(self.tau)
            if self._has_stops:
                self._joint_stops()
        self.steps += 1

    def _run_simulated(self, duration: float | None) -> None:
        """:meth:`run` on simulated time (module doc)."""
        P = self.period
        wall = P / self.real_time_factor  # [s] of wall time per period
        clock = time.monotonic
        end = None if duration is None else round(duration / P)
        self._started = False
        self._publish(0.0)
        base, k0 = clock(), 0
        while not self._stop and (end is None or self.steps < end):
            due = base + (self.steps + 1 - k0) * wall
            sleep_until(due, clock)
            if clock() - due > wall:  # behind by more than a period: slower, no burst
                self.late += 1
                base, k0 = clock(), self.steps + 1
            self._take_command()
            self._step()
            self._publish(self.steps * P)

    def close(self) -> None:
        """Stop the node (idempotent)."""
        self.ros.close()
