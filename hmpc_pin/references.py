"""Joint-space references: the sine of Eq 31, a quintic point-to-point move (Section 5.4).

A reference is any object with ``sample(t) -> (q_ref, dq_ref)`` returning two
arrays of shape (n,) [rad, rad/s]. The MPC samples it at the future instants of
its horizon; a reference may also provide ``sample_many(times)`` returning two
arrays of shape (len(times), n) to do that in one vectorised call.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from .exceptions import LimitError

__all__ = [
    "QuinticReference",
    "Reference",
    "SineReference",
    "check_limits",
    "sample_horizon",
]


@runtime_checkable
class Reference(Protocol):
    """Anything with ``sample(t) -> (q_ref, dq_ref)``."""

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray]: ...


class SineReference:
    """:math:`r_i(t) = o_i + a_i\\sin(2\\pi f_i t + \\phi_i)`, Eq (31).

    The paper's reference is ``SineReference(n=3)``: :math:`r_i = \\sin(0.2\\pi t)`,
    :math:`\\dot r_i = 0.2\\pi\\cos(0.2\\pi t)`.

    Args:
        n: Number of joints.
        amplitude: a [rad], scalar or (n,).
        frequency: f [Hz], scalar or (n,) (paper: 0.1 Hz = 0.2π rad/s).
        offset: o [rad], scalar or (n,).
        phase: φ [rad], scalar or (n,).
    """

    def __init__(self, n: int, amplitude=1.0, frequency=0.1, offset=0.0, phase=0.0):
        self.n = int(n)
        shape = (self.n,)
        self.amplitude = np.broadcast_to(np.asarray(amplitude, float), shape).copy()
        self.omega = 2.0 * np.pi * np.broadcast_to(np.asarray(frequency, float), shape)
        self.offset = np.broadcast_to(np.asarray(offset, float), shape).copy()
        self.phase = np.broadcast_to(np.asarray(phase, float), shape).copy()
        self._amp_omega = self.amplitude * self.omega
        self._tiles: dict[int, tuple[np.ndarray, ...]] = {}

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Reference angle [rad] and velocity [rad/s] at time ``t`` [s]."""
        arg = self.omega * t + self.phase
        return self.offset + self.amplitude * np.sin(arg), self._amp_omega * np.cos(arg)

    def sample_many(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Vectorised :meth:`sample`: arrays of shape (len(times), n)."""
        times = np.asarray(times, dtype=float)
        m = times.size
        if times.ndim != 1:
            m = -1
        # Flat (m·n,) operations on the coefficients tiled once per length (the MPC
        # samples its horizon, always of one length, every step): element for element
        # the same arithmetic as sample(), with fewer and cheaper numpy calls than
        # broadcasting (m, 1) against (n,).
        if m < 0:
            return self._sample_many_broadcast(times)
        omega, phase, amplitude, offset, amp_omega = self._tiles_for(m)
        arg = times.repeat(self.n)
        arg *= omega
        arg += phase
        q = np.sin(arg)
        q *= amplitude
        q += offset
        np.cos(arg, out=arg)
        arg *= amp_omega
        shape = (m, self.n)
        return q.reshape(shape), arg.reshape(shape)

    def _sample_into(
        self, t: float, offsets: np.ndarray, q_out: np.ndarray, dq_out: np.ndarray
    ) -> None:
        """``sample_many(t + o)`` for horizon offsets ``o`` given repeated per joint
        (``o.repeat(n)``), written into two C-contiguous (len(o)·n,) buffers row after
        row (the controller's horizon stack): the same arithmetic, one allocation."""
        omega, phase, amplitude, offset, amp_omega = self._tiles_for(offsets.size // self.n)
        arg = offsets + t
        arg *= omega
        arg += phase
        np.sin(arg, out=q_out)
        q_out *= amplitude
        q_out += offset
        np.cos(arg, out=dq_out)
        dq_out *= amp_omega

    def _tiles_for(self, m: int) -> tuple[np.ndarray, ...]:
        tiles = self._tiles.get(m)
        if tiles is None:
            tiles = tuple(
                np.tile(c, m)
                for c in (self.omega, self.phase, self.amplitude, self.offset, self._amp_omega)
            )
            if len(self._tiles) < 8:
                self._tiles[m] = tiles
        return tiles

    def _sample_many_broadcast(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        arg = np.multiply.outer(times, self.omega)
        arg += self.phase
        q = np.sin(arg)
        q *= self.amplitude
        q += self.offset
        np.cos(arg, out=arg)
        arg *= self._amp_omega
        return q, arg

    def acceleration(self, t: float) -> np.ndarray:
        """Reference acceleration [rad/s²] at ``t``."""
        return -self.amplitude * self.omega**2 * np.sin(self.omega * t + self.phase)


def sample_horizon(reference, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sample ``reference`` at ``times``; returns (q_ref, dq_ref), each (len(times), n)."""
    many = getattr(reference, "sample_many", None)
    if many is not None:
        q, dq = many(times)
        return np.asarray(q, float), np.asarray(dq, float)
    pairs = [reference.sample(float(t)) for t in times]
    return (
        np.array([p[0] for p in pairs], dtype=float),
        np.array([p[1] for p in pairs], dtype=float),
    )


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
        from .exceptions import ConfigError, DimensionError, NonFiniteError

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

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Reference angle [rad] and velocity [rad/s] at time ``t`` [s], each of shape (n,)."""
        s = float(self._phase(t))
        shape = s**3 * (10.0 + s * (-15.0 + 6.0 * s))
        rate = 30.0 * s**2 * (1.0 - s) ** 2 / self.duration
        return self.q_start + self._delta * shape, self._delta * rate

    def sample_many(self, times) -> tuple[np.ndarray, np.ndarray]:
        """Vectorised :meth:`sample`: arrays of shape (len(times), n)."""
        s = self._phase(np.atleast_1d(times))[:, None]
        shape = s**3 * (10.0 + s * (-15.0 + 6.0 * s))
        rate = 30.0 * s**2 * (1.0 - s) ** 2 / self.duration
        return self.q_start + self._delta * shape, self._delta * rate

    def acceleration(self, t: float) -> np.ndarray:
        """Reference acceleration [rad/s²] at ``t`` [s], shape (n,)."""
        s = float(self._phase(t))
        return self._delta * (60.0 * s * (1.0 - s) * (1.0 - 2.0 * s) / self.duration**2)

    def __repr__(self) -> str:
        return (
            f"QuinticReference(q_start={self.q_start.tolist()}, q_goal={self.q_goal.tolist()}, "
            f"t_start={self.t_start}, duration={self.duration})"
        )


def check_limits(
    reference,
    lower: np.ndarray,
    upper: np.ndarray,
    times: np.ndarray,
    joint_names: tuple[str, ...],
    *,
    tol: float = 1e-9,
) -> None:
    """Check that ``reference`` stays within ``[lower − tol, upper + tol]`` at ``times``.

    Raises:
        LimitError: Naming the first joint and time where the reference leaves its limits.
    """
    q_ref, _ = sample_horizon(reference, np.asarray(times, dtype=float))
    out = (q_ref < lower - tol) | (q_ref > upper + tol)
    if out.any():
        k, i = np.argwhere(out)[0]
        raise LimitError(
            "reference", joint_names[i], float(times[k]), float(q_ref[k, i]), lower[i], upper[i]
        )
