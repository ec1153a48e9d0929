"""The ``~/joint_trajectory`` subscription of ``hmpc-pin ros``: each message checked off the
control thread (names, times, limits) and handed to the loop as its new reference
(:class:`~hmpc_pin.apps.ros_trajectories.TrajectorySubscription`), against the limits of
:func:`~hmpc_pin.apps.ros_trajectories.trajectory_limits`.
"""

from __future__ import annotations

import contextlib
import queue
import threading

import numpy as np

from ..exceptions import HmpcError
from ..experiment.build import Experiment
from ..experiment.controllers import controller_limits
from ..experiment.record import recorded_limits
from ..realtime.loop import RealtimeLoop

__all__ = ["TrajectorySubscription", "trajectory_limits"]


def trajectory_limits(experiment: Experiment) -> tuple[np.ndarray, np.ndarray]:
    """The position limits a trajectory message is checked against: the MPC's state
    limits, else the URDF's (a joint without a range: none)."""
    cc = experiment.config.controller
    lim = controller_limits(cc, experiment.robot)
    if lim is not None:
        return np.asarray(lim.lower, dtype=float), np.asarray(lim.upper, dtype=float)
    rec = recorded_limits(experiment.robot)
    return np.asarray(rec["lower"]), np.asarray(rec["upper"])


class TrajectorySubscription:
    """The ``~/joint_trajectory`` subscription. The loop's thread only hands each message
    over (a queue put); a worker thread checks it (names, times, limits) and hands the
    new reference to the loop, which swaps it in at a controller step, or refuses it with
    one logged line. Everything the check needs is loaded before the first cycle
    (:meth:`warm`): accepting a message costs the control thread no slow work."""

    def __init__(self, ros, experiment: Experiment, iface, topic: str, qos):
        self.ros, self.experiment, self.iface = ros, experiment, iface
        self.lower, self.upper = trajectory_limits(experiment)
        self.loop: RealtimeLoop | None = None
        self.events: list[dict] = []
        self._pending: tuple | None = None  # (reference, event) of the last accepted
        self._queue: queue.SimpleQueue = queue.SimpleQueue()
        self._worker = threading.Thread(target=self._work, name="joint_trajectory", daemon=True)
        self.topic = iface.add_subscription(
            ros.msgs["trajectory_msgs"].JointTrajectory, topic, self._queue.put, qos
        )

    def warm(self) -> None:
        """Check one message (a hold of the reference's start, not used) and start the
        worker: the modules and caches the check needs are loaded now, not in a cycle."""
        from ..ros.trajectory import trajectory_from_message

        msgs = self.ros.msgs["trajectory_msgs"]
        robot, ref = self.experiment.robot, self.experiment.reference
        msg = msgs.JointTrajectory()
        msg.joint_names = list(robot.joint_names)
        point = msgs.JointTrajectoryPoint()
        point.positions = [float(x) for x in ref.sample(0.0)[0]]
        point.time_from_start.sec = 1
        msg.points = [point]
        with contextlib.suppress(HmpcError):
            trajectory_from_message(msg, robot, ref, 0.0, self.lower, self.upper)
        self._worker.start()

    def close(self) -> None:
        """Stop the worker (after the messages already queued)."""
        if self._worker.is_alive():
            self._queue.put(None)
            self._worker.join(timeout=5.0)

    def _work(self) -> None:
        while (msg := self._queue.get()) is not None:
            self._check(msg)

    def _check(self, msg) -> None:
        from ..ros.trajectory import refusal, trajectory_from_message

        loop, log = self.loop, self.ros.node.get_logger()
        if loop is None:  # before the loop runs: the config's reference stands
            log.error(
                f"refused a joint_trajectory message on {self.topic}: the controller "
                "is not running yet"
            )
            return
        now = loop.time + self.experiment.controller.Ts  # the step that takes it over
        base = loop.reference
        try:
            traj = trajectory_from_message(
                msg,
                self.experiment.robot,
                base,
                now,
                self.lower,
                self.upper,
                origin=self.iface.origin,
            )
        except HmpcError as exc:
            line = refusal(exc)
            log.error(line)
            self.events.append({"t": now, "accepted": False, "reason": line})
            return
        start = float(traj.times[0])
        if not loop.set_reference(traj, at=start, base=base):
            line = (
                f"refused a joint_trajectory message on {self.topic}: the reference "
                "changed while it was checked (a trajectory sent before it started); "
                "send it again"
            )
            log.error(line)
            self.events.append({"t": now, "accepted": False, "reason": line})
            return
        pending, self._pending = self._pending, None
        if pending is not None and loop.superseded is pending[0]:
            # accepted, but replaced before its start: it never ran (ros2_control's
            # trajectory controller replaces a pending goal the same way)
            pending[1]["superseded_at"] = now
            log.info(
                f"the joint_trajectory accepted for t={pending[1]['t']:.3f} s is "
                "superseded by a newer one before it started"
            )
        line = (
            f"accepted a joint_trajectory message of {len(msg.points)} points: the "
            f"reference from t={start:.3f} s to {traj.t_end:.3f} s, last point held"
        )
        log.info(line)
        event = {"t": start, "accepted": True, "t_end": traj.t_end, "points": len(msg.points)}
        self.events.append(event)
        waiting = loop.pending_reference  # None: the loop has swapped it in already
        self._pending = None if waiting is None else (waiting, event)
