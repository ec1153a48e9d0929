"""The command filter: what every torque sent to a Franka arm passes through.

The FCI aborts a torque motion with a reflex when the first command is not zero, when a
command differs from the last one the robot received (``tau_J_d``) by more than
1000 N·m/s (1 N·m per 1 ms cycle), or when it exceeds a joint's torque limit (87 N·m on
joints 1–4, 12 N·m on 5–7). pylibfranka sends what it is given (it binds neither
libfranka's rate limiter nor its low-pass filter), so :class:`CommandFilter` enforces
the three on every command, in this order:

1. **ramp-in**: cycle :math:`k` of the motion sends :math:`\\min(1, k/K_r)\\,\\tau`
   (:math:`k = 0`: zero);
2. **rate limit**: :math:`\\tau_J^d - \\Delta \\le \\tau \\le \\tau_J^d + \\Delta` with
   :math:`\\Delta` = ``max_step`` (0.999 N·m) and :math:`\\tau_J^d` the torque the robot
   reports it received, and within :math:`\\Delta` of the previous command sent as well
   (a command the robot has not yet received when it sends a state leaves
   :math:`\\tau_J^d` one command behind); where the two boxes do not meet, the first;
3. **torque limit**: :math:`|\\tau_i| \\le L_i` (``limit``, inside the robot's).

A command that is not finite is not filtered: calling the filter raises
:class:`~hmpc_pin.exceptions.NonFiniteError` (the driver then runs its stop sequence;
nothing non-finite reaches the arm). The command excludes gravity: the robot adds
:math:`G(q)` itself.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ...exceptions import ConfigError, DimensionError, NonFiniteError

__all__ = ["FRANKA_TORQUE_LIMIT", "MAX_STEP", "CommandFilter"]

FloatArray = NDArray[np.float64]

#: The Franka arms' joint torque limits [N·m] (FR3 and Panda; the URDFs' effort limits).
FRANKA_TORQUE_LIMIT = np.array([87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0])

#: The largest torque change per 1 ms cycle [N·m]: the robot's 1000 N·m/s rate limit,
#: with a margin of 1 mN·m.
MAX_STEP = 0.999


class CommandFilter:
    """Ramp-in, rate limit against ``tau_J_d`` and torque limit (module doc).

    Args:
        limit: Per-joint torque limit [N·m], (n,), each > 0 (the command is clipped to
            ``[-limit, limit]``).
        max_step: Largest change per cycle [N·m] against ``tau_J_d`` (> 0).
        ramp: :math:`K_r`, the cycles of the ramp-in (>= 1; the first command is zero).

    Attributes:
        cycles: Commands filtered since :meth:`reset`.
    """

    def __init__(self, limit: ArrayLike, max_step: float = MAX_STEP, ramp: int = 100):
        lim = np.array(limit, dtype=float)
        if lim.ndim != 1 or not np.all(np.isfinite(lim)) or np.any(lim <= 0):
            raise ConfigError("franka.torque_limit", f"expected values > 0 [N·m], got {lim}")
        if not (np.isfinite(max_step) and max_step > 0):
            raise ConfigError("franka.max_step", f"expected a step > 0 [N·m], got {max_step!r}")
        if int(ramp) != ramp or ramp < 1:
            raise ConfigError("franka.ramp", f"expected whole cycles >= 1, got {ramp!r}")
        self.limit = lim
        self.max_step = float(max_step)
        self.ramp = int(ramp)
        self.cycles = 0
        self._out = np.zeros(lim.size)
        self._prev = np.zeros(lim.size)

    def reset(self) -> None:
        """Start a new motion: the next command is the first (zero)."""
        self.cycles = 0

    def __call__(self, tau: ArrayLike, tau_J_d: ArrayLike) -> FloatArray:
        """The command to send for the requested ``tau`` [N·m] given the robot's
        ``tau_J_d`` [N·m] (the last torque it received), both (n,).

        Returns:
            The filtered command (a buffer reused by the next call: copy to keep it).

        Raises:
            NonFiniteError: ``tau`` or ``tau_J_d`` is not finite (nothing to send).
            DimensionError: A shape is not (n,).
        """
        tau = np.asarray(tau, dtype=float)
        last = np.asarray(tau_J_d, dtype=float)
        n = self.limit.size
        if tau.shape != (n,) or last.shape != (n,):
            raise DimensionError(
                f"torque of shape {tau.shape}, tau_J_d {last.shape}; expected ({n},)"
            )
        if not np.isfinite(tau).all():
            raise NonFiniteError("command", tau)
        if not np.isfinite(last).all():
            raise NonFiniteError("tau_J_d", last)
        out = self._out
        np.multiply(tau, min(1.0, self.cycles / self.ramp), out=out)
        step = self.max_step
        lo, hi = last - step, last + step
        if self.cycles > 0:  # and near the previous command, where the boxes meet
            prev = self._prev
            lo2, hi2 = np.maximum(lo, prev - step), np.minimum(hi, prev + step)
            meet = lo2 <= hi2
            lo, hi = np.where(meet, lo2, lo), np.where(meet, hi2, hi)
        np.clip(out, lo, hi, out=out)
        np.clip(out, -self.limit, self.limit, out=out)
        self._prev[:] = out
        self.cycles += 1
        return out

    def toward_zero(self, tau_J_d: ArrayLike) -> FloatArray:
        """One step of the ramp to zero: ``tau_J_d`` moved toward 0 by at most
        ``max_step`` per joint, inside the limits."""
        last = np.asarray(tau_J_d, dtype=float)
        out = self._out
        np.clip(0.0, last - self.max_step, last + self.max_step, out=out)
        np.clip(out, -self.limit, self.limit, out=out)
        self._prev[:] = out
        return out
