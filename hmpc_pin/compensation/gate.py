"""A compensation whose estimate can be switched off while it keeps observing.

:class:`FeedbackGate` wraps any :class:`~hmpc_pin.compensation.base.Compensation`: the
wrapped one is updated every period as usual (it sees the torque actually held, which
the controller computed with the gate's output), but what the controller cancels is

.. math::  \\hat d_\\mathrm{fed} = \\begin{cases} \\hat d & \\text{feedback on} \\\\
           0 & \\text{feedback off,} \\end{cases}

so that a reaction (e.g. the collision ``stop`` of
:class:`~hmpc_pin.controllers.wrappers.CollisionReaction`) can stop feeding the estimate
back and still watch it.
"""

from __future__ import annotations

import numpy as np

from .base import Compensation, FloatArray

__all__ = ["FeedbackGate"]


class FeedbackGate:
    """The estimate of ``inner`` fed back while :attr:`feed_back` is true, else zeros.

    Attributes:
        inner: The wrapped compensation (its ``estimate`` is the observed one).
        feed_back: Whether the estimate is cancelled in τ; ``True`` after :meth:`reset`.
    """

    def __init__(self, inner: Compensation):
        self.inner = inner
        self.feed_back = True
        self._zeros = np.zeros_like(np.asarray(inner.estimate, dtype=float))

    @property
    def estimate(self) -> FloatArray:
        """The estimate fed back [N·m]: the inner one, or zeros with feedback off."""
        return self.inner.estimate if self.feed_back else self._zeros

    @property
    def observed(self) -> FloatArray:
        """The inner compensation's estimate :math:`\\hat d` [N·m], fed back or not."""
        return self.inner.estimate

    def reset(self, q0: FloatArray, dq0: FloatArray) -> None:
        """Reset the inner compensation; feedback on."""
        self.inner.reset(q0, dq0)
        self.feed_back = True
        self._zeros = np.zeros_like(np.asarray(self.inner.estimate, dtype=float))

    def update(self, M, nle, q, dq, tau, v) -> FloatArray:
        """Update the inner compensation; return what is fed back [N·m]."""
        estimate = self.inner.update(M, nle, q, dq, tau, v)
        return estimate if self.feed_back else self._zeros.copy()
