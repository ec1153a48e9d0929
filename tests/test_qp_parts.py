"""The joint QPs' parts, each alone against its numpy oracle (tests/reference/qp_parts.py).

``hmpc_pin._core`` binds each part of the compiled joint QPs minimally (BoxQP, BoxActiveSet,
GammaRecursion, BandedKKT); JointQPs composes them and is tested whole in test_joint_mpc.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from hmpc_pin.mpc.condensed import CondensedMPC, cold_twin_settings, solver_settings
from hmpc_pin.native import load as load_native
from tests.reference import qp_parts

core = load_native()
EPS = 1e-9  # the solvers' absolute tolerance


def _mpc(N: int = 12, Nc: int = 5) -> CondensedMPC:
    return CondensedMPC(0.002, N, Nc, np.diag([4e3, 1.0]), 1e-3, np.diag([4e3, 1.0]))


def _gradients(mpc: CondensedMPC, count: int, seed: int) -> list[np.ndarray]:
    """Gradients whose unconstrained minimisers reach a few times the box [−1, 1]."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(count):
        u0 = rng.normal(0.0, 2.0, mpc.Nc)
        out.append(-mpc.H @ u0)
    return out


def test_box_active_set_answers_the_box_qp_of_the_oracle():
    mpc = _mpc()
    H, lo, hi = mpc.H, -1.0, 1.0
    part = core.BoxActiveSet(H)
    answered = 0
    for g in _gradients(mpc, 200, seed=1):
        np.testing.assert_allclose(part.unconstrained(g), -np.linalg.solve(H, g), rtol=1e-9)
        u, z = qp_parts.box_qp(H, g, lo, hi)
        for last in (u, np.zeros_like(u), np.roll(u, 1)):  # exact, far, shifted guesses
            got = part.solve(g, lo, hi, last, 4, EPS)
            if got is None:
                continue  # no answer: JointQPs then asks ProxSuite
            answered += 1
            scale = 1.0 + np.abs(g).max()
            np.testing.assert_allclose(got[0], u, atol=1e-8)
            np.testing.assert_allclose(got[1], z, atol=1e-8 * scale)
    assert answered >= 0.9 * 600, f"the shortcut answered {answered} of 600"


def test_box_active_set_without_exchanges_answers_nothing():
    mpc = _mpc()
    g = _gradients(mpc, 1, seed=2)[0]
    assert core.BoxActiveSet(mpc.H).solve(g, -1.0, 1.0, np.zeros(mpc.Nc), -1, EPS) is None


def test_box_qp_warm_and_cold_twin_solve_the_oracle_qp():
    mpc = _mpc()
    H, Nc = mpc.H, mpc.Nc
    lo, hi = np.full(Nc, -1.0), np.full(Nc, 1.0)
    warm, cold = solver_settings(EPS, 1000), cold_twin_settings(EPS, 1000)
    box = core.BoxQP(H, lo, hi, warm, cold)
    for shift in (0, Nc):
        for g in _gradients(mpc, 20, seed=3):
            x, used_cold = box.solve(g, shift)
            assert not used_cold
            np.testing.assert_allclose(x, qp_parts.box_qp(H, g, -1.0, 1.0)[0], atol=1e-6)
    # A warm QP capped at one iteration does not converge: its cold twin answers.
    capped = solver_settings(EPS, 1)
    box = core.BoxQP(H, lo, hi, capped, cold)
    g = _gradients(mpc, 1, seed=4)[0] * 50.0
    x, used_cold = box.solve(g)
    assert used_cold
    np.testing.assert_allclose(x, qp_parts.box_qp(H, g, -1.0, 1.0)[0], atol=1e-6)
    # Both capped: no answer.
    assert core.BoxQP(H, lo, hi, capped, cold_twin_settings(EPS, 1)).solve(g) is None


def test_gamma_recursion_is_the_dense_product():
    mpc = _mpc(N=30, Nc=7)
    rng = np.random.default_rng(5)
    rec = core.GammaRecursion(mpc.Phi, mpc.Gamma)
    assert rec.recursion
    for _ in range(10):
        u, lam = rng.normal(size=mpc.Nc), rng.normal(size=2 * mpc.N)
        X, dense = rec.apply(u), mpc.Gamma @ u
        np.testing.assert_allclose(X, dense, rtol=0, atol=1e-12 * np.abs(dense).max())
        out, dense_t = rec.apply_transpose(lam), mpc.Gamma.T @ lam
        np.testing.assert_allclose(out, dense_t, rtol=0, atol=1e-12 * np.abs(dense_t).max())
    # A Γ that is not the recursion keeps the dense products.
    other = mpc.Gamma.copy()
    other[5, 2] += 1e-3 * np.abs(other[5]).max()
    rec = core.GammaRecursion(mpc.Phi, other)
    assert not rec.recursion
    u = rng.normal(size=mpc.Nc)
    np.testing.assert_allclose(rec.apply(u), other @ u, rtol=1e-13)


def _kkt(mpc: CondensedMPC):
    """The KKT solver over the soft QP's data as hmpc_pin.mpc.condensed.JointQPs makes it."""
    N = mpc.N
    k = 1.0 / np.sqrt(2.0 * 1e5 * mpc.scale)
    Gq, Gv = mpc.Gamma[0::2], mpc.Gamma[1::2]
    one = np.full((N, 1), k)
    C = np.vstack([np.hstack([G, s * one]) for G in (Gq, Gv) for s in (-1.0, 1.0)])
    row_scale = 1.0 / np.linalg.norm(C, axis=1)
    T, E, Hp = mpc.banded()
    part = core.BandedKKT(mpc.Phi, mpc.Gamma, T, E, Hp, mpc.H, row_scale, k, 1.0, EPS)
    return part, k


@pytest.mark.parametrize("slack", [0, 1])
def test_banded_kkt_solves_the_dense_kkt_system(slack):
    mpc = _mpc(N=20, Nc=8)
    N, Nc = mpc.N, mpc.Nc
    part, k = _kkt(mpc)
    rng = np.random.default_rng(6 + slack)
    for trial in range(20):
        rows, box = np.zeros(2 * N, int), np.zeros(Nc, int)
        # a few q rows late in the horizon and a bound early: independent constraints
        for r in rng.choice(np.arange(2 * (Nc + 1), 2 * N, 2), size=2, replace=False):
            rows[r] = rng.choice([-1, 1])
        box[rng.integers(0, 2)] = rng.choice([-1, 1])
        g = rng.normal(size=Nc + 1) * 10.0
        bnd_lo, bnd_hi = -rng.uniform(0.01, 0.1, 2 * N), rng.uniform(0.01, 0.1, 2 * N)
        out = part.solve(list(rows), list(box), slack, g, -1.0, 1.0, bnd_lo, bnd_hi)
        assert out["ok"] and not out["dropped"], trial
        y, lam, mu = qp_parts.soft_subproblem(
            mpc.H, mpc.Gamma, k, 1.0, g, rows, box, slack, -1.0, 1.0, bnd_lo, bnd_hi
        )
        np.testing.assert_allclose(out["y"], y, rtol=1e-7, atol=1e-9 * np.abs(y).max())
        np.testing.assert_allclose(out["lam"], lam, rtol=1e-6, atol=1e-9 * np.abs(lam).max())
        np.testing.assert_allclose(out["mu"], mu, rtol=1e-6, atol=1e-9 * (np.abs(mu).max() + 1))


def test_banded_kkt_drops_a_bound_its_rows_already_fix():
    """u_a at its bound between two active velocity rows (of x_a and x_{a+1}, which fix u_a)
    is dependent on them: the solve declines and frees the bound."""
    mpc = _mpc(N=20, Nc=8)
    N, Nc = mpc.N, mpc.Nc
    part, _ = _kkt(mpc)
    a = 3
    rows, box = np.zeros(2 * N, int), np.zeros(Nc, int)
    rows[2 * (a - 1) + 1] = rows[2 * a + 1] = 1  # q̇_a and q̇_{a+1} at their upper limits
    box[a] = 1
    bnd = np.full(2 * N, 0.05)
    out = part.solve(list(rows), list(box), 0, np.ones(Nc + 1), -1.0, 1.0, -bnd, bnd)
    assert not out["ok"] and out["dropped"]
    assert out["box"][a] == 0 and out["rows"] == list(rows)
    # solved again without it: the dense oracle's answer
    out = part.solve(out["rows"], out["box"], 0, np.ones(Nc + 1), -1.0, 1.0, -bnd, bnd)
    assert out["ok"]
    box[a] = 0
    y, _, _ = qp_parts.soft_subproblem(
        mpc.H, mpc.Gamma, _kkt(mpc)[1], 1.0, np.ones(Nc + 1), rows, box, 0, -1.0, 1.0, -bnd, bnd
    )
    np.testing.assert_allclose(out["y"], y, rtol=1e-7, atol=1e-9 * np.abs(y).max())


def test_the_parts_reject_arrays_of_the_wrong_size():
    mpc = _mpc()
    with pytest.raises(ValueError, match="g and last"):
        core.BoxActiveSet(mpc.H).solve(np.zeros(2), -1.0, 1.0, np.zeros(2), 4, EPS)
    with pytest.raises(ValueError, match="u of Nc"):
        core.GammaRecursion(mpc.Phi, mpc.Gamma).apply(np.zeros(mpc.Nc + 1))
    part, _ = _kkt(mpc)
    with pytest.raises(ValueError, match="expected rows"):
        part.solve([0], [0] * mpc.Nc, 0, np.zeros(mpc.Nc + 1), -1.0, 1.0, np.zeros(1), np.zeros(1))


def test_joint_qps_knobs_and_counters_are_typed_fields():
    """JointQPs' Options and Stats cross to Python field by field (ProxSuite's Settings and
    Info): the wrapper's properties read and write them, a copy is independent, and the
    counters count what the solves did."""
    import copy

    from hmpc_pin.mpc.condensed import JointQPs

    mpc = _mpc()
    qps = JointQPs(mpc, -np.ones(2), np.ones(2), ("a", "b"), layout="joint")
    core_qps = qps._core
    assert isinstance(core_qps.options, core.JointQPsOptions)
    qps.shift, qps.active_set_iter = True, 7
    assert core_qps.options.shift and core_qps.options.active_set_iter == 7
    core_qps.options.shortcut = False  # live
    assert not qps.shortcut
    options = core.JointQPsOptions()
    options.soft_active_set_iter = 3
    core_qps.options = options
    assert qps.soft_active_set_iter == 3 and not qps.shift  # all fields replaced
    qps.shortcut = True
    before = copy.copy(core_qps.stats)
    inside = np.zeros((2, mpc.Nc))  # u0 = 0: inside the box, the unconstrained answer
    outside = np.vstack([_gradients(mpc, 1, seed=8)[0] * 5.0] * 2)
    qps.solve(inside)
    qps.solve(outside)
    stats = core_qps.stats
    assert stats.unconstrained_solves == before.unconstrained_solves + 2 == qps.unconstrained_solves
    assert stats != before
    assert before == core.JointQPsStats()  # the copy kept its values
    core_qps.stats = before  # restored (as warm_up does)
    assert qps.unconstrained_solves == 0
