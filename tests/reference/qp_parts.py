"""Oracles of the joint QPs' parts (compiled: ``cpp/src/box_qp.cpp``, ``box_active_set.cpp``,
``gamma_recursion.cpp``, ``banded_kkt.cpp``), in plain numpy, written as plainly as possible:

- the box QP :math:`\\min_u \\tfrac12 u^T H u + g^T u` s.t. :math:`lo \\le u \\le hi` by
  enumerating every active set (each input at its lower bound, its upper bound or free:
  :math:`3^{N_c}` sets, small :math:`N_c` only) and keeping the one whose point passes the
  KKT conditions — the minimiser of a strictly convex QP, unique;
- :math:`\\Gamma u` and :math:`\\Gamma^T \\lambda` as the dense products;
- the soft QP's equality-constrained subproblem for an active set by ``numpy.linalg.solve``
  of its dense KKT system in :math:`(U, \\hat s)`.
"""

from __future__ import annotations

import itertools

import numpy as np


def box_qp(H: np.ndarray, g: np.ndarray, lo: float, hi: float, tol: float = 1e-9):
    """The box QP's minimiser and its bounds' multipliers by enumeration of the active sets.

    Args:
        tol: The KKT test's tolerance, relative to 1 + max |g|.

    Returns:
        (u, z): z = −(H u + g) at the inputs at a bound, 0 at the free ones.
    """
    n = len(g)
    tol = tol * (1.0 + np.abs(g).max())
    for state in itertools.product((0, -1, 1), repeat=n):
        s = np.array(state)
        free, fixed = s == 0, s != 0
        u = np.where(s < 0, lo, hi).astype(float)
        if free.any():
            rhs = -(g[free] + H[np.ix_(free, fixed)] @ u[fixed])
            u[free] = np.linalg.solve(H[np.ix_(free, free)], rhs)
        r = H @ u + g
        if np.any(u[free] < lo - tol) or np.any(u[free] > hi + tol):
            continue
        if np.any(s[fixed] * r[fixed] > tol):  # lower bound: r >= 0; upper: r <= 0
            continue
        return u, np.where(fixed, -r, 0.0)
    raise AssertionError("no active set passes the KKT test")


def soft_subproblem(H, Gamma, k_slack, hss, g, rows, box, slack, lo, hi, bnd_lo, bnd_hi):
    """The soft QP's subproblem for an active set, by the dense KKT system.

    min ½ Uᵀ H U + ½ hss ŝ² + gᵀ (U, ŝ) s.t. Γ_r U − rows_r k ŝ = b_r (rows_r ≠ 0, b_r the
    bound of its sign), u_a = lo or hi (box_a ≠ 0), ŝ = 0 unless slack.

    Returns:
        (y, lam, mu): y = (U, ŝ) (Nc + 1); the rows' multipliers (2N) and the bounds' (Nc),
        with H U + g_U + Γᵀ λ + μ = 0 and hss ŝ + g_ŝ − k Σ rows_r λ_r = 0.
    """
    Nc = H.shape[0]
    rows, box = np.asarray(rows), np.asarray(box)
    act_r, act_b = np.flatnonzero(rows), np.flatnonzero(box)
    nv = Nc + (1 if slack else 0)
    A = np.zeros((len(act_r) + len(act_b), nv))
    b = np.zeros(len(A))
    for k, r in enumerate(act_r):
        A[k, :Nc] = Gamma[r]
        if slack:
            A[k, Nc] = -k_slack * rows[r]
        b[k] = bnd_hi[r] if rows[r] > 0 else bnd_lo[r]
    for k, a in enumerate(act_b):
        A[len(act_r) + k, a] = 1.0
        b[len(act_r) + k] = lo if box[a] < 0 else hi
    Hv = np.zeros((nv, nv))
    Hv[:Nc, :Nc] = H
    if slack:
        Hv[Nc, Nc] = hss
    K = np.block([[Hv, A.T], [A, np.zeros((len(A), len(A)))]])
    sol = np.linalg.solve(K, np.concatenate([-g[:nv], b]))
    y = np.zeros(Nc + 1)
    y[:nv] = sol[:nv]
    lam, mu = np.zeros(len(rows)), np.zeros(Nc)
    lam[act_r] = sol[nv : nv + len(act_r)]
    mu[act_b] = sol[nv + len(act_r) :]
    return y, lam, mu
