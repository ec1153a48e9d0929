"""A quintic (minimum-jerk) joint move, used for the Cartesian motion of Section 5.4."""

from __future__ import annotations

import numpy as np

from ..exceptions import ConfigError, DimensionError, NonFiniteError
from .base import FloatArray, Pair, _write

__all__ = ["QuinticReference"]


class QuinticReference:
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
        # sample_many: [s^0..s^5] @ coefficients = [1, shape, rate] with shape(s) =
        # 10 s³ − 15 s⁴ + 6 s⁵ and rate(s) = 30 s²(1 − s)²/T = (30 s² − 60 s³ + 30 s⁴)/T.
        self._work: dict[int, tuple[np.ndarray, ...]] = {}
        c = np.zeros((6, 3))
        c[0, 0] = 1.0
        c[3:, 1] = (10.0, -15.0, 6.0)
        c[2:5, 2] = np.array([30.0, -60.0, 30.0]) / self.duration
        self._coefficients = c
        # [1, shape, rate] @ [q_start; Δ; 0] = q_start + Δ·shape, @ [0; 0; Δ] = Δ·rate
        self._to_q = np.vstack([q0, self._delta, np.zeros_like(q0)])
        self._to_dq = np.vstack([np.zeros_like(q0), np.zeros_like(q0), self._delta])
        self._out: Pair | None = None

    @property
    def t_end(self) -> float:
        """End time :math:`t_0 + T` of the move [s]."""
        return self.t_start + self.duration

    def _phase(self, t):
        return np.clip((np.asarray(t, dtype=float) - self.t_start) / self.duration, 0.0, 1.0)

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Reference angle [rad] and velocity [rad/s] at time ``t`` [s], each of shape (n,)."""
        s = float(self._phase(t))
        shape = s**3 * (10.0 + s * (-15.0 + 6.0 * s))
        rate = 30.0 * s**2 * (1.0 - s) ** 2 / self.duration
        return self.q_start + self._delta * shape, self._delta * rate

    def sample_many(self, times: FloatArray, out: Pair | None = None) -> Pair:
        """Vectorised :meth:`sample`: arrays of shape (len(times), n), written into
        ``out`` when given (the :class:`~hmpc_pin.tasks.base.Reference` protocol).

        Evaluated as products, few numpy calls (the MPC samples its horizon every step):
        the powers :math:`[s^0 \\dots s^5]` of every phase (a cumulative product) times a
        (6, 3) coefficient matrix give :math:`[1, \\text{shape}, \\text{rate}]`, and that
        times :math:`[q_{start}; \\Delta; 0]` and :math:`[0; 0; \\Delta]` the two outputs
        (equal to :meth:`sample` up to rounding, tested).
        """
        t = np.asarray(times, dtype=float)
        if t.ndim != 1:
            s = self._phase(np.atleast_1d(t))[..., None]
            shape = s**3 * (10.0 + s * (-15.0 + 6.0 * s))
            rate = 30.0 * s**2 * (1.0 - s) ** 2 / self.duration
            return _write((self.q_start + self._delta * shape, self._delta * rate), out)
        m = t.size
        work = self._work.get(m)
        if work is None:  # buffers per length (the MPC's horizon: always one length)
            powers = np.ones((m, 6))
            s_col = np.empty((m, 1))
            work = (powers, powers[:, 1:], s_col, s_col[:, 0])
            if len(self._work) < 8:
                self._work[m] = work
        powers, rest, s_col, s = work
        np.subtract(t, self.t_start, out=s)
        np.divide(s, self.duration, out=s)
        np.maximum(s, 0.0, out=s)
        np.minimum(s, 1.0, out=s)
        rest[...] = s_col
        np.multiply.accumulate(rest, axis=1, out=rest)  # (m, 6): s^0 .. s^5
        one_shape_rate = powers.dot(self._coefficients)  # (m, 3): 1, shape, rate
        if out is not None and (out is self._out or self._fits(out, m)):
            self._out = out  # the controller passes the same buffers every step
            np.dot(one_shape_rate, self._to_q, out=out[0])
            np.dot(one_shape_rate, self._to_dq, out=out[1])
            return out
        q = one_shape_rate.dot(self._to_q)
        dq = one_shape_rate.dot(self._to_dq)
        return _write((q, dq), out)

    def native_form(self) -> tuple | None:
        """The move as a piecewise polynomial in :math:`s = t - t_0` for the native step
        (:mod:`hmpc_pin.tasks.base`): hold :math:`q_{start}`, then
        :math:`q = q_{start} + \\Delta(10\\sigma^3 - 15\\sigma^4 + 6\\sigma^5)`,
        :math:`\\sigma = s/T` expanded in powers of :math:`s`, then hold
        :math:`q_{start} + \\Delta`; ``None`` for a subclass that samples otherwise."""
        cls = type(self)
        if cls.sample_many is not QuinticReference.sample_many or (
            cls.sample is not QuinticReference.sample
        ):
            return None
        n, T, d = self.n, self.duration, self._delta
        c = np.zeros((3, 6, 2 * n))
        c[0, 0, :n] = self.q_start
        c[1, 0, :n] = self.q_start
        c[1, 3, :n], c[1, 4, :n], c[1, 5, :n] = 10.0 * d / T**3, -15.0 * d / T**4, 6.0 * d / T**5
        c[1, 2, n:], c[1, 3, n:], c[1, 4, n:] = 30.0 * d / T**3, -60.0 * d / T**4, 30.0 * d / T**5
        c[2, 0, :n] = self.q_start + d
        t0, t1 = self.t_start, self.t_start + T
        return ("ppoly", np.array([t0, t1]), np.array([t0 - 1.0, t0, t1]), c.reshape(-1, 2 * n), 5)

    def _fits(self, out: Pair, m: int) -> bool:
        """Whether ``out`` holds two C-contiguous float arrays of shape (m, n)."""
        shape = (m, self.n)
        return all(a.shape == shape and a.dtype == np.float64 and a.flags.c_contiguous
                   for a in out)  # fmt: skip

    def acceleration(self, t: float) -> np.ndarray:
        """Reference acceleration [rad/s²] at ``t`` [s], shape (n,)."""
        s = float(self._phase(t))
        return self._delta * (60.0 * s * (1.0 - s) * (1.0 - 2.0 * s) / self.duration**2)

    def __repr__(self) -> str:
        return (
            f"QuinticReference(q_start={self.q_start.tolist()}, q_goal={self.q_goal.tolist()}, "
            f"t_start={self.t_start}, duration={self.duration})"
        )
