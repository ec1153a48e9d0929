"""What the real-time loop does when it must stop: the safe torque and the limits it watches.

The safe torque holds the arm against gravity and brakes its motion,

.. math::  \\tau_\\mathrm{safe} = g\\,G(q) - D\\,\\dot q, \\qquad g \\in \\{0, 1\\},

with :math:`G(q)` from Pinocchio (the controller's model, ``rnea(q, 0, 0)``) and
:math:`D = \\mathrm{diag}(d_i)` [N·m·s/rad] the joint damping. It is what a driver sends
while it hands the arm back to its brakes (libfranka's and UR's own stops do the same
with the controller's model replaced by the vendor's).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..exceptions import ConfigError
from ..model.robot import Robot

__all__ = ["STOP_CAUSES", "SafeTorque", "SafetySettings"]

FloatArray = NDArray[np.float64]

#: Why a loop stops early: Ctrl-C, a fault (non-finite value, QP not solved, state beyond
#: limits, any controller error), k consecutive missed deadlines, no new state (watchdog).
STOP_CAUSES = ("interrupted", "fault", "misses", "watchdog")


class SafeTorque:
    """:math:`\\tau_\\mathrm{safe} = g\\,G(q) - D\\dot q` [N·m].

    Args:
        robot: The controller's model (its own ``pin.Data`` is used: call from one thread).
        damping: :math:`d_i` [N·m·s/rad], one value or (n,), each >= 0.
        gravity: Include the gravity compensation :math:`G(q)`.
    """

    def __init__(self, robot: Robot, damping=2.0, gravity: bool = True):
        n = robot.nq
        d = np.broadcast_to(np.asarray(damping, dtype=float), (n,)).copy()
        if not np.all(np.isfinite(d)) or np.any(d < 0):
            raise ConfigError("realtime.damping", f"expected values >= 0, got {d.tolist()}")
        self.robot, self.damping, self.gravity = robot, d, bool(gravity)

    def __call__(self, q: FloatArray, dq: FloatArray) -> FloatArray:
        """The safe torque [N·m], (n,), at the measured state."""
        tau = -self.damping * dq
        if self.gravity:
            tau += self.robot.gravity_torque(q)
        return tau

    def describe(self) -> str:
        """In words, e.g. ``"gravity compensation + damping 2 N·m·s/rad"``."""
        d = self.damping
        damp = f"{d[0]:g}" if np.all(d == d[0]) else "[" + ", ".join(f"{x:g}" for x in d) + "]"
        return ("gravity compensation + " if self.gravity else "") + f"damping {damp} N·m·s/rad"


@dataclass(frozen=True)
class SafetySettings:
    """When the loop stops, and how long it holds the safe torque.

    Attributes:
        lower, upper: Joint position bounds [rad], (n,); a measured q outside is a fault.
        velocity: Joint speed bounds [rad/s], (n,); a measured |q̇| above is a fault.
        max_misses: This many consecutive periods without a torque written in time
            stop the loop (k; libfranka's reflex trips after a few).
        watchdog: A stamp that has not advanced for longer than this [s] stops the loop.
        hold: After a stop, the safe torque is refreshed at the loop rate for this long
            [s] (at least once, immediately).
    """

    lower: FloatArray
    upper: FloatArray
    velocity: FloatArray
    max_misses: int = 10
    watchdog: float = 0.01
    hold: float = 0.1

    @classmethod
    def unlimited(cls, n: int, **kwargs) -> SafetySettings:
        """No position or velocity bound (tests, simulated arms without limits)."""
        inf = np.full(n, np.inf)
        return cls(-inf, inf.copy(), inf.copy(), **kwargs)
