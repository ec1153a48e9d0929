"""The observer of a built experiment along its reference: its modes at each posture and
the tracking error its lag leaves through the MPC's loop.

The linear models of one joint's loop at a fixed posture are in
:mod:`hmpc_pin.compensation.loop_analysis`; here they meet the arm's inertia
:math:`M(q)` and the config's disturbance sampled along the reference. ``hmpc-pin check``
(:mod:`hmpc_pin.apps.check`) turns them into problems and warnings.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from ..compensation.bandwidth import compensation_bandwidth
from ..compensation.observers import DisturbanceObserver, MomentumObserver
from ..identification.observer_model import ObserverModel
from .build import Experiment

__all__ = [
    "lag_inputs",
    "observer_bandwidth",
    "observer_lag_error",
    "observer_modes",
    "running_observer",
    "worst_along",
]


def running_observer(ex: Experiment) -> DisturbanceObserver | MomentumObserver | None:
    """The observer the experiment's controller runs, looked through a feedback gate
    (:class:`~hmpc_pin.compensation.gate.FeedbackGate`, the collision reaction), or
    ``None`` when its compensation is no observer (none, ISM)."""
    comp: Any = getattr(ex.controller, "compensation", None)
    while hasattr(comp, "inner"):  # a gate around the observer (collision reaction)
        comp = comp.inner
    return comp if isinstance(comp, (DisturbanceObserver, MomentumObserver)) else None


def observer_bandwidth(ex: Experiment, M0: np.ndarray) -> np.ndarray | None:
    """The bandwidth per joint [1/s] of the observer ``ex`` runs, at the mass matrix ``M0``
    (``None`` without an observer).

    .. deprecated:: 0.3
        The same as ``compensation_bandwidth(running_observer(ex), M0)``
        (:func:`~hmpc_pin.compensation.bandwidth.compensation_bandwidth`, the one
        computation, and :func:`running_observer`); use those. Not to be confused with
        :func:`hmpc_pin.experiment.controllers.observer_bandwidth`, the bandwidth a config
        asks for.
    """
    import warnings

    warnings.warn(
        "observer_bandwidth(ex, M0) is deprecated: use "
        "hmpc_pin.compensation.bandwidth.compensation_bandwidth(running_observer(ex), M0)",
        DeprecationWarning,
        stacklevel=2,
    )
    return compensation_bandwidth(running_observer(ex), M0)


def observer_modes(ex: Experiment, samples: int = 200) -> tuple[np.ndarray, np.ndarray]:
    """The observer's modal bandwidths [1/s] at postures along the reference.

    The NDO's estimation error obeys :math:`\\dot e = -cY M(q)^{-1} e` (Eq 13 with
    :math:`L = cY M^{-1}`, ``cY`` constant): its modes decay at the eigenvalues of
    :math:`cY M(q)^{-1}` (those of :math:`M(q)^{-1} cY`, the generalized eigenvalues of
    the pair :math:`(cY, M(q))`), which move with the posture although the bandwidth is
    set at :math:`q_0`; the momentum observer's are its gains :math:`K_O` everywhere.

    Args:
        ex: The built experiment (its reference, model and observer).
        samples: Postures sampled, evenly over the run (and at most one per period).

    Returns:
        ``(t, w)``: the times [s], (k,), and per time the n modal bandwidths [1/s],
        (k, n) (real parts); both empty without an observer.
    """
    comp = running_observer(ex)
    n = ex.robot.nq
    cfg = ex.config
    if comp is None:
        return np.zeros(0), np.zeros((0, n))
    Ts, duration = cfg.controller.Ts, cfg.simulation.duration
    k = int(min(samples, max(duration / Ts, 1.0)))
    t = np.linspace(0.0, duration, k + 1)
    if isinstance(comp, MomentumObserver):
        K = np.broadcast_to(np.asarray(comp.K, dtype=float), (n,))
        return t, np.tile(K, (len(t), 1))
    q, _ = ex.reference.sample_many(t)
    cY = np.asarray(comp.cY, dtype=float)
    w = [np.linalg.eigvals(np.linalg.solve(ex.robot.mass_matrix(qk), cY)).real for qk in q]
    return t, np.sort(np.array(w), axis=1)


def lag_inputs(ex: Experiment) -> tuple:
    """:func:`observer_lag_error`'s samples along the reference, every control period
    (computed once for several calls).

    Returns:
        ``(Ts, t, q, d, Minv)``: the period [s], the times [s] (K,), the reference's
        positions (K, n), the config's disturbance there [N·m] (K, n) and
        :math:`M(q_k)^{-1}` (K, n, n).
    """
    cfg = ex.config
    Ts = cfg.controller.Ts
    t = np.arange(0.0, cfg.simulation.duration + Ts / 2, Ts)
    q, dq = ex.reference.sample_many(t)
    q, dq = np.array(q, dtype=float), np.array(dq, dtype=float)
    d = np.array(
        [np.asarray(ex.disturbance(float(t[k]), q[k], dq[k]), dtype=float) for k in range(len(t))]
    )
    minv = np.array([np.linalg.inv(ex.robot.mass_matrix(q[k])) for k in range(len(t))])
    return Ts, t, q, d, minv


def observer_lag_error(
    ex: Experiment,
    kp: float,
    kd: float,
    after: float,
    scale: float = 1.0,
    inputs: tuple | None = None,
) -> np.ndarray:
    r"""Per joint, the largest tracking error [rad] after ``after`` [s] that the
    disturbance the observer has not yet caught leaves, along the reference.

    The config's disturbance :math:`d_k = d(t_k, r_k, \dot r_k)` sampled every
    :math:`T_s` along the reference :math:`r_k`; the observer that runs (its matrix
    :math:`cY` or :math:`K_O` times ``scale``, its discretization;
    ``ObserverModel.filter`` of :mod:`hmpc_pin.identification`) estimating, at
    :math:`t_k`, the disturbance of the period that ended,
    :math:`\hat d_k = F(d_{k-1}, \hat d_{k-1})` (implicit Euler:
    :math:`(I + T_sL_k)\hat d_k = \hat d_{k-1} + T_sL_kd_{k-1}`,
    :math:`L = cY M(r_k)^{-1}`); what it leaves,
    :math:`a_k = M(r_k)^{-1}(d_k - \hat d_k)`, drives each joint's error through the
    MPC's loop (its equivalent feedback, :func:`.lead_radius` without latency):
    :math:`x^+ = x + T_s\dot x + \tfrac12T_s^2(a_k - k_px - k_d\dot x)`,
    :math:`\dot x^+ = \dot x + T_s(a_k - k_px - k_d\dot x)`, from rest. Without an
    observer :math:`\hat d = 0`.

    Args:
        ex: The built experiment (its reference, disturbance, model and observer).
        kp: [1/s²], kd: [1/s]: the MPC's equivalent feedback gains.
        after: The start-up left out [s].
        scale: Factor on the observer's gain [-].
        inputs: ``lag_inputs(ex)``, when already computed.
    """
    Ts, t, q, d, minv = lag_inputs(ex) if inputs is None else inputs
    n = d.shape[1]
    model = ObserverModel.of(getattr(ex.controller, "compensation", None), ex.robot)
    if model is None:
        dhat = np.zeros_like(d)
    else:
        if model.matrix is not None:
            model = replace(model, matrix=np.asarray(model.matrix) * scale)
        else:
            model = replace(model, gain=np.asarray(model.gain, dtype=float) * scale)
        before = np.vstack([np.zeros((1, n)), d[:-1]])  # d over the period that ended
        with np.errstate(over="ignore", invalid="ignore"):  # an unstable observer: inf
            dhat = model.filter(q, before[:, :, None])[:, :, 0]
    x, xd, worst = np.zeros(n), np.zeros(n), np.zeros(n)
    with np.errstate(over="ignore", invalid="ignore"):
        for k in range(len(t)):
            if t[k] >= after - 1e-12:
                worst = np.maximum(worst, np.abs(x))
            acc = minv[k] @ (d[k] - dhat[k]) - kp * x - kd * xd
            x, xd = x + Ts * xd + 0.5 * Ts * Ts * acc, xd + Ts * acc
    return np.where(np.isfinite(worst), worst, np.inf)


def worst_along(radius, t: np.ndarray, modes: np.ndarray) -> tuple[float, float, float]:
    """The largest ``radius(w)`` over the modal bandwidths ``modes`` [1/s] (k, n) at the
    times ``t`` [s] (:func:`observer_modes`). The bandwidths are evaluated once per 1 %
    band (each band at its largest member).

    Args:
        radius: ``radius(w) -> float``, e.g. a loop's spectral radius at the bandwidth
            ``w`` [1/s] (:func:`~hmpc_pin.compensation.loop_analysis.loop_radius`).

    Returns:
        ``(radius, w, t)`` at the worst mode; ``(0, 0, 0)`` without modes.
    """
    w = modes.ravel()
    keep = np.isfinite(w) & (w > 0)
    if not keep.any():
        return 0.0, 0.0, 0.0
    times = np.repeat(t, modes.shape[1])[keep]
    w = w[keep]
    band = np.floor(np.log(w) / math.log(1.01))
    best = (0.0, 0.0, 0.0)
    for b in np.unique(band):
        i = np.flatnonzero(band == b)
        j = i[np.argmax(w[i])]
        r = radius(float(w[j]))
        if r > best[0]:
            best = (r, float(w[j]), float(times[j]))
    return best
