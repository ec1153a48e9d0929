"""A template for a real arm's driver (pylibfranka style). NOT RUN ON HARDWARE.

Superseded by :class:`~hmpc_pin.realtime.franka.FrankaArm` (``hmpc-pin franka``: the
command filter, the checks before the motion, the stop sequence, run against the FCI
simulator); kept for the UR notes below and for code that imports it.

This file has never been connected to a robot: it was written from pylibfranka's
documented API (``Robot(ip)``, ``start_torque_control()``, ``ActiveControl.readOnce()``
returning ``(RobotState, Duration)``, ``writeOnce(Torques)``, ``Robot.stop()``) and is
imported by nothing in hmpc_pin. Treat it as a starting point to review line by line with
the arm's manual and its safety officer, not as a driver. Points that need attention on a
real Panda / FR3:

* libfranka's torque commands are **without gravity**: the robot adds its own gravity
  compensation. The controllers here return the full torque (Eq 4 includes
  :math:`G(q)`), so the driver subtracts the controller model's :math:`G(q)` before
  sending; a mismatch between the two gravity models becomes a disturbance for the NDO.
* ``readOnce()`` blocks until the robot's next 1 kHz packet: the robot paces the loop.
  Run :class:`~hmpc_pin.realtime.loop.RealtimeLoop` with ``sleep=lambda deadline: None``
  and ``clock`` returning the robot's time (``duration`` summed), so that the loop's
  deadlines are the robot's packets.
* libfranka checks the commanded torque rate and the joint limits itself and aborts the
  motion (a reflex) on a violation or on missed packets; run the loop in a process with
  real-time priority (``chrt``/``SCHED_FIFO``) and locked memory, as libfranka requires
  with ``RealtimeConfig.kEnforce``.
* Set conservative collision thresholds (``set_collision_behavior``) and keep the user
  stop in hand.

For a UR arm (ur_rtde), the same shape holds with ``RTDEReceiveInterface.getActualQ()``/
``getActualQd()`` for :meth:`~FrankaTorqueDriver.read`, the controller's direct-torque
command for :meth:`~FrankaTorqueDriver.write` (available only on recent controller software;
check the ur_rtde and PolyScope versions), ``initPeriod()``/``waitPeriod()`` for the pacing and
``stopScript()`` for :meth:`~FrankaTorqueDriver.close`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from ..exceptions import InterfaceError

__all__ = ["FrankaTorqueDriver"]

FloatArray = NDArray[np.float64]


class FrankaTorqueDriver:
    """A :class:`~hmpc_pin.realtime.interface.RobotInterface` over pylibfranka (template,
    never run on hardware; module doc).

    Args:
        address: The robot's FCI address.
        gravity: ``G(q)`` [N·m] of the controller's model (subtracted before sending,
            libfranka adds its own).
        collision_thresholds: ``(lower_torque, upper_torque, lower_force, upper_force)``
            for ``set_collision_behavior``, or ``None`` to keep the robot's.
    """

    nq = 7
    period = 0.001

    def __init__(
        self,
        address: str,
        gravity: Callable[[FloatArray], FloatArray],
        collision_thresholds=None,
    ):
        try:
            import pylibfranka  # type: ignore[import-not-found]
        except ImportError as exc:
            raise InterfaceError(
                address,
                "a reachable Franka arm",
                "pylibfranka is not installed (pip install "
                "pylibfranka; it needs libfranka matching the robot's system version)",
            ) from exc
        self._franka = pylibfranka
        self._robot = pylibfranka.Robot(address)
        if collision_thresholds is not None:
            self._robot.set_collision_behavior(*collision_thresholds)
        self._gravity = gravity
        self._control = self._robot.start_torque_control()
        self._t = 0.0
        self._q = np.zeros(self.nq)
        self._dq = np.zeros(self.nq)
        self._closed = False

    def read(self) -> tuple[float, FloatArray, FloatArray]:
        """Block until the robot's next state; ``(robot time [s], q, dq)``."""
        state, duration = self._control.readOnce()
        self._t += duration.to_sec()
        self._q[:] = state.q
        self._dq[:] = state.dq
        return self._t, self._q, self._dq

    def write(self, tau: FloatArray) -> None:
        """Send ``tau - G(q)`` (libfranka adds gravity itself)."""
        command = np.asarray(tau, dtype=float) - self._gravity(self._q)
        self._control.writeOnce(self._franka.Torques(command.tolist()))

    def close(self) -> None:
        """Stop the motion (the robot engages its brakes)."""
        if not self._closed:
            self._closed = True
            self._robot.stop()
