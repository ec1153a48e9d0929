"""The torque a config's reference needs against its plant's effort limits, along the
reference (``hmpc-pin check``, :mod:`hmpc_pin.apps.check`)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from .build import Experiment

__all__ = ["torque_headroom"]


def torque_headroom(ex: Experiment, limit: np.ndarray | None, damped: bool = True) -> np.ndarray:
    """1 − max |τ_j| / τ_max along the reference (inf without limits): the torque that
    makes the plant, :math:`M\\ddot q + C\\dot q + G + B\\dot q + F\\,\\mathrm{sgn}\\,\\dot q
    = \\tau + d(t, q, \\dot q)`, follow it, with the config's disturbance d and the URDF's
    joint damping and friction when the plant applies them (``damped``).

    The reference is sampled every :math:`T_s/4` over the run, :math:`\\ddot r` by central
    differences, the torque by RNEA.

    Args:
        ex: The built experiment (its reference, model and disturbance).
        limit: The plant's effort limit per joint [N·m or N] (``None``: no limits).
        damped: The plant applies the URDF's joint damping and friction.

    Returns:
        The headroom per joint [-] (inf where a joint has no limit).
    """
    n = ex.robot.nq
    if limit is None:
        return np.full(n, np.inf)
    Ts = ex.config.controller.Ts
    dt = Ts / 4.0
    t = np.arange(0.0, ex.config.simulation.duration + dt / 2, dt)
    q, dq = ex.reference.sample_many(t)
    q, dq = np.array(q, dtype=float), np.array(dq, dtype=float)
    ddq = np.gradient(dq, dt, axis=0)
    model, data = ex.robot.model, ex.robot.model.createData()
    b, f = ex.robot.joint_damping, ex.robot.joint_friction
    if not damped:
        b, f = np.zeros(n), np.zeros(n)
    need = np.zeros(n)
    disturbance = ex.disturbance
    for k in range(len(t)):
        tau = pin.rnea(model, data, q[k], dq[k], ddq[k]) + b * dq[k] + f * np.sign(dq[k])
        tau = tau - np.asarray(disturbance(float(t[k]), q[k], dq[k]), dtype=float)
        need = np.maximum(need, np.abs(tau))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(np.isfinite(limit), 1.0 - need / limit, np.inf)
