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

State constraints (joint position and velocity limits, soft). With limits
:math:`\\underline q \\le q_j \\le \\overline q` and :math:`|\\dot q_j| \\le \\overline{\\dot q}`
imposed on the predicted states :math:`x_1 \\dots x_N`, each joint's QP gains one
slack variable :math:`s \\ge 0` shared by all its state constraints,

.. math::

    \\min_{U, s}\\; J(U) + \\rho_2 s^2 + \\rho_1 s \\quad\\text{s.t.}\\quad
    \\underline q - s \\le \\Phi_q x_0 + \\Gamma_q U \\le \\overline q + s,\\;
    -\\overline{\\dot q} - s \\le \\Phi_v x_0 + \\Gamma_v U \\le \\overline{\\dot q} + s,\\;
    v_{\\min} \\le U \\le v_{\\max},

which is always feasible (a large enough :math:`s` satisfies every row). The
linear weight makes the penalty exact: for :math:`\\rho_1` above the constraint
multipliers, the soft QP returns the hard-constrained solution whenever one exists.

Fast path, exact: if the box-only solution :math:`U^\\star` already satisfies every
state constraint, :math:`(U^\\star, 0)` is optimal for the soft QP too (its cost is a
lower bound of the soft QP's), so the constrained QP is solved only for the joints
whose box-only prediction leaves the limits. Along an activation that continues (the soft
QP answered by the shortcut below from the last step's active set, with the slack or a
row's multiplier nonzero), the next step skips the box QP and goes straight to the soft
shortcut: answered with the limits binding, the box-only solution (a different point)
leaves them; answered without, its solution is the box QP's (the joint counts as
unconstrained); not answered, the box QP is solved and the test above decides.

Soft active-set shortcut, exact. The soft QP of a long horizon has :math:`N_c + 1`
variables and :math:`4N` dense rows; ProxSuite needs 1.5–20 ms for one at
:math:`N = N_c = 100` (cold or warm-started: each solve refactorises a KKT matrix of ~200
rows). Its solution's active set moves one step along the horizon per period, so it is
guessed (the last step's soft solution's, shifted one step or as it stands; at a new
activation, the box-only solution's with the rows its prediction violates active, the
inputs next to them freed and the slack at 0) and refined by primal-dual exchanges. An
input next to a violated state is freed because the limits override the box-only
solution's bound there: at a velocity limit the acceleration drops from its bound to 0,
and keeping both the bound and the rows makes them dependent (each such pair cost an
exchange, and the box-only guess exhausted them). Each guess is an equality-constrained
QP, solved in the banded coordinates :math:`U = T p` of :meth:`CondensedMPC.banded`, where
the Hessian :math:`T^T H T` and every constraint row (:math:`\\Gamma T`, :math:`T`) are
banded: the KKT matrix's LDLᵀ costs O(N). A guess answers only when its point passes the
soft QP's KKT conditions to the solver's own tolerances (``eps_abs`` plus ``eps_rel``
times the size of the terms, as ProxSuite tests them: rows and bounds satisfied, zero
gradient of the Lagrangian in the free variables, multipliers of the right sign): then it
is the QP's minimiser. Otherwise ProxSuite solves the QP from scratch. An active row
that depends on those before it in the factorisation's order (its dependency read from
the factor's row) frees the last input at a bound in that dependency (two velocity rows
in a row fix the input between them to 0, so its bound cannot stay), or, with none, is
left out itself; the next exchange tests what left. An exchange that changes the
slack's status (ŝ enters every row) changes it alone. Where the limits cannot be met (slack
> 0, e.g. past a position limit), the first step of an activation (a vertex far from the
box-only solution's active set, where the exchanges overshoot) is usually ProxSuite's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..exceptions import ConfigError, InterfaceError
from ..native import load as load_native

__all__ = [
    "AUTO_BLOCK_MAX",
    "LAYOUTS",
    "CondensedMPC",
    "JointQPs",
    "StateLimits",
    "cold_twin_settings",
    "qp_settings",
    "resolve_layout",
    "solver_settings",
]

#: Stand-in for an infinite row or box bound (finite, so that no inf reaches ProxSuite's
#: residual and infeasibility arithmetic).
BIG = 1e10

#: The QP layouts of :class:`JointQPs` (``controller.qp_layout``).
LAYOUTS = ("auto", "block", "joint")
#: ``"auto"`` solves the joints as one block QP up to this many variables (n·Nc) and as
#: one QP per joint above: 0, so ``"auto"`` is always ``"joint"`` (:func:`resolve_layout`).
AUTO_BLOCK_MAX = 0


def resolve_layout(layout: str, n: int, Nc: int) -> str:
    """The layout used for ``n`` joints of control horizon ``Nc``: ``layout`` itself, or
    for ``"auto"`` ``"block"`` if n·Nc <= :data:`AUTO_BLOCK_MAX` (0: never), else ``"joint"``.

    The choice is measured (``python benchmarks/qp_layouts.py``: n double integrators
    tracking phase-shifted sines at Ts = 10 ms, N = max(10, Nc), the paper's weights,
    |v| <= 100 rad/s²; "bounds active": kicked ±0.6 rad off every 20 steps; soft limits
    ±0.7 rad, 2 rad/s; both layouts on the same gradient and state sequences, alternating
    in 7 blocks of 400 steps; the ratio is the median over blocks of the per-block ratio of
    the medians). The per-joint layout's time over the block layout's, range over n = 2..7:

    ======  ================  ==============  ================  ==============
    Nc      bounds inactive,  bounds active,  bounds inactive,  bounds active,
            no soft limits    no soft limits  soft limits       soft limits
    ======  ================  ==============  ================  ==============
    1       0.32–0.37         0.16–0.23       0.38–0.40         0.57–0.67
    5       0.09–0.18         0.03–0.08       0.12–0.19         0.87–0.94
    20      0.02–0.08         0.01–0.03       0.04–0.10         0.09–0.20
    ======  ================  ==============  ================  ==============

    The per-joint layout is faster at every point: at Nc = 1 its joints whose minimiser
    :math:`-H^{-1}g` lies in the box (and those answered by the active-set shortcut) need
    no solver call, and a ProxSuite call on one joint's QP costs about what one on the
    block QP does; with soft limits both layouts solve the same per-joint soft QPs, which
    then take most of the step. The joints' QPs share no variable and no cost term (Eq 25
    is a sum over joints), so no cost makes the block layout necessary; ``"block"``
    remains a choice (one ProxSuite call per step, no shortcut). Both layouts return the
    same minimiser to the solver's tolerance.

    Raises:
        ConfigError: ``layout`` is not one of :data:`LAYOUTS`.
    """
    if layout not in LAYOUTS:
        raise ConfigError("qp_layout", f"got {layout!r}; expected one of {LAYOUTS}")
    if layout == "auto":
        return "block" if n * Nc <= AUTO_BLOCK_MAX else "joint"
    return layout


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

    def banded(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The condensed QP in banded coordinates: :math:`U = T p`, with

        .. math::

            u_j = p_j - 2 p_{j-1} + p_{j-2}, \\qquad
            E = \\Gamma T, \\qquad H_p = T^T H T = 2 s (E^T \\bar Q E + T^T \\bar R T),

        :math:`s` the cost's :attr:`scale`. :math:`p` is the double prefix sum of the
        inputs; the double integrator's states are then :math:`\\dot q_{j+1} \\propto
        p_j - p_{j-1}` and :math:`q_{j+1} \\propto p_j + p_{j-1}` (plus the free response),
        so every row of :math:`E` is a run of two consecutive columns (three for the states
        after the control horizon, where the last input is held) and :math:`H_p` is
        pentadiagonal. Entries of :math:`E` below 1e-9 of their row's largest (the
        rounding of the exact zeros) are set to zero, so that the bands are exact.

        Returns:
            ``(T, E, Hp)``: (Nc×Nc), (2N×Nc) in the row order of ``Gamma`` (x_1 .. x_N, q and q̇
            interleaved), (Nc×Nc).
        """
        Nc = self.Nc
        T = np.eye(Nc)
        T[np.arange(1, Nc), np.arange(Nc - 1)] = -2.0
        T[np.arange(2, Nc), np.arange(Nc - 2)] = 1.0
        E = self.Gamma @ T
        E[np.abs(E) <= 1e-9 * np.abs(E).max(axis=1, keepdims=True)] = 0.0
        Hp = 2.0 * self.scale * (E.T @ self.Qbar @ E + T.T @ self.Rbar @ T)
        return T, E, 0.5 * (Hp + Hp.T)

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


@dataclass(frozen=True)
class StateLimits:
    """Per-joint state limits imposed on the MPC prediction (soft constraints).

    Attributes:
        lower, upper: Position limits [rad or m], shape (n,); ±inf disables a side.
        velocity: Velocity limit magnitude [rad/s or m/s], shape (n,); inf disables it.
        slack_weight: Quadratic weight :math:`\\rho_2` on the slack [1/rad²], > 0.
        slack_linear_weight: Linear weight :math:`\\rho_1` on the slack [1/rad], >= 0.
    """

    lower: np.ndarray
    upper: np.ndarray
    velocity: np.ndarray
    slack_weight: float = 1e5
    slack_linear_weight: float = 1e4


def qp_settings(warm: bool = True):
    """This package's ProxSuite settings, the compiled core's typed ``QPSettings`` (each
    field a ProxSuite ``Settings`` attribute, set before ``init``; the fields not chosen
    here keep ProxSuite's defaults).

    ``warm=False`` (the soft state-constrained QPs) solves from scratch each time,
    without the duality-gap test.
    """
    core = load_native()
    s = core.QPSettings()
    # Settings must be set before init(): changing initial_guess after
    # init() crashes proxsuite 0.8.0 (segfault, measured here).
    guess = core.InitialGuess
    s.initial_guess = guess.WARM_START_WITH_PREVIOUS_RESULT if warm else guess.NO_INITIAL_GUESS
    # Soft QPs far outside the limits have slacks of 1e6 and more, where an absolute
    # 1e-9 residual is below double precision: add a relative tolerance there.
    s.eps_rel = 0.0 if warm else 1e-12
    s.verbose = False
    # Without the duality-gap test a warm-started solve can stop after 1-3
    # iterations, reporting SOLVED at a feasible point that keeps a stale bound
    # multiplier (measured here: v off by up to 1e-3 for Nc = 1, 1e-2 for Nc = 3).
    s.check_duality_gap = warm
    s.eps_duality_gap_rel = 0.0
    # Every QP here is feasible by construction (box, or soft constraints with a free
    # slack). ProxSuite's default infeasibility tolerance (1e-4) nevertheless declared
    # soft-constrained QPs PRIMAL_INFEASIBLE after 2-3 iterations (measured here).
    s.eps_primal_inf = 1e-12
    s.eps_dual_inf = 1e-12
    return s


def solver_settings(eps_abs: float, max_iter: int, warm: bool = True):
    """:func:`qp_settings` with the tolerance and the iteration cap of the controller."""
    s = qp_settings(warm)
    s.eps_abs = s.eps_duality_gap_abs = eps_abs
    s.max_iter = max_iter
    return s


def cold_twin_settings(eps_abs: float, max_iter: int):
    """The settings of a box QP's cold twin (the compiled QPs' retry after a warm solve that
    did not converge, ``cpp/src/joint_qps.cpp``): solved from
    scratch without the duality-gap test, like the soft QPs, but with no relative tolerance."""
    settings = solver_settings(eps_abs, max_iter, warm=False)
    settings.eps_rel = 0.0
    return settings


class JointQPs:
    """One ProxSuite dense QP per joint, built once and warm-started (Eq 26).

    Each joint has a box-constrained QP over its inputs. With ``limits`` it also
    has a soft state-constrained QP (module docstring), solved only when the
    box-only solution's prediction leaves the limits (an exact fast path).

    Args:
        mpc: The condensed QP data shared by all joints.
        v_min, v_max: Bounds on each joint's commanded acceleration [rad/s²], shape (n,).
        joint_names: For error messages.
        eps_abs: ProxSuite absolute tolerance.
        max_iter: ProxSuite iteration cap (the solver never runs unbounded).
        limits: Position and velocity limits as soft state constraints; ``None`` for none.
        layout: ``"auto"`` (default): ``"joint"``, measured faster for every n and Nc
            (:func:`resolve_layout`, :data:`AUTO_BLOCK_MAX`); ``"block"``: the n joint
            QPs as one block-diagonal ProxSuite QP of n·Nc variables, one ``update`` +
            ``solve`` per step; ``"joint"``: one QP per joint (n calls; a joint whose
            unconstrained minimiser :math:`-H^{-1}g` lies inside its box takes it without a
            solver call — the solution of a convex QP whose constraints are inactive; failing
            that, the active-set shortcut: the last solution's active set, shifted one step
            along the horizon or as it stands, refined by up to :attr:`active_set_iter`
            exchanges, then the bounds :math:`-H^{-1}g` crosses with four times as many,
            whose point answers only when it passes the box QP's KKT test to ``eps_abs`` —
            free inputs inside the box with zero gradient, multipliers of the fixed ones of
            the right sign, so the QP's minimiser). All have the same minimiser (the blocks
            are independent). The block QP's cost grows with
            (n·Nc)³, the joint QPs' with n·Nc³, and the per-joint shortcuts skip the solver
            for most joints: the joint QPs take 0.01–0.4× the block QP's time without soft
            limits (:func:`resolve_layout`). ProxSuite's batch API (``proxqp.dense.BatchQP``, one
            QP per joint, n ``update`` calls and one ``solve_in_parallel``) was measured too
            (``benchmarks/qp_layouts.py``) and is not offered: slower than the block QP for
            short horizons, e.g. Nc = 1, 3 joints 10.4 µs vs 5.7 µs; 7 joints 22.8 µs on 1
            thread, 16.9 µs on 2, vs 6.9 µs, and ≈ 8 ms whenever its second OpenMP thread
            waits for a busy core.
        stack_rows: Ignored (the controller's step keeps its own memory); accepted so that
            callers passing it keep working.
        always_constrained: Solve the soft QP for every joint at every step instead of
            only where the box-only prediction leaves the limits (the reference path
            that the fast path is tested against).

    Attributes:
        solution: The optimal input sequences of the last :meth:`solve` (Nc×n) [rad/s²]: a
            read-only view of the compiled QPs' own memory, updated in place.
        slack: The slack of each joint at the last solve (n,) [rad]; 0 where the
            state constraints were inactive (a read-only view, like :attr:`solution`).
        constrained: Number of joints whose constrained QP was solved at the last step.
        cold_solves: Number of box QPs solved again from scratch because the warm-started
            solve did not converge (the cold twin, ``cpp/src/joint_qps.cpp``), since construction.
        unconstrained_solves: ``"joint"`` layout: joint QPs not sent to ProxSuite because
            the unconstrained minimiser :math:`-H^{-1}g` lay inside the box (then it is the
            box QP's solution, exactly), since construction.
        active_set_solves: ``"joint"`` layout: joint QPs answered by the active-set shortcut.
        layout: The layout in use (``"block"`` or ``"joint"``; ``"auto"`` resolved).
        x0: The state (2, n) (rows q, q̇) the last :meth:`solve` was given; :meth:`solve`
            copies its ``x0`` argument there unless it is this very object.
    """

    def __init__(
        self,
        mpc: CondensedMPC,
        v_min: np.ndarray,
        v_max: np.ndarray,
        joint_names: tuple[str, ...],
        eps_abs: float = 1e-9,
        max_iter: int = 1000,
        limits: StateLimits | None = None,
        always_constrained: bool = False,
        layout: str = "auto",
        stack_rows: int = 0,
    ):
        del stack_rows  # accepted, unused (see Args)
        self.mpc = mpc
        self.layout = layout = resolve_layout(layout, len(joint_names), mpc.Nc)
        self.always_constrained = always_constrained
        self.joint_names = joint_names
        self.n = n = len(joint_names)
        self.limits = limits
        Nc, N = mpc.Nc, mpc.N
        v_min = np.broadcast_to(np.asarray(v_min, dtype=float), (n,)).astype(float)
        v_max = np.broadcast_to(np.asarray(v_max, dtype=float), (n,)).astype(float)
        bad = np.flatnonzero(~(v_min <= v_max))
        if bad.size:
            i = int(bad[0])
            raise ConfigError(
                "controller.v_min",
                f"joint {joint_names[i]!r}: v_min = {v_min[i]:g} > v_max = {v_max[i]:g} "
                "[rad/s²]; expected v_min <= v_max for every joint",
            )
        self._eps_abs, self._max_iter = eps_abs, max_iter
        self.v_min, self.v_max = v_min, v_max
        self.x0 = np.zeros((2, n))
        # The compiled QPs (cpp/src/joint_qps.cpp), which own their solution and slack.
        self._core = load_native().JointQPs(
            n,
            N,
            Nc,
            layout == "block",
            mpc.H,
            v_min,
            v_max,
            solver_settings(eps_abs, max_iter),
            cold_twin_settings(eps_abs, max_iter),
        )
        self.solution = self._core.solution  # read-only views, solved into place
        self.slack = self._core.slack
        self._core.joint_names = list(joint_names)  # its faults name the joint
        self.soft_qps = False
        if limits is None:
            return

        def vec(x):
            return np.clip(np.broadcast_to(np.asarray(x, float), (n,)), -BIG, BIG)

        lower, upper, vel = vec(limits.lower), vec(limits.upper), vec(limits.velocity)
        Gq, Gv = mpc.Gamma[0::2], mpc.Gamma[1::2]
        # The slack enters the solver scaled, s = k·ŝ, so that its Hessian entry is 1
        # like the inputs' (unscaled, 2ρ₂·scale ~ 1e7 stalls ProxSuite's duality-gap test).
        k = 1.0 / np.sqrt(2.0 * limits.slack_weight * mpc.scale)
        one = np.full((N, 1), k)
        C = np.vstack(
            [
                np.hstack([Gq, -one]),
                np.hstack([Gq, one]),
                np.hstack([Gv, -one]),
                np.hstack([Gv, one]),
            ]
        )
        # Rows normalised to unit norm, the soft QPs solved cold and without the
        # duality-gap test: measured on 36 000 random near-limit states (Nc = 1..10),
        # the only combination for which ProxSuite 0.8.0 solved every one; warm starts or
        # unscaled rows stalled (MAX_ITER) or reported PRIMAL_INFEASIBLE within 500.
        row_scale = 1.0 / np.linalg.norm(C, axis=1)
        C = C * row_scale[:, None]
        Hs = np.zeros((Nc + 1, Nc + 1))
        Hs[:Nc, :Nc] = mpc.H
        Hs[Nc, Nc] = 1.0
        g_slack = limits.slack_linear_weight * mpc.scale * k
        self._core.set_limits(
            mpc.Phi,
            mpc.Gamma,
            lower,
            upper,
            vel,
            Hs,
            C,
            row_scale,
            g_slack,
            k,
            solver_settings(eps_abs, max_iter, warm=False),
            always_constrained,
            *mpc.banded(),
        )
        self.soft_qps = True

    @property
    def cold_solves(self) -> int:
        """Box QPs solved again from scratch after a warm solve that did not converge."""
        return int(self._core.stats.cold_solves)

    @property
    def unconstrained_solves(self) -> int:
        """``"joint"`` layout: joint QPs answered by the unconstrained minimiser."""
        return int(self._core.stats.unconstrained_solves)

    @property
    def active_set_solves(self) -> int:
        """``"joint"`` layout: joint QPs answered by the active-set shortcut (a guessed active
        set whose point passed the box QP's KKT test), since construction."""
        return int(self._core.stats.active_set_solves)

    @property
    def constrained(self) -> int:
        """Joints whose soft-constrained QP was solved at the last step."""
        return int(self._core.stats.constrained)

    @property
    def constrained_last(self) -> bool:
        """Whether any joint's soft QP was solved at the last step."""
        return bool(self._core.stats.constrained_last)

    def restart(self) -> None:
        """Start a new run: every QP as new (no warm start from the last solutions, no
        remembered active set of the shortcuts), the slack 0. The next solves give, bit for
        bit, the answers of a new :class:`JointQPs` (its counters go on)."""
        self._core.restart()

    @property
    def max_iter(self) -> int:
        """ProxSuite's iteration cap per solve; setting it applies to every QP."""
        return self._max_iter

    @max_iter.setter
    def max_iter(self, value: int) -> None:
        self._max_iter = int(value)
        self._core.set_max_iter(self._max_iter)

    @property
    def shortcut(self) -> bool:
        """``"joint"`` layout: the exact unconstrained shortcut (on by default)."""
        return bool(self._core.options.shortcut)

    @shortcut.setter
    def shortcut(self, on: bool) -> None:
        self._core.options.shortcut = bool(on)

    @property
    def active_set_iter(self) -> int:
        """``"joint"`` layout: active-set exchanges the active-set shortcut may make after its
        guess (default 4; negative: no active-set shortcut, ProxSuite for every active box)."""
        return int(self._core.options.active_set_iter)

    @active_set_iter.setter
    def active_set_iter(self, k: int) -> None:
        self._core.options.active_set_iter = int(k)

    @property
    def soft_active_set_iter(self) -> int:
        """Soft QPs: primal-dual exchanges the soft active-set shortcut may make per guess
        (module docstring; default 8; negative: ProxSuite solves every soft QP)."""
        return int(self._core.options.soft_active_set_iter)

    @soft_active_set_iter.setter
    def soft_active_set_iter(self, k: int) -> None:
        self._core.options.soft_active_set_iter = int(k)

    @property
    def soft_step_exchanges(self) -> int:
        """Soft QPs: the exchanges the soft active-set shortcut may make per step over all
        joints (default −1: ``soft_step_work``'s). They are spread over the joints whose
        soft QP the step solves: each gets the exchanges left divided by the joints left
        (rounded up), so that one joint's long activation cannot starve the others. A joint
        reached with none left (or whose guess ran out of its own exchanges) answers the
        fallback, its box-only answer with its first input clipped to the accelerations
        that keep the next state inside the limits (the velocity limit's alone when both
        cannot hold), then to the box (the box's end nearest them when none in it keeps
        them), counted in ``soft_fallbacks``; its exchanges resume where they stopped at the
        next step, so that the soft QP's own answer follows within a few steps. Under a
        bound the shortcut's guesses are stages, each with its own exchanges, spread over
        steps; ProxSuite answers only a joint whose every guess failed within the step's
        exchanges."""
        return int(self._core.options.soft_step_exchanges)

    @soft_step_exchanges.setter
    def soft_step_exchanges(self, k: int) -> None:
        self._core.options.soft_step_exchanges = int(k)

    @property
    def soft_step_work(self) -> int:
        """Soft QPs: the step's work when ``soft_step_exchanges`` is negative, in exchanges
        × horizon steps (an exchange costs O(N)): at most max(1, soft_step_work // N)
        exchanges per step (negative: no bound)."""
        return int(self._core.options.soft_step_work)

    @soft_step_work.setter
    def soft_step_work(self, w: int) -> None:
        self._core.options.soft_step_work = int(w)

    @property
    def soft_fallbacks(self) -> int:
        """Soft QPs answered by the fallback (``soft_step_exchanges`` spent), since
        construction."""
        return int(self._core.stats.soft_fallbacks)

    @property
    def soft_active_set_solves(self) -> int:
        """Soft QPs answered by the soft active-set shortcut (a guessed active set whose
        point passed the soft QP's KKT test), since construction."""
        return int(self._core.stats.soft_active_set_solves)

    @property
    def shift(self) -> bool:
        """Whether ProxSuite's warm start is the last primal and dual solution shifted one
        step along the horizon (default off: the last solution as it stands, measured faster
        in a closed loop; ``benchmarks/studies/long_horizon_active.py``)."""
        return bool(self._core.options.shift)

    @shift.setter
    def shift(self, on: bool) -> None:
        self._core.options.shift = bool(on)

    def predict(self, x0: np.ndarray, U: np.ndarray) -> np.ndarray:
        """Predicted states ``X = Φ x0 + Γ U`` of all joints, shape (2N, n): rows q_1, q̇_1, …

        Args:
            x0: States (2, n). U: Input sequences (Nc, n).
        """
        return self.mpc.Phi @ x0 + self.mpc.Gamma @ U

    def solve(self, G: np.ndarray, x0: np.ndarray | None = None) -> np.ndarray:
        """Solve every joint's QP for the gradients ``G`` (n×Nc); return the first inputs (n,).

        The compiled QPs (``cpp/src/joint_qps.cpp``): the layout's box QPs (with the exact
        unconstrained shortcut per joint and the cold retry), then, with limits, the soft
        QPs of the joints whose box-only prediction leaves them. :attr:`solution` and
        :attr:`slack` are written in place.

        Args:
            G: Scaled gradients from :meth:`CondensedMPC.gradient`, shape (n, Nc).
            x0: Current states (2, n) (rows q, q̇); required when limits are set.

        Raises:
            SolverError: A QP did not report ``PROXQP_SOLVED`` (names joint and status).
        """
        if x0 is None:
            if self.soft_qps:
                raise InterfaceError(
                    x0,
                    "the current states x0, shape (2, n)",
                    "JointQPs.solve needs them when limits are set",
                )
        elif x0 is not self.x0:
            self.x0[:] = x0
        G = np.ascontiguousarray(G, dtype=float)
        if G.shape != (self.n, self.mpc.Nc):
            raise InterfaceError(
                G,
                f"gradients of shape ({self.n}, {self.mpc.Nc})",
                "pass one row of Nc values per joint",
            )
        self._core.solve(G, self.x0[0], self.x0[1])
        return self.solution[0].copy()
