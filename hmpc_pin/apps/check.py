"""``hmpc-pin check CONFIG``: what to know about an arm before anything runs on it.

Per joint, from the config's models alone (nothing is simulated):

* **observer bandwidth** :math:`\\omega_j` [1/s] and :math:`\\omega_j T_s`: the rate at which
  joint j's estimation error decays, :math:`\\omega_j = (cY M(q_0)^{-1})_{jj}` for the NDO
  of Eq (13) (``chen``, ``general``;
  :func:`~hmpc_pin.compensation.bandwidth.implied_bandwidth`), :math:`K_j` for the momentum
  observer;
* **stability margin for the latency**: the rule of :mod:`hmpc_pin.compensation.bandwidth`,
  :math:`\\omega_j r (T_s + L_u) \\le 1/2` with :math:`L_u` the latency the controller does
  not compensate: none when the config declares its latency (``[controller] latency`` > 0),
  else one unknown control period (an arm's interface always delays its measurements).
  With a latency declared, the rule for one declared too long instead,
  :math:`\\omega_j (r T_s + 2\\Delta L - 2T_s) \\le 1` with
  :math:`\\Delta L = \\min(L, T_s)/2` (half an interface cycle;
  :func:`~hmpc_pin.compensation.bandwidth.overdeclared_limit`). The margin is
  :math:`\\omega_{\\max}/\\omega_j` [-] (a problem below 1); the explicit observer also
  needs :math:`T_s\\omega_j < 2`;
* **damping time constant** :math:`1/(b_j (M(q_0)^{-1})_{jj})` [s] of the URDF's joint
  damping (:func:`~hmpc_pin.model.robot.damping_time_constants`)
  against :math:`T_s`: a problem when it is below :math:`2T_s` and the controller does not
  compensate the joint dynamics (``controller.joint_dynamics = false``);
* **torque headroom** along the reference: :math:`1 - \\max_t |\\tau_j(t)| / \\tau_{j,\\max}`
  with :math:`\\tau = M(r)\\ddot r + C(r, \\dot r)\\dot r + G(r)
  + B\\dot r + F\\,\\mathrm{sgn}\\,\\dot r`
  (RNEA along the reference sampled every :math:`T_s/4` over the run, :math:`\\ddot r` by
  central differences) and the plant's effort limits. A problem below
  :data:`MIN_HEADROOM`: the feedback and the disturbance compensation need the rest;

and, with MuJoCo installed, **the model against a second engine**: :math:`M(q)` and the
forward dynamics :math:`\\ddot q(q, \\dot q, \\tau)` of Pinocchio and MuJoCo (the bare arm:
no joint dynamics, no armature, no contacts) at :data:`ENGINE_SAMPLES` seeded states
within the limits. A problem when they differ by more than :data:`ENGINE_RTOL` (relative
to the largest entry): the two engines read the URDF differently.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from ..compensation.bandwidth import (
    MASS_RATIO,
    bandwidth_limit,
    overdeclared_excess,
    overdeclared_limit,
)
from ..experiment.build import Experiment
from ..experiment.plants import _effort_limit
from ..experiment.schema import ExperimentConfig
from ..model.robot import damping_time_constants

__all__ = ["ENGINE_RTOL", "ENGINE_SAMPLES", "MIN_HEADROOM", "CheckReport", "check_config"]

#: Smallest torque headroom along the reference [-] that is not a problem.
MIN_HEADROOM = 0.1
#: States at which Pinocchio and MuJoCo are compared.
ENGINE_SAMPLES = 5
#: Largest relative difference of M(q) and q̈ between Pinocchio and MuJoCo [-] (both are
#: exact rigid-body algorithms on the same inertias: only rounding separates them).
ENGINE_RTOL = 1e-6


@dataclass
class CheckReport:
    """The figures of :func:`check_config` and the problems found.

    Attributes:
        joints: Joint names.
        Ts: Control period [s].
        latency: The latency the controller is told about, ``[controller] latency`` [s].
        bandwidth: Observer bandwidth per joint [1/s] (``None``: no observer).
        margin: The rule's margin :math:`\\omega_{\\max}/\\omega_j` per joint [-] (below 1: a
            problem; inf: no bound; ``None``: no observer).
        damping_tau: Damping time constant per joint [s] (inf: none;
            :func:`~hmpc_pin.model.robot.damping_time_constants`).
        headroom: Torque headroom per joint [-] (inf: no limit).
        engine: ``(max rel. difference of M, of q̈)`` against MuJoCo, or a sentence why
            not compared.
        problems: One line per problem (empty: fine).
    """

    joints: tuple[str, ...]
    Ts: float
    latency: float
    bandwidth: np.ndarray | None
    margin: np.ndarray | None
    damping_tau: np.ndarray
    headroom: np.ndarray
    engine: tuple[float, float] | str
    problems: list[str] = field(default_factory=list)

    def format(self) -> str:
        """The per-joint table, the engine comparison and the problems, as text."""
        lines = [
            f"Ts = {self.Ts:g} s, latency = {self.latency:g} s",
            f"{'joint':<24} {'w [1/s]':>9} {'w*Ts':>7} {'margin':>8} {'T_b [s]':>9} "
            f"{'headroom':>9}",
        ]
        for j, name in enumerate(self.joints):
            bw = "-" if self.bandwidth is None else f"{self.bandwidth[j]:.3g}"
            wts = "-" if self.bandwidth is None else f"{self.bandwidth[j] * self.Ts:.3g}"
            mg = ("-" if self.margin is None else "inf" if np.isinf(self.margin[j])
                  else f"{self.margin[j]:.2g}x")  # fmt: skip
            tau = "-" if not np.isfinite(self.damping_tau[j]) else f"{self.damping_tau[j]:.3g}"
            hr = "-" if not np.isfinite(self.headroom[j]) else f"{100 * self.headroom[j]:.0f} %"
            lines.append(f"{name:<24} {bw:>9} {wts:>7} {mg:>8} {tau:>9} {hr:>9}")
        if isinstance(self.engine, str):
            lines.append(f"MuJoCo: {self.engine}")
        else:
            lines.append(f"MuJoCo: M(q) within {self.engine[0]:.2g}, forward dynamics within "
                         f"{self.engine[1]:.2g} (relative) of Pinocchio's")  # fmt: skip
        return "\n".join(lines)


def _latency(config: ExperimentConfig) -> tuple[float, float]:
    """``(declared, uncompensated)`` latency [s]: ``[controller] latency`` (compensated by
    the controller) and the latency the rule assumes the controller was not told about
    (one control period when none is declared, as
    :func:`~hmpc_pin.compensation.bandwidth.check_bandwidth`)."""
    declared = float(getattr(config.controller, "latency", None) or 0.0)
    return declared, (0.0 if declared > 0 else config.controller.Ts)


def _bandwidth(ex: Experiment, M0: np.ndarray) -> np.ndarray | None:
    """The observer's bandwidth per joint [1/s], or ``None`` without an observer."""
    from ..compensation.bandwidth import implied_bandwidth
    from ..compensation.observers import DisturbanceObserver, MomentumObserver

    comp = getattr(ex.controller, "compensation", None)
    while hasattr(comp, "inner"):  # a gate around the observer (collision reaction)
        comp = comp.inner
    if isinstance(comp, MomentumObserver):
        return np.broadcast_to(np.asarray(comp.K, dtype=float), (M0.shape[0],)).copy()
    if isinstance(comp, DisturbanceObserver):
        return implied_bandwidth(comp.cY, M0)
    return None  # no observer (none, ISM)


def _headroom(ex: Experiment, limit: np.ndarray | None) -> np.ndarray:
    """1 − max |τ_j| / τ_max along the reference (inf without limits)."""
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
    need = np.zeros(n)
    for k in range(len(t)):
        tau = pin.rnea(model, data, q[k], dq[k], ddq[k]) + b * dq[k] + f * np.sign(dq[k])
        need = np.maximum(need, np.abs(tau))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(np.isfinite(limit), 1.0 - need / limit, np.inf)


def _engines(ex: Experiment) -> tuple[float, float] | str:
    """Pinocchio's M(q) and forward dynamics against MuJoCo's at seeded states."""
    try:
        import mujoco
    except ImportError:
        return "not compared (install the 'mujoco' extra)"
    from ..sim.mujoco import MuJoCoSettings, mujoco_model

    robot = ex.robot
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
    for _ in range(ENGINE_SAMPLES):
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


def check_config(config: ExperimentConfig, engines: bool = True) -> CheckReport:
    """The figures and problems of ``config`` (module docstring), nothing run.

    Args:
        config: A validated experiment config.
        engines: Compare the model against MuJoCo (when installed).
    """
    ex = Experiment.from_config(config)
    robot = ex.robot
    names = robot.joint_names
    Ts = config.controller.Ts
    M0 = robot.mass_matrix(ex.q0)
    latency, uncompensated = _latency(config)
    problems: list[str] = []

    bw = _bandwidth(ex, M0)
    margin = None
    if bw is not None:
        excess = overdeclared_excess(Ts, latency)
        limit = (overdeclared_limit(Ts, excess) if latency > 0
                 else bandwidth_limit(Ts, uncompensated))  # fmt: skip
        margin = np.where(bw > 0, limit / np.where(bw > 0, bw, 1.0), np.inf)
        explicit = getattr(config.controller.observer, "discretization", "") == "explicit"
        for j in np.flatnonzero((margin < 1.0 - 1e-9) | (explicit & (bw * Ts >= 2.0))):
            if explicit and bw[j] * Ts >= 2.0:
                problems.append(
                    f"joint {names[j]!r}: observer bandwidth {bw[j]:.3g} 1/s: w Ts = "
                    f"{bw[j] * Ts:.3g} >= 2 puts the explicit observer's pole outside the "
                    f"unit circle; use w < {2 / Ts:.4g} 1/s or discretization = 'implicit'"
                )
            elif latency > 0:
                problems.append(
                    f"joint {names[j]!r}: observer bandwidth {bw[j]:.3g} 1/s (w Ts = "
                    f"{bw[j] * Ts:.3g}) above {limit:.4g} 1/s, the rule "
                    f"w (r Ts + 2 dL - 2 Ts) <= 1 for a latency declared dL = {excess:g} s "
                    f"longer than it is (half an interface cycle, r = {MASS_RATIO:g}): the "
                    "observer's estimate would alternate in sign and grow; lower the "
                    "bandwidth or measure the latency"
                )
            else:
                problems.append(
                    f"joint {names[j]!r}: observer bandwidth {bw[j]:.3g} 1/s (w Ts = "
                    f"{bw[j] * Ts:.3g}) above {limit:.3g} 1/s, the rule w r (Ts + L) <= 1/2 "
                    f"for a latency of L = {uncompensated:g} s the controller is not told "
                    f"about (r = {MASS_RATIO:g}): declare the latency ([controller] latency) "
                    "or lower the observer gain"
                )

    damping_tau = damping_time_constants(robot, ex.q0)
    compensated = bool(getattr(config.controller, "joint_dynamics", False))
    if not compensated:
        for j in np.flatnonzero(damping_tau < 2 * Ts):
            problems.append(
                f"joint {names[j]!r}: damping time constant 1/(b (M^-1)_jj) = "
                f"{damping_tau[j]:.3g} s is "
                f"below 2 Ts = {2 * Ts:g} s and controller.joint_dynamics is false; set it "
                "true (compensation with the zero-order-hold gain) or lower Ts"
            )

    headroom = _headroom(ex, _effort_limit(config, ex.plant))
    for j in np.flatnonzero(headroom < MIN_HEADROOM):
        problems.append(
            f"joint {names[j]!r}: the reference needs {100 * (1 - headroom[j]):.0f} % of the "
            f"effort limit (headroom {100 * headroom[j]:.0f} %, expected >= "
            f"{100 * MIN_HEADROOM:.0f} %); slow or shrink the reference"
        )

    engine: tuple[float, float] | str = "not compared (--no-engine)"
    if engines:
        engine = _engines(ex)
        if not isinstance(engine, str):
            for what, err in zip(("M(q)", "the forward dynamics"), engine, strict=True):
                if err > ENGINE_RTOL:
                    problems.append(
                        f"model: MuJoCo's {what} differs from Pinocchio's by {err:.2g} "
                        f"(relative, expected <= {ENGINE_RTOL:g}); the engines read the URDF "
                        "differently (check its <inertial> frames)"
                    )
    return CheckReport(names, Ts, latency, bw, margin, damping_tau, headroom, engine, problems)
