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
   (``benchmarks/studies/observer_rule.py``), the largest stable :math:`T_s\\omega` with a PD outer
   loop (kp = 100, kd = 20) / the paper MPC's equivalent gains (274, 22.7) is 1.26 / 1.0 at
   D = 1 and 0.25 / 0.2 at D = 2 (r = 1.25), where the rule allows 0.2 and 0.13; at D = 3
   with the MPC's gains the rule is no longer conservative (0.032 stable, 0.1 allowed):
   declare such a latency.

4. *A latency declared longer than it is* (by :math:`\\Delta L = \\beta T_s`,
   :math:`0 < \\beta \\le 1`): the observer pairs the velocity change caused by
   :math:`\\tau_{k-1}` with :math:`\\beta\\tau_{k-2} + (1 - \\beta)\\tau_{k-1}`, a torque
   partly one period too early. With :math:`u = v - \\hat d` the estimate obeys
   :math:`\\hat d_k = (1 - g(r + \\beta))\\hat d_{k-1} + g\\beta\\,\\hat d_{k-2} + \\dots`,
   denominator :math:`z^2 - (1 - g(r + \\beta))z - g\\beta`; Jury's conditions reduce to
   :math:`g(r + 2\\beta) < 2`, i.e. with :math:`g = T_s\\omega/(1 + T_s\\omega)`

   .. math:: \\omega\\,(r T_s + 2\\Delta L - 2 T_s) < 2,

   no bound while :math:`r T_s + 2\\Delta L \\le 2 T_s`. The pole leaves the unit circle
   at :math:`z = -1`: the estimate alternates in sign every period and grows (the
   observer-only loop, exact as :math:`T_s \\to 0` against the outer loop). A full period
   too many (:math:`\\beta = 1`) allows :math:`T_s\\omega < 2/r` (1.6 at r = 1.25); half a
   period (:math:`\\beta = \\tfrac12`) :math:`T_s\\omega < 2/(r - 1)` (8). The package keeps
   half of it, :math:`\\omega (r T_s + 2\\Delta L - 2T_s) \\le 1`
   (:func:`overdeclared_limit`). Measured with ``python benchmarks/studies/observer_rule.py
   --over`` at Ts = 1 ms, the largest stable :math:`T_s\\omega` (r = 1.25, a PD outer
   loop and the paper MPC's equivalent gains alike) is 7.1 at β = ½ and 1.4 at β = 1,
   where the rule allows 4 and 0.8; at Ts = 10 ms the outer loop lowers it to 4.0 / 3.5
   (PD / MPC) at β = ½ and 1.1 / 1.0 at β = 1 (with r = 1: 14 / 11 at β = ½, where the
   rule sets no bound), below the rule's 4 with the MPC's gains. The rule is meant for
   what a measured latency may be off by, half an interface cycle: a large fraction of a
   1 kHz control period, a small one of a 10 ms period (no bound then).

:func:`check_bandwidth` applies case 3 with :math:`L_u = T_s` (an interface cycle the
controller was not told about) when ``[controller] latency`` is 0, and case 4 with
:math:`\\Delta L = \\min(L, T_s)/2` (:func:`overdeclared_excess`: half an interface cycle,
the error a latency measured in whole cycles may have, the cycle taken no longer than the
declared latency nor the control period) when a latency L is declared.
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
    "bandwidth_posture",
    "check_bandwidth",
    "compensation_bandwidth",
    "implied_bandwidth",
    "latency_tolerance",
    "observer_cY",
    "overdeclared_excess",
    "overdeclared_limit",
]

#: The worst plant-to-model inertia ratio the rule is checked for (a link 20 % lighter).
MASS_RATIO = 1.25
#: The bound of :math:`\\omega r (T_s + L_u)`.
RULE = 0.5
#: The bound of :math:`\\omega (r T_s + 2\\Delta L - 2 T_s)` for a latency declared
#: :math:`\\Delta L` too long (half the stability bound 2; module docstring, case 4).
RULE_OVER = 1.0


def bandwidth_limit(Ts: float, uncompensated: float, mass_ratio: float = MASS_RATIO) -> float:
    """The largest bandwidth [1/s] the rule allows: :math:`\\tfrac12 / (r (T_s + L_u))`
    with :math:`L_u` = ``uncompensated`` [s]; ``inf`` when :math:`L_u = 0` (case 1 of the
    module docstring: any bandwidth is stable with the implicit observer)."""
    if uncompensated <= 0:
        return math.inf
    return RULE / (mass_ratio * (Ts + uncompensated))


def overdeclared_limit(Ts: float, excess: float, mass_ratio: float = MASS_RATIO) -> float:
    """The largest bandwidth [1/s] the rule for a latency declared ``excess`` [s] longer
    than the measurements' age allows: :math:`\\omega (r T_s + 2\\Delta L - 2T_s) \\le 1`
    (module docstring, case 4); ``inf`` when :math:`r T_s + 2\\Delta L \\le 2T_s`."""
    den = mass_ratio * Ts + 2.0 * excess - 2.0 * Ts
    return math.inf if den <= 0 else RULE_OVER / den


def overdeclared_excess(Ts: float, latency: float) -> float:
    """The over-declaration [s] :func:`check_bandwidth` checks a declared ``latency`` [s]
    for: :math:`\\min(L, T_s)/2`, half an interface cycle (a latency measured in whole
    cycles is off by up to half of one; the cycle no longer than the latency nor Ts)."""
    return 0.5 * min(latency, Ts) if latency > 0 else 0.0


def bandwidth_posture(robot) -> np.ndarray:
    """The posture :math:`q_0` [rad] at which a bandwidth is exact: q = 0 moved to the
    nearest joint limit where 0 is outside the range."""
    return np.minimum(np.maximum(np.zeros(robot.nq), robot.lower), robot.upper)


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
            :func:`bandwidth_limit` for one unknown control period of latency; with a
            latency declared, those above :func:`overdeclared_limit` for a latency
            declared :func:`overdeclared_excess` too long.
    """
    w = np.asarray(bandwidth, dtype=float)
    names = list(joint_names)
    if explicit:
        bad = np.flatnonzero(Ts * w >= 2.0)
        if bad.size:
            j = int(bad[0])
            raise ConfigError(
                key,
                f"joint {names[j]!r}: Ts·ω = {Ts * w[j]:.3g} >= 2 puts the explicit "
                f"observer's pole 1 - Ts·ω outside the unit circle; use ω < {2 / Ts:.4g} 1/s "
                "or discretization = 'implicit'",
            )
    if latency > 0:
        excess = overdeclared_excess(Ts, latency)
        limit = overdeclared_limit(Ts, excess)
        bad = np.flatnonzero(w > limit * (1 + 1e-9))  # at the limit (init's value): silent
        if bad.size:
            listed = ", ".join(f"{names[j]!r} ({w[j]:.4g} 1/s)" for j in bad)
            warnings.warn(
                f"{key}: joint(s) {listed} above {limit:.4g} 1/s, the bound "
                f"ω·(r·Ts + 2·ΔL - 2·Ts) <= 1 for a latency declared ΔL = {excess:g} s longer "
                f"than it is (half an interface cycle; Ts = {Ts:g} s, latency = {latency:g} s, "
                "r = 1.25): then the observer pairs each velocity change with a torque one "
                "period too early and its estimate oscillates, alternating in sign, and grows; "
                f"lower the bandwidth to {limit:.4g} 1/s or below, and measure the latency "
                "(guide 'Sensing and latency')",
                ValidityWarning,
                stacklevel=4,
            )
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
    """Per joint the bandwidth [1/s] of the observer ``compensation`` runs, at the mass
    matrix ``M0``: the rate :math:`\\omega_j` at which its estimation error decays at the
    posture of ``M0`` (module docstring).

    :func:`implied_bandwidth` of an NDO (its ``cY``), the momentum observer's gains
    :math:`K_O`; a wrapper with an ``inner`` compensation (the collision reaction's
    :class:`~hmpc_pin.compensation.gate.FeedbackGate`) is looked through; ``None`` for a
    compensation that is not an observer (none, ISM). The one computation of a running
    observer's bandwidth: :func:`hmpc_pin.experiment.observer_analysis.running_observer`
    finds a built experiment's observer, :func:`hmpc_pin.experiment.controllers.observer_bandwidth`
    reads the bandwidth a config asks for (before anything is built) and
    :func:`hmpc_pin.experiment.observer_analysis.observer_modes` gives the error's modal
    decay rates along a reference (the eigenvalues of :math:`cY M(q)^{-1}`, of which this is
    the diagonal at one posture).

    Args:
        compensation: A compensation object (an observer, or a gate around one).
        M0: The mass matrix :math:`M(q_0)` [kg·m²], (n, n).

    Returns:
        The bandwidths [1/s], (n,), or ``None``.
    """
    while hasattr(compensation, "inner"):  # a gate around the observer (collision reaction)
        compensation = compensation.inner
    n = np.shape(M0)[0]
    cY = getattr(compensation, "cY", None)
    if cY is not None:
        return implied_bandwidth(cY, M0)
    K = getattr(compensation, "K", None)
    if K is not None:
        return np.broadcast_to(np.asarray(K, dtype=float), (n,)).copy()
    return None


def latency_tolerance(
    bandwidth: np.ndarray | None, Ts: float, period: float, *, over: bool = False
) -> float:
    """How far [s] a measured latency may lie from the declared one
    (``[controller] latency``) before the real-time loop warns.

    A measured latency above the declared one leaves :math:`L_u` = the difference
    uncompensated; the rule (module docstring, case 3) tolerates it while
    :math:`\\omega_{\\max} r (T_s + L_u) \\le 1/2`, i.e. up to
    :math:`1/(2 r \\omega_{\\max}) - T_s`. The measured age has the granularity of the
    interface period P (a state every P), so half a period is always tolerated:

    .. math:: \\Delta L = \\max(P/2,\\ 1/(2 r \\omega_{\\max}) - T_s)

    (:math:`P/2` without an observer). A declared latency above the measured one
    (``over``) is checked against case 4 instead, :math:`\\omega_{\\max}(r T_s + 2\\Delta L
    - 2T_s) \\le 1`, derived for up to one period:

    .. math:: \\Delta L = \\max\\big(P/2,\\ \\min(T_s,\\ (1/\\omega_{\\max} - (r - 2) T_s)/2)\\big)

    (:math:`P/2` without an observer: the controller then only predicts the state
    further ahead than it is old).

    Args:
        bandwidth: The observer's bandwidth per joint [1/s] (``None``: no observer).
        Ts: Control period [s].
        period: Interface period P [s].
        over: The declared latency is the larger one.
    """
    tol = 0.5 * period
    if bandwidth is not None and np.size(bandwidth):
        w = float(np.max(bandwidth))
        if w > 0:
            if over:
                reach = 0.5 * (RULE_OVER / w - (MASS_RATIO - 2.0) * Ts)
                tol = max(tol, min(Ts, reach))
            else:
                tol = max(tol, RULE / (MASS_RATIO * w) - Ts)
    return tol
