"""``[simulation]``: the run's duration and initial state."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._fields import _array, _float, _set


@dataclass(frozen=True, eq=False)
class SimulationConfig:
    """Closed-loop run settings.

    Attributes:
        duration: Simulated time [s] (paper: 10).
        q0: Initial joint angles [rad] (paper: 1, 1, 1); ``None`` starts on the
            reference, r(0) (for a Cartesian motion: the start pose's IK solution).
        dq0: Initial joint velocities [rad/s] (paper: 0).
        state_bound: The run stops as diverged (``complete = False``, CLI exit 1) at the
            first control period after which any |q| [rad] or |q̇| [rad/s] of the plant
            exceeds it (default 1e3).
    """

    duration: float = 10.0
    q0: np.ndarray | None = None
    dq0: np.ndarray = 0.0
    state_bound: float = 1e3

    def __post_init__(self):
        _set(self, "duration", _float("duration", self.duration, positive=True))
        if self.q0 is not None:
            _set(self, "q0", _array("q0", self.q0))
        _set(self, "dq0", _array("dq0", self.dq0))
        _set(self, "state_bound", _float("state_bound", self.state_bound, positive=True))
