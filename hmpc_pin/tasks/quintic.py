"""A quintic (minimum-jerk) joint move, used for the Cartesian motion of Section 5.4."""

from __future__ import annotations

import numpy as np

from ..exceptions import ConfigError, DimensionError, NonFiniteError
from .base import CompiledSampling, PolynomialSampling

__all__ = ["QuinticReference"]


class QuinticReference(CompiledSampling):
    """Joint-space quintic (minimum-jerk) move from ``q_start`` to ``q_goal``, §5.4.

    With :math:`s = \\operatorname{clip}((t - t_0)/T, 0, 1)` and
    :math:`\\Delta = q_{goal} - q_{start}`,

    .. math::

        r(t) = q_{start} + \\Delta\\,(10 s^3 - 15 s^4 + 6 s^5), \\qquad
        \\dot r(t) = \\frac{\\Delta}{T}\\,30 s^2 (1 - s)^2, \\qquad
        \\ddot r(t) = \\frac{\\Delta}{T^2}\\,60 s (1 - s)(1 - 2 s),

    so velocity and acceleration are zero at both ends, and the reference is
    constant (:math:`q_{start}` before :math:`t_0`, :math:`q_{goal}` after
    :math:`t_0 + T`) outside the move. Used to join the two inverse-kinematics
    poses of the paper's Cartesian motion (Section 5.4).

    Args:
        q_start: Start angles [rad], shape (n,).
        q_goal: Goal angles [rad], shape (n,).
        t_start: Start time :math:`t_0` of the move [s].
        duration: Duration :math:`T > 0` of the move [s].

    Raises:
        DimensionError: If ``q_start`` and ``q_goal`` are not two vectors of one shape (n,).
        NonFiniteError: If an argument is NaN or infinite.
        ConfigError: If ``duration`` is not > 0.
    """

    def __init__(self, q_start, q_goal, t_start: float, duration: float):

        q0 = np.asarray(q_start, dtype=float)
        q1 = np.asarray(q_goal, dtype=float)
        if q0.ndim != 1 or q0.size == 0 or q1.shape != q0.shape:
            raise DimensionError(
                f"q_start has shape {q0.shape} and q_goal has shape {q1.shape}; "
                "pass two joint vectors of the same shape (n,)"
            )
        for name, value in (("q_start", q0), ("q_goal", q1)):
            if not np.all(np.isfinite(value)):
                raise NonFiniteError(name, value, "in QuinticReference")
        for name, value in (("t_start", t_start), ("duration", duration)):
            if not np.isfinite(value):
                raise NonFiniteError(name, value, "in QuinticReference")
        if not duration > 0:
            raise ConfigError(
                "QuinticReference.duration", f"{duration!r}; expected a duration > 0 [s]"
            )
        self.n = q0.size
        self.q_start = q0.copy()
        self.q_goal = q1.copy()
        self.t_start = float(t_start)
        self.duration = float(duration)
        self._delta = q1 - q0

    @property
    def t_end(self) -> float:
        """End time :math:`t_0 + T` of the move [s]."""
        return self.t_start + self.duration

    def _phase(self, t):
        return np.clip((np.asarray(t, dtype=float) - self.t_start) / self.duration, 0.0, 1.0)

    def _form(self) -> PolynomialSampling:
        """The move as a piecewise polynomial in :math:`s = t - t_0` for the compiled
        sampler (:class:`~hmpc_pin.tasks.base.CompiledSampling`): hold :math:`q_{start}`,
        then :math:`q = q_{start} + \\Delta(10\\sigma^3 - 15\\sigma^4 + 6\\sigma^5)`,
        :math:`\\sigma = s/T` expanded in powers of :math:`s`, then hold
        :math:`q_{start} + \\Delta`."""
        n, T, d = self.n, self.duration, self._delta
        c = np.zeros((3, 6, 2 * n))
        c[0, 0, :n] = self.q_start
        c[1, 0, :n] = self.q_start
        c[1, 3, :n], c[1, 4, :n], c[1, 5, :n] = 10.0 * d / T**3, -15.0 * d / T**4, 6.0 * d / T**5
        c[1, 2, n:], c[1, 3, n:], c[1, 4, n:] = 30.0 * d / T**3, -60.0 * d / T**4, 30.0 * d / T**5
        c[2, 0, :n] = self.q_start + d
        t0, t1 = self.t_start, self.t_start + T
        return PolynomialSampling(
            np.array([t0, t1]), np.array([t0 - 1.0, t0, t1]), c.reshape(-1, 2 * n), 5
        )

    def acceleration(self, t: float) -> np.ndarray:
        """Reference acceleration [rad/s²] at ``t`` [s], shape (n,)."""
        s = float(self._phase(t))
        return self._delta * (60.0 * s * (1.0 - s) * (1.0 - 2.0 * s) / self.duration**2)

    def __repr__(self) -> str:
        return (
            f"QuinticReference(q_start={self.q_start.tolist()}, q_goal={self.q_goal.tolist()}, "
            f"t_start={self.t_start}, duration={self.duration})"
        )
