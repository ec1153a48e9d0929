"""Joint-space references: the paper's sine (Eq 31) and the reference protocol.

A reference is any object with ``sample(t) -> (q_ref, dq_ref)`` returning two
arrays of shape (n,) [rad, rad/s]. The MPC samples it at the future instants of
its horizon; a reference may also provide ``sample_many(times)`` returning two
arrays of shape (len(times), n) to do that in one vectorised call.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

__all__ = ["Reference", "SineReference", "sample_horizon"]


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

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Reference angle [rad] and velocity [rad/s] at time ``t`` [s]."""
        arg = self.omega * t + self.phase
        return self.offset + self.amplitude * np.sin(arg), self.amplitude * self.omega * np.cos(arg)

    def sample_many(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Vectorised :meth:`sample`: arrays of shape (len(times), n)."""
        arg = np.multiply.outer(times, self.omega) + self.phase
        return self.offset + self.amplitude * np.sin(arg), self.amplitude * self.omega * np.cos(arg)

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
