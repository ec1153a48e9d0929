"""The sine reference of the paper, Eq (31)."""

from __future__ import annotations

import numpy as np

from .base import CompiledSampling, SineSampling

__all__ = ["SineReference"]


class SineReference(CompiledSampling):
    """:math:`r_i(t) = o_i + a_i\\sin(2\\pi f_i t + \\phi_i)`, Eq (31).

    Sampled by the compiled sampler (:class:`~hmpc_pin.tasks.base.CompiledSampling`).
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

    def _form(self) -> SineSampling:
        """The compiled sampler's :math:`q = o + a\\sin(\\omega t + \\phi)`,
        :math:`\\dot q = (a\\omega)\\cos(\\omega t + \\phi)`."""
        return SineSampling(self.omega, self.phase, self.amplitude, self.offset, self._amp_omega)

    def acceleration(self, t: float) -> np.ndarray:
        """Reference acceleration [rad/s²] at ``t``."""
        return -self.amplitude * self.omega**2 * np.sin(self.omega * t + self.phase)
