"""Oracle of the per-joint MPC's QPs, Eq (25)–(26) (compiled: ``cpp/src/joint_qps.cpp``).

Each joint's condensed QP :math:`\\min_U \\tfrac12 U^T H U + g_i^T U` s.t.
:math:`v_{\\min,i} \\le U \\le v_{\\max,i}` (Eq 26), and with soft state limits the QP with
one slack :math:`s \\ge 0` (``hmpc_pin.mpc.condensed``, module docstring), solved here with
ProxSuite's *Python* API and numpy, written as plainly as possible: every joint's box QP
solved by its own ProxSuite QP from scratch (no warm start, no shortcut, no block layout, no
cold retry), and the soft QP solved for a joint whose box-only prediction
:math:`X = \\Phi x_0 + \\Gamma U` leaves the limits, detected with numpy on the whole
prediction. The compiled component must give the same solution to the solver's tolerance.
"""

from __future__ import annotations

import numpy as np
from proxsuite import proxqp

BIG = 1e10


def _qp(nvar: int, n_in: int, eps_abs: float):
    qp = proxqp.dense.QP(nvar, 0, n_in, True)
    qp.settings.initial_guess = proxqp.InitialGuess.NO_INITIAL_GUESS
    qp.settings.eps_abs = eps_abs
    qp.settings.eps_rel = 0.0
    qp.settings.verbose = False
    qp.settings.eps_primal_inf = 1e-12
    qp.settings.eps_dual_inf = 1e-12
    qp.settings.max_iter = 10000
    return qp


class NumpyJointQPs:
    """The joint QPs, literally (module docstring).

    Args:
        mpc: ``hmpc_pin.mpc.condensed.CondensedMPC`` (H, Φ, Γ, scale).
        v_min, v_max: Input bounds [rad/s²], (n,).
        limits: ``StateLimits`` or ``None``.
        eps_abs: ProxSuite's absolute tolerance.
    """

    def __init__(self, mpc, v_min, v_max, limits=None, eps_abs: float = 1e-9):
        self.mpc, self.limits, self.eps_abs = mpc, limits, eps_abs
        self.v_min = np.asarray(v_min, dtype=float)
        self.v_max = np.asarray(v_max, dtype=float)
        self.n = self.v_min.size

    def box(self, i: int, g: np.ndarray) -> np.ndarray:
        """Joint ``i``'s box QP (Eq 26) for the gradient ``g`` (Nc,)."""
        Nc = self.mpc.Nc
        qp = _qp(Nc, 0, self.eps_abs)
        qp.init(self.mpc.H, g, None, None, None, None, None,
                np.full(Nc, self.v_min[i]), np.full(Nc, self.v_max[i]))  # fmt: skip
        qp.solve()
        assert qp.results.info.status == proxqp.QPSolverOutput.PROXQP_SOLVED
        return qp.results.x.copy()

    def soft(self, i: int, g: np.ndarray, x0: np.ndarray) -> tuple[np.ndarray, float]:
        """Joint ``i``'s soft-constrained QP at the state ``x0`` (2,); returns (U, s)."""
        mpc, lim = self.mpc, self.limits
        N, Nc = mpc.N, mpc.Nc
        lo = float(np.clip(lim.lower[i], -BIG, BIG))
        hi = float(np.clip(lim.upper[i], -BIG, BIG))
        vel = float(np.clip(lim.velocity[i], -BIG, BIG))
        # s = k·ŝ: the slack's Hessian entry 1 (the compiled QP's scaling, same minimiser)
        k = 1.0 / np.sqrt(2.0 * lim.slack_weight * mpc.scale)
        free = mpc.Phi @ x0
        Gq, Gv = mpc.Gamma[0::2], mpc.Gamma[1::2]
        fq, fv = free[0::2], free[1::2]
        ones = np.full((N, 1), k)
        # q − s ≤ hi, q + s ≥ lo, q̇ − s ≤ vel, q̇ + s ≥ −vel (one row each, per step)
        C = np.vstack([np.hstack([Gq, -ones]), np.hstack([Gq, ones]),
                       np.hstack([Gv, -ones]), np.hstack([Gv, ones])])  # fmt: skip
        u = np.concatenate([hi - fq, np.full(N, BIG), vel - fv, np.full(N, BIG)])
        low = np.concatenate([np.full(N, -BIG), lo - fq, np.full(N, -BIG), -vel - fv])
        scale = 1.0 / np.linalg.norm(C, axis=1)
        H = np.zeros((Nc + 1, Nc + 1))
        H[:Nc, :Nc] = mpc.H
        H[Nc, Nc] = 1.0
        gs = np.append(g, lim.slack_linear_weight * mpc.scale * k)
        qp = _qp(Nc + 1, 4 * N, self.eps_abs)
        qp.settings.eps_rel = 1e-12
        qp.settings.check_duality_gap = False
        qp.init(H, gs, None, None, C * scale[:, None], low * scale, u * scale,
                np.append(np.full(Nc, self.v_min[i]), 0.0),
                np.append(np.full(Nc, self.v_max[i]), BIG))  # fmt: skip
        qp.solve()
        assert qp.results.info.status == proxqp.QPSolverOutput.PROXQP_SOLVED
        x = qp.results.x
        return x[:Nc].copy(), max(float(x[Nc]), 0.0) * k

    def outside(self, i: int, U_i: np.ndarray, x0: np.ndarray) -> bool:
        """Whether joint ``i``'s prediction with inputs ``U_i`` leaves its limits."""
        lim = self.limits
        X = self.mpc.Phi @ x0 + self.mpc.Gamma @ U_i
        q, v = X[0::2], X[1::2]
        return bool((q > lim.upper[i]).any() or (q < lim.lower[i]).any()
                    or (np.abs(v) > lim.velocity[i]).any())  # fmt: skip

    def solve(self, G: np.ndarray, x0: np.ndarray | None = None):
        """All joints for the gradients ``G`` (n, Nc) at the states ``x0`` (2, n); returns
        ``(U (Nc, n), slack (n,), soft (n,) bool)``."""
        Nc = self.mpc.Nc
        U = np.empty((Nc, self.n))
        slack = np.zeros(self.n)
        soft = np.zeros(self.n, dtype=bool)
        for i in range(self.n):
            U[:, i] = self.box(i, G[i])
            if self.limits is not None and self.outside(i, U[:, i], x0[:, i]):
                U[:, i], slack[i] = self.soft(i, G[i], x0[:, i])
                soft[i] = True
        return U, slack, soft
