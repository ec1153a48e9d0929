"""The move to the reference's start: a quintic in joint space, in the robot's own joint
position control, before the torque motion.

:math:`q(t) = q_0 + (q_1 - q_0)\\,s(t/T)`, :math:`s(x) = 10x^3 - 15x^4 + 6x^5`: zero
velocity and acceleration at both ends, peak speed :math:`\\tfrac{15}{8}|\\Delta q|/T` and
peak acceleration :math:`\\tfrac{10}{\\sqrt 3}|\\Delta q|/T^2`; :func:`quintic_duration`
takes the shortest :math:`T` that keeps every joint within its bounds.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ...exceptions import ArmError

__all__ = ["quintic", "quintic_duration"]

FloatArray = NDArray[np.float64]


def quintic_duration(delta: ArrayLike, velocity: ArrayLike, acceleration: ArrayLike) -> float:
    """The shortest duration [s] of the quintic move by ``delta`` [rad] with peak speeds
    within ``velocity`` [rad/s] and peak accelerations within ``acceleration`` [rad/s²]
    (each (n,), > 0)."""
    d = np.abs(np.asarray(delta, dtype=float))
    v = np.asarray(velocity, dtype=float)
    a = np.asarray(acceleration, dtype=float)
    t_v = 15.0 / 8.0 * d / v
    t_a = np.sqrt(10.0 / math.sqrt(3.0) * d / a)
    return float(max(np.max(t_v, initial=0.0), np.max(t_a, initial=0.0)))


def quintic(q0: ArrayLike, q1: ArrayLike, T: float, t: float) -> FloatArray:
    """The quintic's position [rad] at ``t`` [s] (``q1`` from ``T`` on)."""
    q0 = np.asarray(q0, dtype=float)
    q1 = np.asarray(q1, dtype=float)
    x = 1.0 if T <= 0 else min(max(t / T, 0.0), 1.0)
    s = x * x * x * (10.0 - 15.0 * x + 6.0 * x * x)
    return q0 + (q1 - q0) * s


def check_move(q0: FloatArray, q1: FloatArray, max_distance: float, names) -> None:
    """Refuse a move longer than ``max_distance`` [rad] on any joint (naming it).

    Raises:
        ArmError: A joint is farther than ``max_distance`` from its start.
    """
    d = np.abs(np.asarray(q1) - np.asarray(q0))
    i = int(np.argmax(d))
    if d[i] > max_distance:
        raise ArmError(
            f"joint {names[i]!r} is {d[i]:.3f} rad from the reference's start "
            f"(q={q0[i]:.4f}, start {q1[i]:.4f} rad), beyond the {max_distance:g} rad this "
            "command moves the arm by itself (--max-move); move the arm closer (Desk, or "
            "guiding) and start again. Nothing was sent to the arm"
        )
