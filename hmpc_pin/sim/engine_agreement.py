"""The arm's model against a second engine: Pinocchio's mass matrix :math:`M(q)` and
forward dynamics :math:`\\ddot q(q, \\dot q, \\tau)` against MuJoCo's, on the bare arm.

Both engines run exact rigid-body algorithms on the same inertias, so only rounding
separates them; a larger difference means the engines read the URDF differently
(``hmpc-pin check`` reports it, :mod:`hmpc_pin.apps.check`).
"""

from __future__ import annotations

import math

import numpy as np

from ..model.robot import Robot

__all__ = ["ENGINE_SAMPLES", "engine_agreement"]


#: States at which Pinocchio and MuJoCo are compared.
ENGINE_SAMPLES = 5


def engine_agreement(robot: Robot, samples: int = ENGINE_SAMPLES) -> tuple[float, float] | str:
    """Pinocchio's M(q) and forward dynamics against MuJoCo's at seeded states.

    The states are drawn with the seed 0: :math:`q` uniform within the joint limits
    (:math:`\\pm\\pi` where a joint has none), :math:`\\dot q` and
    :math:`\\tau / \\max(M_{jj}(q), 10^{-3})` standard normal.

    Args:
        robot: The arm (MuJoCo loads its URDF without geometry and without the URDF's
            joint dynamics).
        samples: States compared.

    Returns:
        ``(M, a)``: the largest relative difference of :math:`M(q)` and of
        :math:`\\ddot q` [-]; or why the engines were not compared (MuJoCo not installed,
        mimic joints, a different number of degrees of freedom).

    Raises:
        URDFError: MuJoCo refuses the URDF.
    """
    try:
        import mujoco
    except ImportError:
        return "not compared (install the 'mujoco' extra)"
    from .mjcf import mujoco_model
    from .mujoco_settings import MuJoCoSettings

    if robot.mimic_joints:
        return "not compared (mimic joints: MuJoCo holds them by a soft constraint)"
    model = mujoco_model(robot, MuJoCoSettings(geometry="none", import_urdf_dynamics=False))
    data = mujoco.MjData(model)
    qadr = np.array([model.joint(j).qposadr[0] for j in robot.joint_names])
    vadr = np.array([model.joint(j).dofadr[0] for j in robot.joint_names])
    if model.nq != robot.nq or model.nv != robot.nq:
        return f"not compared (MuJoCo's model has {model.nv} dofs, the controller's {robot.nq})"
    rng = np.random.default_rng(0)
    lo = np.where(np.isfinite(robot.lower), robot.lower, -math.pi)
    hi = np.where(np.isfinite(robot.upper), robot.upper, math.pi)
    full = np.zeros((model.nv, model.nv))
    err_M = err_a = 0.0
    for _ in range(samples):
        q = rng.uniform(lo, hi)
        dq = rng.standard_normal(robot.nq)
        tau = rng.standard_normal(robot.nq) * np.maximum(np.diag(robot.mass_matrix(q)), 1e-3)
        mujoco.mj_resetData(model, data)
        data.qpos[qadr], data.qvel[vadr] = q, dq
        data.qfrc_applied[vadr] = tau
        mujoco.mj_forward(model, data)
        try:  # MuJoCo >= 3.3: mj_fullM(m, d, dst); before: mj_fullM(m, dst, d.qM)
            mujoco.mj_fullM(model, data, full)
        except TypeError:
            mujoco.mj_fullM(model, full, data.qM)
        M_mj = full[np.ix_(vadr, vadr)]
        M_pin = robot.mass_matrix(q)
        err_M = max(err_M, float(np.abs(M_mj - M_pin).max() / np.abs(M_pin).max()))
        a_pin = robot.forward_dynamics(q, dq, tau)
        a_mj = data.qacc[vadr]
        err_a = max(err_a, float(np.abs(a_mj - a_pin).max() / max(np.abs(a_pin).max(), 1e-9)))
    return err_M, err_a
