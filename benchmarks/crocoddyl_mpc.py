"""Nonlinear MPC with Crocoddyl (Box-)FDDP on the nominal model, for comparison (issue 6).

The optimal-control problem at every control instant :math:`t_k`, over the horizon
:math:`N` with nodes :math:`T_s` apart, on the full nonlinear rigid-body dynamics
(``DifferentialActionModelFreeFwdDynamics``, Pinocchio ABA, the controller's model, no
disturbance model):

.. math::

    \\min_{\\tau_0..\\tau_{N-1}} \\sum_{j=0}^{N-1} \\big(e_j^T Q e_j
        + R_\\tau \\|\\tau_j - G(q_j)\\|^2\\big) + e_N^T P e_N,
    \\qquad e_j = [q_j - r(t_k + jT_s);\\ \\dot q_j - \\dot r(t_k + jT_s)],

with the hierarchical MPC's per-joint :math:`Q`, :math:`P` (their diagonals: Crocoddyl's
weighted-quadratic activation is diagonal; the paper's weights are diagonal) and
:math:`R_\\tau` = the config's R as a small control regularisation towards gravity
compensation along the reference, :math:`r_j = r(t_k + jT_s)` [1/(N·m)²]
(``ResidualModelControl`` with its reference set every step; Crocoddyl 3.2.1's
``ResidualModelControlGrav`` raises ``MemoryError`` on construction with Pinocchio 4.1 from
PyPI). The :math:`e_0` term is constant, as in :mod:`hmpc_pin.mpc.condensed`.

- Integration: Crocoddyl's ``IntegratedActionModelEuler`` at :math:`T_s` (semi-implicit
  Euler, :math:`\\dot q^+ = \\dot q + T_s\\ddot q,\\ q^+ = q + T_s\\dot q^+`). Running costs
  are weighted so that the sum equals the one above (Crocoddyl multiplies running costs
  by :math:`T_s` and halves weighted squares).
- Torque limits: the URDF effort limits as control bounds, handled by ``SolverBoxFDDP``
  (``SolverFDDP`` ignores them; then :class:`CrocoddylMPC` clips).
- Warm start: the previous solution shifted by one node (last node repeated), its first
  state replaced by the measured one; at the first step, the measured state everywhere
  and quasi-static torques.
- Fixed iteration budget: at most ``iterations`` (Box-)FDDP iterations per step; the
  first input of the (possibly unconverged) solution is applied. Solver thresholds are
  Crocoddyl's defaults.
- One thread (``ShootingProblem.nthreads = 1``), like the other controllers.

There is no disturbance observer: :attr:`CrocoddylMPC.disturbance_estimate` stays zero.
Crocoddyl is an optional dependency (the extra ``bench``: ``pip install -e ".[bench]"``);
:data:`AVAILABLE` says whether it could be imported.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from hmpc_pin import ControllerConfig, Robot
from hmpc_pin.tasks import sample_horizon

try:
    import crocoddyl
except ImportError:  # optional dependency: the benchmark is skipped with a message
    crocoddyl = None

__all__ = ["AVAILABLE", "CrocoddylMPC", "crocoddyl_version"]

#: Whether ``crocoddyl`` is importable.
AVAILABLE = crocoddyl is not None


def crocoddyl_version() -> str | None:
    """Crocoddyl's version string, or ``None`` when it is not installed."""
    return None if crocoddyl is None else str(crocoddyl.__version__)


class CrocoddylMPC:
    """Receding-horizon (Box-)FDDP controller (module docstring).

    Same interface as :class:`hmpc_pin.HierarchicalMPC` (``Ts``, ``reset``, ``step``,
    ``disturbance_estimate``), so it runs through :func:`hmpc_pin.sim.simulate`.

    Args:
        robot: The controller's (nominal) model; Crocoddyl gets a copy of its ``pin.Model``.
        config: Ts, N, Q, P and R are used.
        iterations: Iteration budget per step (>= 1).
        box: Use ``SolverBoxFDDP`` with the URDF effort limits (if the URDF has any);
            ``False`` uses ``SolverFDDP`` and clips the torque to the limits.

    Attributes:
        disturbance_estimate: Always zeros [N·m], shape (n,) (no observer).
        tau: The last torque [N·m], shape (n,).
        iterations_used: Iterations of the last solve.

    Raises:
        ImportError: Crocoddyl is not installed.
    """

    def __init__(
        self,
        robot: Robot,
        config: ControllerConfig | None = None,
        iterations: int = 3,
        box: bool = True,
    ):
        if crocoddyl is None:
            raise ImportError(
                'crocoddyl is not installed; it is in the extra "bench": pip install -e ".[bench]"'
            )
        if iterations < 1:
            raise ValueError(f"iterations={iterations}; expected >= 1")
        self.robot = robot
        self.config = config = config if config is not None else ControllerConfig()
        self.n = n = robot.nq
        self.N = N = config.N
        self.budget = int(iterations)
        Ts = config.Ts
        eff = np.asarray(robot.effort_limit, dtype=float)
        limited = (eff > 0) & np.isfinite(eff)
        self.effort = np.where(limited, eff, np.inf)
        self.box = bool(box and limited.any())

        self.model = robot.model.copy()
        self.data = self.model.createData()  # for G(r_j), the control regularisation's target
        state = crocoddyl.StateMultibody(self.model)
        actuation = crocoddyl.ActuationModelFull(state)
        nu = actuation.nu
        qd, pd = np.diag(config.Q), np.diag(config.P)
        # Crocoddyl: running cost = Ts * 1/2 * r^T W r, terminal = 1/2 r^T W r.
        w_run = np.concatenate([np.full(n, qd[0]), np.full(n, qd[1])]) * 2.0 / Ts
        w_term = np.concatenate([np.full(n, pd[0]), np.full(n, pd[1])]) * 2.0
        w_u = np.full(nu, 2.0 * config.R / Ts)
        self._state_residuals = []
        self._control_residuals = []
        running = []
        for _ in range(N):
            costs = crocoddyl.CostModelSum(state, nu)
            xres = crocoddyl.ResidualModelState(state, np.zeros(state.nx), nu)
            ures = crocoddyl.ResidualModelControl(state, np.zeros(nu))
            costs.addCost(
                "state",
                crocoddyl.CostModelResidual(
                    state, crocoddyl.ActivationModelWeightedQuad(w_run), xres
                ),
                1.0,
            )
            costs.addCost(
                "control",
                crocoddyl.CostModelResidual(
                    state, crocoddyl.ActivationModelWeightedQuad(w_u), ures
                ),
                1.0,
            )
            dam = crocoddyl.DifferentialActionModelFreeFwdDynamics(state, actuation, costs)
            iam = crocoddyl.IntegratedActionModelEuler(dam, Ts)
            if self.box:
                big = 1e10
                iam.u_lb = np.where(limited, -eff, -big)
                iam.u_ub = np.where(limited, eff, big)
            running.append(iam)
            self._state_residuals.append(xres)
            self._control_residuals.append(ures)
        costs = crocoddyl.CostModelSum(state, nu)
        xres = crocoddyl.ResidualModelState(state, np.zeros(state.nx), nu)
        costs.addCost(
            "state",
            crocoddyl.CostModelResidual(state, crocoddyl.ActivationModelWeightedQuad(w_term), xres),
            1.0,
        )
        self._state_residuals.append(xres)
        terminal = crocoddyl.IntegratedActionModelEuler(
            crocoddyl.DifferentialActionModelFreeFwdDynamics(state, actuation, costs), 0.0
        )
        self.problem = crocoddyl.ShootingProblem(np.zeros(state.nx), running, terminal)
        # One thread, like the other controllers. Crocoddyl's default (OpenMP over the
        # nodes, 2 threads here) stalled steps for 40-60 ms whenever the other core was busy.
        self.problem.nthreads = 1
        self.solver = (crocoddyl.SolverBoxFDDP if self.box else crocoddyl.SolverFDDP)(self.problem)
        self._offsets = Ts * np.arange(0, N + 1)
        self.disturbance_estimate = np.zeros(n)
        self.tau = np.zeros(n)
        self.iterations_used = 0
        self._xs: list[np.ndarray] | None = None
        self._us: list[np.ndarray] | None = None

    @property
    def Ts(self) -> float:
        """Control period [s]."""
        return self.config.Ts

    def reset(self, q0: np.ndarray, dq0: np.ndarray) -> None:
        """Start a new run from ``(q0, dq0)`` [rad, rad/s]: forget the warm start."""
        self.robot.check_vector("q0", q0)
        self.robot.check_vector("dq0", dq0)
        self._xs = self._us = None
        self.disturbance_estimate = np.zeros(self.n)
        self.tau = np.zeros(self.n)

    def step(self, t: float, q: np.ndarray, dq: np.ndarray, reference) -> np.ndarray:
        """Torque [N·m], shape (n,), for the measured state at time ``t`` [s].

        Args:
            t: Time [s]. q: Joint positions [rad]. dq: Joint velocities [rad/s].
            reference: Object with ``sample(t) -> (q_ref, dq_ref)``.
        """
        x = np.concatenate([np.asarray(q, dtype=float), np.asarray(dq, dtype=float)])
        q_ref, dq_ref = sample_horizon(reference, t + self._offsets)
        x_ref = np.hstack([q_ref, dq_ref])
        for res, xr in zip(self._state_residuals, x_ref, strict=True):
            res.reference = xr
        model, data = self.model, self.data
        for res, qr in zip(self._control_residuals, q_ref[: self.N], strict=True):
            res.reference = pin.computeGeneralizedGravity(model, data, qr)
        self.problem.x0 = x
        if self._xs is None:
            xs = [x] * (self.N + 1)
            us = self.problem.quasiStatic(xs[:-1])
        else:
            xs = [x, *self._xs[2:], self._xs[-1]]
            us = [*self._us[1:], self._us[-1]]
        self.solver.solve(xs, us, self.budget, False)
        self.iterations_used = self.solver.iter
        self._xs = list(self.solver.xs)
        self._us = list(self.solver.us)
        tau = np.array(self._us[0], dtype=float)
        if not self.box:
            tau = np.clip(tau, -self.effort, self.effort)
        self.tau = tau
        return tau.copy()
