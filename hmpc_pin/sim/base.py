"""The plant protocol: what a closed loop (simulated or real-time) needs from the arm."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from ..exceptions import HmpcError, NonFiniteError, SimulationError

__all__ = ["Plant", "state_error"]

FloatArray = NDArray[np.float64]


@runtime_checkable
class Plant(Protocol):
    """An arm advanced one control period at a time with the torque held.

    Attributes:
        nq: Number of joints n.
        Ts: Control period [s]: :meth:`advance` integrates over it.
        t: Current time [s].
    """

    nq: int
    Ts: float
    t: float

    def reset(self, q0: FloatArray, dq0: FloatArray, t0: float = 0.0) -> None:
        """Start at ``q0`` [rad], ``dq0`` [rad/s] (each (n,)) at time ``t0`` [s]."""
        ...

    def advance(self, tau: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Hold ``tau`` [N·m] over one period; return new ``(q, dq)`` at ``t + Ts``."""
        ...

    def disturbance_now(self) -> FloatArray:
        """The disturbance :math:`d(t, q, \\dot q)` [N·m] at the current time and state."""
        ...


def state_error(q: np.ndarray, dq: np.ndarray, t: float, state_bound: float) -> HmpcError:
    """The error of a plant state ``(q, dq)`` at ``t`` [s] that failed the test
    :math:`|q|, |\\dot q| \\le` ``state_bound``: not finite, or diverged."""
    if not (np.isfinite(q).all() and np.isfinite(dq).all()):
        return NonFiniteError("plant state", (q, dq), f"at t={t:.6g}")
    return SimulationError(
        f"run diverged at t={t:.6g}: max |q|={np.abs(q).max():.3g}, "
        f"max |dq|={np.abs(dq).max():.3g} exceed state_bound={state_bound}"
    )
