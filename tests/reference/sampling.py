"""Oracles of the compiled references (``cpp/src/references.cpp``), from the closed forms.

* The sine of Eq (31): :math:`q = o + a\\sin(\\omega t + \\phi)`,
  :math:`\\dot q = a\\omega\\cos(\\omega t + \\phi)`.
* The quintic move of Section 5.4 in its phase :math:`\\sigma = \\mathrm{clip}((t - t_0)/T, 0,
  1)`: :math:`q = q_0 + \\Delta(10\\sigma^3 - 15\\sigma^4 + 6\\sigma^5)`,
  :math:`\\dot q = 30\\Delta\\sigma^2(1 - \\sigma)^2/T` (the compiled sampler evaluates the
  same move expanded in powers of :math:`t - t_0`).
* A piecewise polynomial: the segment of :math:`t` found by a search over the breakpoints,
  then :math:`\\sum_j c_j s^j` with the powers formed explicitly (the compiled sampler uses
  Horner-like accumulation).
"""

from __future__ import annotations

import numpy as np


def sine(ref, times):
    arg = np.multiply.outer(np.asarray(times, dtype=float), ref.omega) + ref.phase
    return ref.offset + ref.amplitude * np.sin(arg), ref.amplitude * ref.omega * np.cos(arg)


def quintic(ref, times):
    sigma = np.clip((np.asarray(times, dtype=float) - ref.t_start) / ref.duration, 0.0, 1.0)
    sigma = sigma[:, None]
    delta = ref.q_goal - ref.q_start
    q = ref.q_start + delta * (10 * sigma**3 - 15 * sigma**4 + 6 * sigma**5)
    return q, delta * 30.0 * sigma**2 * (1.0 - sigma) ** 2 / ref.duration


def ppoly(times_k, knots, coef, degree, n, times):
    """``coef``: ((K + 1)·(degree + 1), 2n), [q | q̇] per power, segment by segment."""
    t = np.asarray(times, dtype=float)
    seg = np.searchsorted(times_k, t, side="right")
    s = t - knots[seg]
    blocks = coef.reshape(-1, degree + 1, 2 * n)[seg]  # (m, degree + 1, 2n)
    powers = s[:, None] ** np.arange(degree + 1)
    both = np.einsum("mj,mjk->mk", powers, blocks)
    return both[:, :n], both[:, n:]
