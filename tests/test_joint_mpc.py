"""Tests of :mod:`hmpc_pin.mpc.condensed` against an independent condensation of Eq (24)–(26).

Nothing here reuses the package's ``Phi``, ``Gamma`` or ``H``. The reference is built
from first principles:

* the double integrator ``x_{j+1} = A x_j + B v_j`` with ``A = [[1, Ts], [0, 1]]`` and
  ``B = [Ts²/2, Ts]`` is simulated step by step, with inputs ``v_j = U[min(j, Nc - 1)]``
  (the last free input is held to the end of the horizon);
* the paper's cost, Eq (25), ``Σ_{j<N} e_jᵀQe_j + v_jᵀRv_j + e_NᵀPe_N``, is summed along
  that simulation (``e_0`` uses a reference ``r_0`` that the MPC never sees, so it only
  adds a constant);
* since this cost is exactly quadratic in ``U``, its Hessian ``H`` and gradient ``g`` at
  ``U = 0`` are recovered exactly (up to rounding) by central and mixed differences of the
  simulated cost;
* the box-constrained minimiser of ``½UᵀHU + gᵀU`` is then obtained by clipping
  (``Nc = 1``), checked through the KKT conditions, and found by enumerating all ``3^Nc``
  active sets (each variable free, at its lower or at its upper bound).

ProxSuite solves a scaled copy of the QP to an absolute tolerance ``eps_abs`` on the dual
residual, so a solution can differ from the exact minimiser by at most
``√Nc · eps_abs / λ_min(H_scaled)``; the tolerances below are derived from that bound.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from hmpc_pin.mpc.condensed import CondensedMPC, JointQPs, StateLimits

TS = 0.01
Q_PAPER = np.diag([50.0, 0.0])
R_PAPER = 1e-6
P_PAPER = 2.0 * Q_PAPER
V_LIMIT = 100.0
EPS_ABS = 1e-9
#: A weighting with a velocity term as well, so that the tests do not rely on Q[1,1] = 0.
Q_VEL = np.array([[40.0, 2.0], [2.0, 0.5]])
R_VEL = 1e-4
P_VEL = np.array([[120.0, 5.0], [5.0, 3.0]])
WEIGHTS = {"paper": (Q_PAPER, R_PAPER, P_PAPER), "velocity": (Q_VEL, R_VEL, P_VEL)}


# ------------------------------------------------------------ independent reference
def simulate(U: np.ndarray, x0: np.ndarray, N: int, Ts: float = TS):
    """Simulate the double integrator over N steps; return states x_0..x_N and inputs v_j."""
    A = np.array([[1.0, Ts], [0.0, 1.0]])
    B = np.array([Ts * Ts / 2.0, Ts])
    Nc = len(U)
    xs = [np.asarray(x0, dtype=float)]
    vs = []
    for j in range(N):
        v = U[min(j, Nc - 1)]
        vs.append(v)
        xs.append(A @ xs[-1] + B * v)
    return np.array(xs), np.array(vs)


def simulated_cost(U, x0, r0, ref, N, Q, R, P) -> float:
    """The paper's cost Eq (25) summed along the simulated trajectory.

    ``ref`` has rows r_1, ṙ_1, ..., r_N, ṙ_N (the MPC's layout); ``r0`` is [r_0, ṙ_0].
    """
    xs, vs = simulate(U, x0, N)
    refs = np.vstack([r0, ref.reshape(N, 2)])
    e = xs - refs
    stage = sum(e[j] @ Q @ e[j] + R * vs[j] ** 2 for j in range(N))
    return float(stage + e[N] @ P @ e[N])


def own_condensation(x0, r0, ref, N, Nc, Q, R, P, step: float = 100.0):
    """Exact H, g, c of the simulated cost J(U) = ½UᵀHU + gᵀU + c by finite differences.

    The simulated cost is a quadratic polynomial in U, so central and mixed differences
    are exact up to rounding whatever the step; a large step keeps rounding small.
    """

    def J(U):
        return simulated_cost(U, x0, r0, ref, N, Q, R, P)

    eye = np.eye(Nc) * step
    c = J(np.zeros(Nc))
    plus = np.array([J(eye[i]) for i in range(Nc)])
    minus = np.array([J(-eye[i]) for i in range(Nc)])
    g = (plus - minus) / (2.0 * step)
    H = np.zeros((Nc, Nc))
    for i in range(Nc):
        H[i, i] = (plus[i] + minus[i] - 2.0 * c) / step**2
        for k in range(i + 1, Nc):
            H[i, k] = H[k, i] = (J(eye[i] + eye[k]) - plus[i] - plus[k] + c) / step**2
    return H, g, c


def brute_force_box_qp(H, g, lo, hi):
    """Minimise ½xᵀHx + gᵀx on lo <= x <= hi by enumerating all 3^n active sets."""
    n = len(g)
    best_x, best_f = None, np.inf
    for pattern in itertools.product((-1, 0, 1), repeat=n):
        pattern = np.array(pattern)
        x = np.where(pattern < 0, lo, hi).astype(float)
        free = pattern == 0
        if free.any():
            fixed = ~free
            rhs = -(g[free] + H[np.ix_(free, fixed)] @ x[fixed])
            x[free] = np.linalg.solve(H[np.ix_(free, free)], rhs)
            span = np.maximum(1.0, np.abs(hi - lo))
            if np.any(x < lo - 1e-12 * span) or np.any(x > hi + 1e-12 * span):
                continue
        f = 0.5 * x @ H @ x + g @ x
        if f < best_f:
            best_x, best_f = x, f
    return best_x


def solution_tolerance(H: np.ndarray) -> float:
    """Bound on |x_proxsuite - x*| from the dual-residual tolerance on the scaled QP."""
    Hs = H / np.mean(np.diag(H))
    return 10.0 * np.sqrt(len(H)) * EPS_ABS / np.linalg.eigvalsh(Hs)[0]


# --------------------------------------------------------------------- fixtures
@pytest.fixture
def make_problem(make_rng):
    """Factory of random (x0, r0, ref) for one joint; ``offset`` shifts the reference.

    A reference offset of a few tenths of a radian or more drives the unconstrained
    optimum beyond ±100 rad/s², so the bounds become active.
    """

    def _make(N: int, seed: int = 0, scale: float = 0.05, offset: float = 0.0):
        rng = make_rng(seed)
        x0 = rng.normal(0.0, scale, size=2)
        r0 = rng.normal(0.0, scale, size=2)
        ref = rng.normal(0.0, scale, size=2 * N)
        ref[0::2] += offset
        return x0, r0, ref

    return _make


@pytest.fixture
def make_qps():
    """Factory of (CondensedMPC, JointQPs) for n joints with scalar or per-joint bounds."""

    def _make(N, Nc, weights="paper", n=1, v_min=-V_LIMIT, v_max=V_LIMIT):
        Q, R, P = WEIGHTS[weights]
        mpc = CondensedMPC(TS, N, Nc, Q, R, P)
        v_min = np.broadcast_to(np.asarray(v_min, dtype=float), (n,)).copy()
        v_max = np.broadcast_to(np.asarray(v_max, dtype=float), (n,)).copy()
        names = tuple(f"j{i}" for i in range(n))
        return mpc, JointQPs(mpc, v_min, v_max, names, eps_abs=EPS_ABS, max_iter=1000)

    return _make


def single_gradient(mpc: CondensedMPC, x0: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """The (1, Nc) gradient of one joint, as the controller would compute it."""
    return mpc.gradient(x0[:, None], ref[:, None])


# ------------------------------------------------------------------- reference sanity
def test_own_condensation_reproduces_simulated_cost(make_rng, make_problem):
    """The finite-difference quadratic equals the simulated cost at unrelated points."""
    rng = make_rng(1)
    N, Nc = 8, 3
    x0, r0, ref = make_problem(N, seed=1, scale=0.5)
    H, g, c = own_condensation(x0, r0, ref, N, Nc, *WEIGHTS["velocity"])
    for _ in range(5):
        U = rng.normal(0.0, 50.0, size=Nc)
        expected = simulated_cost(U, x0, r0, ref, N, *WEIGHTS["velocity"])
        assert 0.5 * U @ H @ U + g @ U + c == pytest.approx(expected, rel=1e-11)


def test_brute_force_solver_satisfies_kkt(make_rng):
    """The enumeration solver finds the KKT point of a random strictly convex box QP."""
    rng = make_rng(2)
    A = rng.normal(size=(4, 4))
    H = A @ A.T + 0.1 * np.eye(4)
    g = rng.normal(0.0, 5.0, size=4)
    lo, hi = -np.ones(4), np.ones(4)
    x = brute_force_box_qp(H, g, lo, hi)
    z = -(H @ x + g)
    assert np.any(np.isclose(x, lo) | np.isclose(x, hi))
    for i in range(4):
        if np.isclose(x[i], hi[i]):
            assert z[i] >= -1e-12
        elif np.isclose(x[i], lo[i]):
            assert z[i] <= 1e-12
        else:
            assert abs(z[i]) < 1e-10


# ------------------------------------------------------------------ condensed data
@pytest.mark.parametrize(("N", "Nc"), [(1, 1), (5, 1), (10, 1), (10, 3), (6, 6), (10, 10)])
@pytest.mark.parametrize("weights", ["paper", "velocity"])
def test_hessian_and_gradient_match_simulation(make_problem, N, Nc, weights):
    """Unscaled H and g of the package equal those of the simulated cost."""
    Q, R, P = WEIGHTS[weights]
    mpc = CondensedMPC(TS, N, Nc, Q, R, P)
    for seed in range(3):
        x0, r0, ref = make_problem(N, seed=seed, scale=0.3)
        H, g, _ = own_condensation(x0, r0, ref, N, Nc, Q, R, P)
        np.testing.assert_allclose(mpc.H / mpc.scale, H, rtol=1e-9, atol=1e-12 * np.abs(H).max())
        g_pkg = single_gradient(mpc, x0, ref)[0] / mpc.scale
        np.testing.assert_allclose(g_pkg, g, rtol=1e-8, atol=1e-10 * np.abs(g).max())


@pytest.mark.parametrize(("N", "Nc"), [(1, 1), (10, 1), (10, 3), (7, 4), (10, 10)])
@pytest.mark.parametrize("weights", ["paper", "velocity"])
def test_cost_differences_match_simulated_cost(make_rng, make_problem, N, Nc, weights):
    """``mpc.cost`` has the U-dependence of Eq (25): J(U) - J(U') agrees with simulation."""
    Q, R, P = WEIGHTS[weights]
    mpc = CondensedMPC(TS, N, Nc, Q, R, P)
    rng = make_rng(3)
    for seed in range(3):
        x0, r0, ref = make_problem(N, seed=seed, scale=0.3)
        U0 = np.zeros(Nc)
        base_pkg = mpc.cost(U0, x0, ref)
        base_sim = simulated_cost(U0, x0, r0, ref, N, Q, R, P)
        for _ in range(3):
            U = rng.normal(0.0, 30.0, size=Nc)
            diff_pkg = mpc.cost(U, x0, ref) - base_pkg
            diff_sim = simulated_cost(U, x0, r0, ref, N, Q, R, P) - base_sim
            assert diff_pkg == pytest.approx(diff_sim, rel=1e-8, abs=1e-10 * abs(base_sim))


@pytest.mark.parametrize(("N", "Nc"), [(10, 1), (10, 3), (10, 10)])
def test_cost_equals_simulated_cost_minus_initial_error(make_rng, make_problem, N, Nc):
    """``mpc.cost(U, x0, ref)`` = simulated Eq (25) cost − e_0ᵀQe_0, as documented."""
    Q, R, P = WEIGHTS["paper"]
    mpc = CondensedMPC(TS, N, Nc, Q, R, P)
    rng = make_rng(4)
    x0, r0, ref = make_problem(N, seed=4, scale=0.3)
    e0 = x0 - r0
    U = rng.normal(0.0, 30.0, size=Nc)
    expected = simulated_cost(U, x0, r0, ref, N, Q, R, P) - e0 @ Q @ e0
    assert mpc.cost(U, x0, ref) == pytest.approx(expected, rel=1e-9)


# ------------------------------------------------------------------------- Nc = 1
@pytest.mark.parametrize(
    ("scale", "offset", "expect"),
    [
        (0.01, 0.0, "free"),
        (0.02, 0.0, "free"),
        (0.05, 0.0, "free"),
        (0.05, 3.0, "upper"),
        (0.05, -3.0, "lower"),
        (1.0, 5.0, "upper"),
    ],
)
@pytest.mark.parametrize("weights", ["paper", "velocity"])
def test_nc1_equals_clipped_closed_form(make_problem, make_qps, scale, offset, expect, weights):
    """With one free input the QP optimum is clip(-g/H, v_min, v_max).

    Each problem gets a freshly built JointQPs (see the warm-start tests for sequences).
    """
    N = 10
    Q, R, P = WEIGHTS[weights]
    for seed in range(4):
        mpc, qps = make_qps(N, 1, weights)
        x0, r0, ref = make_problem(N, seed=seed, scale=scale, offset=offset)
        H, g, _ = own_condensation(x0, r0, ref, N, 1, Q, R, P)
        u_free = -g[0] / H[0, 0]
        u_star = float(np.clip(u_free, -V_LIMIT, V_LIMIT))
        if expect == "free":
            assert abs(u_free) < V_LIMIT
        elif expect == "upper":
            assert u_free > V_LIMIT
        else:
            assert u_free < -V_LIMIT
        v0 = qps.solve(single_gradient(mpc, x0, ref))
        assert v0.shape == (1,)
        assert v0[0] == pytest.approx(u_star, abs=1e-7)
        assert qps.solution[0, 0] == v0[0]


# ------------------------------------------------------------------------- Nc > 1
def kkt_violations(H, g, x, lo, hi, tol_z, tol_x=1e-8, active_tol=1e-7):
    """List of violated KKT conditions of min ½xᵀHx + gᵀx s.t. lo <= x <= hi."""
    problems = []
    z = -(H @ x + g)  # stationarity: H x + g + z = 0
    for i in range(len(x)):
        if x[i] < lo[i] - tol_x or x[i] > hi[i] + tol_x:
            problems.append(f"x[{i}]={x[i]} outside [{lo[i]}, {hi[i]}]")
        at_hi = x[i] >= hi[i] - active_tol
        at_lo = x[i] <= lo[i] + active_tol
        if z[i] > tol_z and not at_hi:
            problems.append(f"z[{i}]={z[i]} > 0 but x[{i}]={x[i]} not at upper bound")
        if z[i] < -tol_z and not at_lo:
            problems.append(f"z[{i}]={z[i]} < 0 but x[{i}]={x[i]} not at lower bound")
    return problems


BOX_CASES = [
    # (Nc, weights, seed, scale, offset, must_be_active)
    (3, "paper", 0, 0.01, 0.0, False),
    (3, "paper", 1, 0.05, 0.5, True),
    (3, "paper", 2, 0.5, -3.0, True),
    (3, "velocity", 3, 0.02, 0.0, False),
    (3, "velocity", 4, 0.3, 1.0, True),
    (5, "paper", 5, 0.01, 0.0, False),
    (5, "paper", 6, 0.05, 0.3, True),
    (5, "paper", 7, 1.0, 0.0, True),
    (5, "velocity", 8, 0.2, -1.0, True),
    (5, "velocity", 9, 0.02, 0.0, False),
]


@pytest.mark.parametrize(("Nc", "weights", "seed", "scale", "offset", "active"), BOX_CASES)
def test_box_qp_satisfies_kkt(make_problem, make_qps, Nc, weights, seed, scale, offset, active):
    """The full input sequence satisfies the KKT conditions of the unscaled box QP."""
    N = 10
    Q, R, P = WEIGHTS[weights]
    mpc, qps = make_qps(N, Nc, weights)
    x0, r0, ref = make_problem(N, seed=seed, scale=scale, offset=offset)
    H, g, _ = own_condensation(x0, r0, ref, N, Nc, Q, R, P)
    lo, hi = np.full(Nc, -V_LIMIT), np.full(Nc, V_LIMIT)
    v0 = qps.solve(single_gradient(mpc, x0, ref))
    x = qps.solution[:, 0].copy()
    assert v0[0] == x[0]
    # the solver's scaled dual residual is <= eps_abs; unscaled that is eps_abs·mean diag H
    tol_z = 10.0 * EPS_ABS * np.mean(np.diag(H))
    assert kkt_violations(H, g, x, lo, hi, tol_z) == []
    n_active = int(np.sum((x <= lo + 1e-7) | (x >= hi - 1e-7)))
    if active:
        assert n_active >= 1
    else:
        assert n_active == 0


@pytest.mark.parametrize(("Nc", "weights", "seed", "scale", "offset", "active"), BOX_CASES)
def test_box_qp_matches_active_set_enumeration(
    make_problem, make_qps, Nc, weights, seed, scale, offset, active
):
    """The solution equals the minimiser found by enumerating all 3^Nc active sets."""
    N = 10
    Q, R, P = WEIGHTS[weights]
    mpc, qps = make_qps(N, Nc, weights)
    x0, r0, ref = make_problem(N, seed=seed, scale=scale, offset=offset)
    H, g, _ = own_condensation(x0, r0, ref, N, Nc, Q, R, P)
    x_bf = brute_force_box_qp(H, g, np.full(Nc, -V_LIMIT), np.full(Nc, V_LIMIT))
    assert (np.sum(np.abs(np.abs(x_bf) - V_LIMIT) < 1e-9) >= 1) == active
    qps.solve(single_gradient(mpc, x0, ref))
    np.testing.assert_allclose(qps.solution[:, 0], x_bf, rtol=0, atol=solution_tolerance(H))


def test_nc_equals_n_matches_active_set_enumeration(make_problem, make_qps):
    """Nc = N (every input free, no hold) against enumeration, with active bounds."""
    N = Nc = 6
    Q, R, P = WEIGHTS["paper"]
    mpc, qps = make_qps(N, Nc)
    x0, r0, ref = make_problem(N, seed=11, scale=0.05, offset=0.4)
    H, g, _ = own_condensation(x0, r0, ref, N, Nc, Q, R, P)
    x_bf = brute_force_box_qp(H, g, np.full(Nc, -V_LIMIT), np.full(Nc, V_LIMIT))
    assert np.any(np.abs(np.abs(x_bf) - V_LIMIT) < 1e-9)
    qps.solve(single_gradient(mpc, x0, ref))
    np.testing.assert_allclose(qps.solution[:, 0], x_bf, rtol=0, atol=solution_tolerance(H))


# ------------------------------------------------------------------ warm starting
#: Reference offsets of a sequence of problems. Offsets beyond about ±0.3 rad make a bound
#: active, so the sequence mixes interior problems with runs of consecutive problems that
#: have the same bound active, where a warm start matters most (without ProxSuite's
#: duality-gap test such solves stopped early with errors up to 1e-2, see joint_mpc.py).
SEQUENCE_OFFSETS = tuple(np.random.default_rng(1).uniform(-1.5, 1.5, size=30))


def solve_sequence(make_problem, make_qps, Nc: int, n: int = 3):
    """Solve SEQUENCE_OFFSETS with one warm-started object and with fresh objects.

    Returns a list of (warm solution, fresh solution, enumerated optimum, tolerance),
    each (Nc, n) except the tolerance, which is (n,).
    """
    N = 10
    Q, R, P = WEIGHTS["paper"]
    mpc, warm = make_qps(N, Nc, n=n)
    out = []
    for step, offset in enumerate(SEQUENCE_OFFSETS):
        problems = [make_problem(N, seed=100 * Nc + n * step + i, offset=offset) for i in range(n)]
        x0 = np.column_stack([p[0] for p in problems])
        ref = np.column_stack([p[2] for p in problems])
        G = mpc.gradient(x0, ref)
        assert G.shape == (n, Nc)
        assert G.flags.c_contiguous
        v_warm = warm.solve(G)
        sol_warm = warm.solution.copy()
        np.testing.assert_array_equal(v_warm, sol_warm[0])
        _, fresh = make_qps(N, Nc, n=n)
        fresh.solve(G)
        exact = np.zeros((Nc, n))
        tol = np.zeros(n)
        for i, (x0_i, r0_i, ref_i) in enumerate(problems):
            H, g, _ = own_condensation(x0_i, r0_i, ref_i, N, Nc, Q, R, P)
            exact[:, i] = brute_force_box_qp(H, g, np.full(Nc, -V_LIMIT), np.full(Nc, V_LIMIT))
            tol[i] = solution_tolerance(H)
        out.append((sol_warm, fresh.solution.copy(), exact, tol))
    return out


@pytest.mark.parametrize("Nc", [1, 3, 5])
def test_fresh_solves_of_sequence_are_exact(make_problem, make_qps, Nc):
    """Sanity of the sequence: it visits both bounds, and fresh objects solve it exactly."""
    results = solve_sequence(make_problem, make_qps, Nc)
    exact = np.stack([r[2] for r in results])
    assert np.any(np.isclose(exact, V_LIMIT, rtol=0, atol=1e-9))
    assert np.any(np.isclose(exact, -V_LIMIT, rtol=0, atol=1e-9))
    assert np.any(np.all(np.abs(exact) < V_LIMIT - 1e-6, axis=1))
    for _, fresh, exact_k, tol in results:
        assert np.all(np.abs(fresh - exact_k) <= tol)


@pytest.mark.parametrize("Nc", [1, 3, 5])
def test_warm_started_sequence_equals_fresh_solves(make_problem, make_qps, Nc):
    """Warm-started answers equal fresh ones and the exact optimum to the solver tolerance."""
    for warm, fresh, exact, tol in solve_sequence(make_problem, make_qps, Nc):
        assert np.all(np.abs(warm - exact) <= tol)
        assert np.all(np.abs(warm - fresh) <= 2.0 * tol)


# ------------------------------------------------------------------ per-joint bounds
PER_JOINT_V_MIN = np.array([-100.0, -5.0, -50.0, 25.0, -1.0])
PER_JOINT_V_MAX = np.array([100.0, 2.0, 10.0, 60.0, 15.0])


def solve_per_joint_bounds(make_problem, make_qps, Nc: int):
    """Five joints share one gradient but have different boxes (one excludes v = 0).

    Returns (solution (Nc, n), first inputs (n,), enumerated optima (Nc, n), tolerance).
    """
    N = 10
    Q, R, P = WEIGHTS["paper"]
    n = len(PER_JOINT_V_MIN)
    x0, r0, ref = make_problem(N, seed=30, scale=0.02, offset=0.1)
    H, g, _ = own_condensation(x0, r0, ref, N, Nc, Q, R, P)
    mpc, qps = make_qps(N, Nc, n=n, v_min=PER_JOINT_V_MIN, v_max=PER_JOINT_V_MAX)
    G = np.ascontiguousarray(np.tile(single_gradient(mpc, x0, ref), (n, 1)))
    v0 = qps.solve(G)
    exact = np.column_stack(
        [
            brute_force_box_qp(H, g, np.full(Nc, lo), np.full(Nc, hi))
            for lo, hi in zip(PER_JOINT_V_MIN, PER_JOINT_V_MAX, strict=True)
        ]
    )
    return qps.solution.copy(), v0, exact, solution_tolerance(H)


@pytest.mark.parametrize("Nc", [1, 3])
def test_per_joint_bounds_are_honoured(make_problem, make_qps, Nc):
    """Each joint's solution lies in its own box and is that box's optimum.

    One joint's box excludes v = 0, so the constructor's solve with g = 0 leaves it
    warm-started at a bound: the first real solve must still reach the optimum.
    """
    sol, v0, exact, tol = solve_per_joint_bounds(make_problem, make_qps, Nc)
    n = sol.shape[1]
    # the boxes matter: every joint has a different optimum
    gaps = np.abs(exact[:, :, None] - exact[:, None, :]).max(axis=0)
    assert np.all(gaps[~np.eye(n, dtype=bool)] > 1.0)
    assert np.all(sol >= PER_JOINT_V_MIN - 1e-8)
    assert np.all(sol <= PER_JOINT_V_MAX + 1e-8)
    assert np.all(np.abs(sol - exact) <= tol)
    np.testing.assert_array_equal(v0, sol[0])


# ------------------------------------------------------------------ paper settings
def test_paper_settings_give_positive_hessian(make_problem):
    """Ts = 0.01, N = 10, Nc = 1, Q = diag(50, 0), R = 1e-6, P = 2Q: H is finite and > 0."""
    mpc = CondensedMPC(0.01, 10, 1, Q_PAPER, R_PAPER, P_PAPER)
    assert mpc.H.shape == (1, 1)
    assert np.isfinite(mpc.H).all()
    assert np.isfinite(mpc.scale)
    assert mpc.scale > 0
    H_unscaled = mpc.H[0, 0] / mpc.scale
    assert H_unscaled > 0
    x0, r0, ref = make_problem(10, seed=40)
    H, _, _ = own_condensation(x0, r0, ref, 10, 1, Q_PAPER, R_PAPER, P_PAPER)
    assert H_unscaled == pytest.approx(H[0, 0], rel=1e-9)
    # closed form: Σ_{j=1..9} 2·50·(j²Ts²/2)² + 2·100·(100·Ts²/2)² + 2·R·10
    positions = np.array([(j * 0.01) ** 2 / 2.0 for j in range(1, 11)])
    closed = 2.0 * (50.0 * np.sum(positions[:-1] ** 2) + 100.0 * positions[-1] ** 2 + 10e-6)
    assert H_unscaled == pytest.approx(closed, rel=1e-12)


# ------------------------------------------------------- soft state constraints
SOFT = {"rho2": 1e5, "rho1": 1e4}  # the defaults of StateLimits


def own_soft_solution(x0, ref, N, lo, hi, vel, v_lim=V_LIMIT, grid=4001):
    """Nc = 1 soft-constrained optimum by 1-D minimisation, independent of the package.

    For a held input u the predicted states come from :func:`simulate`; the smallest
    slack that satisfies every constraint is s(u) = max(0, max violation), and the soft
    cost J(u) + ρ₂s² + ρ₁s is convex in u. A dense grid on [−v, v] followed by golden
    section search on the bracketing cell finds the minimiser.
    """

    def cost(u):
        X = simulate(np.array([u]), x0, N)[0][1:]
        q, v = X[:, 0], X[:, 1]
        s = max(0.0, (q - hi).max(), (lo - q).max(), (np.abs(v) - vel).max())
        E = X - ref
        J = sum(E[j] @ Q_PAPER @ E[j] for j in range(N - 1)) + E[-1] @ P_PAPER @ E[-1]
        J += N * R_PAPER * u * u
        return J + SOFT["rho2"] * s * s + SOFT["rho1"] * s, s

    us = np.linspace(-v_lim, v_lim, grid)
    k = int(np.argmin([cost(u)[0] for u in us]))
    a, b = us[max(k - 1, 0)], us[min(k + 1, grid - 1)]
    g = (np.sqrt(5.0) - 1.0) / 2.0
    for _ in range(200):
        c, d = b - g * (b - a), a + g * (b - a)
        if cost(c)[0] < cost(d)[0]:
            b = d
        else:
            a = c
    u = 0.5 * (a + b)
    return u, cost(u)[1]


def soft_qps(N, Nc, lo, hi, vel, always=False, Ts=TS):
    mpc = CondensedMPC(Ts, N, Nc, Q_PAPER, R_PAPER, P_PAPER)
    limits = StateLimits(
        np.array([lo]), np.array([hi]), np.array([vel]), SOFT["rho2"], SOFT["rho1"]
    )
    qps = JointQPs(
        mpc,
        np.array([-V_LIMIT]),
        np.array([V_LIMIT]),
        ("j",),
        eps_abs=EPS_ABS,
        limits=limits,
        always_constrained=always,
    )
    return mpc, qps


def near_limit_states(rng, count, hi=1.5, vel=3.0):
    """States close to (or past) the upper position limit, moving at up to 1.5 x vel."""
    return [
        np.array([hi + rng.normal(0.0, 0.05), rng.uniform(-1.5, 1.5) * vel]) for _ in range(count)
    ]


@pytest.mark.parametrize("seed", range(3))
def test_soft_constrained_nc1_matches_own_minimisation(make_rng, seed):
    """Joints pushed towards their limit: u and slack equal an independent 1-D minimisation."""
    rng = make_rng(seed)
    N, lo, hi, vel = 10, -1.5, 1.5, 3.0
    mpc, qps = soft_qps(N, 1, lo, hi, vel)
    checked = 0
    for x0 in near_limit_states(rng, 15, hi, vel):
        ref = np.zeros((N, 2))
        ref[:, 0] = hi + rng.uniform(0.0, 0.5)  # the reference pulls beyond the limit
        flat = ref.reshape(-1, 1)
        u = qps.solve(mpc.gradient(x0.reshape(2, 1), flat), x0.reshape(2, 1))[0]
        u_own, s_own = own_soft_solution(x0, ref, N, lo, hi, vel)
        assert u == pytest.approx(u_own, abs=2e-3), (x0, u, u_own)
        assert qps.slack[0] == pytest.approx(s_own, abs=1e-5)
        checked += qps.constrained
    assert checked > 0  # the constrained QP was exercised


def test_soft_constraints_keep_prediction_inside_when_feasible(make_rng):
    """Where a feasible input exists, the exact penalty makes the slack zero: hard limits."""
    rng = make_rng(5)
    N, lo, hi, vel = 10, -1.5, 1.5, 3.0
    mpc, qps = soft_qps(N, 3, lo, hi, vel)
    for _ in range(40):
        # Feasible: full braking (v = -100) stops the joint v²/200 short of the limit.
        dq = rng.uniform(0.0, 2.0)
        x0 = np.array([[hi - dq * dq / (2 * V_LIMIT) - rng.uniform(0.002, 0.2)], [dq]])
        ref = np.zeros((2 * N, 1))
        ref[0::2] = hi + 1.0
        qps.solve(mpc.gradient(x0, ref), x0)
        X = qps.predict(x0, qps.solution)
        assert qps.slack[0] < 1e-7
        assert X[0::2].max() <= hi + 1e-7 and np.abs(X[1::2]).max() <= vel + 1e-7


def fast_path_draws(rng, N, Nc, draws, q_low, Ts=TS, check_inside=False):
    """``draws`` random soft QPs (limits ±1.5 rad, 3 rad/s; the start position drawn in
    [``q_low``, 1.6] rad) solved by the fast path and always constrained: the two agree.
    With ``check_inside``, a box solution the fast path keeps predicts inside the limits.

    Returns:
        How many of the draws took the constrained branch.
    """
    lo, hi, vel = -1.5, 1.5, 3.0
    mpc, fast = soft_qps(N, Nc, lo, hi, vel, Ts=Ts)
    _, full = soft_qps(N, Nc, lo, hi, vel, always=True, Ts=Ts)
    used = 0
    for _ in range(draws):
        x0 = np.array([[rng.uniform(q_low, 1.6)], [rng.uniform(-3.0, 3.0)]])
        ref = np.zeros((2 * N, 1))
        ref[0::2] = rng.uniform(0.0, 2.0)
        G = mpc.gradient(x0, ref)
        v_fast = fast.solve(G, x0)
        used += fast.constrained
        v_full = full.solve(G, x0)
        assert v_fast == pytest.approx(v_full, abs=1e-4)
        if check_inside and not fast.constrained:  # the box solution's prediction
            X = fast.predict(x0, fast.solution)
            assert X[0::2].max() <= hi + 1e-9 and X[0::2].min() >= lo - 1e-9
            assert np.abs(X[1::2]).max() <= vel + 1e-9
    return used


@pytest.mark.parametrize("Nc", [1, 3, 5])
def test_fast_path_equals_always_constrained(make_rng, Nc):
    """Solving the soft QP only where the box solution leaves the limits changes nothing."""
    used = fast_path_draws(make_rng(Nc), 10, Nc, 60, q_low=0.5)
    assert 0 < used < 60  # both branches of the fast path were taken


@pytest.mark.parametrize("N, Nc", [(100, 3), (60, 60)])
def test_fast_path_equals_always_constrained_for_long_horizons(make_rng, N, Nc):
    """The one-sided limit test of long horizons (N·Nc > 200) decides as the soft QP does."""
    used = fast_path_draws(make_rng(N + Nc), N, Nc, 40, q_low=0.8, Ts=0.002, check_inside=True)
    assert 0 < used < 40  # both branches of the fast path were taken


# --------------------------------------------------------------- QP layout by size
def test_auto_layout_resolves_by_problem_size():
    from hmpc_pin.exceptions import ConfigError
    from hmpc_pin.mpc.condensed import AUTO_BLOCK_MAX, resolve_layout

    assert AUTO_BLOCK_MAX == 0  # measured: the per-joint layout is faster everywhere
    for n, Nc in ((1, 1), (3, 1), (7, 5), (7, 100)):
        assert resolve_layout("auto", n, Nc) == "joint"
    assert resolve_layout("block", 7, 100) == "block"
    assert resolve_layout("joint", 3, 1) == "joint"
    with pytest.raises(ConfigError, match="qp_layout"):
        resolve_layout("banded", 3, 1)


def recorded_qp_inputs(planar3, N, Nc, steps):
    """(G, x0) of every step of a closed-loop planar3 run whose reference leaves the joint
    limits (amplitude 1.9 rad on ±1.57 rad joints), so the soft state constraints act."""
    import hmpc_pin
    from hmpc_pin.controllers.hierarchical import MPCSettings

    settings = MPCSettings(N=N, Nc=Nc, qp_layout="block")
    ctrl = hmpc_pin.HierarchicalMPC(planar3, settings)
    ref = hmpc_pin.SineReference(3, amplitude=1.9, frequency=0.5)
    inputs, step = [], ctrl.step

    def spy(t, q, dq, reference):
        tau = step(t, q, dq, reference)
        # the step's state and horizon (its data's views) give G (CondensedMPC.gradient)
        d = ctrl._data
        horizon = np.empty((2 * N, 3))
        horizon[0::2], horizon[1::2] = d.q_ref, d.dq_ref  # rows r_1, ṙ_1, ..., r_N, ṙ_N
        x0 = np.vstack([d.q, d.dq])
        inputs.append((ctrl.mpc.gradient(x0, horizon), x0))
        return tau

    ctrl.step = spy
    hmpc_pin.simulate(planar3, ctrl, ref, None, duration=(steps - 1) * ctrl.Ts,
                      q0=np.zeros(3))  # fmt: skip
    return ctrl, inputs


@pytest.mark.parametrize("N, Nc", [(10, 1), (10, 5), (50, 50)])
def test_layouts_give_the_block_solution_on_recorded_gradients(planar3, N, Nc):
    """Block, per-joint and auto layouts: the same inputs (solver tolerance) on the
    gradients and states of a closed-loop run that drives the joints into their soft
    limits, for a short and a long control horizon; where no soft QP was solved (Nc <= 5),
    each equals the box QP's minimiser found by enumerating its active sets."""
    from hmpc_pin.mpc.condensed import resolve_layout

    ctrl, inputs = recorded_qp_inputs(planar3, N, Nc, 150)
    v_min, v_max = ctrl.settings.bounds(3)
    layouts = {
        name: JointQPs(ctrl.mpc, v_min, v_max, planar3.joint_names, limits=ctrl.limits, layout=name)
        for name in ("block", "joint", "auto")
    }
    assert layouts["auto"].layout == resolve_layout("auto", 3, Nc)
    tol = solution_tolerance(ctrl.mpc.H * ctrl.mpc.scale)
    constrained = box_checked = 0
    for G, x0 in inputs:
        sols = {}
        for name, qps in layouts.items():
            qps.solve(G, x0)
            sols[name] = qps.solution.copy()
        constrained += layouts["joint"].constrained
        for name in ("joint", "auto"):
            np.testing.assert_allclose(sols[name], sols["block"], rtol=0, atol=tol)
        if Nc <= 5 and layouts["joint"].constrained == 0:  # the box QPs' own minimisers
            for i in range(3):
                exact = brute_force_box_qp(ctrl.mpc.H, G[i], np.full(Nc, v_min[i]),
                                           np.full(Nc, v_max[i]))  # fmt: skip
                for name, U in sols.items():
                    np.testing.assert_allclose(U[:, i], exact, rtol=0, atol=tol, err_msg=name)
                box_checked += 1
    assert constrained > 0  # the soft state constraints were exercised
    assert Nc > 5 or box_checked > 0


def test_solve_without_states_is_refused_when_limits_are_set():
    from hmpc_pin.exceptions import InterfaceError

    _mpc, qps = soft_qps(10, 1, -1.5, 1.5, 3.0)
    with pytest.raises(InterfaceError, match="x0"):
        qps.solve(np.zeros((1, 1)))


@pytest.mark.parametrize("N, Nc", [(10, 5), (100, 100)])
def test_joint_layout_shortcut_is_the_box_qp_solution(make_rng, N, Nc):
    """The per-joint layout takes -H⁻¹g without ProxSuite where it lies in the box: on
    gradients with the box inactive for some joints and active for others, the solutions
    equal the block QP's (ProxSuite for all) to solver tolerance, the shortcut's satisfy
    the stationarity H U + g = 0, and both paths were taken."""
    rng = make_rng(5)
    mpc = CondensedMPC(0.001 if N == 100 else 0.01, N, Nc, np.diag([50.0, 0.0]), 1e-6,
                       np.diag([100.0, 0.0]))  # fmt: skip
    n = 4
    v_min, v_max = np.full(n, -100.0), np.full(n, 100.0)
    names = tuple(f"j{i}" for i in range(n))
    joint = JointQPs(mpc, v_min, v_max, names, layout="joint")
    block = JointQPs(mpc, v_min, v_max, names, layout="block")
    free = -np.linalg.solve(mpc.H, np.eye(Nc))  # −H⁻¹, independently
    tol = solution_tolerance(mpc.H)
    for _ in range(40):
        # gradients whose unconstrained minimiser is ~ 0.3–3 × the bound
        G = rng.normal(size=(n, Nc))
        G *= rng.uniform(0.3, 3.0, size=(n, 1)) * 100.0 / np.abs(G @ free).max(axis=1)[:, None]
        before = joint.unconstrained_solves
        joint.solve(G)
        block.solve(G)
        np.testing.assert_allclose(joint.solution, block.solution, rtol=0, atol=tol)
        took = joint.unconstrained_solves - before
        inside = (np.abs(G @ free) <= 100.0).all(axis=1)
        assert took == inside.sum()
        for i in np.flatnonzero(inside):
            np.testing.assert_allclose(mpc.H @ joint.solution[:, i] + G[i], 0.0, atol=1e-9)
    assert 0 < joint.unconstrained_solves < 40 * n


# ------------------------------------------------ the compiled QPs against their oracle
SOFT_TOL = 1e-4  # [rad/s²]: two soft solves agree to this (test_fast_path_equals_...)


def _compare_with_oracle(qps, oracle, G, x0, tol):
    qps.solve(G, x0)
    U, slack, soft = oracle.solve(G, x0)
    for i in range(G.shape[0]):
        np.testing.assert_allclose(qps.solution[:, i], U[:, i], rtol=0,
                                   atol=SOFT_TOL if soft[i] else tol)  # fmt: skip
    np.testing.assert_allclose(qps.slack, slack, rtol=0, atol=1e-5)
    assert qps.constrained == int(soft.sum())
    return int(soft.sum())


@pytest.mark.parametrize("layout", ["block", "joint"])
@pytest.mark.parametrize("Nc", [1, 3])
def test_compiled_qps_equal_the_oracle_on_random_states(make_rng, layout, Nc):
    """Random gradients and states near the limits of 3 joints: the compiled QPs (layout,
    shortcut, warm starts, soft limits) give the oracle's solution (tests/reference:
    every QP solved from scratch by ProxSuite's Python API), slack and soft joints."""
    from .reference.joint_qps import NumpyJointQPs

    rng = make_rng(Nc + (layout == "joint"))
    N, n = 10, 3
    mpc = CondensedMPC(TS, N, Nc, Q_PAPER, R_PAPER, P_PAPER)
    lo, hi, vel = np.full(n, -1.5), np.full(n, 1.5), np.full(n, 3.0)
    limits = StateLimits(lo, hi, vel, SOFT["rho2"], SOFT["rho1"])
    bound = np.full(n, V_LIMIT)
    qps = JointQPs(mpc, -bound, bound, ("a", "b", "c"), eps_abs=EPS_ABS, limits=limits,
                   layout=layout)  # fmt: skip
    oracle = NumpyJointQPs(mpc, -bound, bound, limits, eps_abs=EPS_ABS)
    tol = solution_tolerance(mpc.H)
    soft = 0
    for _ in range(40):
        x0 = np.vstack([rng.uniform(0.5, 1.6, n), rng.uniform(-3.0, 3.0, n)])
        ref = np.zeros((2 * N, n))
        ref[0::2] = rng.uniform(0.0, 2.0, n)
        G = mpc.gradient(x0, ref)
        soft += _compare_with_oracle(qps, oracle, G, x0, tol)
    assert soft > 0  # the soft QPs were exercised


@pytest.mark.parametrize("N, Nc", [(10, 1), (10, 5)])
def test_compiled_qps_equal_the_oracle_along_a_closed_loop(planar3, N, Nc):
    """The gradients and states of a closed-loop run into the soft limits, replayed into
    fresh compiled QPs (warm-started along the run, as in the controller) and the oracle."""
    from .reference.joint_qps import NumpyJointQPs

    ctrl, inputs = recorded_qp_inputs(planar3, N, Nc, 150)
    v_min, v_max = ctrl.settings.bounds(3)
    qps = JointQPs(ctrl.mpc, v_min, v_max, planar3.joint_names, limits=ctrl.limits)
    oracle = NumpyJointQPs(ctrl.mpc, v_min, v_max, ctrl.limits)
    tol = solution_tolerance(ctrl.mpc.H)
    soft = sum(_compare_with_oracle(qps, oracle, G, x0, tol) for G, x0 in inputs)
    assert soft > 0


def test_inverted_input_bounds_are_one_config_error_naming_the_joint():
    """v_min > v_max for one joint: refused before any solve, naming the joint and both
    values (ProxSuite would iterate to its cap on an empty box)."""
    from hmpc_pin.exceptions import ConfigError

    mpc = CondensedMPC(TS, 10, 1, Q_PAPER, R_PAPER, P_PAPER)
    with pytest.raises(ConfigError, match=r"joint 'b': v_min = 5 > v_max = -5"):
        JointQPs(mpc, np.array([-1.0, 5.0]), np.array([1.0, -5.0]), ("a", "b"))


# ------------------------------------------------- long horizons with active bounds
def cold_box_solve(H: np.ndarray, g: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """An independent solve: a fresh ProxSuite QP (Python API), no warm start."""
    from proxsuite import proxqp

    qp = proxqp.dense.QP(len(g), 0, 0, True)
    qp.settings.eps_abs, qp.settings.eps_rel, qp.settings.verbose = EPS_ABS, 0.0, False
    qp.settings.initial_guess = proxqp.InitialGuess.NO_INITIAL_GUESS
    qp.init(H, g, None, None, None, None, None, lo, hi)
    qp.solve()
    assert qp.results.info.status == proxqp.QPSolverOutput.PROXQP_SOLVED
    return qp.results.x.copy()


LONG_STRATEGIES = {  # (shift, active_set_iter)
    "default": (False, 4),
    "proxsuite, previous": (False, -1),
    "proxsuite, shifted": (True, -1),
    "active set, shifted proxsuite": (True, 4),
}


@pytest.mark.parametrize("strategy", list(LONG_STRATEGIES))
@pytest.mark.parametrize("case", ["closed loop", "held 0.2", "held 0.05"])
def test_long_horizon_with_active_bounds_equals_cold_solves_and_kkt(strategy, case):
    """Ts = 1 ms, N = Nc = 100, three joints 0.2 rad off a sine reference (a closed loop of
    the double integrators of Eq 24 from there, or the state held 0.2 or 0.05 rad off): at
    every step each joint's solution equals a cold ProxSuite solve to the solver's tolerance
    and satisfies the box QP's KKT conditions, whichever path answered (the active-set
    shortcut, ProxSuite warm-started from the last solution as it stands or shifted)."""
    N = Nc = 100
    Ts, n = 0.001, 3
    mpc = CondensedMPC(Ts, N, Nc, Q_PAPER, R_PAPER, P_PAPER)
    lo, hi = np.full(Nc, -V_LIMIT), np.full(Nc, V_LIMIT)
    qps = JointQPs(mpc, -V_LIMIT, V_LIMIT, ("a", "b", "c"), eps_abs=EPS_ABS, layout="joint")
    qps.shift, qps.active_set_iter = LONG_STRATEGIES[strategy]
    phase = np.array([0.0, 1.0, 2.0])
    w = 2.0 * np.pi

    def reference(t):  # r, ṙ of the sine, shape (2, n)
        return np.vstack([0.5 * np.sin(w * t + phase), 0.5 * w * np.cos(w * t + phase)])

    offset = 0.2 if case == "closed loop" else float(case.split()[1])
    x = reference(0.0) + np.array([[offset], [0.0]])
    tol = solution_tolerance(mpc.H)
    A = np.array([[1.0, Ts], [0.0, 1.0]])
    B = np.array([[Ts * Ts / 2.0], [Ts]])
    active = 0
    for k in range(30):
        t = k * Ts
        if case != "closed loop":
            x = reference(t) + np.array([[offset], [0.0]])
        ref = np.vstack([reference(t + j * Ts) for j in range(1, N + 1)])  # (2N, n)
        G = mpc.gradient(x, ref)
        qps.solve(G, x)
        for i in range(n):
            u = qps.solution[:, i]
            np.testing.assert_allclose(u, cold_box_solve(mpc.H, G[i], lo, hi), rtol=0, atol=tol)
            assert kkt_violations(mpc.H, G[i], u, lo, hi, tol_z=10.0 * EPS_ABS) == []
            active += int(np.sum((u <= lo + 1e-7) | (u >= hi - 1e-7)) > 0)
        if case == "closed loop":
            x = A @ x + B @ qps.solution[:1]
    assert active >= 10 * n  # the bounds were active
    if qps.active_set_iter >= 0:
        assert qps.active_set_solves > 0
    else:
        assert qps.active_set_solves == 0


# ------------------------------------------- long horizons with active soft limits
def own_soft_qp(x0, ref, N, Nc, Ts, lo, hi, vel):
    """The soft-limit QP of one joint (module docstring of hmpc_pin.mpc.condensed) built
    here from the simulated double integrator: variables z = (U, s) [rad/s², rad],

        min  J(U) + ρ₂ s² + ρ₁ s,   J = Σ_{j<N} e_jᵀQe_j + R v_j² + e_NᵀPe_N (Eq 25)
        s.t. lo − s <= q_j <= hi + s,  −vel − s <= q̇_j <= vel + s  (j = 1..N),
             −V <= U <= V,  s >= 0.

    Returns (Hz, gz, A, b): cost ½zᵀHz z + gzᵀz (+ const) and the rows A z <= b (the
    state constraints, the input box and s >= 0, all as rows).
    """
    free = simulate(np.zeros(Nc), x0, N, Ts)[0][1:].reshape(-1)  # Φ x0: q_1, q̇_1, …
    Gam = np.column_stack(
        [simulate(np.eye(Nc)[c], np.zeros(2), N, Ts)[0][1:].reshape(-1) for c in range(Nc)]
    )
    Qbar = np.kron(np.eye(N), Q_PAPER)
    Qbar[-2:, -2:] = P_PAPER
    counts = np.ones(Nc)
    counts[-1] = N - Nc + 1
    H = 2.0 * (Gam.T @ Qbar @ Gam + R_PAPER * np.diag(counts))
    g = 2.0 * Gam.T @ Qbar @ (free - ref)
    Hz = np.zeros((Nc + 1, Nc + 1))
    Hz[:Nc, :Nc] = H
    Hz[Nc, Nc] = 2.0 * SOFT["rho2"]
    gz = np.append(g, SOFT["rho1"])
    Gq, Gv, fq, fv = Gam[0::2], Gam[1::2], free[0::2], free[1::2]
    minus = -np.ones((N, 1))
    A = np.vstack([
        np.hstack([Gq, minus]), np.hstack([-Gq, minus]),
        np.hstack([Gv, minus]), np.hstack([-Gv, minus]),
        np.hstack([np.eye(Nc), np.zeros((Nc, 1))]), np.hstack([-np.eye(Nc), np.zeros((Nc, 1))]),
        -np.eye(Nc + 1)[Nc:],
    ])  # fmt: skip
    b = np.concatenate([hi - fq, fq - lo, vel - fv, vel + fv,
                        np.full(Nc, V_LIMIT), np.full(Nc, V_LIMIT), [0.0]])  # fmt: skip
    return Hz, gz, A, b


def soft_kkt_residual(Hz, gz, A, b, z, active_tol):
    """The KKT conditions of min ½zᵀHz z + gzᵀz s.t. A z <= b at z: (largest row violation,
    smallest stationarity residual ‖D (Hz z + gz + A_Wᵀλ)‖∞ over multipliers λ >= 0 of the
    rows W within active_tol of their bound, by non-negative least squares). D states it in
    the units of the solver's tolerance: the cost divided by the mean of the inputs' Hessian
    diagonal (σ), the slack in units of k = 1/√(2ρ₂σ) (module docstring of
    hmpc_pin.mpc.condensed: the QP as the solver sees it, each Hessian entry ~1)."""
    from scipy.optimize import nnls

    slack = A @ z - b
    active = slack >= -active_tol
    sigma = 1.0 / np.mean(np.diag(Hz)[:-1])
    D = np.full(len(z), sigma)
    D[-1] = sigma / np.sqrt(Hz[-1, -1] * sigma)  # σ k, with Hz[-1, -1] = 2ρ₂
    grad = D * (Hz @ z + gz)
    M = A[active].T * D[:, None]
    lam, _ = nnls(M, -grad, maxiter=50 * M.shape[1])
    return float(slack.max()), float(np.abs(M @ lam + grad).max())


def _assert_soft_answers(qps, cold, x, ref, Nc, Ts, limits, tol_kkt, tol, where) -> None:
    """Each joint's (U, s) of ``qps`` at the state ``x`` (2, n) and reference ``ref`` (2N, n)
    satisfies the KKT conditions of the soft-limit QP built here (:func:`own_soft_qp`,
    ``limits`` = (lo, hi, vel)) and equals ``cold``'s (ProxSuite from scratch) to ``tol``."""
    lo, hi, vel = limits
    N = ref.shape[0] // 2
    for i in range(qps.solution.shape[1]):
        z = np.append(qps.solution[:, i], qps.slack[i])
        Hz, gz, A, b = own_soft_qp(x[:, i], ref[:, i], N, Nc, Ts, lo, hi, vel)
        violation, residual = soft_kkt_residual(Hz, gz, A, b, z, active_tol=1e-7)
        assert violation <= 1e-7, (where, i, violation)
        assert residual <= tol_kkt, (where, i, residual)
        np.testing.assert_allclose(z, np.append(cold.solution[:, i], cold.slack[i]),
                                   rtol=0, atol=tol)  # fmt: skip


SOFT_LONG = {  # (Ts, N = Nc, start offset [rad] from the sine, limits (lo, hi, vel))
    "1 ms, N = 100, velocity limits": (0.001, 100, 0.2, (-2.0, 2.0, 1.0)),
    "10 ms, N = 50, velocity limits": (0.01, 50, 0.2, (-2.0, 2.0, 1.0)),
    "1 ms, N = 100, started past the position limit": (0.001, 100, 0.3, (-0.45, 0.45, 4.0)),
    "10 ms, N = 50, started past the position limit": (0.01, 50, 0.3, (-0.45, 0.45, 4.0)),
}


def _soft_long_qps(case: str):
    """Three joints' soft-limit QPs of ``SOFT_LONG[case]`` (paper weights, N = Nc): the
    condensed MPC, the QPs with the soft active-set shortcut, and the same QPs solved
    cold by ProxSuite."""
    Ts, N, _, (lo, hi, vel) = SOFT_LONG[case]
    mpc = CondensedMPC(Ts, N, N, Q_PAPER, R_PAPER, P_PAPER)
    limits = StateLimits(np.full(3, lo), np.full(3, hi), np.full(3, vel), SOFT["rho2"],
                         SOFT["rho1"])  # fmt: skip
    qps = JointQPs(mpc, -V_LIMIT, V_LIMIT, ("a", "b", "c"), eps_abs=EPS_ABS, limits=limits)
    cold = JointQPs(mpc, -V_LIMIT, V_LIMIT, ("a", "b", "c"), eps_abs=EPS_ABS, limits=limits)
    cold.soft_active_set_iter = -1  # every soft QP solved from scratch by ProxSuite
    return mpc, qps, cold


@pytest.mark.parametrize("case", list(SOFT_LONG))
def test_long_horizon_soft_limits_satisfy_kkt_and_equal_cold_solves(case):
    """Three joints in a closed loop of the double integrators (Eq 24) started off a sine
    (amplitude 0.5 rad, 1 Hz) whose velocity (π rad/s) exceeds the velocity limit, or from
    past the position limit (the hard constraints infeasible: slack > 0): at every step each
    joint's solution (U, s) satisfies the KKT conditions of the soft-limit QP built here
    (:func:`own_soft_qp`) and equals the soft QP solved from scratch by ProxSuite (the
    shortcut off), to the solver's tolerance. With the velocity limits active the soft
    active-set shortcut answered most of them, past the position limit (slack > 0) too;
    the first step of an activation past the position limit (its optimum a vertex far from
    the box-only solution's active set) may be left to ProxSuite."""
    Ts, N, offset, (lo, hi, vel) = SOFT_LONG[case]
    n = 3
    mpc, qps, cold = _soft_long_qps(case)
    phase = np.array([0.0, 1.0, 2.0])
    w = 2.0 * np.pi

    def reference(t):  # r, ṙ of the sine, shape (2, n)
        return np.vstack([0.5 * np.sin(w * t + phase), 0.5 * w * np.cos(w * t + phase)])

    x = reference(0.0) + np.array([[offset], [0.0]])
    if "position" in case:
        x[0] = hi + 0.05  # past the upper limit, no input brings q_1 inside
    # Tolerances from the solver's: eps_abs on the scaled QP's gradient, 100x for the
    # multipliers' least squares. Solutions: the strong-convexity bound of the box QPs.
    tol_kkt = 100.0 * EPS_ABS
    tol = solution_tolerance(mpc.H)
    A_dyn = np.array([[1.0, Ts], [0.0, 1.0]])
    B_dyn = np.array([[Ts * Ts / 2.0], [Ts]])
    soft_steps = positive_slack = 0
    for k in range(25):
        t = k * Ts
        ref = np.vstack([reference(t + j * Ts) for j in range(1, N + 1)])  # (2N, n)
        G = mpc.gradient(x, ref)
        qps.solve(G, x)
        cold.solve(G, x)
        soft_steps += qps.constrained
        _assert_soft_answers(qps, cold, x, ref, N, Ts, (lo, hi, vel), tol_kkt, tol, k)
        positive_slack += int((qps.slack > 1e-6).sum())
        x = A_dyn @ x + B_dyn @ qps.solution[:1]
    assert soft_steps >= 10 * n  # the soft limits were active
    if "position" in case:
        assert positive_slack > 0  # the hard constraints were infeasible somewhere
    assert qps.soft_active_set_solves >= soft_steps // 2  # the shortcut answered


@pytest.mark.parametrize(
    "case", ["1 ms, N = 100, velocity limits", "10 ms, N = 50, velocity limits"]
)
def test_first_step_of_each_soft_activation_is_answered_by_the_shortcut(case):
    """Each activation of the soft limits (a joint's first soft QP after a step without
    one) is answered by the soft active-set shortcut at its first step, with a solution that
    satisfies the soft QP's KKT conditions (:func:`own_soft_qp`) and equals the soft QP
    solved from scratch by ProxSuite to the solver's tolerance. Activations: the states put
    off a sine (amplitude 0.1 rad, 1 Hz, its velocity inside the limit): the way back at
    the bound on v leaves the velocity limit, which the inputs can meet (zero slack, the
    Panda's start 0.2 rad off; at Ts = 10 ms a row of the guess depends on an input at its
    bound, which the exchanges must free); in between, a step at rest on a reference at
    rest (no soft QP)."""
    Ts, N, offset, (lo, hi, vel) = SOFT_LONG[case]
    n = 3
    mpc, qps, cold = _soft_long_qps(case)
    phase = np.array([0.0, 1.0, 2.0])
    w = 2.0 * np.pi

    def reference(t):  # r, ṙ of the sine, shape (2, n)
        return np.vstack([0.1 * np.sin(w * t + phase), 0.1 * w * np.cos(w * t + phase)])

    tol_kkt, tol = 100.0 * EPS_ABS, solution_tolerance(mpc.H)
    activations = 0
    for k, kick in enumerate((offset, None, -offset, None, 0.7 * offset, None, -offset)):
        t = 0.07 * k
        if kick is None:  # at rest on a reference at rest: U = 0, no soft QP
            qps.solve(np.zeros((n, N)), np.zeros((2, n)))
            assert qps.constrained == 0
            continue
        ref = np.vstack([reference(t + j * Ts) for j in range(1, N + 1)])  # (2N, n)
        x = reference(t) + np.array([[kick], [0.0]])
        G = mpc.gradient(x, ref)
        before = qps.soft_active_set_solves
        qps.solve(G, x)
        cold.solve(G, x)
        assert qps.constrained == n
        activations += 1
        assert qps.soft_active_set_solves - before == n, k  # every first step answered
        assert np.all(qps.slack == 0.0)  # the limits met
        _assert_soft_answers(qps, cold, x, ref, N, Ts, (lo, hi, vel), tol_kkt, tol, k)
    assert activations == 4


@pytest.mark.parametrize(
    "case",
    ["1 ms, N = 100, started past the position limit",
     "10 ms, N = 50, started past the position limit"],
)  # fmt: skip
def test_positive_slack_activations_are_answered_by_the_shortcut(case):
    """Activations whose limits cannot be met within the horizon (a joint past its position
    limit, most moving further out: the slack is positive at the optimum) are answered by
    the soft active-set shortcut at most steps after their first (from the last step's
    active set; measured: all at Ts = 1 ms, 15 of 18 at Ts = 10 ms), with a solution that
    satisfies the soft QP's KKT conditions (:func:`own_soft_qp`, multipliers by
    non-negative least squares) and equals the soft QP solved from scratch by ProxSuite to
    the solver's tolerance. The first step of such
    an activation may be left to ProxSuite (its optimum is a vertex far from the box-only
    solution's active set); its answer is held to the same conditions. In between, a step
    at rest on a reference at rest (no soft QP), so that each is a new activation."""
    Ts, N, _, (lo, hi, vel) = SOFT_LONG[case]
    n = 3
    mpc, qps, cold = _soft_long_qps(case)
    A_dyn = np.array([[1.0, Ts], [0.0, 1.0]])
    B_dyn = np.array([[Ts * Ts / 2.0], [Ts]])
    tol_kkt, tol = 100.0 * EPS_ABS, solution_tolerance(mpc.H)
    ref = np.zeros((2 * N, n))  # at rest at 0, inside the limits
    # (past the limit [rad], velocity [rad/s]) per joint: upper and lower side, moving out
    starts = (
        (np.array([0.05, 0.02, 0.1]), np.array([0.5, 1.5, 0.0])),
        (np.array([-0.03, -0.08, -0.01]), np.array([-1.0, 0.0, -2.5])),
    )
    answered = positive = 0  # soft QPs after the first steps answered by the shortcut
    for past, speed in starts:
        qps.solve(np.zeros((n, N)), np.zeros((2, n)))  # at rest: no soft QP
        assert qps.constrained == 0
        x = np.vstack([np.where(past > 0, hi, lo) + past, speed])
        for step in range(4):
            G = mpc.gradient(x, ref)
            before = qps.soft_active_set_solves
            qps.solve(G, x)
            cold.solve(G, x)
            assert qps.constrained == n
            if step > 0:
                answered += qps.soft_active_set_solves - before
            _assert_soft_answers(qps, cold, x, ref, N, Ts, (lo, hi, vel), tol_kkt, tol, None)
            positive += int((qps.slack > 1e-6).sum())
            x = A_dyn @ x + B_dyn @ qps.solution[:1]
    assert positive >= n * len(starts)  # the limits could not be met at the first steps
    assert answered >= 2 * n * len(starts), answered  # two thirds of those after the first


@pytest.mark.parametrize("Ts, N, Nc", [(0.01, 50, 20), (0.001, 100, 30)])
def test_soft_limits_with_held_last_input_satisfy_kkt_and_equal_cold_solves(Ts, N, Nc):
    """Nc < N (the last input held over the rest of the horizon, a column of Γ summing
    N − Nc + 1 steps): three joints in a closed loop of the double integrators started
    0.2 rad off a sine whose velocity exceeds the velocity limit; at every step each joint's
    (U, s) satisfies the KKT conditions of the soft-limit QP built here
    (:func:`own_soft_qp`, Γ by simulation) and equals the soft QP solved from scratch by
    ProxSuite, to the solver's tolerance, and the same joints are constrained. The soft
    active-set shortcut answered some (along activations that continue from step to step,
    the box QP is not solved first); measured: 36 of 60 at Ts = 1 ms, 1 of 60 at 10 ms,
    where its exchanges run out and ProxSuite answers."""
    lo, hi, vel, n = -2.0, 2.0, 1.0, 3
    mpc = CondensedMPC(Ts, N, Nc, Q_PAPER, R_PAPER, P_PAPER)
    limits = StateLimits(np.full(n, lo), np.full(n, hi), np.full(n, vel), SOFT["rho2"],
                         SOFT["rho1"])  # fmt: skip
    qps = JointQPs(mpc, -V_LIMIT, V_LIMIT, ("a", "b", "c"), eps_abs=EPS_ABS, limits=limits)
    cold = JointQPs(mpc, -V_LIMIT, V_LIMIT, ("a", "b", "c"), eps_abs=EPS_ABS, limits=limits)
    cold.soft_active_set_iter = -1
    phase, w = np.array([0.0, 1.0, 2.0]), 2.0 * np.pi

    def reference(t):  # r, ṙ of the sine, shape (2, n)
        return np.vstack([0.5 * np.sin(w * t + phase), 0.5 * w * np.cos(w * t + phase)])

    x = reference(0.0) + np.array([[0.2], [0.0]])
    tol_kkt, tol = 100.0 * EPS_ABS, solution_tolerance(mpc.H)
    A_dyn = np.array([[1.0, Ts], [0.0, 1.0]])
    B_dyn = np.array([[Ts * Ts / 2.0], [Ts]])
    soft_steps = 0
    for k in range(20):
        ref = np.vstack([reference((k + j) * Ts) for j in range(1, N + 1)])  # (2N, n)
        G = mpc.gradient(x, ref)
        qps.solve(G, x)
        cold.solve(G, x)
        soft_steps += qps.constrained
        assert qps.constrained == cold.constrained, k  # the same joints leave the limits
        _assert_soft_answers(qps, cold, x, ref, Nc, Ts, (lo, hi, vel), tol_kkt, tol, k)
        x = A_dyn @ x + B_dyn @ qps.solution[:1]
    assert soft_steps >= 5 * n  # the soft limits were active over several steps
    assert qps.soft_active_set_solves > 0  # the shortcut answered


def test_restart_answers_as_new_qps_bit_for_bit():
    """After ``restart`` the QPs answer a closed loop, bit for bit, as new ones do: a run
    past the position limit (ProxSuite and the soft shortcut, slack > 0), a restart, then a
    run off the sine with the velocity limits active, against the same run on new QPs.
    Measured without the restart: the second run 4.6e-6 off the new QPs' (ProxSuite's warm
    starts from the first run's last solutions, each within the solver's tolerance)."""
    case = "10 ms, N = 50, started past the position limit"
    Ts, N, offset, (_, hi, _) = SOFT_LONG[case]
    mpc, used, _ = _soft_long_qps(case)
    _, new, _ = _soft_long_qps(case)
    phase, w = np.array([0.0, 1.0, 2.0]), 2.0 * np.pi
    A_dyn = np.array([[1.0, Ts], [0.0, 1.0]])
    B_dyn = np.array([[Ts * Ts / 2.0], [Ts]])

    def reference(t):  # r, ṙ of the sine, shape (2, n)
        return np.vstack([0.5 * np.sin(w * t + phase), 0.5 * w * np.cos(w * t + phase)])

    def run(qps, x):
        out = []
        for k in range(20):
            ref = np.vstack([reference((k + j) * Ts) for j in range(1, N + 1)])  # (2N, n)
            qps.solve(mpc.gradient(x, ref), x)
            out.append(np.vstack([qps.solution, qps.slack]))
            x = A_dyn @ x + B_dyn @ qps.solution[:1]
        return np.array(out)

    first = run(used, np.array([[hi + 0.05] * 3, [0.0] * 3]))
    assert np.any(first[:, -1] > 1e-6)  # slack > 0: the hard limits were infeasible
    start = reference(0.0) + np.array([[offset], [0.0]])
    used.restart()
    np.testing.assert_array_equal(run(used, start), run(new, start))


@pytest.mark.parametrize(
    "case", ["1 ms, N = 100, velocity limits", "10 ms, N = 50, velocity limits"]
)
def test_stalled_arm_soft_qps_satisfy_kkt_and_are_answered_from_the_held_active_set(case):
    """An arm held still off a moving reference (stalled against something: the same state
    at every step, the sine's velocity beyond the velocity limit): at every step each
    joint's (U, s) satisfies the KKT conditions of the soft-limit QP built here
    (:func:`own_soft_qp`) and equals the soft QP solved from scratch by ProxSuite, to the
    solver's tolerance; every soft QP after the first step is answered by the soft
    active-set shortcut, and its guess shifted along the horizon (a moving arm's) fails at
    most once per joint: after the unshifted one answered, a continued activation tries
    that one first."""
    Ts, N, _, (lo, hi, vel) = SOFT_LONG[case]
    n = 3
    mpc, qps, cold = _soft_long_qps(case)
    phase, w = np.array([0.0, 1.0, 2.0]), 2.0 * np.pi

    def reference(t):  # r, ṙ of the sine, shape (2, n)
        return np.vstack([0.5 * np.sin(w * t + phase), 0.5 * w * np.cos(w * t + phase)])

    x = np.vstack([reference(0.0)[0] + 0.2, np.zeros(n)])  # held here, at rest
    tol_kkt, tol = 100.0 * EPS_ABS, solution_tolerance(mpc.H)
    steps = 12
    for k in range(steps):
        ref = np.vstack([reference((k + j) * Ts) for j in range(1, N + 1)])  # (2N, n)
        G = mpc.gradient(x, ref)
        qps.solve(G, x)
        cold.solve(G, x)
        assert qps.constrained == n, k
        _assert_soft_answers(qps, cold, x, ref, N, Ts, (lo, hi, vel), tol_kkt, tol, k)
    # every soft QP after the first step (measured: all at 1 ms, 35 of 36 at 10 ms)
    assert qps.soft_active_set_solves >= (steps - 1) * n, qps.soft_active_set_solves
    assert qps._core.stats.soft_fail_exchanges <= n, qps._core.stats.soft_fail_exchanges


BOUNDS = {  # options: (soft_step_exchanges, soft_step_work), the step's exchanges at N = 100
    "16 exchanges": (16, -1),
    "20 exchanges": (20, -1),
    "30 exchanges": (30, -1),
    "40 exchanges": (40, -1),
    "work 2000 (20 exchanges)": (-1, 2000),
}


@pytest.mark.parametrize("case", ["closed loop", "held still"])
@pytest.mark.parametrize("bound", list(BOUNDS))
def test_bounded_soft_exchanges_answer_kkt_points_or_the_counted_fallback(bound, case):
    """A bound on the soft shortcut's exchanges per step (``soft_step_exchanges``, or
    ``soft_step_work`` / N): three joints at 1 ms, N = 100 started 0.2 rad off the sine, whose
    velocity (π rad/s) is beyond the velocity limit (1 rad/s: the limits cannot be met at
    once, the slack positive at the optimum), in the closed loop of the double integrators
    or held still. At every step the exchanges stay within the bound, and each joint's
    (U, s) either satisfies the KKT conditions of the soft-limit QP built here
    (:func:`own_soft_qp`) or is the fallback: as many joints fail them as the step counted
    in ``soft_fallbacks``, none went to ProxSuite, each fallback's first input inside the
    box and its next velocity inside the limit when an input in the box can keep it there,
    else braking at the box's bound. Progress: the stages resume where they stopped, so that
    no joint stays in fallback more than 8 steps in a row, fallbacks are at most a sixth of
    the soft QPs, and the other answers are the KKT points (ProxSuite's from scratch to the
    solver's tolerance). Measured (closed loop, 40 steps): fallbacks at steps 1, 4–9, 21, 22
    with 16 exchanges, 1, 6, 21 with 20, 1, 21 with 30; held still, at step 0 only; before
    the stages (the stopped guess's exchanges resumed as they were) every step ended in
    fallbacks with 16 to 30."""
    name = "1 ms, N = 100, velocity limits"
    Ts, N, offset, (lo, hi, vel) = SOFT_LONG[name]
    n = 3
    mpc, qps, cold = _soft_long_qps(name)
    core = qps._core
    assert core.options.soft_step_exchanges < 0  # no bound by default
    assert core.options.soft_step_work < 0
    qps.soft_step_exchanges, qps.soft_step_work = BOUNDS[bound]
    budget = qps.soft_step_exchanges if qps.soft_step_exchanges >= 0 else qps.soft_step_work // N
    phase, w = np.array([0.0, 1.0, 2.0]), 2.0 * np.pi

    def reference(t):  # r, ṙ of the sine, shape (2, n)
        return np.vstack([0.5 * np.sin(w * t + phase), 0.5 * w * np.cos(w * t + phase)])

    x = reference(0.0) + np.array([[offset], [0.0]])
    tol_kkt, tol = 100.0 * EPS_ABS, solution_tolerance(mpc.H)
    A_dyn = np.array([[1.0, Ts], [0.0, 1.0]])
    B_dyn = np.array([[Ts * Ts / 2.0], [Ts]])
    run, longest, soft = np.zeros(n, int), 0, 0
    for k in range(25):
        ref = np.vstack([reference((k + j) * Ts) for j in range(1, N + 1)])  # (2N, n)
        G = mpc.gradient(x, ref)
        before, spent = core.stats.soft_fallbacks, core.stats.soft_exchanges
        qps.solve(G, x)
        soft += qps.constrained
        assert core.stats.soft_exchanges - spent <= budget, k
        fallbacks = core.stats.soft_fallbacks - before
        failed = 0
        for i in range(n):
            z = np.append(qps.solution[:, i], qps.slack[i])
            Hz, gz, A, b = own_soft_qp(x[:, i], ref[:, i], N, N, Ts, lo, hi, vel)
            violation, residual = soft_kkt_residual(Hz, gz, A, b, z, active_tol=1e-7)
            run[i] = run[i] + 1 if violation > 1e-7 or residual > tol_kkt else 0
            if run[i]:
                failed += 1
                u0 = qps.solution[0, i]
                assert -V_LIMIT - 1e-12 <= u0 <= V_LIMIT + 1e-12
                v1, reach = x[1, i] + Ts * u0, x[1, i] + Ts * np.array([-V_LIMIT, V_LIMIT])
                if reach[0] <= vel and reach[1] >= -vel:  # an input keeps |q̇_1| <= vel
                    assert abs(v1) <= vel + 1e-9, (k, i, v1)
                else:  # none does: braking at the box's bound
                    assert u0 == (-V_LIMIT if x[1, i] > 0 else V_LIMIT), (k, i, u0)
        assert failed == fallbacks, (k, failed, fallbacks)
        longest = max(longest, run.max())
        if not fallbacks:
            cold.solve(G, x)
            _assert_soft_answers(qps, cold, x, ref, N, Ts, (lo, hi, vel), tol_kkt, tol, k)
        if case == "closed loop":
            x = A_dyn @ x + B_dyn @ qps.solution[:1]
    assert longest <= 8, longest  # the exact answers reached again
    assert 6 * qps.soft_fallbacks <= soft, (qps.soft_fallbacks, soft)
    assert soft == qps.soft_active_set_solves + qps.soft_fallbacks  # none by ProxSuite
    if budget <= 30 and case == "closed loop":
        assert qps.soft_fallbacks > 0  # the bound bound (at the activation's second step)


@pytest.mark.parametrize("N, Nc", [(10, 1), (10, 5), (50, 50)])
def test_reach_bound_answers_as_the_full_limit_test(planar3, N, Nc):
    """The O(1) reach bound before the soft-limit test (JointQPsOptions.soft_reach_test)
    answers what the full O(N) test answers: on the gradients and states of a closed-loop
    run driven into its soft limits, the per-joint QPs with the bound and without it give
    the same solutions and slacks to the last bit and the same counters; where the bound
    answered for every joint, the box-only prediction X = Φ x0 + Γ U (numpy) is inside the
    limits."""
    ctrl, inputs = recorded_qp_inputs(planar3, N, Nc, 150)
    v_min, v_max = ctrl.settings.bounds(3)
    lim = ctrl.limits
    fast, full = (
        JointQPs(ctrl.mpc, v_min, v_max, planar3.joint_names, limits=lim, layout="joint")
        for _ in range(2)
    )
    full._core.options.soft_reach_test = False
    assert fast._core.options.soft_reach_test
    constrained = all_inside = 0
    for G, x0 in inputs:
        before = fast._core.stats.soft_reach_inside
        fast.solve(G, x0)
        full.solve(G, x0)
        np.testing.assert_array_equal(fast.solution, full.solution)
        np.testing.assert_array_equal(fast.slack, full.slack)
        assert fast.constrained == full.constrained
        constrained += fast.constrained
        if fast._core.stats.soft_reach_inside - before == 3:  # the bound answered every joint
            X = fast.predict(x0, fast.solution)
            assert (X[0::2] > lim.lower).all() and (X[0::2] < lim.upper).all()
            assert (np.abs(X[1::2]) < lim.velocity).all()
            all_inside += 1
    assert full._core.stats.soft_reach_inside == 0
    s, f = fast._core.stats, full._core.stats
    for name in ("soft_active_set_solves", "soft_exchanges", "unconstrained_solves",
                 "active_set_solves", "soft_fallbacks"):  # fmt: skip
        assert getattr(s, name) == getattr(f, name), name
    assert constrained > 0  # the soft QPs were exercised
    # the bound answered (at N = 50 its reach, 50 steps of the inputs, does not tell here:
    # that case checks that it stays silent where it cannot tell)
    assert N > 10 or (s.soft_reach_inside > 0 and all_inside > 0), s.soft_reach_inside
