"""Numpy oracle of the latency-aware step's two parts (compiled: ``cpp/src/latency.cpp``,
``HierarchicalStep.set_latency``), written from their definitions.

With the measurement at :math:`t_k` describing the arm at :math:`t_k - L`,
:math:`L = (m + \\alpha) T_s`, :math:`0 \\le \\alpha < 1`:

* the observer's interval :math:`[t_{k-1} - L, t_k - L]` saw :math:`\\tau_{k-2-m}` for
  :math:`\\alpha T_s` and :math:`\\tau_{k-1-m}` for :math:`(1 - \\alpha) T_s`: its input is the
  mean :math:`\\alpha\\tau_{k-2-m} + (1 - \\alpha)\\tau_{k-1-m}`;
* the state at :math:`t_k` is the measured one carried over :math:`[t_k - L, t_k]` by
  :math:`\\ddot q = v` with the accelerations commanded then (piecewise constant).
"""

from __future__ import annotations

import math

import numpy as np


def split(L: float, Ts: float) -> tuple[int, float]:
    """``(m, alpha)`` with :math:`L = (m + \\alpha)T_s`."""
    m = math.floor(L / Ts + 1e-9)
    alpha = L / Ts - m
    return m, (0.0 if alpha < 1e-9 else alpha)


def aligned(history: list[np.ndarray], k: int, L: float, Ts: float) -> np.ndarray:
    """The mean of the torques ``history[j]`` (held over :math:`[t_j, t_{j+1})`) over
    :math:`[t_{k-1} - L, t_k - L]`, by integrating the piecewise-constant torque."""
    a, b = (k - 1) * Ts - L, k * Ts - L
    total = np.zeros_like(history[0])
    for j, tau in enumerate(history):
        lo, hi = max(a, j * Ts), min(b, (j + 1) * Ts)
        if hi > lo:
            total += (hi - lo) * tau
    return total / Ts


def predict(q, dq, v_history: list[np.ndarray], k: int, L: float, Ts: float):
    """Carry ``(q, dq)`` from :math:`t_k - L` to :math:`t_k` with :math:`\\ddot q = v_j`
    over :math:`[t_j, t_{j+1})` (zero before the start), in fine Euler-exact segments."""
    q, dq = np.array(q, float), np.array(dq, float)
    t = k * Ts - L
    while t < k * Ts - 1e-15:
        j = math.floor(t / Ts + 1e-12)
        end = min((j + 1) * Ts, k * Ts)
        h = end - t
        v = v_history[j] if 0 <= j < len(v_history) else np.zeros_like(q)
        q = q + h * dq + 0.5 * h * h * v
        dq = dq + h * v
        t = end
    return q, dq
