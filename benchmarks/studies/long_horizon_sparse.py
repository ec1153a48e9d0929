"""One joint's long-horizon MPC QP (Ts = 1 ms, N = Nc = 100) in the uncondensed, banded
form on ProxSuite's sparse backend, against the condensed dense QP the package solves.

Issue 18 asked to measure the banded structure of the uncondensed problem. Per joint:
decision z = [u_0..u_{N-1}, x_1..x_N] (300 variables), the dynamics x_{k+1} = A x_k + B u_k
as 200 equality rows, |u| <= 100 as 100 inequality rows (the sparse API has no box), the
paper's Q = diag(50, 0), P = 2Q, R = 1e-6. Both QPs are warm-started and fed the same
sequence of references and initial states (a sine sampled every 1 ms); the figure is the
median of ``update`` + ``solve`` over 300 steps.

Run: ``python benchmarks/studies/long_horizon_sparse.py``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from proxsuite import proxqp

if str(Path(__file__).resolve().parents[2]) not in sys.path:  # run as a script
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from benchmarks._fixtures import new_qp
from hmpc_pin.mpc.condensed import CondensedMPC

N, TS, R = 100, 0.001, 1e-6
Q, P = np.diag([50.0, 0.0]), np.diag([100.0, 0.0])


def sparse_qp():
    A = np.array([[1.0, TS], [0.0, 1.0]])
    B = np.array([TS * TS / 2.0, TS])
    nu, nx = N, 2 * N
    n = nu + nx
    H = sp.lil_matrix((n, n))
    for k in range(N):
        H[k, k] = 2.0 * R
    for k in range(1, N + 1):
        i = nu + 2 * (k - 1)
        H[i : i + 2, i : i + 2] = 2.0 * (Q if k < N else P)
    Aeq = sp.lil_matrix((nx, n))
    for k in range(N):
        r = 2 * k
        Aeq[r : r + 2, nu + r : nu + r + 2] = np.eye(2)
        Aeq[r : r + 2, k] = -B.reshape(2, 1)
        if k > 0:
            Aeq[r : r + 2, nu + r - 2 : nu + r] = -A
    C = sp.csc_matrix((np.ones(nu), (np.arange(nu), np.arange(nu))), shape=(nu, n))
    qp = proxqp.sparse.QP(n, nx, nu)
    qp.settings.eps_abs, qp.settings.eps_rel, qp.settings.verbose = 1e-9, 0.0, False
    qp.settings.initial_guess = proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
    qp.init(sp.csc_matrix(H), np.zeros(n), sp.csc_matrix(Aeq), np.zeros(nx), C,
            np.full(nu, -100.0), np.full(nu, 100.0))  # fmt: skip
    qp.solve()
    return qp, A


def main() -> int:
    sparse, A = sparse_qp()
    mpc = CondensedMPC(TS, N, N, Q, R, P)
    dense = new_qp(N, 0, 1e-9, 1000)
    dense.init(mpc.H, np.zeros(N), None, None, None, None, None,
               np.full(N, -100.0), np.full(N, 100.0))  # fmt: skip
    dense.solve()
    nu = N
    g = np.zeros(3 * N)
    b = np.zeros(2 * N)
    times = {"sparse (uncondensed, banded)": [], "dense (condensed, the package's)": []}
    worst = 0.0
    clock = time.perf_counter_ns
    for i in range(300):
        t = i * TS
        r = np.sin(t + TS * np.arange(1, N + 1))
        x0 = np.array([np.sin(t), np.cos(t)])
        g[nu::2] = -2.0 * 50.0 * r
        g[nu + 2 * (N - 1)] = -2.0 * 100.0 * r[-1]
        b[:2] = A @ x0
        ref = np.zeros(2 * N)
        ref[0::2] = r
        gd = mpc.F @ np.concatenate([x0, ref])
        t0 = clock()
        sparse.update(g=g, b=b)
        sparse.solve()
        t1 = clock()
        dense.update(g=gd)
        dense.solve()
        t2 = clock()
        times["sparse (uncondensed, banded)"].append(t1 - t0)
        times["dense (condensed, the package's)"].append(t2 - t1)
        worst = max(worst, float(np.abs(sparse.results.x[:nu] - dense.results.x).max()))
    for name, ns in times.items():
        print(f"{name:<34} median {np.median(ns) / 1e3:7.1f} µs per joint QP")
    print(f"largest |u_sparse - u_dense| over the run: {worst:.1e} rad/s²")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
