"""A simulated arm as a ROS 2 node, with the topics and message types of ros2_control.

Every interface period :math:`T_a` (absolute deadlines on the system clock; a late wake
steps through every period it missed and publishes each state, so the arm's time follows
the wall and a state is published per period) the node
advances its :class:`~hmpc_pin.sim.base.Plant` by one period with the latest effort
command held, then publishes ``sensor_msgs/JointState`` (name, position, velocity, the
applied effort; ``header.stamp`` the period's instant :math:`t_0 + kT_a` on the system
clock, the simulated measurement's time) as
joint_state_broadcaster does. Effort commands arrive as ``std_msgs/Float64MultiArray``
(JointGroupEffortController's input), one value per joint in the robot's order, and are
clipped to the effort limits; a command of the wrong length or with a non-finite value
is ignored and logged. Until the first command the arm holds still (on its brakes),
publishing its state.

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
from ..sim.base import Plant
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

    Attributes:
        steps: Periods elapsed (a state published for each). late: Periods the node
            woke too late for (stepped and published late).
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
        self.steps = self.late = self.commands = self.rejected = 0
        sensor = ros.msgs["sensor_msgs"]
        self._msg = sensor.JointState()
        self._msg.name = self.names
        self._pub = ros.node.create_publisher(sensor.JointState, joint_states, ros.qos(10))
        self._sub = ros.subscribe(ros.msgs["std_msgs"].Float64MultiArray, commands, ros.qos(10))
        self.commands_topic = ros.topic(commands)
        self.joint_states_topic = ros.topic(joint_states)
        self._stop = False

    def _on_command(self, msg) -> None:
        tau = np.asarray(msg.data, dtype=float)
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
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 1_000_000_000)
        msg.position = self.q.tolist()
        msg.velocity = self.dq.tolist()
        msg.effort = self.tau.tolist()
        self._pub.publish(msg)

    def stop(self) -> None:
        """Make :meth:`run` return at its next period (from another thread or a handler)."""
        self._stop = True

    def run(self, duration: float | None = None) -> None:
        """Publish and step until ``duration`` [s] (``None``: until :meth:`stop`):
        :math:`\\mathrm{round}(d/T_a)` periods, however late the node wakes."""
        P = self.period
        clock = time.time
        t0 = clock()
        k = 0
        end = None if duration is None else round(duration / P)
        started = False
        self._publish(t0)
        while not self._stop and (end is None or k < end):
            k += 1
            sleep_until(t0 + k * P, clock)
            for msg in self.ros.take(self._sub):  # the newest valid command counts
                self._on_command(msg)
            cmd, self._cmd = self._cmd, None
            if cmd is not None:
                started = True
                self.commands += 1
                if self.limit is not None and self.gravity is None:
                    np.clip(cmd, -self.limit, self.limit, out=self._command)
                else:  # (with gravity added by the arm, the total is clipped at each step)
                    self._command[:] = cmd
            due = int((clock() - t0) / P)
            if end is not None:  # (a late wake near the end steps no period past it)
                due = min(due, end)
            if due > k:
                self.late += due - k
                k = due
            # (a late wake steps through the missed periods and publishes each: a state per
            # period, as a driver's, so that the controller counts the periods it missed)
            while self.steps < k:
                if started:
                    self.tau[:] = self._command
                    if self.gravity is not None:
                        self.tau += self.gravity(self.q)
                        if self.limit is not None:  # the total joint torque is limited
                            np.clip(self.tau, -self.limit, self.limit, out=self.tau)
                    self.q, self.dq = self.plant.advance(self.tau)
                self.steps += 1
                self._publish(t0 + self.steps * P)

    def close(self) -> None:
        """Stop the node (idempotent)."""
        self.ros.close()
