"""Joint friction identified from a run of the controller (``hmpc-pin identify``).

The model is the package's friction model (Eq 32, sign ``"opposing"``): joint i feels the
torque :math:`d_i = -f_i` with

.. math::

    f_i = a_i\\,\\dot q_i + b_i\\,\\mathrm{sgn}\\,\\dot q_i ,

:math:`a_i` the viscous coefficient [N·m·s/rad], :math:`b_i` the Coulomb level [N·m].
A positive :math:`a_i, b_i` opposes the motion; a negative one feeds energy in (the
paper's Eq 32 read literally, README "Friction sign").

Two measurements of :math:`f` are offered (``source``):

* ``"observer"``: the observer's estimate, :math:`f \\approx -\\hat d`, plus any friction
  the run already fed forward (:math:`\\hat d` then holds only what was left). The
  observer lags the true disturbance by its bandwidth; samples within ``velocity_threshold``
  of a velocity reversal (where the Coulomb term jumps) are left out. A joint at rest
  sticks: its friction is then a holding torque :math:`\\varphi \\in [-b, b]`, not
  :math:`b\\,\\mathrm{sgn}\\,0 = 0`, and the observer carries it on after the joint
  moves again. So the stuck intervals (the measured velocity within its noise band for a
  period or more, :func:`stuck_samples`) are left out, and with them
  :data:`.SETTLING_TIME_CONSTANTS` time constants of the observer that ran after each
  (:meth:`.ObserverModel.time_constant`; every joint's samples for the NDO, whose
  :math:`L = cYM^{-1}` couples the joints, that joint's alone for the momentum observer).
* ``"dynamics"``: the rigid-body model's inverse dynamics over each control period,
  :math:`f_k = \\tau_k - [M(\\bar q)\\,\\ddot q_k + C(\\bar q, \\bar{\\dot q})\\bar{\\dot q} +
  G(\\bar q)]` with :math:`\\ddot q_k = (\\dot q_{k+1} - \\dot q_k)/T_s`, the mid-period state
  :math:`\\bar q = (q_k + q_{k+1})/2` and :math:`\\tau_k` the torque applied over the
  period; the rigid-body part is Pinocchio's joint-torque regressor times the model's
  inertial parameters, :math:`Y(q, \\dot q, \\ddot q)\\,\\pi`. No lag, but it needs the model
  to be right.
* ``"regressor"``: the same equation with the rigid-body parameters fitted too,
  :math:`\\tau_k = Y_k\\,\\pi + \\Phi_k\\,\\theta`, :math:`\\pi` reduced to the columns of
  :math:`Y` that the run identifies (QR with column pivoting of the stacked regressor:
  the base parameters of this motion). For an arm whose model is off (a payload, a
  wrong link mass); it needs a richer motion than the friction alone.

Per joint, ordinary least squares on :math:`A = [\\dot q,\\ \\mathrm{sgn}\\,\\dot q]`:
:math:`\\hat\\theta = (A^TA)^{-1}A^Ty`, residual :math:`r = y - A\\hat\\theta`,
:math:`\\hat\\sigma^2 = r^Tr/(m - 2)`, and the confidence interval
:math:`\\hat\\theta_j \\pm t_{1-\\alpha/2,\\,m_e-2}\\,\\hat\\sigma\\sqrt{[(A^TA)^{-1}]_{jj}
\\cdot m/m_e}`, where :math:`m_e = m(1-\\rho)/(1+\\rho)` is the effective number of samples
of a residual whose lag-1 autocorrelation is :math:`\\rho > 0` (an AR(1) correction: the
residual of a closed-loop run is not white; with :math:`\\rho \\le 0`, :math:`m_e = m`).

A joint is identifiable when it moves both ways at speed: at least ``min_coverage`` of the
samples with :math:`\\dot q_i > v_e` and as many with :math:`\\dot q_i < -v_e`
(``excitation_velocity``, 0.05 rad/s: a joint only shaken by its neighbours' tracking
errors is refused), and the
column-normalised :math:`A` has a condition number <= ``max_condition``. Otherwise
:class:`ExcitationError` names the joint and the motion that would identify it.
"""

from __future__ import annotations

import numpy as np

from ..exceptions import ConfigError, ExcitationError
from ..sim.result import Result
from .friction_fit import (
    MIN_DEGREES_OF_FREEDOM,
    SETTLING_TIME_CONSTANTS,
    FrictionFit,
    JointFriction,
)
from .observer_model import ObserverModel

__all__ = [
    "PULSE_SIGMAS",
    "SOURCES",
    "FrictionFit",
    "JointFriction",
    "ObserverModel",
    "applied_torque",
    "dynamics_friction",
    "fit_friction",
    "fit_joint",
]

#: A Gaussian disturbance pulse is negligible this many standard deviations from its
#: centre (exp(-4²/2) = 3e-4 of its amplitude): ``identify`` names the time past a run's
#: pulses, and ``init`` the run that reaches it, with it.
PULSE_SIGMAS = 4.0
#: Measurements of the friction torque a fit can use.
SOURCES = ("observer", "dynamics", "regressor")
#: A joint is stuck where its measured velocity stays within this many noise deviations
#: :math:`\hat\sigma_v` (or within ``velocity_threshold``, the larger) for a period or more.
STUCK_NOISE_DEVIATIONS = 4.0


def coverage(dq: np.ndarray, velocity_threshold: float) -> tuple[float, float]:
    """Fractions of the samples moving forward and backward faster than :math:`v_0`."""
    total = max(len(dq), 1)
    fast = np.isfinite(dq) & (np.abs(dq) > velocity_threshold)
    return (
        float(np.count_nonzero(fast & (dq > 0)) / total),
        float(np.count_nonzero(fast & (dq < 0)) / total),
    )


def check_excitation(
    name: str, dq: np.ndarray, velocity_threshold: float, min_coverage: float
) -> tuple[float, float]:
    """The coverage of one joint at :math:`v_e` (``velocity_threshold``), or
    :class:`ExcitationError` if it does not move both ways."""
    forward, backward = coverage(dq, velocity_threshold)
    if min(forward, backward) < min_coverage:
        peak = float(np.max(np.abs(dq))) if len(dq) else 0.0
        raise ExcitationError(
            name,
            f"moves forward in {100 * forward:.1f} % and backward in {100 * backward:.1f} % "
            f"of the samples faster than {velocity_threshold:g} rad/s (peak |q̇| "
            f"{peak:.3g} rad/s); at least {100 * min_coverage:g} % each way is needed",
        )
    return forward, backward


def _condition(name: str, A: np.ndarray, max_condition: float) -> float:
    cond = float(np.linalg.cond(A / np.linalg.norm(A, axis=0)))
    if not cond <= max_condition:
        raise ExcitationError(
            name,
            f"its velocity and velocity sign are nearly collinear (condition number "
            f"{cond:.3g} > {max_condition:g}): viscous and Coulomb friction cannot be "
            "told apart",
        )
    return cond


def _lag1(r: np.ndarray) -> float:
    rr = float(np.dot(r, r))
    return float(np.dot(r[1:], r[:-1]) / rr) if len(r) > 2 and rr > 0 else 0.0


def _least_squares(blocks: list[tuple[np.ndarray, np.ndarray]], confidence: float):
    """Weighted least squares over joint blocks ``(A_i, y_i)`` sharing one parameter
    vector: each block weighted by its residual variance of an ordinary fit
    (feasible GLS; with block-diagonal regressors it is one OLS per joint).

    Returns:
        (theta, half-widths of the intervals, residuals per block, m_e per block).
    """
    from scipy.stats import t as student_t

    A = np.vstack([a for a, _ in blocks])
    y = np.concatenate([v for _, v in blocks])
    norms = np.linalg.norm(A, axis=0)
    norms[norms == 0] = 1.0
    blocks = [(a / norms, v) for a, v in blocks]  # unit columns: a well-scaled A^T W A
    A = A / norms
    theta = np.linalg.lstsq(A, y, rcond=None)[0]
    p = A.shape[1]
    var = [max(float(np.mean((v - a @ theta) ** 2)), 1e-300) for a, v in blocks]
    W = np.concatenate([np.full(len(v), 1.0 / s) for (_, v), s in zip(blocks, var, strict=True)])
    AtWA_inv = np.linalg.inv(A.T @ (A * W[:, None]))
    theta = AtWA_inv @ (A.T @ (W * y))
    res = [v - a @ theta for a, v in blocks]
    m = len(y)
    rho = max(0.0, float(np.mean([_lag1(r) for r in res])))
    m_eff = m * (1 - rho) / (1 + rho)
    chi2 = float(sum(float(r @ r) / s for r, s in zip(res, var, strict=True)))
    scale = chi2 / max(m - p, 1)  # ≈ 1 when the weights are the residual variances
    # too few effective samples: NaN here, and _joint gives no interval below its rule
    half = student_t.ppf(0.5 + confidence / 2, max(m_eff - p, 1.0)) * np.sqrt(
        scale * np.diag(AtWA_inv) * m / max(m_eff, 1e-300)
    )
    m_effs = [len(r) * (1 - max(0.0, _lag1(r))) / (1 + max(0.0, _lag1(r))) for r in res]
    return theta / norms, half / norms, res, m_effs


def fit_joint(
    y: np.ndarray,
    dq: np.ndarray,
    *,
    name: str = "joint",
    velocity_threshold: float = 0.01,
    confidence: float = 0.95,
    min_coverage: float = 0.05,
    max_condition: float = 100.0,
    excitation_velocity: float = 0.05,
) -> JointFriction:
    """Fit :math:`y = a\\dot q + b\\,\\mathrm{sgn}\\,\\dot q` on the samples with
    :math:`|\\dot q| > v_0` (``velocity_threshold``); see the module docstring.

    Args:
        y: Friction torque samples [N·m], (m,). dq: Joint velocity [rad/s], (m,).

    Raises:
        ExcitationError: The joint does not move both ways enough, or the regressor is
            ill-conditioned; the message names the joint and the motion that would do.
    """
    y, dq = np.asarray(y, float), np.asarray(dq, float)
    cover = check_excitation(name, dq, max(excitation_velocity, velocity_threshold), min_coverage)
    keep = np.isfinite(y) & np.isfinite(dq) & (np.abs(dq) > velocity_threshold)
    A = np.column_stack([dq[keep], np.sign(dq[keep])])
    cond = _condition(name, A, max_condition)
    theta, half, res, m_eff = _least_squares([(A, y[keep])], confidence)
    return _joint(name, theta, half, res[0], m_eff[0], cond, cover)


def _joint(name, theta, half, r, m_eff, cond, cover) -> JointFriction:
    if m_eff - 2 < MIN_DEGREES_OF_FREEDOM:  # its residual too correlated: no interval
        half = np.full(2, np.nan)
    return JointFriction(
        name=name,
        viscous=float(theta[0]),
        coulomb=float(theta[1]),
        viscous_ci=(float(theta[0] - half[0]), float(theta[0] + half[0])),
        coulomb_ci=(float(theta[1] - half[1]), float(theta[1] + half[1])),
        residual_rms=float(np.sqrt(np.mean(r * r))),
        samples=len(r),
        effective_samples=float(m_eff),
        condition=cond,
        coverage=cover,
    )


def _feedforward(result: Result, dq: np.ndarray) -> np.ndarray:
    """The friction model the run fed forward, at the velocities ``dq`` [N·m] (zeros if
    none)."""
    ff = result.meta.get("friction_feedforward")
    if not ff:
        return np.zeros_like(dq)
    a, b = np.asarray(ff["viscous"], float), np.asarray(ff["coulomb"], float)
    s = float(ff.get("smoothing", 0.0))
    sgn = np.tanh(dq / s) if s > 0 else np.sign(dq)
    return a * dq + b * sgn


def velocity_noise(dq: np.ndarray) -> np.ndarray:
    """The measured velocity's noise deviation per joint [rad/s], from its second
    differences: :math:`\\hat\\sigma_v = 1.4826\\,\\mathrm{median}|\\Delta^2\\dot q| /
    \\sqrt 6` (a white noise of deviation :math:`\\sigma` gives second differences of
    deviation :math:`\\sqrt 6\\,\\sigma`; the smooth motion's own are
    :math:`T_s^2\\,\\dddot q`, and the median ignores the jumps at a stick or a
    breakaway). Zero for fewer than three samples."""
    dq = np.asarray(dq, float)
    if len(dq) < 3:
        return np.zeros(dq.shape[1])
    d2 = np.diff(dq, n=2, axis=0)
    return 1.4826 * np.median(np.abs(d2), axis=0) / np.sqrt(6.0)


def stuck_samples(
    dq: np.ndarray, velocity_threshold: float, noise: np.ndarray | None = None
) -> tuple[np.ndarray, list[list[tuple[int, int]]]]:
    """Where each joint was stuck: its measured velocity within the band
    :math:`|\\dot q_i| \\le \\max(v_0,\\ 4\\hat\\sigma_{v,i})` for two samples or more in a
    row (at rest over a whole period; :data:`STUCK_NOISE_DEVIATIONS`). A joint passing
    through zero at speed is in the band for one sample at most and is not stuck.

    Args:
        dq: Measured velocities [rad/s], (K, n). velocity_threshold: :math:`v_0` [rad/s].
        noise: :math:`\\hat\\sigma_v` per joint [rad/s]; ``None``: :func:`velocity_noise`.

    Returns:
        (mask (K, n) of the stuck samples, per joint the (start, stop) index ranges).
    """
    dq = np.asarray(dq, float)
    sigma = velocity_noise(dq) if noise is None else np.asarray(noise, float)
    band = np.maximum(velocity_threshold, STUCK_NOISE_DEVIATIONS * sigma)
    mask = np.zeros(dq.shape, dtype=bool)
    ranges = []
    for i in range(dq.shape[1]):
        runs = [(s, e) for s, e in _runs(np.abs(dq[:, i]) <= band[i]) if e - s >= 2]
        for s, e in runs:
            mask[s:e, i] = True
        ranges.append(runs)
    return mask, ranges


def _stuck_and_settling(
    t: np.ndarray, ranges: list[list[tuple[int, int]]], settling: float, coupled: bool
) -> np.ndarray:
    """(K, n): the samples of each stuck interval and those up to ``settling`` [s] after
    its first moving sample; every joint's when the observer couples the joints."""
    out = np.zeros((len(t), len(ranges)), dtype=bool)
    for i, runs in enumerate(ranges):
        for s, e in runs:
            end = t[min(e, len(t) - 1)] + settling
            out[s:, i] |= t[s:] <= end + 1e-12
    if coupled:
        out[:] = out.any(axis=1, keepdims=True)
    return out


def _observer_stuck(clean: Result, valid, t, observer, velocity_threshold: float):
    """The observer source's stuck samples and settling (module docstring): (mask (K, n),
    indices of the joints found stuck, the observer's time constant [s], 0 without it)."""
    moving = np.where(valid[:, None], clean.dq, np.inf)  # a gap is no stuck joint
    _, ranges = stuck_samples(moving, velocity_threshold, velocity_noise(clean.dq[valid]))
    tau = 0.0
    if observer is not None:
        tau = observer.time_constant(clean.q[valid] if valid.any() else clean.q)
    coupled = observer is not None and observer.coupled()
    mask = _stuck_and_settling(t, ranges, SETTLING_TIME_CONSTANTS * tau, coupled)
    return mask, tuple(i for i, r in enumerate(ranges) if r), tau


def _regressors(dq: np.ndarray) -> np.ndarray:
    """:math:`\\Phi` (K, n, 2n): joint i's viscous and Coulomb columns 2i, 2i+1."""
    K, n = dq.shape
    phi = np.zeros((K, n, 2 * n))
    for i in range(n):
        phi[:, i, 2 * i] = dq[:, i]
        phi[:, i, 2 * i + 1] = np.sign(dq[:, i])
    return phi


def applied_torque(result: Result, robot) -> np.ndarray:
    """The torque on the joints at each sample [N·m], (K+1, n): ``tau_applied`` (else
    ``tau``), plus :math:`G(q_k)` of ``robot`` when the arm added gravity to the torque
    recorded (:attr:`Result.gravity_by_arm <hmpc_pin.sim.result.Result.gravity_by_arm>`:
    a Franka arm, a ROS arm with ``[ros] gravity = "arm"``)."""
    tau = result.tau_applied if result.tau_applied is not None else result.tau
    if not result.gravity_by_arm:
        return tau
    finite = np.all(np.isfinite(result.q), axis=1)
    gravity = np.zeros_like(tau)
    for k in np.flatnonzero(finite):
        gravity[k] = robot.gravity_torque(result.q[k])
    return tau + gravity


def dynamics_friction(result: Result, robot) -> tuple[np.ndarray, np.ndarray]:
    """``(f, dq)`` over each period from the rigid-body model (module docstring):
    :math:`f_k = \\tau_k - Y(\\bar q, \\bar{\\dot q}, \\ddot q_k)\\,\\pi`, with Pinocchio's
    joint-torque regressor :math:`Y` and the model's inertial parameters :math:`\\pi`.

    Args:
        robot: A :class:`~hmpc_pin.model.robot.Robot` of the arm that ran.
    """
    import pinocchio as pin

    model = robot.model
    data = model.createData()
    pi = np.concatenate([model.inertias[j].toDynamicParameters() for j in range(1, model.njoints)])
    t, q, dq = result.t, result.q, result.dq
    tau = applied_torque(result, robot)
    dt = np.diff(t)
    f = np.full((len(t) - 1, q.shape[1]), np.nan)
    dq_mid = 0.5 * (dq[1:] + dq[:-1])
    for k in range(len(t) - 1):
        ddq = (dq[k + 1] - dq[k]) / dt[k]
        qm = 0.5 * (q[k] + q[k + 1])
        Y = pin.computeJointTorqueRegressor(model, data, qm, dq_mid[k], ddq)
        f[k] = tau[k] - Y @ pi
    return f, dq_mid


def _regressor_rows(result: Result, robot):
    """Per period: the joint-torque regressor :math:`Y_k` (n, 10·n_b), the applied torque,
    the mid-period velocity and time."""
    import pinocchio as pin

    model = robot.model
    data = model.createData()
    t, q, dq = result.t, result.q, result.dq
    tau = applied_torque(result, robot)
    dq_mid = 0.5 * (dq[1:] + dq[:-1])
    Y = np.empty((len(t) - 1, q.shape[1], 10 * (model.njoints - 1)))
    for k in range(len(t) - 1):
        ddq = (dq[k + 1] - dq[k]) / (t[k + 1] - t[k])
        Y[k] = pin.computeJointTorqueRegressor(model, data, 0.5 * (q[k] + q[k + 1]), dq_mid[k], ddq)
    return Y, tau[:-1], dq_mid, 0.5 * (t[1:] + t[:-1])


def _base_columns(Y: np.ndarray, tol: float = 1e-8) -> np.ndarray:
    """Indices of a maximal set of independent columns of ``Y`` (QR, column pivoting)."""
    from scipy.linalg import qr

    norms = np.linalg.norm(Y, axis=0)
    live = np.flatnonzero(norms > tol * max(norms.max(), 1e-300))
    _, R, piv = qr(Y[:, live] / norms[live], mode="economic", pivoting=True)
    d = np.abs(np.diag(R))
    rank = int(np.count_nonzero(d > tol * d[0])) if d.size else 0
    return np.sort(live[piv[:rank]])


def _valid_rows(result: Result, source: str, observer) -> tuple[np.ndarray, list[str]]:
    """Per sample: whether every recorded column the fit reads is finite there, and the
    names of the columns that are not somewhere. The applied torque of the last sample
    (no period follows it) is not read; the time must be finite (``load_run`` checks)."""
    columns = {"q": result.q, "dq": result.dq}
    if source == "observer":
        columns["d_hat"] = result.d_hat
    else:
        tau = result.tau_applied if result.tau_applied is not None else result.tau
        columns["tau_applied"] = np.vstack([tau[:-1], np.zeros((1, tau.shape[1]))])
    valid = np.ones(len(result.t), dtype=bool)
    bad = []
    for name, arr in columns.items():
        ok = np.all(np.isfinite(arr), axis=1)
        if not ok.all():
            bad.append(name)
        valid &= ok
    return valid, bad


def _runs(valid: np.ndarray) -> list[tuple[int, int]]:
    """The ``(start, stop)`` index ranges of the consecutive ``True`` samples of ``valid``."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], valid.astype(int), [0]])))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def _zero_filled(result: Result, valid: np.ndarray) -> Result:
    """``result`` with the rows that are not ``valid`` set to zero (the fit leaves them
    out; zeros keep NaN out of Pinocchio and the observer's filter)."""
    from dataclasses import replace

    if valid.all():
        return result

    def fill(a):
        return None if a is None else np.where(valid.reshape(-1, *([1] * (a.ndim - 1))), a, 0.0)

    names = ("q", "dq", "tau", "tau_applied", "d_hat")
    return replace(result, **{k: fill(getattr(result, k)) for k in names})


def _check_options(source: str, confidence: float, velocity_threshold: float, robot) -> None:
    """``fit_friction``'s options, checked before anything is computed.

    Raises:
        ConfigError: An unknown source, a confidence level outside (0, 1), a velocity
            threshold below 0 or not finite, or a model source without the arm's model.
    """
    if source not in SOURCES:
        raise ConfigError("--source", f"expected one of {SOURCES}, got {source!r}")
    if not 0 < confidence < 1:
        raise ConfigError("--confidence", f"expected a level in (0, 1), got {confidence!r}")
    if not (np.isfinite(velocity_threshold) and velocity_threshold >= 0):
        raise ConfigError(
            "--velocity-threshold", f"expected a number >= 0, got {velocity_threshold!r}"
        )
    if source in ("dynamics", "regressor") and robot is None:
        raise ConfigError("robot", f"the {source!r} source needs the arm's model")


def _measurements(
    result: Result, clean: Result, valid: np.ndarray, source: str, robot, observer, after: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The regression's rows for ``source`` (module docstring): the regressors ``g``
    (K, n, p), the measured friction ``y`` (K, n), the velocities ``dq`` (K, n) and the
    times ``t`` (K,) they belong to, and which rows are ``valid`` (K,).

    ``clean`` is ``result`` with its invalid rows zeroed (:func:`_zero_filled`); ``valid``
    marks them per sample. The model sources use one row per control period (both ends
    recorded); the observer's filter starts again from rest after each gap and its
    start-up (``after`` [s]) is then left out as at the run's start.
    """
    n = result.dq.shape[1]
    if source in ("regressor", "dynamics"):
        valid = valid[:-1] & valid[1:]  # per period: both ends recorded
    if source == "regressor":
        Yr, tau, dq, t = _regressor_rows(clean, robot)
        use = (t >= after - 1e-12) & valid
        base = _base_columns(Yr[use].reshape(-1, Yr.shape[2]))
        phi = _regressors(dq)
        g = np.concatenate([phi, Yr[:, :, base]], axis=2)  # friction first, then pi_base
        return g, tau, dq, t, valid
    if source == "dynamics":
        y, dq = dynamics_friction(clean, robot)
        t = 0.5 * (result.t[1:] + result.t[:-1])
        return _regressors(dq), y, dq, t, valid
    if observer is None:
        dq, t = clean.dq, clean.t
        return _regressors(dq), _feedforward(clean, dq) - clean.d_hat, dq, t, valid
    # the observer's response to each regressor and to the fed-forward friction
    dq = np.vstack([clean.dq[:1], 0.5 * (clean.dq[1:] + clean.dq[:-1])])
    t = clean.t
    ff = np.vstack([np.zeros((1, n)), _feedforward(clean, clean.dq[:-1])])
    phi = np.concatenate([_regressors(dq), ff[:, :, None]], axis=2)
    # the filter's state cannot cross a gap: it starts again from rest after each,
    # and the start-up it then needs (``after``) is left out as at the run's start
    filtered = np.zeros_like(phi)
    settled = np.ones(len(t), dtype=bool)
    for s, e in _runs(valid):
        filtered[s:e] = observer.filter(clean.q[s:e], phi[s:e])
        if s > 0:
            settled[s:e] = t[s:e] >= t[s] + after - 1e-12
    return filtered[:, :, :-1], filtered[:, :, -1] - clean.d_hat, dq, t, valid & settled


def _check_left(use: np.ndarray, valid: np.ndarray, after: float, bad_columns: list[str]) -> int:
    """The samples after ``after`` [s] left out for NaN or inf in a recorded column.

    Raises:
        ConfigError: Every sample after ``after`` is left out: nothing to fit.
    """
    excluded = int(np.count_nonzero(use & ~valid))
    if excluded and not np.any(use & valid):
        raise ConfigError(
            "RUN",
            f"every sample after {after:g} s has NaN or inf in "
            f"{' or '.join(bad_columns)}: nothing to fit"
            + (
                " (a file written before 0.3 of a saturated run does not know the "
                "applied torque; use --source observer)"
                if bad_columns == ["tau_applied"]
                else ""
            ),
        )
    return excluded


def _joint_blocks(
    names: tuple[str, ...],
    use: np.ndarray,
    stuck: np.ndarray,
    g: np.ndarray,
    y: np.ndarray,
    dq: np.ndarray,
    options: tuple[float, float, float, float],
    stuck_names: tuple[str, ...],
    settling: float,
) -> tuple[list[tuple[np.ndarray, np.ndarray]], list[tuple[float, float]], list[float]]:
    """Per joint, its least-squares block ``(A, y)`` of the samples it moved in, its
    coverage and its regressor's condition number, after checking its excitation.

    Args:
        options: ``(velocity_threshold, excitation_velocity, min_coverage,
            max_condition)`` of :func:`fit_friction`.

    Raises:
        ExcitationError: A joint is not excited enough (the first such joint), naming the
            stuck joints when leaving them out took the excitation away.
    """
    velocity_threshold, excitation_velocity, min_coverage, max_condition = options
    blocks, covers, conds = [], [], []
    for i, name in enumerate(names):
        ok = use & ~stuck[:, i]
        try:
            covers.append(
                check_excitation(
                    name, dq[ok, i], max(excitation_velocity, velocity_threshold), min_coverage
                )
            )
        except ExcitationError as exc:
            if not np.any(use & stuck[:, i]):
                raise
            raise ExcitationError(
                name,
                f"{exc.reason}, after leaving out the {np.count_nonzero(use & stuck[:, i])} "
                f"samples where {', '.join(stuck_names)} stuck and the observer's settling "
                f"after each ({settling:.3g} s); fewer reversals, or a faster observer",
            ) from None
        keep = ok & np.isfinite(y[:, i]) & (np.abs(dq[:, i]) > velocity_threshold)
        raw = np.column_stack([dq[keep, i], np.sign(dq[keep, i])])
        conds.append(_condition(name, raw, max_condition))
        blocks.append((g[keep, i, :], y[keep, i]))
    return blocks, covers, conds


def _solve(
    names: tuple[str, ...],
    blocks: list[tuple[np.ndarray, np.ndarray]],
    covers: list[tuple[float, float]],
    conds: list[float],
    confidence: float,
    separate: bool,
) -> tuple[JointFriction, ...]:
    """The least-squares fit of the blocks: one per joint on its own two columns
    (``separate``: the joints do not share a regressor), or all joints together."""
    if separate:
        fits = []
        for i, (A, v) in enumerate(blocks):
            theta, half, res, m_eff = _least_squares([(A[:, 2 * i : 2 * i + 2], v)], confidence)
            fits.append(_joint(names[i], theta, half, res[0], m_eff[0], conds[i], covers[i]))
        return tuple(fits)
    theta, half, res, m_eff = _least_squares(blocks, confidence)
    return tuple(
        _joint(
            name,
            theta[2 * i : 2 * i + 2],
            half[2 * i : 2 * i + 2],
            res[i],
            m_eff[i],
            conds[i],
            covers[i],
        )
        for i, name in enumerate(names)
    )


def fit_friction(
    result: Result,
    *,
    source: str = "observer",
    robot=None,
    observer: ObserverModel | None = None,
    after: float = 0.5,
    velocity_threshold: float = 0.01,
    confidence: float = 0.95,
    min_coverage: float = 0.05,
    max_condition: float = 100.0,
    excitation_velocity: float = 0.05,
    run: str = "",
) -> FrictionFit:
    """Fit every joint's viscous and Coulomb friction from ``result``.

    Args:
        result: A run of ``hmpc-pin run`` / ``realtime`` (:class:`~hmpc_pin.sim.result.Result`).
        source: ``"observer"`` or ``"dynamics"`` (module docstring).
        robot: The arm's :class:`~hmpc_pin.model.robot.Robot` (``"dynamics"`` only).
        observer: With ``"observer"``: the observer that ran; the regressors are passed
            through its dynamics, so that its lag is no bias (all joints are then fitted
            together). ``None``: :math:`\\hat d` is taken as the disturbance itself.
        after: Samples before this time [s] are left out (the observer's start-up).
        velocity_threshold: :math:`v_0` [rad/s]: slower samples are left out.
        confidence: Level of the intervals, in (0, 1).
        min_coverage: Fraction of samples needed moving each way faster than
            ``excitation_velocity`` [rad/s].
        max_condition: Largest condition number of the normalised regressor.

    Raises:
        ExcitationError: A joint is not excited enough (the first such joint).
        ConfigError: A bad option.
    """
    _check_options(source, confidence, velocity_threshold, robot)
    n = result.dq.shape[1]
    names = result.joint_names or tuple(f"joint{i + 1}" for i in range(n))
    valid, bad_columns = _valid_rows(result, source, observer)
    clean = _zero_filled(result, valid)
    g, y, dq, t, valid = _measurements(result, clean, valid, source, robot, observer, after)
    stuck, tau_obs = np.zeros((len(t), n), dtype=bool), 0.0
    stuck_names: tuple[str, ...] = ()
    if source == "observer":  # a stuck joint's holding torque, and the observer after it
        stuck, joints, tau_obs = _observer_stuck(clean, valid, t, observer, velocity_threshold)
        stuck_names = tuple(names[i] for i in joints)
    settling = SETTLING_TIME_CONSTANTS * tau_obs
    use = t >= after - 1e-12
    excluded = _check_left(use, valid, after, bad_columns)
    use &= valid
    left_out = int(np.count_nonzero(use & stuck.any(axis=1)))
    options = (velocity_threshold, excitation_velocity, min_coverage, max_condition)
    blocks, covers, conds = _joint_blocks(
        names, use, stuck, g, y, dq, options, stuck_names, settling
    )
    separate = source == "dynamics" or (source == "observer" and observer is None)
    fits = _solve(names, blocks, covers, conds, confidence, separate)
    return FrictionFit(
        fits, source, confidence, run, excluded, "", left_out, stuck_names, settling, tau_obs
    )
