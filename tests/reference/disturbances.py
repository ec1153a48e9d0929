"""Oracles of the compiled disturbances (``cpp/src/disturbances.cpp``), from the closed forms.

* The Gaussian pulse of Eq (33): :math:`d_i = a_i\\exp(-(t - b_i)^2 / (2\\sigma_i^2))`.
* The friction of Eq (32) with the physical sign: :math:`d_i = -(a_i\\dot q_i + b_i\\,
  \\mathrm{sgn}\\,\\dot q_i)`, :math:`\\mathrm{sgn}\\,0 = 0`.
"""

from __future__ import annotations

import numpy as np


def pulses(amplitude, center, sigma, times):
    """(m, n) [N·m] at ``times`` (m,) [s]."""
    t = np.asarray(times, dtype=float)[:, None]
    return amplitude * np.exp(-((t - center) ** 2) / (2.0 * np.asarray(sigma) ** 2))


def friction(viscous, coulomb, dq):
    """(n,) [N·m] at the velocities ``dq`` [rad/s]."""
    dq = np.asarray(dq, dtype=float)
    return -(viscous * dq + coulomb * np.sign(dq))
