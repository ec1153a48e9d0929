"""Numpy oracle of the interface model (compiled: ``cpp/src/measurement.cpp``,
``SensingMeasurement``), written from its definitions with SciPy's cubic Hermite spline.

The arm's states :math:`(q_k, \\dot q_k)` at :math:`t_k = k T_s` define the motion: the cubic
Hermite spline through them, and :math:`q(t) = q_0 + t\\,\\dot q_0` before the start. At
:math:`t_k` the interface has sampled it at :math:`s = t_k - L - i T_\\mathrm{if}`,
:math:`i = m-1 \\ldots 0` (one sample at :math:`k = 0`); each sample is

* :math:`\\tilde q = \\Delta\\,\\mathrm{round}(q(s)/\\Delta)` (:math:`\\Delta = 0`: exact);
* :math:`\\tilde{\\dot q} = a (\\tilde q - \\tilde q_\\mathrm{prev})/T_\\mathrm{if}
  + (1 - a)\\,\\tilde{\\dot q}_\\mathrm{prev}` with the finite difference, the first sample
  :math:`\\dot q(s)`; without it :math:`\\dot q(s)`;

then noise :math:`\\sigma_q \\varepsilon, \\sigma_{\\dot q} \\varepsilon'` is added, and the
controller at :math:`t_k` gets the measurement of :math:`t_{\\max(0, k-D)}`.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicHermiteSpline


def motion(Ts: float, q: np.ndarray, dq: np.ndarray):
    """``(angle(t), velocity(t))`` of the states ``q, dq`` (K+1, n) at ``k Ts``."""
    times = Ts * np.arange(len(q))
    spline = CubicHermiteSpline(times, q, dq, axis=0) if len(q) > 1 else None

    def angle(t: float) -> np.ndarray:
        if t <= 0 or spline is None:
            return q[0] + min(t, 0.0) * dq[0]
        return spline(t)

    def velocity(t: float) -> np.ndarray:
        if t <= 0 or spline is None:
            return dq[0].copy()
        return spline(t, 1)

    return angle, velocity


def handed_over(
    Ts: float,
    q: np.ndarray,
    dq: np.ndarray,
    *,
    rate: float,
    latency: float = 0.0,
    step: np.ndarray | None = None,
    difference: bool = False,
    gain: float = 1.0,
    noise: np.ndarray | None = None,
    sigma: tuple[float, float] = (0.0, 0.0),
    delay: int = 0,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """The measurement handed over at each ``t_k`` for the states ``q, dq`` (K+1, n).

    Args:
        Ts: Control period [s]. rate: Interface rate [Hz]. latency: L [s].
        step: Encoder step Δ [rad] per joint (``None``: exact angles).
        difference: The velocity by finite difference (else the motion's).
        gain: a of the velocity's low-pass (1: none).
        noise: Standard normal draws, one row of 2n per measurement (``None``: none).
        sigma: (σ_q [rad], σ_q̇ [rad/s]). delay: D [periods].
    """
    Tif = 1.0 / rate
    m = round(Ts * rate)
    n = q.shape[1]
    taken = []
    prev_q = prev_v = None
    for k in range(len(q)):
        angle, velocity = motion(Ts, q[: k + 1], dq[: k + 1])
        for i in range(m - 1 if k else 0, -1, -1):
            s = k * Ts - latency - i * Tif
            qs = angle(s)
            if step is not None:
                qs = np.where(step > 0, step * np.round(qs / np.where(step > 0, step, 1)), qs)
            if not difference or prev_q is None:
                vs = velocity(s)
            else:
                vs = gain * (qs - prev_q) / Tif + (1 - gain) * prev_v
            prev_q, prev_v = qs, vs
        q_m, v_m = qs.copy(), vs.copy()
        if noise is not None:
            q_m = q_m + sigma[0] * noise[k, :n]
            v_m = v_m + sigma[1] * noise[k, n:]
        taken.append((q_m, v_m))
    return [taken[max(0, k - delay)] for k in range(len(q))]
