"""One joint's loop as a linear system: the observer and the MPC with a latency declared
too long, their spectral radii per control period.

The rule of :mod:`hmpc_pin.compensation.bandwidth` bounds the observer's bandwidth alone;
here each loop is a transition matrix over one control period and its largest eigenvalue
modulus :math:`|z|` says whether it decays (:math:`|z| < 1`) and how fast
(:math:`-\\ln|z|/T_s` [1/s]):

* :func:`overdeclared_radius`: the observer alone, the MPC's input taken as given;
* :func:`lead_radius`: the MPC alone, acting on the state predicted over the declared
  latency, the disturbance taken as cancelled;
* :func:`loop_radius`: the two together;
* :func:`explicit_loop_slow`: the forward-Euler observer's loop with the MPC against the
  backward-Euler one's.

``hmpc-pin check`` (:mod:`hmpc_pin.apps.check`) turns them into problems and warnings.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "MIN_DECAY",
    "explicit_loop_slow",
    "lead_radius",
    "loop_radius",
    "overdeclared_radius",
]


#: Smallest share [-] of the outer loop's decay rate :math:`-\ln|z|/T_s` without a
#: prediction that it may keep with a latency declared too long (:func:`lead_radius`):
#: the paper's MPC (kp = 274, kd = 22.7 at Ts = 10 ms, 12 1/s) tracks with 5 periods
#: declared too many (6.7 1/s) and leaves its tolerance with 10 (3.1 1/s).
MIN_DECAY = 0.5


def overdeclared_radius(wTs: float, ratio: float, over: float, explicit: bool = False) -> float:
    """Spectral radius [-] of the observer loop with a latency declared ``over`` control
    periods longer than the measurements' age (case 4 of
    :mod:`hmpc_pin.compensation.bandwidth`, extended to several periods).

    With the fraction of the way the observer moves per period, Eq (13) discretised:
    :math:`g = T_s\\omega/(1 + T_s\\omega)` for backward (implicit) Euler,
    :math:`(M + T_s cY) w = \\dots`, and :math:`g = T_s\\omega` for forward (explicit)
    Euler, :math:`M w = \\dots`
    (:meth:`~hmpc_pin.compensation.observers.DisturbanceObserver.update`), the over-declaration
    :math:`m + \\beta` periods (m whole, :math:`0 \\le \\beta < 1`) and a plant whose
    inertia is :math:`1/r` of the model's, the observer pairs the velocity change caused
    by :math:`u_{k-1}` with :math:`(1-\\beta) u_{k-1-m} + \\beta u_{k-2-m}`, and with
    :math:`u = v - \\hat d` its estimate obeys

    .. math:: \\hat d_k = (1 - g - g r)\\hat d_{k-1} + g(1-\\beta)\\hat d_{k-1-m}
              + g\\beta\\,\\hat d_{k-2-m} + \\dots

    whose characteristic polynomial's largest root modulus is returned (m = 0 gives the
    docstring's :math:`z^2 - (1 - g(r + \\beta))z - g\\beta`).

    Args:
        wTs: :math:`T_s\\omega` [-].
        ratio: r, model-to-plant inertia ratio [-].
        over: The over-declaration in control periods [-] (>= 0).
        explicit: The observer is the forward-Euler form (``discretization =
            "explicit"``).
    """
    g = wTs if explicit else wTs / (1.0 + wTs)
    m = math.floor(over + 1e-9)
    beta = max(over - m, 0.0)
    coeffs = np.zeros(m + 3)
    coeffs[0] = 1.0
    coeffs[1] -= 1.0 - g - g * ratio * ((1.0 - g) if explicit else 1.0)
    coeffs[1 + m] -= g * (1.0 - beta)
    coeffs[2 + m] -= g * beta
    return float(np.max(np.abs(np.roots(np.trim_zeros(coeffs, "b"))), initial=0.0))


def lead_radius(kp: float, kd: float, Ts: float, over: float) -> float:
    """Spectral radius [-] of one joint's outer loop when the controller predicts its
    state ``over`` control periods ahead of measurements that are fresh (a latency
    declared that much too long).

    The joint is the double integrator the inverse dynamics leaves, held for a period
    (:math:`x^+ = x + T_s\\dot x + \\tfrac12 T_s^2 u`, :math:`\\dot x^+ = \\dot x + T_s u`),
    under the MPC's equivalent feedback :math:`u_k = -k_p\\hat x_k - k_d\\hat{\\dot x}_k`
    (:func:`~hmpc_pin.controllers.computed_torque.mpc_feedback_gain`), where
    :math:`\\hat x_k` is the measured state integrated over :math:`L = D T_s` with the
    inputs of the last :math:`\\lceil D\\rceil` periods, as the controller does for a
    latency L (the oldest over the fraction :math:`D - \\lceil D\\rceil + 1` of a period).
    The loop's state is :math:`[x, \\dot x, u_{k-1}, \\dots, u_{k-\\lceil D\\rceil}]`.

    Args:
        kp: [1/s²], kd: [1/s]: the feedback gains.
        Ts: Control period [s].
        over: D, the over-declaration in control periods [-] (>= 0).
    """
    m = math.ceil(over - 1e-9) if over > 0 else 0
    size = 2 + m

    def hold(h: float) -> tuple[np.ndarray, np.ndarray]:
        return np.array([[1.0, h], [0.0, 1.0]]), np.array([0.5 * h * h, h])

    predict = np.eye(2, size)  # (x̂, v̂) as a map of the loop's state
    for i in range(m, 0, -1):  # u_{k-i}, the oldest first
        A, B = hold((over - (m - 1) if i == m else 1.0) * Ts)
        predict = A @ predict
        predict[:, 1 + i] += B
    gain = -np.array([kp, kd]) @ predict  # u_k
    A, B = hold(Ts)
    step = np.zeros((size, size))
    step[:2] = A @ np.eye(2, size) + np.outer(B, gain)
    if m:
        step[2] = gain
        for i in range(1, m):
            step[2 + i, 1 + i] = 1.0
    return float(np.max(np.abs(np.linalg.eigvals(step))))


def loop_radius(
    kp: float,
    kd: float,
    Ts: float,
    wTs: float,
    over: float,
    ratio: float = 1.0,
    explicit: bool = False,
) -> float:
    """Spectral radius [-] of one joint's whole loop, the MPC and the observer together,
    with a latency declared ``over`` control periods too long (measurements fresh).

    :func:`overdeclared_radius` takes the MPC's input as given and :func:`lead_radius`
    the disturbance as cancelled; each may pass a fractional over-declaration that the
    two loops together do not. Per period k, in acceleration units (the inverse dynamics
    leaves a double integrator; a plant of inertia :math:`1/r` of the model's), with the
    commanded :math:`u_k = v_k - \\hat e_k`:

    * the observer, with :math:`g` as in :func:`overdeclared_radius` and the
      over-declaration :math:`m + \\beta`:
      :math:`\\hat e_k = (1-g)\\hat e_{k-1} + g\\,(r u_{k-1} - (1-\\beta)u_{k-1-m}
      - \\beta u_{k-2-m})` (the velocity change of period k-1 paired with the torques
      the declared latency names);
    * the MPC, :math:`v_k = -k_p\\hat x_k - k_d\\hat{\\dot x}_k` on the state predicted
      over :math:`L = DT_s` with the past :math:`v` (as in :func:`lead_radius`);
    * the joint, held for a period: :math:`x^+ = x + T_s\\dot x + \\tfrac12T_s^2 r u_k`,
      :math:`\\dot x^+ = \\dot x + T_s r u_k`.

    The loop's state is :math:`[x, \\dot x, \\hat e_{k-1}, u_{k-1}, \\dots, u_{k-2-m},
    v_{k-1}, \\dots, v_{k-\\lceil D\\rceil}]`; its transition matrix's largest eigenvalue
    modulus is returned.

    Args:
        kp: [1/s²], kd: [1/s]: the MPC's equivalent feedback gains.
        Ts: Control period [s].
        wTs: The observer's :math:`T_s\\omega` [-].
        over: D, the over-declaration in control periods [-] (>= 0).
        ratio: r, model-to-plant inertia ratio [-].
        explicit: The observer is the forward-Euler form.
    """
    g = wTs if explicit else wTs / (1.0 + wTs)
    m = math.floor(over + 1e-9)
    beta = max(over - m, 0.0)
    lead = math.ceil(over - 1e-9) if over > 0 else 0  # the v's the prediction integrates
    nu = m + 2  # u_{k-1} .. u_{k-2-m}
    size = 3 + nu + lead

    def iu(j: int) -> int:  # u_{k-j}
        return 2 + j

    def iv(j: int) -> int:  # v_{k-j}
        return 2 + nu + j

    estimate = np.zeros(size)  # ê_k
    estimate[2] = 1.0 - g
    estimate[iu(1)] += g * ratio * ((1.0 - g) if explicit else 1.0)
    estimate[iu(1 + m)] -= g * (1.0 - beta)
    estimate[iu(2 + m)] -= g * beta
    predict = np.eye(2, size)  # (x̂, v̂)
    for i in range(lead, 0, -1):  # v_{k-i}, the oldest first
        h = ((over - (lead - 1)) if i == lead else 1.0) * Ts
        predict = np.array([[1.0, h], [0.0, 1.0]]) @ predict
        predict[:, iv(i)] += np.array([0.5 * h * h, h])
    v = -kp * predict[0] - kd * predict[1]
    u = v - estimate
    step = np.zeros((size, size))
    step[:2] = np.array([[1.0, Ts], [0.0, 1.0]]) @ np.eye(2, size) + np.outer(
        np.array([0.5 * Ts * Ts, Ts]), ratio * u
    )
    step[2] = estimate
    step[iu(1)] = u
    for j in range(2, nu + 1):
        step[iu(j), iu(j - 1)] = 1.0
    if lead:
        step[iv(1)] = v
        for j in range(2, lead + 1):
            step[iv(j), iv(j - 1)] = 1.0
    return float(np.max(np.abs(np.linalg.eigvals(step))))


def explicit_loop_slow(
    kp: float, kd: float, Ts: float, wTs: np.ndarray, ratio: float = 1.0
) -> np.ndarray:
    """Per joint, whether the explicit observer's loop with the MPC, without latency,
    grows or decays slowly: :func:`loop_radius` (``explicit``, no latency) :math:`|z|`
    against the implicit form's at the same :math:`T_s\\omega_j`, :math:`|z_i|`:
    :math:`\\ln\\min(|z|, 1) > ` :data:`MIN_DECAY` :math:`\\ln|z_i|`.

    Forward Euler pairs the velocity change of the period that ended with the estimate of
    the period before, so its estimate keeps :math:`-(T_s\\omega)^2` times the arm's
    acceleration and feeds the MPC's own input back (backward Euler cancels it).

    Args:
        kp: [1/s²], kd: [1/s]: the MPC's equivalent feedback gains.
        Ts: Control period [s].
        wTs: :math:`T_s\\omega_j` per joint [-].
        ratio: r, model-to-plant inertia ratio [-].
    """
    wTs = np.atleast_1d(np.asarray(wTs, dtype=float))
    radius = np.array([loop_radius(kp, kd, Ts, w, 0.0, ratio, True) for w in wTs])
    implicit = np.array([loop_radius(kp, kd, Ts, w, 0.0, ratio) for w in wTs])
    with np.errstate(divide="ignore"):
        return np.log(np.minimum(radius, 1.0)) > MIN_DECAY * np.log(implicit)
