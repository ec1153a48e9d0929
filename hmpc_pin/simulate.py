"""Closed-loop simulation: controller at period Ts, plant integrated with Pinocchio ABA.

The torque returned by the controller at :math:`t_k` is held over
:math:`[t_k, t_k + T_s)` (zero-order hold). The plant, which owns its own
``pin.Model``/``pin.Data`` (possibly a different URDF: model mismatch), is
integrated with a fixed step ``dt`` that divides :math:`T_s` (default 1 ms),

.. math::  \\ddot q = \\mathrm{ABA}(q, \\dot q, \\tau + d(t, q, \\dot q)),

with the disturbance evaluated at every plant step (and every RK4 stage).
"""

from __future__ import annotations

import json
import os
import sys
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

from .disturbances import ZeroDisturbance
from .exceptions import (
    ConfigError,
    DimensionError,
    HmpcError,
    NonFiniteError,
    OutputError,
    SimulationError,
)
from .plant import RK4Plant
from .robot import Robot

__all__ = ["Result", "simulate"]

#: Arrays stored in a :class:`Result`, each of shape (K+1, n) except ``t`` (K+1,).
RESULT_ARRAYS = ("t", "q", "dq", "tau", "d", "d_hat", "q_ref", "dq_ref")


@dataclass
class Result:
    """Trajectories of a closed-loop run, sampled at the control instants.

    Attributes:
        t: Time [s], shape (K+1,).
        q, dq: Joint positions [rad] and velocities [rad/s], shape (K+1, n).
        tau: Torque computed at each instant and held over the next period [N·m].
        d: True disturbance :math:`d(t_k, q_k, \\dot q_k)` [N·m].
        d_hat: Observer estimate :math:`\\hat d_k` [N·m] (zeros without observer).
        q_ref, dq_ref: Reference at :math:`t_k` [rad, rad/s].
        joint_names: Names of the joints.
        complete: ``False`` when the run stopped early; ``message`` says why.
        meta: Free-form metadata (config name, settings), saved as JSON.
    """

    t: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    tau: np.ndarray
    d: np.ndarray
    d_hat: np.ndarray
    q_ref: np.ndarray
    dq_ref: np.ndarray
    joint_names: tuple[str, ...] = ()
    complete: bool = True
    message: str = ""
    meta: dict = field(default_factory=dict)

    @property
    def error(self) -> np.ndarray:
        """Tracking error :math:`q - r` [rad], shape (K+1, n)."""
        return self.q - self.q_ref

    @property
    def observer_error(self) -> np.ndarray:
        """Observer error :math:`w = d - \\hat d` (Eq 14) [N·m]."""
        return self.d - self.d_hat

    def save(self, path: str | Path) -> Path:
        """Write the arrays, joint names, completeness flag and metadata to ``.npz``.

        The file is byte-for-byte reproducible (fixed zip timestamps, sorted JSON), so
        the same run saves the same bytes, and it is written to ``<path>.part`` first
        and renamed: no half-written file is ever left under the final name.
        """
        path = Path(path)
        if path.suffix != ".npz":
            path = path.with_name(path.name + ".npz")
        arrays = {
            **{name: getattr(self, name) for name in RESULT_ARRAYS},
            "joint_names": np.array(self.joint_names, dtype=str),
            "complete": np.array(self.complete),
            "message": np.array(self.message),
            "meta": np.array(json.dumps(self.meta, sort_keys=True)),
        }
        part = path.with_name(path.name + ".part")
        try:
            if not path.parent.is_dir():
                raise OutputError(path.parent, "no such directory")
            with zipfile.ZipFile(part, "w", compression=zipfile.ZIP_STORED) as zf:
                for name, arr in arrays.items():
                    info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
                    with zf.open(info, "w", force_zip64=True) as f:
                        np.lib.format.write_array(f, np.asanyarray(arr), allow_pickle=False)
            os.replace(part, path)
        except OSError as exc:
            raise OutputError(path.parent, exc.strerror or str(exc)) from exc
        finally:
            if part.exists():
                part.unlink()
        return path

    @classmethod
    def load(cls, path: str | Path) -> Result:
        """Read a result written by :meth:`save`."""
        with np.load(path, allow_pickle=False) as f:
            return cls(
                **{name: f[name] for name in RESULT_ARRAYS},
                joint_names=tuple(str(s) for s in f["joint_names"]),
                complete=bool(f["complete"]),
                message=str(f["message"]),
                meta=json.loads(str(f["meta"])),
            )


def simulate(
    robot: Robot,
    controller,
    reference,
    disturbance=None,
    *,
    duration: float,
    q0,
    dq0=None,
    plant: Robot | None = None,
    dt: float = 0.001,
    integrator: str = "rk4",
    state_bound: float = 1e3,
    effort_limit=None,
    meta: dict | None = None,
    on_step=None,
) -> Result:
    """Run the closed loop and return the sampled trajectories.

    Args:
        robot: The controller's model (used only for dimensions here).
        controller: Object with ``Ts``, ``reset(q0, dq0)``, ``step(t, q, dq, reference)``
            and ``disturbance_estimate`` (e.g. :class:`~hmpc_pin.HierarchicalMPC`).
        reference: Object with ``sample(t) -> (q_ref, dq_ref)``.
        disturbance: Callable ``d(t, q, dq) -> (n,)`` [N·m]; ``None`` for no disturbance.
        duration: Simulated time [s].
        q0, dq0: Initial state [rad, rad/s] (``dq0`` defaults to zero).
        plant: The plant's model; ``None`` uses a copy of ``robot`` (no mismatch).
        dt: Plant integration step [s]; must divide the control period.
        integrator: ``"rk4"`` (classical Runge–Kutta) or ``"euler"`` (semi-implicit).
        state_bound: The run stops as diverged if any |q| or |q̇| exceeds it.
        effort_limit: Actuator limits [N·m], shape (n,) (inf: none). The plant applies
            :math:`\\mathrm{clip}(\\tau, -\\tau_{\\max}, \\tau_{\\max})`; ``None`` applies τ as is.
            The result's ``meta["saturation"]`` reports, per joint, the number of
            control periods saturated and the largest excess :math:`|\\tau| - \\tau_{\\max}`.
        meta: Metadata stored in the result.
        on_step: Optional callable ``on_step(t, q, q_ref)`` called at every control
            instant (e.g. :class:`~hmpc_pin.viz.LiveView`).

    Returns:
        :class:`Result` with K+1 samples, K = round(duration / Ts).

    Raises:
        SimulationError: The state became non-finite or exceeded ``state_bound``, or
            the controller failed; ``exc.result`` holds the run up to that step
            (``complete=False``).
    """
    n = robot.nq
    q = robot.check_vector("q0", q0).copy()
    dq = robot.check_vector("dq0", np.zeros(n) if dq0 is None else dq0).copy()
    plant = plant if plant is not None else robot.copy()
    if plant.nq != n:
        raise DimensionError(f"{plant.nq=} but {robot.nq=}; the plant must have the same joints")
    Ts = float(controller.Ts)
    substeps = round(Ts / dt)
    if substeps < 1 or abs(substeps * dt - Ts) > 1e-9 * Ts:
        raise ConfigError("dt", f"plant dt={dt} does not divide the control period Ts={Ts}")
    if integrator not in ("rk4", "euler"):
        raise ConfigError("integrator", f"integrator={integrator!r}; expected 'rk4' or 'euler'")
    # Boundary check of the reference (once, before the loop): wrong shape or non-finite
    # at t = 0 is bad input, not a failure of the run.
    for name, value in zip(("q_ref", "dq_ref"), reference.sample(0.0), strict=True):
        robot.check_vector(f"reference.sample(0) {name}", value)
    h = Ts / substeps
    K = round(duration / Ts)
    dist = disturbance if disturbance is not None else ZeroDisturbance(n)

    t_arr = Ts * np.arange(K + 1)
    rec = {name: np.full((K + 1, n), np.nan) for name in RESULT_ARRAYS if name != "t"}
    model, data = plant.model, plant.data
    aba = pin.aba

    def acc(t, q, dq, tau):
        return aba(model, data, q, dq, tau + dist(t, q, dq))

    # Classical RK4 over each control period, the disturbance at every stage (plant.py).
    rk4 = RK4Plant(plant, dist, Ts, substeps) if integrator == "rk4" else None

    limit = None if effort_limit is None else robot.check_vector("effort_limit", effort_limit,
                                                                  finite=False)  # fmt: skip
    sat_steps = np.zeros(n, dtype=int)
    sat_excess = np.zeros(n)

    rec_q, rec_dq, rec_tau, rec_d, rec_d_hat, rec_q_ref, rec_dq_ref = (
        rec[name] for name in RESULT_ARRAYS[1:]
    )
    bound = min(state_bound, sys.float_info.max)
    controller.reset(q, dq)
    last = -1
    message = ""
    try:
        for k in range(K + 1):
            t = t_arr[k]
            tau = controller.step(t, q, dq, reference)
            q_ref, dq_ref = reference.sample(t)
            rec_q[k] = q
            rec_dq[k] = dq
            rec_tau[k] = tau
            rec_d[k] = dist(t, q, dq)
            rec_d_hat[k] = controller.disturbance_estimate
            rec_q_ref[k] = q_ref
            rec_dq_ref[k] = dq_ref
            last = k
            if on_step is not None:
                on_step(t, q, q_ref)
            if k == K:
                break
            if np.count_nonzero(np.isfinite(tau)) != n:
                raise NonFiniteError("tau", tau, f"at t={t:.6g}")
            if limit is not None:
                excess = np.abs(tau) - limit
                if (excess > 0).any():
                    sat_steps += excess > 0
                    np.maximum(sat_excess, excess, out=sat_excess)
                    tau = np.clip(tau, -limit, limit)
            if rk4 is not None:
                q, dq = rk4.advance(t, q, dq, tau)
            else:
                for s in range(substeps):
                    dq = dq + h * acc(t + s * h, q, dq, tau)
                    q = q + h * dq
            # One comparison per period in the common case; it fails for a NaN, an
            # infinite (the bound is capped at the largest float) or a too large entry.
            q_max, dq_max = np.abs(q).max(), np.abs(dq).max()
            if q_max <= bound and dq_max <= bound:
                continue
            if not (np.isfinite(q).all() and np.isfinite(dq).all()):
                raise NonFiniteError("plant state", (q, dq), f"at t={t + Ts:.6g}")
            if q_max > state_bound or dq_max > state_bound:
                raise SimulationError(
                    f"run diverged at t={t + Ts:.6g}: max |q|={np.abs(q).max():.3g}, "
                    f"max |dq|={np.abs(dq).max():.3g} exceed state_bound={state_bound}"
                )
    except HmpcError as exc:
        message = str(exc)
        cause = exc
    else:
        cause = None

    m = last + 1
    result = Result(
        t=t_arr[:m],
        **{name: arr[:m] for name, arr in rec.items()},
        joint_names=tuple(robot.joint_names),
        complete=cause is None,
        message=message,
        meta=dict(meta or {}),
    )
    if limit is not None:
        result.meta["saturation"] = {
            "effort_limit": [float(x) for x in limit],
            "steps": sat_steps.tolist(),
            "max_excess": sat_excess.tolist(),
        }
    if cause is not None:
        # k is the control step during which the fault was detected (in the controller,
        # in the torque check or in the plant integration over [t_k, t_k + Ts)).
        result.meta["failed_step"] = int(k)
        result.meta["failed_at"] = float(t_arr[k])
        raise SimulationError(
            f"simulation stopped in step {k} (t={t_arr[k]:.6g} s), {m} of {K + 1} samples "
            f"kept: {message}",
            result,
        ) from cause
    return result
