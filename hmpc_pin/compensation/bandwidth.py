"""Observer gains in bandwidth units, and the rule relating bandwidth, Ts and latency.

A bandwidth :math:`\\omega_j` [1/s] is the rate at which joint j's estimation error decays:
:math:`\\dot w_j = -\\omega_j w_j` for a constant disturbance. For the general NDO
(:math:`\\dot w = -cY M(q)^{-1} w`, Eq 18) it is obtained with :math:`cY = W M(q_0)`,
:math:`W = \\mathrm{diag}(\\omega)` (exact at :math:`q_0`); for the momentum observer it is
:math:`K_O` itself. An existing gain has the bandwidth :math:`\\omega_j = (cY M(q_0)^{-1})_{jj}`
(:func:`implied_bandwidth`).

**The rule.** Per period the implicit (backward-Euler) observer moves its estimate the
fraction :math:`g_j = T_s\\omega_j/(1 + T_s\\omega_j)` of the way to the residual it measures,
:math:`\\hat d_k = (1 - g)\\hat d_{k-1} + g\\,\\delta_k` with
:math:`\\delta_k = \\hat M\\,\\Delta\\dot q_k/T_s - \\tau`. Three cases:

1. *No latency, or a latency the controller compensates* (``[controller] latency``: the
   observer gets the torque applied over its measured interval). With a plant whose
   inertia is :math:`1/r` of the model's, :math:`\\hat d_k = \\hat d_{k-1} - g r\\,
   \\hat d_{k-1} + \\dots`: the pole :math:`1 - gr` lies in the unit circle for
   :math:`gr < 2`, i.e. for every bandwidth when :math:`r < 2` (implicit Euler). The
   explicit (forward-Euler) form has :math:`g = T_s\\omega` and needs
   :math:`T_s\\omega_j < 2` (pole :math:`1 - T_s\\omega_j`): a :class:`ConfigError` otherwise.
2. *A latency L the controller does not compensate* (:math:`D = L/T_s` periods): the
   observer pairs the velocity change caused by :math:`\\tau_{k-1-D}` with
   :math:`\\tau_{k-1}`. Its estimate then obeys :math:`e_k = e_{k-1} + g(v_{k-1} -
   a_{k-1-D})` (e: acceleration-level error, a = v + e the arm's acceleration): the
   loop from the commanded to the actual acceleration has the denominator
   :math:`z^{D+1} - z^D + gr`, stable only for :math:`gr < 2\\sin(\\pi/(2(2D+1)))`
   (1 for D = 1) and resonant near it (at :math:`f_s/6` for D = 1: the 16–17 Hz
   oscillation seen at 100 Hz), and the outer loop closes around that resonance. In the
   continuous limit (:math:`2\\sin x \\approx 2x`) the condition reads
   :math:`\\omega r (T_s/2 + L) < \\pi/2`.
3. *The rule this package checks* keeps a margin for the outer loop:

   .. math::  \\omega_j\\, r\\, (T_s + L_u) \\le \\tfrac12,

   with :math:`L_u` the latency not compensated and r the worst plant-to-model inertia
   ratio (1.25: a link 20 % lighter). Measured on a joint with the package's observer
   (``benchmarks/observer_rule.py``), the largest stable :math:`T_s\\omega` with a PD outer
   loop (kp = 100, kd = 20) / the paper MPC's equivalent gains (274, 22.7) is 1.26 / 1.0 at
   D = 1 and 0.25 / 0.2 at D = 2 (r = 1.25), where the rule allows 0.2 and 0.13; at D = 3
   with the MPC's gains the rule is no longer conservative (0.032 stable, 0.1 allowed):
   declare such a latency.

:func:`check_bandwidth` applies it with :math:`L_u = T_s` (an interface cycle the controller
was not told about) when ``[controller] latency`` is 0, and with :math:`L_u = 0` (no bound
but the explicit form's) when a latency is declared.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from ..exceptions import ConfigError, ValidityWarning

__all__ = [
    "MASS_RATIO",
    "RULE",
    "bandwidth_limit",
    "check_bandwidth",
    "compensation_bandwidth",
    "implied_bandwidth",
    "latency_tolerance",
    "observer_cY",
]

#: The worst plant-to-model inertia ratio the rule is checked for (a link 20 % lighter).
MASS_RATIO = 1.25
#: The bound of :math:`\\omega r (T_s + L_u)`.
RULE = 0.5


def bandwidth_limit(Ts: float, uncompensated: float, mass_ratio: float = MASS_RATIO) -> float:
    """The largest bandwidth [1/s] the rule allows: :math:`\\tfrac12 / (r (T_s + L_u))`
    with :math:`L_u` = ``uncompensated`` [s]; ``inf`` when :math:`L_u = 0` (case 1 of the
    module docstring: any bandwidth is stable with the implicit observer)."""
    if uncompensated <= 0:
        return math.inf
    return RULE / (mass_ratio * (Ts + uncompensated))


def observer_cY(bandwidth: np.ndarray, M0: np.ndarray) -> np.ndarray:
    """:math:`cY = \\mathrm{diag}(\\omega) M(q_0)` [N·m·s/rad per 1/s]: the general NDO
    whose error decays at :math:`\\omega_j` on joint j at :math:`q_0`."""
    return np.diag(np.asarray(bandwidth, dtype=float)) @ np.asarray(M0, dtype=float)


def implied_bandwidth(cY: np.ndarray, M0: np.ndarray) -> np.ndarray:
    """Per joint :math:`(cY M(q_0)^{-1})_{jj}` [1/s]: the bandwidth of a gain."""
    return np.diag(np.linalg.solve(np.asarray(M0).T, np.asarray(cY).T).T).copy()


def check_bandwidth(
    bandwidth: np.ndarray,
    Ts: float,
    latency: float,
    joint_names,
    *,
    explicit: bool = False,
    key: str = "controller.observer.bandwidth",
) -> None:
    """Apply the rule (module docstring) to per-joint ``bandwidth`` [1/s].

    Args:
        bandwidth: :math:`\\omega_j` [1/s], (n,).
        Ts: Control period [s].
        latency: The latency the controller compensates [s] (``[controller] latency``).
        joint_names: Names of the joints, for the messages.
        explicit: The observer is the forward-Euler form.
        key: The config key named in the messages.

    Raises:
        ConfigError: ``explicit`` and :math:`T_s\\omega_j \\ge 2` (the pole
            :math:`1 - T_s\\omega_j` outside the unit circle), naming the joint.

    Warns:
        ValidityWarning: With ``latency`` 0, the joints whose bandwidth exceeds
            :func:`bandwidth_limit` for one unknown control period of latency.
    """
    w = np.asarray(bandwidth, dtype=float)
    names = list(joint_names)
    if explicit:
        bad = np.flatnonzero(Ts * w >= 2.0)
        if bad.size:
            j = int(bad[0])
            raise ConfigError(
                key, f"joint {names[j]!r}: Ts·ω = {Ts * w[j]:.3g} >= 2 puts the explicit "
                f"observer's pole 1 - Ts·ω outside the unit circle; use ω < {2 / Ts:.4g} 1/s "
                "or discretization = 'implicit'",
            )  # fmt: skip
    if latency > 0:
        return
    limit = bandwidth_limit(Ts, Ts)
    bad = np.flatnonzero(w > limit)
    if bad.size:
        listed = ", ".join(f"{names[j]!r} ({w[j]:.4g} 1/s)" for j in bad)
        warnings.warn(
            f"{key}: joint(s) {listed} above {limit:.4g} 1/s, the bound ω·r·(Ts + L) <= 1/2 "
            f"for an unknown latency of one period (L = Ts = {Ts:g} s) and a link 20 % "
            "lighter (r = 1.25); an arm's interface delays its measurements: declare the "
            "latency ([controller] latency, then any bandwidth is stable) or lower the "
            "bandwidth (guide 'Sensing and latency')",
            ValidityWarning,
            stacklevel=4,
        )


def compensation_bandwidth(compensation, M0: np.ndarray) -> np.ndarray | None:
    """Per joint the bandwidth [1/s] of ``compensation`` at the mass matrix ``M0``:
    :func:`implied_bandwidth` of an NDO (its ``cY``), the momentum observer's ``K``;
    ``None`` for a compensation that is not an observer."""
    cY = getattr(compensation, "cY", None)
    if cY is not None:
        return implied_bandwidth(cY, M0)
    K = getattr(compensation, "K", None)
    if K is not None:
        return np.asarray(K, dtype=float).copy()
    return None


def latency_tolerance(bandwidth: np.ndarray | None, Ts: float, period: float) -> float:
    """How far [s] a measured latency may lie from the declared one
    (``[controller] latency``) before the real-time loop warns.

    A measured latency above the declared one leaves :math:`L_u` = the difference
    uncompensated; the rule (module docstring) tolerates it while
    :math:`\\omega_{\\max} r (T_s + L_u) \\le 1/2`, i.e. up to
    :math:`1/(2 r \\omega_{\\max}) - T_s`. The measured age has the granularity of the
    interface period P (a state every P), so half a period is always tolerated:

    .. math:: \\Delta L = \\max(P/2,\\ 1/(2 r \\omega_{\\max}) - T_s)

    (:math:`P/2` without an observer). A declared latency above the measured one by more
    than :math:`\\Delta L` is reported too: the controller then predicts the state further
    ahead than it is old.

    Args:
        bandwidth: The observer's bandwidth per joint [1/s] (``None``: no observer).
        Ts: Control period [s].
        period: Interface period P [s].
    """
    tol = 0.5 * period
    if bandwidth is not None and np.size(bandwidth):
        w = float(np.max(bandwidth))
        if w > 0:
            tol = max(tol, RULE / (MASS_RATIO * w) - Ts)
    return tol
