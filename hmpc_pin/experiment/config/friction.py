"""``[controller.friction]``: the arm's joint friction, compensated feed-forward."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ._fields import _array, _float, _set


@dataclass(frozen=True, eq=False)
class FrictionModelConfig:
    """A friction model of the arm that the controller cancels feed-forward.

    The torque :math:`\\tau_f = a\\,\\dot q + b\\,\\sigma(\\dot q)` is added to the
    controller's torque at the measured velocity, with :math:`\\sigma = \\mathrm{sgn}`
    (``smoothing = 0``) or :math:`\\tanh(\\dot q / v_s)`. The observer then estimates only
    what is left of the disturbance. ``hmpc-pin identify RUN.npz`` writes this table from
    a run (:mod:`hmpc_pin.identification.friction`). Applies to every controller ×
    compensation.

    Attributes:
        viscous: :math:`a` [N·m·s/rad], one value or one per joint (positive: friction
            opposing the motion, the package's sign convention).
        coulomb: :math:`b` [N·m], one value or one per joint.
        smoothing: :math:`v_s` [rad/s] of the sign, >= 0 (0: the exact sign, the model
            ``identify`` fits; a small value avoids torque chatter from velocity noise
            at rest).
    """

    viscous: np.ndarray = field(default_factory=lambda: np.array(0.0))
    coulomb: np.ndarray = field(default_factory=lambda: np.array(0.0))
    smoothing: float = 0.0

    def __post_init__(self):
        _set(self, "viscous", _array("viscous", self.viscous))
        _set(self, "coulomb", _array("coulomb", self.coulomb))
        _set(self, "smoothing", _float("smoothing", self.smoothing, nonneg=True))
