"""Tracking and observer metrics of a :class:`~hmpc_pin.sim.result.Result`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "DEFAULT_ERROR_THRESHOLD",
    "RUN_WARN_AFTER",
    "UNITS",
    "Metrics",
    "TaskMetrics",
    "chattering",
    "compute_metrics",
    "contact_lines",
    "joint_units",
    "quat_angle",
    "run_warnings",
    "settling_time",
    "task_metrics",
    "unit_labels",
]

#: Default threshold of the tracking-error warning [rad] (``--warn-error``).
DEFAULT_ERROR_THRESHOLD = 0.05
#: The start-up [s] that `run`'s tracking warning leaves out (:func:`run_warnings`).
RUN_WARN_AFTER = 1.0

#: Units of a joint's (position, velocity, effort) by kind.
UNITS = {"revolute": ("rad", "rad/s", "N·m"), "prismatic": ("m", "m/s", "N")}


def joint_units(result) -> list[tuple[str, str, str]]:
    """Per joint of ``result``, its (position, velocity, effort) units: metres, m/s and
    newtons for a prismatic joint (``result.meta["joint_kinds"]``), else rad, rad/s, N·m."""
    n = result.q.shape[1]
    kinds = result.meta.get("joint_kinds") or ["revolute"] * n
    return [UNITS.get(k, UNITS["revolute"]) for k in kinds]


def unit_labels(result) -> dict[str, str]:
    """Column-header units for a table of ``result``'s joints: ``{"rad": "rad", "N·m":
    "N·m", "rad/s": "rad/s"}`` for revolute joints only, ``"rad|m"`` etc. when some joint
    is prismatic (its row then says which)."""
    units = joint_units(result)
    out = {}
    for k, base in enumerate(UNITS["revolute"]):
        found = sorted({u[k] for u in units}, key=lambda x: x != base)
        out[base] = "|".join(found)
    return out


def joint_label(name: str, units: tuple[str, str, str]) -> str:
    """``name``, with its units appended when they are not the revolute ones."""
    return name if units == UNITS["revolute"] else f"{name} ({units[0]}, {units[2]})"


def settling_time(t: np.ndarray, error: np.ndarray, tol: float) -> np.ndarray:
    """Per joint, the first time after which |error| stays below ``tol`` for good.

    Returns ``t[0]`` if it never leaves the band and ``nan`` if it is outside at
    the last sample. ``error`` has shape (K+1, n).
    """
    outside = np.abs(error) >= tol
    out = np.full(error.shape[1], np.nan)
    for i in range(error.shape[1]):
        idx = np.flatnonzero(outside[:, i])
        if idx.size == 0:
            out[i] = t[0]
        elif idx[-1] < len(t) - 1:
            out[i] = t[idx[-1] + 1]
    return out


def chattering(
    t: np.ndarray, tau: np.ndarray, cutoff: float = 10.0
) -> tuple[np.ndarray, np.ndarray]:
    """Two chattering measures of a torque record, per joint.

    Args:
        t: Uniform sample times [s], shape (K,).
        tau: Torques [N·m], shape (K, n).
        cutoff: Frequency above which energy counts as chattering [Hz].

    Returns:
        ``(tv, share)``: the total variation per second
        :math:`\\frac{1}{t_{K-1} - t_0}\\sum_k |\\tau_{k+1} - \\tau_k|` [N·m/s], and the share of
        the energy of :math:`\\tau - \\bar\\tau` (its mean removed) above ``cutoff``, from the
        discrete Fourier transform (Parseval), in [0, 1].
    """
    span = t[-1] - t[0]
    tv = np.abs(np.diff(tau, axis=0)).sum(axis=0) / span
    K = len(t)
    power = np.abs(np.fft.rfft(tau - tau.mean(axis=0), axis=0)) ** 2
    power[1 : (K + 1) // 2] *= 2.0  # one-sided spectrum: each bin but DC (and Nyquist) twice
    freq = np.fft.rfftfreq(K, span / (K - 1))
    total = power.sum(axis=0)  # = K * sum((tau - mean)**2) by Parseval
    share = np.divide(
        power[freq > cutoff].sum(axis=0), total, out=np.zeros_like(total), where=total > 0
    )
    return tv, share


@dataclass(frozen=True)
class TaskMetrics:
    """Task-space metrics of an end-effector task after ``after`` seconds.

    Attributes:
        position_rms: :math:`\\sqrt{\\mathrm{mean}_k \\|p_k - p^*_k\\|^2}` [m].
        position_max: :math:`\\max_k \\|p_k - p^*_k\\|` [m].
        orientation_rms: RMS of the angle :math:`\\|\\log R^{*T}_k R_k\\|` [rad].
        orientation_max: Its maximum [rad].
        frame: The frame.
    """

    position_rms: float
    position_max: float
    orientation_rms: float
    orientation_max: float
    frame: str


def quat_angle(q_ref: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Angle [rad] between unit quaternions (rows, any order of components as long as
    both use the same): :math:`2\\arccos|\\langle q^*, q\\rangle|`."""
    dot = np.abs(np.sum(q_ref * q, axis=1)) / (
        np.linalg.norm(q_ref, axis=1) * np.linalg.norm(q, axis=1)
    )
    return 2.0 * np.arccos(np.clip(dot, 0.0, 1.0))


def task_metrics(result, after: float = 1.0) -> TaskMetrics | None:
    """:class:`TaskMetrics` of ``result`` over ``t >= after`` [s]; ``None`` without
    task-space arrays (a joint-space reference)."""
    if getattr(result, "ee_pos", None) is None:
        return None
    mask = result.t >= after - 1e-12
    e = np.linalg.norm(result.ee_pos[mask] - result.ee_pos_ref[mask], axis=1)
    a = quat_angle(result.ee_quat_ref[mask], result.ee_quat[mask])
    if e.size == 0:
        return None
    return TaskMetrics(
        position_rms=float(np.sqrt(np.mean(e**2))),
        position_max=float(e.max()),
        orientation_rms=float(np.sqrt(np.mean(a**2))),
        orientation_max=float(a.max()),
        frame=str(result.meta.get("task", {}).get("frame", "")),
    )


@dataclass(frozen=True)
class Metrics:
    """Per-joint metrics (arrays of shape (n,)).

    Attributes:
        rms_error, max_error: RMS and max |q − r| after ``after`` seconds [rad].
        settling_time: Time to stay within ``tol`` for good [s] (nan: never).
        observer_rms, observer_peak: RMS and max |d − d̂| after ``after`` seconds [N·m].
        tau_peak: max |τ| over the whole run, τ as commanded by the controller [N·m].
        tau_applied_peak: max |τ| the plant applied (τ clipped to the effort limit) over
            the whole run [N·m].
        limit_violation: max distance of q outside the position limits recorded in
            ``result.meta["limits"]`` over the whole run [rad] (0 inside; nan if none recorded).
        saturated_steps: Control periods in which the plant clipped τ to the effort
            limit (from ``result.meta["saturation"]``; 0 if none recorded).
        tau_rms: RMS of τ after ``after`` seconds (control effort) [N·m].
        tau_tv: Total variation of τ per second after ``after`` seconds [N·m/s]
            (:func:`chattering`).
        tau_hf_share: Share of τ's energy above 10 Hz after ``after`` seconds
            (:func:`chattering`).
        task: :class:`TaskMetrics` of an end-effector task (``None`` otherwise).
    """

    rms_error: np.ndarray
    max_error: np.ndarray
    settling_time: np.ndarray
    observer_rms: np.ndarray
    observer_peak: np.ndarray
    tau_peak: np.ndarray
    after: float
    tol: float
    limit_violation: np.ndarray | None = None
    saturated_steps: np.ndarray | None = None
    tau_rms: np.ndarray | None = None
    tau_tv: np.ndarray | None = None
    tau_hf_share: np.ndarray | None = None
    tau_applied_peak: np.ndarray | None = None
    task: TaskMetrics | None = None


def compute_metrics(result, after: float = 1.0, tol: float = 0.01) -> Metrics:
    """Metrics of ``result`` with errors taken over ``t >= after`` [s] and band ``tol`` [rad]."""
    mask = result.t >= after - 1e-12
    e = result.error[mask]
    w = result.observer_error[mask]
    n = result.q.shape[1]
    limits = result.meta.get("limits")
    if limits:
        lo, hi = np.asarray(limits["lower"], float), np.asarray(limits["upper"], float)
        viol = np.maximum(np.maximum(lo - result.q, result.q - hi), 0.0).max(axis=0)
    else:
        viol = np.full(n, np.nan)
    sat = result.meta.get("saturation")
    steps = np.asarray(sat["steps"], dtype=int) if sat else np.zeros(n, dtype=int)
    tau = result.tau[mask]
    tv, share = chattering(result.t[mask], tau) if len(tau) > 1 else (np.full(n, np.nan),) * 2
    return Metrics(
        rms_error=np.sqrt(np.mean(e**2, axis=0)),
        max_error=np.abs(e).max(axis=0),
        settling_time=settling_time(result.t, result.error, tol),
        observer_rms=np.sqrt(np.mean(w**2, axis=0)),
        observer_peak=np.abs(w).max(axis=0),
        tau_peak=np.abs(result.tau).max(axis=0),
        after=after,
        tol=tol,
        limit_violation=viol,
        saturated_steps=steps,
        tau_rms=np.sqrt(np.mean(tau**2, axis=0)),
        tau_tv=tv,
        tau_hf_share=share,
        tau_applied_peak=_nanmax_abs(result.tau_applied),
        task=task_metrics(result, after),
    )


def _nanmax_abs(a: np.ndarray) -> np.ndarray:
    a = np.abs(a)
    return np.where(np.isnan(a).all(axis=0), np.nan, np.nanmax(np.where(np.isnan(a), -1, a), 0))


def run_warnings(
    result, error_threshold: float = DEFAULT_ERROR_THRESHOLD, after: float = RUN_WARN_AFTER
) -> list[str]:
    """Lines warning that a run which completed was not controlled as designed.

    Two checks: (1) the plant clipped the torque (``result.meta["saturation"]``): per
    joint the saturated periods, the commanded peak |τ| and the limit; (2) the tracking
    error :math:`\\max_{t \\ge t_a} |q - r|` exceeds ``error_threshold`` [rad]
    (:math:`t_a` = ``after`` [s]; not checked on a run shorter than that).

    Returns:
        One line per failed check (empty when the run is clean).
    """
    names = result.joint_names or tuple(f"joint{i + 1}" for i in range(result.q.shape[1]))
    lines = []
    sat = result.meta.get("saturation") or {}
    steps = np.asarray(sat.get("steps", np.zeros(len(names))), dtype=int)
    if steps.any():
        limit = np.asarray(sat["effort_limit"], float)
        peak = np.abs(result.tau).max(axis=0)
        periods = max(len(result.t) - 1, 1)
        parts = [
            f"{names[i]} {steps[i]} of {periods} periods (commanded peak {peak[i]:.4g} N·m, "
            f"limit {limit[i]:.4g} N·m)"
            for i in np.flatnonzero(steps)
        ]
        lines.append(
            "torque saturated: " + "; ".join(parts) + " — the plant applied the clipped "
            "torque (tau_applied), not the controller's"
        )
    mask = result.t >= after - 1e-12
    if mask.any():  # a run shorter than ``after`` is all start-up transient: not checked
        e = np.abs(result.error[mask]).max(axis=0)
        bad = np.flatnonzero(~(e <= error_threshold))
        if bad.size:
            parts = ", ".join(f"{names[i]} {e[i]:.3g} rad" for i in bad)
            lines.append(
                f"tracking error exceeds {error_threshold:g} rad after {after:g} s: max |e| "
                f"{parts} (threshold: --warn-error)"
            )
    return lines


def format_metrics(metrics: Metrics, joint_names=None, result=None) -> str:
    """A plain-text table of ``metrics``, one row per joint (units of a prismatic joint,
    m and N, from ``result``'s ``joint_kinds``, on its row)."""
    n = len(metrics.rms_error)
    names = list(joint_names) if joint_names else [f"joint{i + 1}" for i in range(n)]
    labels = {"rad": "rad", "N·m": "N·m"}
    if result is not None:
        labels = unit_labels(result)
        names = [joint_label(x, u) for x, u in zip(names, joint_units(result), strict=True)]
    w = max(10, *(len(x) for x in names))
    a = f"{metrics.after:g}"
    r, e = labels["rad"], labels["N·m"]
    head = (
        f"{'joint':<{w}} {'RMS e (t>=' + a + 's) [' + r + ']':>22} {'max |e| [' + r + ']':>14} "
        f"{'within ' + format(metrics.tol, 'g') + ' ' + r + ' from [s]':>23} "
        f"{'RMS d-d^ [' + e + ']':>15} {'peak |tau| [' + e + ']':>17} "
        f"{'applied [' + e + ']':>14} "
        f"{'limit viol. [' + r + ']':>18} {'saturated':>10}"
    )
    lines = [head, "-" * len(head)]
    viol = metrics.limit_violation if metrics.limit_violation is not None else [np.nan] * n
    sat = metrics.saturated_steps if metrics.saturated_steps is not None else [0] * n
    applied = metrics.tau_applied_peak if metrics.tau_applied_peak is not None else [np.nan] * n
    for i in range(n):
        st = metrics.settling_time[i]
        st_s = "never" if st != st else f"{st:.2f}"
        v_s = "n/a" if viol[i] != viol[i] else f"{viol[i]:.1e}"
        lines.append(
            f"{names[i]:<{w}} {metrics.rms_error[i]:>22.3e} {metrics.max_error[i]:>14.3e} "
            f"{st_s:>23} {metrics.observer_rms[i]:>15.3e} {metrics.tau_peak[i]:>17.1f} "
            f"{applied[i]:>14.1f} {v_s:>18} {int(sat[i]):>10}"
        )
    tm = metrics.task
    if tm is not None:
        lines.append(
            f"task space ({tm.frame}, t>={a}s): position RMS {tm.position_rms:.3e} m "
            f"(max {tm.position_max:.3e} m), orientation RMS {tm.orientation_rms:.3e} rad "
            f"(max {tm.orientation_max:.3e} rad)"
        )
    return "\n".join(lines)


def contact_lines(result) -> list[str]:
    """Lines saying what touched what in a run: the first contact with the obstacle
    (MuJoCo, ``meta["first_contact"]``, with the peak generalized contact force per joint)
    and the collision watch's flag (``meta["collision"]``: when, which joint, the reaction).

    Returns:
        Empty when the run had neither an obstacle nor a collision watch.
    """
    meta = result.meta
    names = result.joint_names or tuple(f"joint{i + 1}" for i in range(result.q.shape[1]))
    lines = []
    if "first_contact" in meta:
        first = meta["first_contact"]
        if first is None:
            lines.append("contact: the arm never touched the obstacle")
        else:
            force = np.abs(np.asarray(result.extra.get("contact_force", np.zeros((1, 1)))))
            peak = force.max(axis=0) if force.size else np.zeros(len(names))
            j = int(np.argmax(peak))
            lines.append(
                f"contact: first at t = {first:.3f} s with the obstacle; peak generalized "
                f"contact force {peak[j]:.4g} {joint_units(result)[j][2]} at {names[j]}"
            )
    collision = meta.get("collision")
    if collision:
        at, reaction = collision.get("detected_at"), collision.get("reaction")
        if at is None:
            lines.append("collision: none flagged (|d_hat| stayed below the threshold)")
        else:
            joint = collision.get("joint")
            k = names.index(joint) if joint in names else None
            limit = collision.get("threshold")
            unit = joint_units(result)[k][2] if k is not None else ""
            bound = f" above its threshold {limit[k]:g} {unit}" if k is not None and limit else ""
            lines.append(
                f"collision: flagged at t = {at:.3f} s on {joint} (|d_hat|{bound}); "
                f"reaction: {reaction}"
            )
    return lines
