"""Centralized linear MPC over the full 2n-state coupled model, for comparison (issue 6).

"Traditional" MPC, the baseline the paper's hierarchical scheme is meant to beat on
online cost: one QP over all joints at once, on the arm's dynamics linearised at the
current state, instead of inverse dynamics + n decoupled double-integrator QPs.

At every control instant :math:`t_k`, with :math:`x = [q; \\dot q]` (2n) and the
torque :math:`\\tau` (n) as input:

1. **Linearisation.** Pinocchio's ``computeABADerivatives`` at the measured state and
   the previous torque :math:`\\tau_{k-1}` (gravity+Coriolis :math:`C\\dot q + G` at the
   first step) gives :math:`\\ddot q_0`, :math:`\\partial\\ddot q/\\partial q`,
   :math:`\\partial\\ddot q/\\partial\\dot q` and :math:`M^{-1}`:

   .. math::

       \\dot x \\approx A_c x + B_c \\tau + c_c, \\quad
       A_c = \\begin{bmatrix}0 & I\\\\ \\partial_q\\ddot q & \\partial_{\\dot q}\\ddot q
       \\end{bmatrix},\\;
       B_c = \\begin{bmatrix}0\\\\ M^{-1}\\end{bmatrix},\\;
       c_c = \\begin{bmatrix}\\dot q_0\\\\ \\ddot q_0\\end{bmatrix} - A_c x_0 - B_c\\tau_{k-1}.

2. **Discretisation: exact zero-order hold** at :math:`T_s` (the same hold as the
   plant's and as the hierarchical MPC's double integrators), from the matrix
   exponential of the augmented matrix :math:`[[A_c, B_c, c_c], [0, 0, 0]]\\,T_s`.
   The model is frozen over the horizon (linear time-invariant prediction).
3. **Condensing** over :math:`N` steps with :math:`N_c` free inputs (the last one held
   to the end of the horizon, as in :mod:`hmpc_pin.mpc.condensed`):
   :math:`X = \\Phi x_0 + \\Gamma U + c`.
4. **Cost**: the hierarchical MPC's weights stacked over the joints: :math:`Q`, :math:`P`
   (2×2 per joint on :math:`[q_i - r_i, \\dot q_i - \\dot r_i]`) over
   :math:`x_1 \\dots x_{N-1}` and :math:`x_N`, and :math:`R` on the commanded
   acceleration :math:`v = M^{-1}(\\tau - C\\dot q - G)` of every input (the last free
   one counted :math:`N - N_c + 1` times), so that R means what it means there.
5. **Constraints** (the choice documented here): the hierarchical MPC's acceleration
   bounds, translated exactly through :math:`\\tau = M v + C\\dot q + G` at the current
   state, :math:`v_{\\min} \\le M^{-1}(\\tau_j - C\\dot q - G) \\le v_{\\max}` for every free
   input (n·Nc general rows, normalised), plus the URDF effort limits as a box on
   :math:`\\tau` (none where the URDF gives none). The joint-limit state constraints of
   the hierarchical MPC are not imposed here.
6. **Solve**: one ProxSuite dense QP, created once (settings before ``init``, one solve
   right after ``init``: ProxSuite 0.8.0 segfaults otherwise) and, every step,
   ``update``-d (H, g, C, l, u all change) and solved warm-started from the previous
   solution. The cost is scaled by :math:`1/\\overline{\\mathrm{diag}(H)}`.

There is no disturbance observer: :attr:`CentralizedMPC.disturbance_estimate` stays zero.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from proxsuite import proxqp

from hmpc_pin import ControllerConfig, HmpcError, Robot
from hmpc_pin.tasks import sample_horizon

__all__ = ["CentralizedMPC", "CentralizedSolverError", "expm", "zoh"]

#: Finite stand-in for an absent bound (ProxSuite's residuals must stay finite).
BIG = 1e10


class CentralizedSolverError(HmpcError, RuntimeError):
    """The centralized QP did not report solved (an :class:`hmpc_pin.HmpcError`, so that
    :func:`hmpc_pin.sim.simulate` stops the run and keeps what was computed)."""


def expm(A: np.ndarray) -> np.ndarray:
    """Matrix exponential by scaling and squaring with a degree-12 Taylor polynomial.

    The matrix is scaled by :math:`2^{-s}` until its 1-norm is at most 1/4, which bounds
    the truncation error of the series by :math:`4^{-13}/13! < 10^{-17}` relative.

    Args:
        A: Square matrix.

    Returns:
        :math:`e^A`, same shape.
    """
    norm = float(np.abs(A).sum(axis=0).max())
    s = max(0, int(np.ceil(np.log2(norm / 0.25)))) if norm > 0.25 else 0
    X = A / (2.0**s)
    n = A.shape[0]
    E = np.eye(n)
    term = np.eye(n)
    for k in range(1, 13):
        term = term @ X / k
        E = E + term
    for _ in range(s):
        E = E @ E
    return E


def zoh(
    Ac: np.ndarray, Bc: np.ndarray, cc: np.ndarray, Ts: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact zero-order-hold discretisation of :math:`\\dot x = A_c x + B_c u + c_c`.

    Args:
        Ac: State matrix (nx×nx) [1/s]. Bc: Input matrix (nx×nu). cc: Affine term (nx,).
        Ts: Sampling period [s].

    Returns:
        ``(Ad, Bd, cd)`` with :math:`x_{k+1} = A_d x_k + B_d u_k + c_d`.
    """
    nx, nu = Bc.shape
    aug = np.zeros((nx + nu + 1, nx + nu + 1))
    aug[:nx, :nx] = Ac
    aug[:nx, nx : nx + nu] = Bc
    aug[:nx, -1] = cc
    E = expm(aug * Ts)
    return E[:nx, :nx], E[:nx, nx : nx + nu], E[:nx, -1]


class CentralizedMPC:
    """Linear MPC over the coupled 2n-state model, one ProxSuite QP per step (module doc).

    Same interface as :class:`hmpc_pin.HierarchicalMPC` (``Ts``, ``reset``, ``step``,
    ``disturbance_estimate``), so it runs through :func:`hmpc_pin.sim.simulate`.

    Args:
        robot: The controller's (nominal) model; this object keeps its own ``pin.Data``.
        config: Ts, N, Nc, Q, R, P, v_min, v_max, eps_abs, max_iter are used; the
            observer and the state constraints are not.

    Attributes:
        disturbance_estimate: Always zeros [N·m], shape (n,) (no observer).
        tau: The last torque [N·m], shape (n,).
        iterations: ProxSuite iterations of the last solve.
    """

    def __init__(self, robot: Robot, config: ControllerConfig | None = None):
        self.robot = robot
        self.config = config = config if config is not None else ControllerConfig()
        self.model = robot.model
        self.data = robot.model.createData()
        self.n = n = robot.nq
        N, Nc = config.N, config.Nc
        self.N, self.Nc = N, Nc
        self.v_min, self.v_max = config.bounds(n)
        eff = np.asarray(robot.effort_limit, dtype=float)
        self.effort = np.where((eff > 0) & np.isfinite(eff), np.minimum(eff, BIG), BIG)

        eye = np.eye(n)
        Qx, Px = np.kron(config.Q, eye), np.kron(config.P, eye)  # on x = [q; q̇]
        self.Qbar = np.zeros((2 * n * N, 2 * n * N))
        for j in range(N):
            sl = slice(2 * n * j, 2 * n * (j + 1))
            self.Qbar[sl, sl] = Px if j == N - 1 else Qx
        counts = np.ones(Nc)
        counts[-1] = N - Nc + 1
        self.counts = counts
        self._offsets = config.Ts * np.arange(1, N + 1)
        self._zero_n = np.zeros((n, n))

        nv = n * Nc
        qp = proxqp.dense.QP(nv, 0, nv, True)
        # Every setting before init(): changing initial_guess after init() segfaults
        # ProxSuite 0.8.0 (see hmpc_pin.mpc.condensed).
        qp.settings.initial_guess = proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
        qp.settings.eps_abs = config.eps_abs
        qp.settings.eps_rel = 0.0
        qp.settings.max_iter = config.max_iter
        qp.settings.verbose = False
        qp.settings.check_duality_gap = True  # as the joint QPs (stale multipliers otherwise)
        qp.settings.eps_duality_gap_abs = config.eps_abs
        qp.settings.eps_duality_gap_rel = 0.0
        qp.settings.eps_primal_inf = 1e-12
        qp.settings.eps_dual_inf = 1e-12
        box = np.tile(self.effort, Nc)
        qp.init(
            np.eye(nv),
            np.zeros(nv),
            None,
            None,
            np.eye(nv),
            -np.full(nv, BIG),
            np.full(nv, BIG),
            -box,
            box,
        )
        # Solve once right after init(): update() before any solve() segfaults with warm start.
        qp.solve()
        self.qp = qp
        self._solved = proxqp.QPSolverOutput.PROXQP_SOLVED
        self.disturbance_estimate = np.zeros(n)
        self.tau = np.zeros(n)
        self.iterations = 0
        self._started = False

    @property
    def Ts(self) -> float:
        """Control period [s]."""
        return self.config.Ts

    def reset(self, q0: np.ndarray, dq0: np.ndarray) -> None:
        """Start a new run from ``(q0, dq0)`` [rad, rad/s]; the first linearisation uses
        the torque :math:`C\\dot q_0 + G(q_0)` [N·m]."""
        q0 = self.robot.check_vector("q0", q0)
        dq0 = self.robot.check_vector("dq0", dq0)
        self.tau = pin.nonLinearEffects(self.model, self.data, q0, dq0).copy()
        self.disturbance_estimate = np.zeros(self.n)
        self._started = False

    def prediction(
        self, q: np.ndarray, dq: np.ndarray, tau_lin: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Linearise at ``(q, dq, tau_lin)`` and condense the prediction over the horizon.

        Args:
            q: Joint positions [rad], shape (n,). dq: Velocities [rad/s], shape (n,).
            tau_lin: Torque the dynamics are linearised at [N·m], shape (n,).

        Returns:
            ``(Phi, Gamma, c, Minv, nle)``: :math:`X = \\Phi x_0 + \\Gamma U + c` with X the
            stacked states :math:`x_1 \\dots x_N` (2nN) and U the free torques (n·Nc);
            :math:`M^{-1}` (n×n) and :math:`C\\dot q + G` [N·m] at the state.
        """
        n, N, Nc = self.n, self.N, self.Nc
        model, data = self.model, self.data
        ddq_dq, ddq_dv, Minv = pin.computeABADerivatives(model, data, q, dq, tau_lin)
        ddq0 = data.ddq.copy()
        nle = pin.nonLinearEffects(model, data, q, dq).copy()
        Ac = np.block([[self._zero_n, np.eye(n)], [ddq_dq, ddq_dv]])
        Bc = np.vstack([self._zero_n, Minv])
        x0 = np.concatenate([q, dq])
        cc = np.concatenate([dq, ddq0]) - Ac @ x0 - Bc @ tau_lin
        Ad, Bd, cd = zoh(Ac, Bc, cc, self.config.Ts)

        powers = np.empty((N + 1, 2 * n, 2 * n))
        powers[0] = np.eye(2 * n)
        for j in range(1, N + 1):
            powers[j] = Ad @ powers[j - 1]
        AB = powers[:N] @ Bd  # AB[k] = Ad^k Bd, (N, 2n, n)
        Gamma = np.zeros((N, 2 * n, Nc, n))
        for col in range(Nc - 1):  # x_j gets Ad^(j-1-col) Bd u_col
            Gamma[col:, :, col, :] = AB[: N - col]
        # The last free input is held from step Nc-1 to N-1: x_j gets sum_{k<=j-Nc} Ad^k Bd.
        Gamma[Nc - 1 :, :, Nc - 1, :] = np.cumsum(AB, axis=0)[: N - Nc + 1]
        c = np.cumsum(powers[:N] @ cd, axis=0)  # sum_{i<j} Ad^i cd, (N, 2n)
        Phi = powers[1:].reshape(2 * n * N, 2 * n)
        return Phi, Gamma.reshape(2 * n * N, n * Nc), c.reshape(-1), Minv, nle

    def step(self, t: float, q: np.ndarray, dq: np.ndarray, reference) -> np.ndarray:
        """Torque [N·m], shape (n,), for the measured state at time ``t`` [s].

        Args:
            t: Time [s]. q: Joint positions [rad]. dq: Joint velocities [rad/s].
            reference: Object with ``sample(t) -> (q_ref, dq_ref)``.

        Raises:
            CentralizedSolverError: The QP did not report solved.
        """
        n, Nc, cfg = self.n, self.Nc, self.config
        q = np.asarray(q, dtype=float)
        dq = np.asarray(dq, dtype=float)
        Phi, Gamma, c, Minv, nle = self.prediction(q, dq, self.tau)
        q_ref, dq_ref = sample_horizon(reference, t + self._offsets)
        X_ref = np.hstack([q_ref, dq_ref]).reshape(-1)  # x_j = [r_j; ṙ_j], j = 1..N
        free = Phi @ np.concatenate([q, dq]) + c - X_ref
        GQ = Gamma.T @ self.Qbar
        Rv = cfg.R * (Minv.T @ Minv)  # R on v = M^-1 (tau - nle)
        H = 2.0 * (GQ @ Gamma + np.kron(np.diag(self.counts), Rv))
        g = 2.0 * (GQ @ free - np.kron(self.counts, Rv @ nle))
        scale = 1.0 / float(np.mean(np.diag(H)))
        H = scale * 0.5 * (H + H.T)
        g = scale * g
        rs = 1.0 / np.linalg.norm(Minv, axis=1)
        Cj = Minv * rs[:, None]
        base = Minv @ nle
        lo = np.tile((self.v_min + base) * rs, Nc)
        up = np.tile((self.v_max + base) * rs, Nc)
        C = np.kron(np.eye(Nc), Cj)
        self.qp.update(H=H, g=g, C=C, l=lo, u=up)
        self.qp.solve()
        res = self.qp.results
        self.iterations = res.info.iter
        if res.info.status != self._solved:
            raise CentralizedSolverError(
                f"centralized MPC QP not solved at t={t:.6g}: {res.info.status} "
                f"after {res.info.iter} iterations"
            )
        self.tau = res.x[:n].copy()
        self._started = True
        return self.tau.copy()
