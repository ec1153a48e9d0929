"""``[collision]``: the collision reaction on the observer's estimate."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._fields import _array, _choice, _set


@dataclass(frozen=True, eq=False)
class CollisionConfig:
    """Collision detection on the disturbance estimate, and the reaction to it.

    A collision is flagged at the first control instant at which
    :math:`|\\hat d_i| > \\text{threshold}_i` for some joint i (the observer as a
    contact-torque estimator).

    Attributes:
        threshold: Estimate magnitude [N·m] that flags a collision, per joint or one value.
        reaction: ``"ignore"`` (keep compensating, the paper's behaviour: the arm keeps
            pushing) or ``"stop"`` (hold the position reached, the estimate no longer
            fed back).
    """

    threshold: np.ndarray = 1.0
    reaction: str = "ignore"

    def __post_init__(self):
        _set(self, "threshold", _array("threshold", self.threshold, positive=True))
        _set(self, "reaction", _choice("reaction", self.reaction, ("ignore", "stop")))
