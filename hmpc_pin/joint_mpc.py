"""Per-joint MPC, Eq (20)–(26): a condensed box-constrained QP solved by ProxSuite.

After inverse dynamics (Eq 4) every joint is a double integrator (Eq 20–21) with
state :math:`x_i = [q_i, \\dot q_i]^T` and input :math:`v_i` (the commanded
acceleration). Its exact zero-order-hold discretisation at period :math:`T_s` is
(Eq 24)

.. math::

    x(k+1) = A_d x(k) + B_d v(k), \\quad
    A_d = \\begin{bmatrix}1 & T_s\\\\ 0 & 1\\end{bmatrix}, \\quad
    B_d = \\begin{bmatrix}T_s^2/2\\\\ T_s\\end{bmatrix}.

Over a prediction horizon :math:`N` with a control horizon :math:`N_c \\le N`
(inputs :math:`v_0 \\dots v_{N_c-1}` are free, the last one is held until the end
of the horizon), the cost of Eq (25)

.. math::

    J = \\sum_{j=0}^{N-1} e_j^T Q e_j + v_j^T R v_j + e_N^T P e_N, \\qquad
    e_j = x_j - [r_j, \\dot r_j]^T

is condensed into :math:`J(U) = \\tfrac12 U^T H U + g^T U + \\text{const}` with
:math:`X = \\Phi x_0 + \\Gamma U`:

.. math::

    H = 2(\\Gamma^T \\bar Q \\Gamma + \\bar R), \\qquad
    g = 2\\Gamma^T \\bar Q (\\Phi x_0 - \\bar r),

and minimised subject to :math:`v_{\\min} \\le U \\le v_{\\max}` (Eq 26). :math:`H`
depends only on the settings, so each joint's QP is built once; per step only
:math:`g` changes. The gradients of all joints come from one matrix product.
Only the first input :math:`v_0` is applied (receding horizon).

The QP is scaled by :math:`1/\\overline{\\mathrm{diag}(H)}` before it reaches the
solver (the paper's weights give :math:`H \\sim 10^{-3}`); the minimiser is unchanged.
"""

from __future__ import annotations

import numpy as np
from proxsuite import proxqp

from .exceptions import SolverError

__all__ = ["CondensedMPC", "JointQPs"]


class CondensedMPC:
    """The condensed QP data of one joint's MPC (identical for every joint).

    Args:
        Ts: Sampling period [s].
        N: Prediction horizon (steps), ``N >= 1``.
        Nc: Control horizon (free inputs), ``1 <= Nc <= N``.
        Q: State weight (2×2, PSD) on :math:`[q - r, \\dot q - \\dot r]`.
        R: Input weight (> 0) on :math:`v` [1/(rad/s²)²].
        P: Terminal weight (2×2, PSD).

    Attributes:
        H: Scaled Hessian (Nc×Nc).
        F: Scaled gradient map (Nc × (2 + 2N)): ``g = F @ [x0; r_1; ṙ_1; ...; r_N; ṙ_N]``.
        Phi: Free response (2N×2); ``Gamma``: forced response (2N×Nc).
        scale: The factor applied to the cost.
    """

    def __init__(self, Ts: float, N: int, Nc: int, Q: np.ndarray, R: float, P: np.ndarray):
        self.Ts, self.N, self.Nc = float(Ts), int(N), int(Nc)
        A = np.array([[1.0, Ts], [0.0, 1.0]])
        B = np.array([Ts * Ts / 2.0, Ts])
        powers = [np.eye(2)]
        for _ in range(N):
            powers.append(A @ powers[-1])
        Phi = np.vstack(powers[1:])  # rows of x_1 .. x_N
        Gamma = np.zeros((2 * N, Nc))
        for j in range(1, N + 1):  # x_j = A^j x0 + sum_{i<j} A^{j-1-i} B v_i
            for i in range(j):
                Gamma[2 * (j - 1) : 2 * j, min(i, Nc - 1)] += powers[j - 1 - i] @ B
        Qbar = np.zeros((2 * N, 2 * N))
        for j in range(N - 1):
            Qbar[2 * j : 2 * j + 2, 2 * j : 2 * j + 2] = Q
        Qbar[2 * N - 2 :, 2 * N - 2 :] = P
        counts = np.ones(Nc)
        counts[-1] = N - Nc + 1  # the last free input is applied N - Nc + 1 times
        Rbar = float(R) * np.diag(counts)
        H = 2.0 * (Gamma.T @ Qbar @ Gamma + Rbar)
        H = 0.5 * (H + H.T)
        self.scale = 1.0 / float(np.mean(np.diag(H)))
        self.Phi, self.Gamma, self.Qbar, self.Rbar = Phi, Gamma, Qbar, Rbar
        self.H = H * self.scale
        GQ = 2.0 * self.scale * Gamma.T @ Qbar
        self.F = np.hstack([GQ @ Phi, -GQ])
        self.FT = np.ascontiguousarray(self.F.T)

    def gradient(self, x0: np.ndarray, ref: np.ndarray) -> np.ndarray:
        """Scaled gradients of all joints.

        Args:
            x0: Current states, shape (2, n): rows q and q̇.
            ref: References, shape (2N, n): rows r_1, ṙ_1, ..., r_N, ṙ_N.

        Returns:
            Gradients, shape (n, Nc), C-contiguous, row i for joint i.
        """
        return np.vstack([x0, ref]).T @ self.FT

    def cost(self, U: np.ndarray, x0: np.ndarray, ref: np.ndarray) -> float:
        """Cost of Eq (25) for one joint without its constant first term :math:`e_0^TQe_0`.

        Args:
            U: Free inputs (Nc,) [rad/s²].
            x0: State (2,).
            ref: Reference (2N,): r_1, ṙ_1, ..., r_N, ṙ_N.
        """
        E = self.Phi @ x0 + self.Gamma @ U - ref
        return float(E @ self.Qbar @ E + U @ self.Rbar @ U)


class JointQPs:
    """One ProxSuite dense box-constrained QP per joint, built once and warm-started.

    Args:
        mpc: The condensed QP data shared by all joints.
        v_min, v_max: Bounds on each joint's commanded acceleration [rad/s²], shape (n,).
        joint_names: For error messages.
        eps_abs: ProxSuite absolute tolerance.
        max_iter: ProxSuite iteration cap (the solver never runs unbounded).
    """

    def __init__(
        self,
        mpc: CondensedMPC,
        v_min: np.ndarray,
        v_max: np.ndarray,
        joint_names: tuple[str, ...],
        eps_abs: float = 1e-9,
        max_iter: int = 1000,
    ):
        self.mpc = mpc
        self.joint_names = joint_names
        self.n = len(joint_names)
        Nc = mpc.Nc
        self.qps = []
        for i in range(self.n):
            qp = proxqp.dense.QP(Nc, 0, 0, True)
            # Settings must be set before init(): changing initial_guess after
            # init() crashes proxsuite 0.8.0 (segfault, measured here).
            qp.settings.initial_guess = proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
            qp.settings.eps_abs = eps_abs
            qp.settings.eps_rel = 0.0
            qp.settings.max_iter = max_iter
            qp.settings.verbose = False
            # Without the duality-gap test a warm-started solve can stop after 1-3
            # iterations, reporting SOLVED at a feasible point that keeps a stale bound
            # multiplier (measured here: v off by up to 1e-3 for Nc = 1, 1e-2 for Nc = 3).
            qp.settings.check_duality_gap = True
            qp.settings.eps_duality_gap_abs = eps_abs
            qp.settings.eps_duality_gap_rel = 0.0
            qp.init(
                mpc.H,
                np.zeros(Nc),
                None,
                None,
                None,
                None,
                None,
                np.full(Nc, v_min[i]),
                np.full(Nc, v_max[i]),
            )
            # One solve right after init(): update() before any solve() crashes
            # proxsuite 0.8.0 with warm start (segfault, measured here).
            qp.solve()
            self.qps.append(qp)
        self._solved = proxqp.QPSolverOutput.PROXQP_SOLVED
        self.solution = np.zeros((Nc, self.n))

    def solve(self, G: np.ndarray) -> np.ndarray:
        """Solve every joint's QP for the gradients ``G`` (n×Nc); return the first inputs (n,).
        Each row ``G[i]`` is passed to ProxSuite as is (C-contiguous, no copy).

        The full optimal input sequences are kept in :attr:`solution` (Nc×n).

        Raises:
            SolverError: A QP did not report ``PROXQP_SOLVED`` (names joint and status).
        """
        sol = self.solution
        for i, qp in enumerate(self.qps):
            qp.update(g=G[i])
            qp.solve()
            res = qp.results
            if res.info.status != self._solved:
                raise SolverError(i, self.joint_names[i], str(res.info.status), res.info.iter)
            sol[:, i] = res.x
        return sol[0].copy()
