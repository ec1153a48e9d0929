"""The hierarchical multiloop MPC (paper Figure 1): inverse dynamics + NDO + per-joint MPC.

At every control instant :math:`t_k`:

1. Pinocchio gives :math:`M(q_k)` and :math:`C\\dot q_k + G` at the measured state.
2. The NDO (Eq 13) is advanced over the period that just ended with the torque
   that was held over it, giving :math:`\\hat d_k`.
3. Each joint's MPC (Eq 25–26) chooses its acceleration :math:`v_i` from the
   reference sampled at :math:`t_k + jT_s,\\ j = 1..N`.
4. Inverse dynamics (Eq 4): :math:`\\tau = M(q)v + C(q,\\dot q)\\dot q + G(q) - \\hat d`.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from .config import ControllerConfig
from .exceptions import ConfigError, DimensionError, NonFiniteError
from .ism import IntegralSlidingMode
from .joint_mpc import CondensedMPC, JointQPs, StateLimits
from .observers import make_observer
from .references import SineReference, sample_horizon
from .robot import Robot

__all__ = ["HMPC_KINDS", "ControllerWrapper", "HierarchicalMPC", "make_controller"]

#: The ``[controller] kind`` values built by :class:`HierarchicalMPC`.
HMPC_KINDS = ("hmpc", "hmpc-none", "hmpc-momentum", "hmpc-ism", "hmpc-ism-bl")


class ControllerWrapper:
    """Base of wrappers that keep a controller's interface (``Ts``, ``reset``, ``step``,
    ``disturbance_estimate``) and change one thing, e.g. timing or measurement.

    Subclasses override :meth:`reset` and/or :meth:`step`; the rest is delegated.
    """

    def __init__(self, controller):
        self.controller = controller

    @property
    def Ts(self) -> float:
        """Control period [s] of the wrapped controller."""
        return self.controller.Ts

    @property
    def disturbance_estimate(self) -> np.ndarray:
        """The wrapped controller's disturbance estimate [N·m]."""
        return self.controller.disturbance_estimate

    def reset(self, q0: np.ndarray, dq0: np.ndarray) -> None:
        """Reset the wrapped controller."""
        self.controller.reset(q0, dq0)

    def step(self, t: float, q: np.ndarray, dq: np.ndarray, reference) -> np.ndarray:
        """The wrapped controller's step [N·m]."""
        return self.controller.step(t, q, dq, reference)


def make_controller(robot: Robot, config: ControllerConfig | None = None):
    """The controller named by ``config.kind`` (README, "Controllers").

    ``hmpc*`` kinds give a :class:`HierarchicalMPC`, ``computed-torque*`` a
    :class:`~hmpc_pin.computed_torque.ComputedTorque`. All share the duck-typed
    interface :func:`~hmpc_pin.simulate.simulate` drives: ``Ts``, ``reset(q0, dq0)``,
    ``step(t, q, dq, reference)``, ``disturbance_estimate``.
    """
    config = config if config is not None else ControllerConfig()
    if config.kind in HMPC_KINDS:
        return HierarchicalMPC(robot, config)
    from .computed_torque import ComputedTorque

    return ComputedTorque(robot, config)


class HierarchicalMPC:
    """Inverse dynamics + disturbance compensation + one ProxSuite MPC per joint (``hmpc*`` kinds).

    Args:
        robot: The controller's model of the arm (its :class:`~hmpc_pin.robot.Robot`).
        config: Settings; the default is the paper's controller (Section 4).

    Attributes:
        disturbance_estimate: :math:`\\hat d` [N·m], shape (n,), updated by :meth:`step`
            (the observer's estimate; for ``hmpc-ism*`` the ISM torque :math:`-M u_{ism}`;
            zeros without compensation).
        v: The last commanded accelerations [rad/s²], shape (n,).
        tau: The last torque [N·m], shape (n,).
        limits: The joint limits imposed on each MPC's prediction as soft state
            constraints (:class:`~hmpc_pin.joint_mpc.StateLimits`), ``None`` if disabled.

    Example:
        >>> robot = hmpc_pin.load_robot("robots/planar3.urdf")
        >>> ctrl = hmpc_pin.HierarchicalMPC(robot)
        >>> ctrl.reset(q0, dq0)
        >>> tau = ctrl.step(t, q, dq, hmpc_pin.SineReference(robot.nq))
    """

    def __init__(self, robot: Robot, config: ControllerConfig | None = None):
        self.robot = robot
        self.config = config = config if config is not None else ControllerConfig()
        if config.kind not in HMPC_KINDS:
            raise ConfigError(
                "controller.kind",
                f"{config.kind!r} is not a hierarchical MPC (one of {HMPC_KINDS}); "
                "build it with hmpc_pin.make_controller",
            )
        n = robot.nq
        self.n = n
        v_min, v_max = config.bounds(n)
        self.mpc = CondensedMPC(config.Ts, config.N, config.Nc, config.Q, config.R, config.P)
        limits = config.constraints.limits(robot)
        self.limits = (
            None
            if limits is None
            else StateLimits(
                *limits,
                slack_weight=config.constraints.slack_weight,
                slack_linear_weight=config.constraints.slack_linear_weight,
            )
        )
        self.qps = JointQPs(
            self.mpc,
            v_min,
            v_max,
            robot.joint_names,
            eps_abs=config.eps_abs,
            max_iter=config.max_iter,
            limits=self.limits,
            layout=config.qp_layout,
        )
        obs = config.observer
        self.observer = self.ism = None
        if config.kind == "hmpc" and obs.enabled:
            self.observer = make_observer(robot, config.Ts, obs.kind, obs.gain, obs.discretization)
        elif config.kind == "hmpc-momentum":
            self.observer = make_observer(robot, config.Ts, "momentum", obs.gain)
        elif config.kind in ("hmpc-ism", "hmpc-ism-bl"):
            ism = config.ism
            width = ism.width(config.Ts) if config.kind == "hmpc-ism-bl" else None
            self.ism = IntegralSlidingMode(n, config.Ts, ism.gain, width)
        N = config.N
        self._offsets = config.Ts * np.arange(1, N + 1)
        self._offsets_rep = self._offsets.repeat(n)
        # The stack [q; q̇; r_1..r_N; ṙ_1..ṙ_N] (rows), each block contiguous, and the
        # gradient map with its rows in that order (CondensedMPC.F interleaves r_j, ṙ_j).
        self._stack = np.empty((2 * N + 2, n))
        self._stack_flat = self._stack.reshape(-1)
        self._stack_finite = np.empty(self._stack_flat.size, dtype=bool)
        self._stack_q_ref = self._stack[2 : N + 2]
        self._stack_dq_ref = self._stack[N + 2 :]
        self._stack_flat_q_ref = self._stack_flat[2 * n : (N + 2) * n]
        self._stack_flat_dq_ref = self._stack_flat[(N + 2) * n :]
        order = np.concatenate([[0, 1], np.arange(2, 2 * N + 2, 2), np.arange(3, 2 * N + 2, 2)])
        self._FT = np.ascontiguousarray(self.mpc.FT[order])
        self._model, self._data = robot.model, robot.data
        self._symmetrize = getattr(robot, "_symmetrize", True)
        self._ref_shape = (config.N, n)
        self.disturbance_estimate = np.zeros(n)
        self.v = np.zeros(n)
        self.tau = np.zeros(n)
        self._started = False

    def _raise_non_finite(self, t, q, dq, q_ref, dq_ref) -> None:
        """Name the first non-finite input (slow path); return if every input is finite."""
        self.robot.check_vector("q", q)
        self.robot.check_vector("dq", dq)
        bad_rows = np.flatnonzero(
            ~(np.isfinite(q_ref).all(axis=1) & np.isfinite(dq_ref).all(axis=1))
        )
        if bad_rows.size == 0:
            return
        bad = int(bad_rows[0])
        raise NonFiniteError(
            "reference", (q_ref[bad], dq_ref[bad]), f"at t={t + self._offsets[bad]:.6g}"
        )

    @property
    def Ts(self) -> float:
        """Control period [s]."""
        return self.config.Ts

    def reset(self, q0: np.ndarray, dq0: np.ndarray) -> None:
        """Start a new run from the state ``(q0, dq0)``; the estimate restarts at zero."""
        self.robot.check_vector("q0", q0)
        dq0 = self.robot.check_vector("dq0", dq0)
        if self.observer is not None:
            self.observer.reset(dq0, q0)
        if self.ism is not None:
            self.ism.reset(dq0, q0)
        self.disturbance_estimate = np.zeros(self.n)
        self.v = np.zeros(self.n)
        self.tau = np.zeros(self.n)
        self._started = False

    def step(self, t: float, q: np.ndarray, dq: np.ndarray, reference) -> np.ndarray:
        """Compute the torque for the measured state at time ``t``.

        Call once per control period :math:`T_s`, after :meth:`reset`. The
        observer assumes the torque returned by the previous call was held since.

        Args:
            t: Time [s].
            q: Measured joint positions [rad], shape (n,).
            dq: Measured joint velocities [rad/s], shape (n,).
            reference: Object with ``sample(t) -> (q_ref, dq_ref)``.

        Returns:
            Joint torques :math:`\\tau` [N·m], shape (n,), Eq (4).

        Raises:
            NonFiniteError: ``t``, ``q``, ``dq`` or the reference is not finite.
            DimensionError: ``q``, ``dq`` or the reference has the wrong shape.
            SolverError: A joint QP did not report solved.
        """
        if not math.isfinite(t):
            raise NonFiniteError("t", t)
        q = np.asarray(q, dtype=float)
        dq = np.asarray(dq, dtype=float)
        n = self.n
        if q.shape != (n,) or dq.shape != (n,):
            self.robot.check_vector("q", q)  # raises the precise error
            self.robot.check_vector("dq", dq)

        S = self._stack
        S[0] = q
        S[1] = dq
        if type(reference) is SineReference and reference.n == n:
            # Sampled straight into the stack (the values of sample_many(t + offsets)).
            reference._sample_into(
                t, self._offsets_rep, self._stack_flat_q_ref, self._stack_flat_dq_ref
            )
            q_ref, dq_ref = self._stack_q_ref, self._stack_dq_ref
        else:
            q_ref, dq_ref = sample_horizon(reference, t + self._offsets)
            if q_ref.shape != self._ref_shape or dq_ref.shape != self._ref_shape:
                raise DimensionError(
                    f"reference.sample returned q_ref of shape {q_ref.shape[1:]} and dq_ref "
                    f"of shape {dq_ref.shape[1:]} but the robot has {n} joints; return two "
                    f"arrays of shape ({n},)"
                )
            self._stack_q_ref[:] = q_ref
            self._stack_dq_ref[:] = dq_ref
        # One finiteness test covers q, q̇ and the whole reference horizon, before
        # anything is updated: a bad input changes no state.
        finite = np.isfinite(self._stack_flat, out=self._stack_finite)
        if np.count_nonzero(finite) != finite.size:
            self._raise_non_finite(t, q, dq, q_ref, dq_ref)
        G = S.T.dot(self._FT)  # (n, Nc), one row per joint

        # pin.crba and pin.nonLinearEffects return new arrays (no copy needed)
        M = self.robot.mass_matrix(q) if self._symmetrize else pin.crba(self._model, self._data, q)
        nle = pin.nonLinearEffects(self._model, self._data, q, dq)
        if self.observer is not None:
            if self._started:
                self.disturbance_estimate = self.observer.update(M, nle, dq, self.tau, q)
            else:
                self.disturbance_estimate = self.observer.estimate.copy()
        elif self.ism is not None and self._started:
            self.disturbance_estimate = self.ism.update(M, dq, self.v)

        self.v = v = self.qps.solve(G, S[:2])
        tau = M.dot(v)
        tau += nle
        tau -= self.disturbance_estimate
        self.tau = tau
        self._started = True
        return tau.copy()
