"""Peers: the package's joint QPs against CasADi's QP solvers on the identical problem, and
the controller's step against a Crocoddyl Box-FDDP NMPC's, timed in one process.

**QP solvers through CasADi.** The per-joint MPC's box-constrained QP of Eq (26), built
from the package's own condensed matrices (:class:`hmpc_pin.mpc.condensed.CondensedMPC`:
the scaled Hessian :math:`H`, the gradients :math:`g_i = F [x_{0,i}; \\bar r_i]` of every
joint, the bounds :math:`v_{\\min} \\le U_i \\le v_{\\max}`),

.. math::

    \\min_{U_i}\\ \\tfrac12 U_i^T H U_i + g_i^T U_i
    \\quad\\text{s.t.}\\quad v_{\\min} \\le U_i \\le v_{\\max},\\qquad i = 1..n,

is solved along one recorded gradient sequence by the package
(:class:`hmpc_pin.mpc.condensed.JointQPs`, the compiled QPs of the controller's step) and
by ``casadi.conic`` with ``qpoases``, ``osqp``, ``proxqp`` and ``daqp`` (the package: one QP
per joint, :func:`hmpc_pin.mpc.condensed.resolve_layout`; the peers: one block-diagonal QP
of n·Nc variables up to :data:`PEER_BLOCK_MAX`, one QP per joint above,
:func:`peer_layout`), warm-started where the
plugin allows (``x0``, ``lam_x0`` from the previous solution). The gradient sequence comes
from a closed loop of the feedback-linearised arm (:math:`\\ddot q = v`, Eq 24 exactly)
tracking the benchmark's sine around the arm's home pose, the state kicked
:math:`\\pm` ``KICK`` rad off the reference every ``kick_every`` steps, so that the
acceleration bounds are active in part of the steps (the table gives the share).

Before any timing, every solution of every solver is checked along the whole sequence:
its distance to the package's solution, :math:`\\max |U_{\\text{peer}} - U|` [rad/s²], must
be at most :data:`TOLERANCE`, and the torque it makes, :math:`\\max |M(q)\\,\\Delta v_0|`
[N·m], is reported; both solutions' box-QP optimality residuals
(:func:`box_qp_residual`) are reported beside. A peer that solves another problem
stops the program (exit 1).

Timing: the package and each peer replay the sequence in alternating blocks (A, B, C, …,
A, B, C, …), each call timed with ``perf_counter_ns``; per block the median call, and the
figure is the median over blocks of (peer / package) beside the medians of the absolute
block medians. A CasADi ``Function`` that only returns its inputs, called the same way, is
timed too: the cost of a call through CasADi's Python interface.

**The whole step.** The package's step without observer, joint dynamics and state limits
against :class:`CasadiStep`, the same step written in Python around CasADi's QP, on the
states of the same closed loops; every torque checked (:func:`step_peers`) before the
alternating blocks.

**Crocoddyl** (``benchmarks/crocoddyl_mpc.py``): the controller's ``step`` and
:class:`~benchmarks.crocoddyl_mpc.CrocoddylMPC`'s on the states of the hierarchical MPC's
closed-loop run of the comparison scenario (``benchmarks/comparisons.py``), alternating
blocks, each controller reset and warmed up at the start of its block.

Run from the repository root: ``python benchmarks/peers.py [--quick] [--blocks 5]``;
prints Markdown tables. CasADi and Crocoddyl are in the ``bench`` extra
(``pip install -e ".[bench]"``); without them their part is skipped with a message.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pinocchio as pin

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import hmpc_pin  # noqa: E402
from benchmarks import crocoddyl_mpc  # noqa: E402
from benchmarks._fixtures import HOMES, PANDA_LOCKED, Arm, Settings, load_arm, log  # noqa: E402
from benchmarks.comparisons import (  # noqa: E402
    CompareRow,
    Scenario,
    bench_compare,
    panda_scenario,
    planar3_scenario,
)
from hmpc_pin.compensation.base import NoCompensation  # noqa: E402
from hmpc_pin.controllers.hierarchical import HierarchicalMPC, MPCSettings  # noqa: E402
from hmpc_pin.mpc.condensed import CondensedMPC, JointQPs, resolve_layout  # noqa: E402
from hmpc_pin.tasks import sample_horizon  # noqa: E402

try:
    import casadi
except ImportError:  # optional dependency (extra "bench"): the CasADi part is skipped
    casadi = None

__all__ = [
    "AVAILABLE",
    "KICK",
    "PEER_BLOCK_MAX",
    "PLUGINS",
    "SCENARIOS",
    "TOLERANCE",
    "CasadiQPs",
    "CasadiStep",
    "CrocoddylRow",
    "OtherLayout",
    "PeerCase",
    "QPProblem",
    "QPScenario",
    "StepCase",
    "box_qp_residual",
    "check_peer",
    "crocoddyl_rows",
    "crocoddyl_steps",
    "crocoddyl_table",
    "main",
    "peer_layout",
    "qp_peers",
    "qp_table",
    "record_problem",
    "step_peers",
    "step_table",
]

#: Whether ``casadi`` is importable.
AVAILABLE = casadi is not None
#: The extra that installs CasADi and Crocoddyl.
EXTRA_MESSAGE = (
    "needs the optional packages of the extra 'bench' (casadi, crocoddyl), not installed "
    'here; install them with: pip install -e ".[bench]"'
)
#: Largest distance allowed between a peer's solution and the package's [rad/s²]: a tenth
#: of a µrad/s², i.e. 1e-7 N·m of torque per kg·m² of joint inertia.
TOLERANCE = 1e-7
#: The kick of the closed loop away from the reference [rad].
KICK = 0.5

#: The CasADi plugins and their options: every solver at a tolerance that meets
#: :data:`TOLERANCE`, failures raised (``error_on_fail``).
PLUGINS: dict[str, dict] = {
    # active set; CasADi's interface re-initialises qpOASES at every call (the iterations
    # of a repeated identical QP do not fall), so there is no warm start to give it
    "qpoases": {"printLevel": "none", "error_on_fail": True},
    # ADMM, warm-started from x0, lam_x0; polished (the active set's exact solution; with
    # OSQP's default 3 refinement steps its solutions stayed 2e-5 rad/s² off on Panda, Nc = 5)
    "osqp": {"osqp": {"eps_abs": 1e-10, "eps_rel": 1e-10, "polish": True, "polish_refine_iter": 10,
                      "verbose": False, "max_iter": 100000},
             "warm_start_primal": True, "warm_start_dual": True, "error_on_fail": True},
    # the ProxSuite solver the package uses, through CasADi, warm-started from x0, lam_x0;
    # eps_abs per layout (proxqp_eps)
    "proxqp": {"proxqp": {"eps_rel": 0.0, "max_iter": 10000},
               "warm_start_primal": True, "warm_start_dual": True, "error_on_fail": True},
    # dual active set; CasADi's plugin documents no warm start
    "daqp": {"error_on_fail": True},
}  # fmt: skip


def proxqp_eps(layout: str) -> float:
    """ProxQP's ``eps_abs`` through CasADi: the loosest that meets :data:`TOLERANCE`.

    Measured on the scenarios below: at 1e-9 its solutions stopped up to 1.3e-5 rad/s²
    inside an active bound (Panda, block layout; its residuals are those of its
    preconditioned problem), at 1e-11 up to 1.05e-7; 1e-12 meets the tolerance there, but on
    the 100-variable joint QPs it fails (CasADi: "conic process failed"), where 1e-11 meets it.
    """
    return 1e-12 if layout == "block" else 1e-11


def plugin_options(plugin: str, layout: str) -> dict:
    """The options of ``plugin`` (:data:`PLUGINS`) for the QPs of ``layout``."""
    opts = dict(PLUGINS[plugin])
    if plugin == "proxqp":
        opts["proxqp"] = dict(opts["proxqp"], eps_abs=proxqp_eps(layout))
    return opts


@dataclass(frozen=True)
class QPScenario:
    """One arm and MPC setting of the QP comparison.

    Attributes:
        arm: ``"planar3"`` or ``"panda"``. label: The setting, in words.
        Ts: Control period [s]. N, Nc: Prediction and control horizons [steps].
        steps: Length of the recorded gradient sequence (the steps of one block).
        kick_every: Steps between two kicks of the closed loop off the reference.
    """

    arm: str
    label: str
    Ts: float
    N: int
    Nc: int
    steps: int
    kick_every: int


#: The paper's setting (Ts = 10 ms, N = 10, Nc = 1), N = 10 with Nc = 5, and a long horizon
#: (Ts = 1 ms, N = Nc = 100), on planar3 and Panda.
SCENARIOS = (
    QPScenario("planar3", "paper: Ts = 10 ms, N = 10, Nc = 1", 0.01, 10, 1, 200, 20),
    QPScenario("panda", "paper: Ts = 10 ms, N = 10, Nc = 1", 0.01, 10, 1, 200, 20),
    QPScenario("panda", "Ts = 10 ms, N = 10, Nc = 5", 0.01, 10, 5, 200, 20),
    QPScenario("planar3", "long: Ts = 1 ms, N = Nc = 100", 0.001, 100, 100, 40, 20),
    QPScenario("panda", "long: Ts = 1 ms, N = Nc = 100", 0.001, 100, 100, 40, 20),
)


@dataclass
class QPProblem:
    """A recorded sequence of the joint QPs and the package's solver of them.

    Attributes:
        scenario: Its setting. mpc: The condensed matrices. v_min, v_max: Bounds (n,).
        G: Gradients, shape (steps, n, Nc). q, dq: The closed loop's states (steps, n).
        M: The arm's mass matrix at each q, shape (steps, n, n) [kg·m²].
        qps: The package's QPs (:class:`JointQPs`, layout ``"auto"``).
        layout: The resolved layout. active: Share of the steps with a bound active.
    """

    scenario: QPScenario
    mpc: CondensedMPC
    v_min: np.ndarray
    v_max: np.ndarray
    G: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    M: np.ndarray
    qps: JointQPs
    layout: str
    active: float = 0.0

    @property
    def n(self) -> int:
        """Number of joints."""
        return int(self.G.shape[1])

    def package_solve(self, G: np.ndarray) -> np.ndarray:
        """The package's solution (Nc, n) [rad/s²] of the QPs of gradients ``G``."""
        self.qps.solve(G)
        return self.qps.solution.copy()


def box_qp_residual(H: np.ndarray, g: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                    u: np.ndarray) -> float:  # fmt: skip
    """Optimality residual of ``u`` for the box QP min ½uᵀHu + gᵀu, lo ≤ u ≤ hi.

    The natural residual :math:`\\|u - \\Pi_{[lo, hi]}(u - (Hu + g))\\|_\\infty`: zero exactly
    when ``u`` satisfies the KKT conditions (feasible, zero gradient on the free entries, a
    gradient pointing out of the box on the bounded ones), i.e. is the minimiser of the
    convex QP; same units as ``u``. Independent of any solver.
    """
    u = np.asarray(u, dtype=float)
    return float(np.max(np.abs(u - np.clip(u - (H @ u + g), lo, hi))))


@contextlib.contextmanager
def _quiet():
    """The process's standard output (file descriptor 1) sent to /dev/null: qpOASES prints its
    banner and OSQP its polishing notes there from C, whatever their print options."""
    sys.stdout.flush()
    saved = os.dup(1)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)
        os.close(devnull)


def _arm(name: str) -> Arm:
    if name == "planar3":
        return load_arm("planar3", ROOT / "robots" / "planar3.urdf", HOMES["planar3"], "chen")
    return load_arm("panda", "panda", HOMES["panda"], "general", PANDA_LOCKED)


def record_problem(sc: QPScenario, arms: dict[str, Arm] | None = None) -> QPProblem:
    """Record the joint QPs' gradients along the kicked closed loop of ``sc`` (module
    docstring), solved by the package's :class:`JointQPs`."""
    arms = arms if arms is not None else {}
    if sc.arm not in arms:
        arms[sc.arm] = _arm(sc.arm)
    arm = arms[sc.arm]
    n = arm.n
    s = MPCSettings(Ts=sc.Ts, N=sc.N, Nc=sc.Nc)
    mpc = CondensedMPC(s.Ts, s.N, s.Nc, s.Q, s.R, s.P)
    v_min, v_max = np.full(n, float(s.v_min)), np.full(n, float(s.v_max))
    names = tuple(arm.robot.joint_names)
    qps = JointQPs(mpc, v_min, v_max, names, eps_abs=s.eps_abs, max_iter=s.max_iter)
    ref = arm.reference()
    offsets = sc.Ts * np.arange(1, sc.N + 1)
    model = arm.robot.model
    data = model.createData()
    G, Q, DQ, M = [], [], [], []
    q, dq = ref.sample(0.0)
    active = 0
    for k in range(sc.steps):
        t = k * sc.Ts
        if k % sc.kick_every == 0:
            q = ref.sample(t)[0] + KICK * (-1.0) ** (k // sc.kick_every)
        q_ref, dq_ref = sample_horizon(ref, t + offsets)
        stack = np.empty((2 * sc.N, n))
        stack[0::2], stack[1::2] = q_ref, dq_ref
        g = mpc.gradient(np.vstack([q, dq]), stack)
        qps.solve(g)
        v = qps.solution[0].copy()
        at_bound = (np.abs(qps.solution - v_min) <= 1e-9) | (np.abs(qps.solution - v_max) <= 1e-9)
        active += bool(at_bound.any())
        G.append(g.copy())
        Q.append(q.copy())
        DQ.append(dq.copy())
        M.append(pin.crba(model, data, q).copy())
        q, dq = q + sc.Ts * dq + 0.5 * sc.Ts**2 * v, dq + sc.Ts * v
    return QPProblem(sc, mpc, v_min, v_max, np.array(G), np.array(Q), np.array(DQ),
                     np.array(M), qps, qps.layout, active / sc.steps)  # fmt: skip


#: The largest block-diagonal QP (n·Nc variables) the peers solve in one call; above it one
#: QP per joint. One call per step is how a CasADi user poses n small independent QPs (each
#: call through CasADi costs ~70 µs, so n calls would time its interface n times), and
#: CasADi's qpOASES plugin ignores the bounds of a one-variable QP (H = 1, g = -152,
#: bounds +/-100 gives 152), which the per-joint layout at Nc = 1 would pose.
PEER_BLOCK_MAX = 140


def peer_layout(problem: QPProblem | SimpleNamespace) -> str:
    """The layout the peers solve ``problem``'s QPs in (:data:`PEER_BLOCK_MAX`)."""
    return "block" if problem.n * problem.mpc.Nc <= PEER_BLOCK_MAX else "joint"


class CasadiQPs:
    """The joint QPs through ``casadi.conic`` with one plugin, in the package's layout.

    Args:
        problem: The QPs (their ``n``, ``mpc``, ``v_min``, ``v_max``, ``layout``).
        plugin: A key of :data:`PLUGINS`.
    """

    def __init__(self, problem: QPProblem | SimpleNamespace, plugin: str):
        n, Nc = problem.n, problem.mpc.Nc
        self.n, self.Nc, self.block = n, Nc, peer_layout(problem) == "block"
        H = casadi.DM(problem.mpc.H)
        if self.block:
            H = casadi.diagcat(*([H] * n))  # block-diagonal sparsity: n dense Nc×Nc blocks
            lo, hi = np.repeat(problem.v_min, Nc), np.repeat(problem.v_max, Nc)
            self.bounds = [(lo, hi)]
        else:
            self.bounds = [(np.full(Nc, problem.v_min[i]), np.full(Nc, problem.v_max[i]))
                           for i in range(n)]  # fmt: skip
        self.H = H
        nv = H.size1()
        self.solvers = [
            casadi.conic(f"{plugin}_{k}", plugin,
                         {"h": H.sparsity(), "a": casadi.Sparsity(0, nv)},
                         plugin_options(plugin, peer_layout(problem)))
            for k in range(len(self.bounds))
        ]  # fmt: skip
        self.x = [np.zeros(nv) for _ in self.solvers]
        self.lam = [np.zeros(nv) for _ in self.solvers]

    def solve(self, G: np.ndarray) -> None:
        """Solve the QPs of gradients ``G`` (n, Nc), warm-started from the last solution."""
        gs = [G.ravel()] if self.block else list(G)
        for k, (solver, g, (lo, hi)) in enumerate(zip(self.solvers, gs, self.bounds,
                                                      strict=True)):  # fmt: skip
            r = solver(h=self.H, g=g, lbx=lo, ubx=hi, x0=self.x[k], lam_x0=self.lam[k])
            self.x[k], self.lam[k] = r["x"], r["lam_x"]

    def solution(self) -> np.ndarray:
        """The last solution, shape (Nc, n) [rad/s²]."""
        if self.block:
            return np.array(self.x[0]).reshape(self.n, self.Nc).T
        return np.hstack([np.array(x) for x in self.x])


def _call_floor(problem: QPProblem) -> Callable[[np.ndarray], None]:
    """A CasADi ``Function`` of the conic's inputs that returns two of them, called as the
    peers are: the cost of a call through CasADi's Python interface."""
    block = peer_layout(problem) == "block"
    nv = problem.n * problem.mpc.Nc if block else problem.mpc.Nc
    H = casadi.DM(problem.mpc.H)
    if block:
        H = casadi.diagcat(*([H] * problem.n))
    sym = {k: casadi.SX.sym(k, nv) for k in ("g", "lbx", "ubx", "x0", "lam_x0")}
    h = casadi.SX.sym("h", H.sparsity())
    fn = casadi.Function("floor", [h, *sym.values()], [sym["x0"], sym["lam_x0"]],
                         ["h", *sym], ["x", "lam_x"])  # fmt: skip
    calls = 1 if block else problem.n
    lo, hi, z = np.full(nv, -1.0), np.full(nv, 1.0), np.zeros(nv)

    def run(G: np.ndarray) -> None:
        for k in range(calls):
            fn(h=H, g=G.ravel()[k * nv : (k + 1) * nv], lbx=lo, ubx=hi, x0=z, lam_x0=z)

    return run


@dataclass
class PeerCase:
    """One scenario's figures.

    Attributes:
        problem: The recorded QPs. blocks_us: Variant → per-block medians [µs].
        diff: Peer → max |U_peer − U| [rad/s²]. torque: Peer → max |M Δv₀| [N·m].
        residual: Solver (``"hmpc_pin"`` and peers) → largest box-QP residual [rad/s²].
        failed: Peer → why it was left out.
    """

    problem: QPProblem
    blocks_us: dict[str, np.ndarray]
    diff: dict[str, float]
    torque: dict[str, float]
    residual: dict[str, float]
    failed: dict[str, str] = field(default_factory=dict)

    def median_us(self, name: str) -> float:
        """Median over blocks of the variant's block medians [µs]."""
        return float(np.median(self.blocks_us[name]))

    def ratios(self, name: str) -> np.ndarray:
        """Per-block ratios variant / package."""
        return self.blocks_us[name] / self.blocks_us["hmpc_pin"]


class OtherLayout:
    """The package's QPs of ``problem`` in the other layout (``"joint"`` for a ``"block"``
    problem and vice versa), with :class:`CasadiQPs`'s ``solve``/``solution``."""

    def __init__(self, problem: QPProblem):
        layout = "joint" if problem.layout == "block" else "block"
        names = tuple(f"joint {i}" for i in range(problem.n))
        s = MPCSettings()  # the solver settings of record_problem's QPs
        self.qps = JointQPs(problem.mpc, problem.v_min, problem.v_max, names,
                            eps_abs=s.eps_abs, max_iter=s.max_iter, layout=layout)  # fmt: skip
        self.solve = self.qps.solve

    def solution(self) -> np.ndarray:
        """The last solution, shape (Nc, n) [rad/s²]."""
        return self.qps.solution.copy()


def check_peer(
    problem: QPProblem, peer: CasadiQPs | OtherLayout, name: str
) -> tuple[float, float, float]:
    """Solve the whole sequence with the package and ``peer``; the largest solution
    difference [rad/s²], torque difference [N·m] and the peer's KKT residual; raises
    ``AssertionError`` beyond :data:`TOLERANCE`."""
    H, Nc = problem.mpc.H, problem.mpc.Nc
    diff = torque = residual = 0.0
    for k, G in enumerate(problem.G):
        U = problem.package_solve(G)
        peer.solve(G)
        V = peer.solution()
        diff = max(diff, float(np.max(np.abs(V - U))))
        torque = max(torque, float(np.max(np.abs(problem.M[k] @ (V[0] - U[0])))))
        for i in range(problem.n):
            lo, hi = np.full(Nc, problem.v_min[i]), np.full(Nc, problem.v_max[i])
            residual = max(residual, box_qp_residual(H, G[i], lo, hi, V[:, i]))
    if not diff <= TOLERANCE:
        raise AssertionError(
            f"{problem.scenario.arm}, {problem.scenario.label}: {name}'s solutions differ from "
            f"the package's by up to {diff:.2e} rad/s², more than {TOLERANCE:g}: not the same "
            "problem, or a solver off its tolerance"
        )
    return diff, torque, residual


def _package_residual(problem: QPProblem) -> float:
    H, Nc = problem.mpc.H, problem.mpc.Nc
    worst = 0.0
    for G in problem.G:
        U = problem.package_solve(G)
        for i in range(problem.n):
            lo, hi = np.full(Nc, problem.v_min[i]), np.full(Nc, problem.v_max[i])
            worst = max(worst, box_qp_residual(H, G[i], lo, hi, U[:, i]))
    return worst


def _alternate(variants: dict[str, Callable[[np.ndarray], object]], G: np.ndarray,
               blocks: int, warmup: int) -> dict[str, np.ndarray]:  # fmt: skip
    """Per variant, the median call [µs] of each block; variants alternate block by block."""
    clock = time.perf_counter_ns
    out: dict[str, list[float]] = {name: [] for name in variants}
    for _ in range(blocks):
        for name, fn in variants.items():
            samples = np.empty(len(G) - warmup, dtype=np.int64)
            for k, g in enumerate(G):
                t0 = clock()
                fn(g)
                if k >= warmup:
                    samples[k - warmup] = clock() - t0
            out[name].append(float(np.median(samples)) / 1e3)
    return {name: np.array(v) for name, v in out.items()}


def _scaled(sc: QPScenario, steps_scale: float) -> QPScenario:
    """``sc`` with its recorded steps scaled by ``steps_scale`` (at least 20; ``--quick``)."""
    if steps_scale == 1.0:
        return sc
    steps = max(20, int(sc.steps * steps_scale))
    return QPScenario(sc.arm, sc.label, sc.Ts, sc.N, sc.Nc, steps, sc.kick_every)


def qp_peers(scenarios=SCENARIOS, blocks: int = 5, steps_scale: float = 1.0) -> list[PeerCase]:
    """Check and time every scenario (module docstring); requires CasADi."""
    if casadi is None:
        raise ImportError(f"the CasADi comparison {EXTRA_MESSAGE}")
    arms: dict[str, Arm] = {}
    cases = []
    for sc in scenarios:
        sc = _scaled(sc, steps_scale)
        log(f"  {sc.arm}, {sc.label}: recording {sc.steps} steps")
        problem = record_problem(sc, arms)
        variants: dict[str, Callable[[np.ndarray], object]] = {"hmpc_pin": problem.qps.solve}
        diff, torque, failed = {}, {}, {}
        residual = {"hmpc_pin": _package_residual(problem)}
        with _quiet():
            for name in PLUGINS:
                try:
                    peer = CasadiQPs(problem, name)
                    diff[name], torque[name], residual[name] = check_peer(problem, peer, name)
                except RuntimeError as exc:  # the plugin failed on a QP: reported, not timed
                    failed[name] = str(exc).splitlines()[-1][:200]
                    log(f"    {name}: failed ({failed[name]})")
                    continue
                variants[name] = peer.solve
            variants["CasADi call (identity Function)"] = _call_floor(problem)
            if peer_layout(problem) != problem.layout:  # the package in the peers' layout
                other = OtherLayout(problem)
                name = f"hmpc_pin, {other.qps.layout} layout"
                diff[name], torque[name], residual[name] = check_peer(problem, other, name)
                variants[name] = other.solve
            blocks_us = _alternate(variants, problem.G, blocks, warmup=min(5, sc.steps // 4))
        case = PeerCase(problem, blocks_us, diff, torque, residual, failed)
        log("    " + ", ".join(f"{k} {case.median_us(k):.0f} µs" for k in blocks_us))
        cases.append(case)
    return cases


class CasadiStep:
    """The hierarchical MPC's step without observer and joint dynamics, built around a CasADi
    QP: the reference over the horizon (``sample_horizon``), the gradients
    :math:`g = F[x_0; \bar r]` (:class:`CondensedMPC`), the joint QPs through
    :class:`CasadiQPs`, Pinocchio's ``crba`` and ``nonLinearEffects`` and Eq (4),
    :math:`\tau = M(q)v_0 + C(q,\\dot q)\\dot q + G(q)` [N·m], all called from Python.

    Args:
        robot: The arm. settings: Ts, N, Nc, weights, bounds, layout. plugin: A CasADi plugin.
    """

    def __init__(self, robot: hmpc_pin.Robot, settings: MPCSettings, plugin: str):
        n, s = robot.nq, settings
        self.mpc = CondensedMPC(s.Ts, s.N, s.Nc, s.Q, s.R, s.P)
        v_min, v_max = s.bounds(n)
        layout = resolve_layout(s.qp_layout, n, s.Nc)
        qps = SimpleNamespace(n=n, mpc=self.mpc, v_min=v_min, v_max=v_max, layout=layout)
        self.qp = CasadiQPs(qps, plugin)
        self.model = robot.model
        self.data = self.model.createData()
        self.offsets = s.Ts * np.arange(1, s.N + 1)
        self.stack = np.empty((2 * s.N, n))

    def step(self, t: float, q: np.ndarray, dq: np.ndarray, reference) -> np.ndarray:
        """Torque [N·m], shape (n,), for the state (q, q̇) at time ``t`` [s]."""
        q_ref, dq_ref = sample_horizon(reference, t + self.offsets)
        self.stack[0::2], self.stack[1::2] = q_ref, dq_ref
        self.qp.solve(self.mpc.gradient(np.vstack([q, dq]), self.stack))
        v = self.qp.solution()[0]
        M = pin.crba(self.model, self.data, q)
        return M @ v + pin.nonLinearEffects(self.model, self.data, q, dq)


@dataclass
class StepCase:
    """One arm's whole-step comparison.

    Attributes:
        scenario: Its setting (states: the scenario's kicked closed loop).
        blocks_us: Variant → per-block median steps [µs] (``"hmpc_pin"`` the package's).
        dtau: Peer → max |τ_peer − τ| [N·m]. bound: The largest allowed [N·m].
    """

    scenario: QPScenario
    blocks_us: dict[str, np.ndarray]
    dtau: dict[str, float]
    bound: float


def step_peers(
    scenarios=SCENARIOS[:2], blocks: int = 5, steps_scale: float = 1.0
) -> list[StepCase]:
    """The package's step (no observer, no joint dynamics, no state limits) against
    :class:`CasadiStep` with every plugin, on the states of each scenario's kicked closed
    loop; the torques checked at every state (|Δτ| ≤ ``TOLERANCE``·‖M‖∞ + 1e-9 N·m, the QPs'
    tolerance through the mass matrix) before the alternating blocks."""
    if casadi is None:
        raise ImportError(f"the CasADi comparison {EXTRA_MESSAGE}")
    arms: dict[str, Arm] = {}
    out = []
    for sc in scenarios:
        sc = _scaled(sc, steps_scale)
        problem = record_problem(sc, arms)
        arm = arms[sc.arm]
        ref, n = arm.reference(), arm.n
        settings = MPCSettings(Ts=sc.Ts, N=sc.N, Nc=sc.Nc, joint_dynamics=False)
        hmpc = HierarchicalMPC(arm.robot, settings, NoCompensation(n), limits=None)
        states = [(k * sc.Ts, problem.q[k], problem.dq[k]) for k in range(len(problem.q))]
        hmpc.reset(states[0][1], states[0][2])
        bound = TOLERANCE * float(np.abs(problem.M).sum(axis=2).max()) + 1e-9
        variants: dict[str, Callable] = {"hmpc_pin": lambda s, c=hmpc, r=ref: c.step(*s, r)}
        dtau = {}
        log(f"  step, {sc.arm}, {sc.label}: hmpc_pin against CasADi-built steps")
        with _quiet():
            for plugin in PLUGINS:
                peer = CasadiStep(arm.robot, settings, plugin)
                dtau[plugin] = max(
                    float(np.max(np.abs(peer.step(*st, ref) - hmpc.step(*st, ref))))
                    for st in states
                )
                if not dtau[plugin] <= bound:
                    raise AssertionError(
                        f"{sc.arm}, {sc.label}: the step built on {plugin} gives torques up to "
                        f"{dtau[plugin]:.2e} N·m from the package's, more than {bound:.1e}"
                    )
                variants[plugin] = lambda s, c=peer, r=ref: c.step(*s, r)
            blocks_us = _alternate(variants, states, blocks, warmup=min(5, len(states) // 4))
        log("    " + ", ".join(f"{k} {np.median(v):.0f} µs" for k, v in blocks_us.items()))
        out.append(StepCase(sc, blocks_us, dtau, bound))
    return out


def step_table(cases: list[StepCase]) -> str:
    """The whole-step table (Markdown)."""
    lines = [
        "| arm | setting | step | median [µs] | hmpc_pin step [µs] | **step / hmpc_pin** "
        "(range) | max \\|Δτ\\| [N·m] (allowed) |",
        "|---|---|---|---|---|---|---|",
    ]
    for c in cases:
        base = np.median(c.blocks_us["hmpc_pin"])
        for name, b in c.blocks_us.items():
            if name == "hmpc_pin":
                continue
            r = b / c.blocks_us["hmpc_pin"]
            lines.append(
                f"| {c.scenario.arm} | {c.scenario.label} | Python + Pinocchio + CasADi "
                f"{name} | {_us(np.median(b))} | {_us(base)} | **{_ratio(np.median(r))}** "
                f"({_ratio(r.min())}–{_ratio(r.max())}) | {c.dtau[name]:.0e} "
                f"({c.bound:.0e}) |"
            )
    return "\n".join(lines)


def crocoddyl_steps(scenario, iterations: int, blocks: int, duration: float):
    """The step of the hierarchical MPC and of Crocoddyl's NMPC on the states of the
    former's closed-loop run of ``scenario`` (``benchmarks.comparisons.Scenario``),
    alternating blocks. Returns per-block medians [µs] by controller name."""
    robot, cfg = scenario.robot, scenario.config
    hmpc = hmpc_pin.make_controller(robot, cfg)
    res = hmpc_pin.simulate(robot, hmpc, scenario.reference, scenario.disturbance,
                            duration=duration, q0=scenario.q0, dq0=scenario.dq0,
                            plant=scenario.plant, dt=scenario.dt,
                            integrator=scenario.integrator,
                            effort_limit=scenario.effort_limit)  # fmt: skip
    croc = crocoddyl_mpc.CrocoddylMPC(robot, cfg, iterations)
    states = [(float(res.t[i]), res.q[i].copy(), res.dq[i].copy()) for i in range(len(res.t))]
    ref = scenario.reference
    clock = time.perf_counter_ns
    out: dict[str, list[float]] = {"hmpc_pin": [], "crocoddyl": []}
    warmup = min(10, len(states) // 4)
    for _ in range(blocks):
        for name, ctrl in (("hmpc_pin", hmpc), ("crocoddyl", croc)):
            ctrl.reset(states[0][1], states[0][2])
            samples = []
            for k, (t, q, dq) in enumerate(states):
                t0 = clock()
                ctrl.step(t, q, dq, ref)
                if k >= warmup:
                    samples.append(clock() - t0)
            out[name].append(float(np.median(samples)) / 1e3)
    return {name: np.array(v) for name, v in out.items()}


@dataclass
class CrocoddylRow:
    """One scenario's Crocoddyl figures.

    Attributes:
        scenario: Its name. iterations: Box-FDDP's budget per step.
        blocks_us: ``"hmpc_pin"``, ``"crocoddyl"`` → per-block median steps [µs].
        rms: Worst joint's RMS error after 1 s [rad] of the closed-loop runs (``"hmpc"``,
            ``"hmpc, no NDO"``, ``"crocoddyl"``; ``None`` for a run that failed).
    """

    scenario: str
    iterations: int
    blocks_us: dict[str, np.ndarray]
    rms: dict[str, float | None]

    def ratio(self) -> np.ndarray:
        """Per-block ratios Crocoddyl / hmpc_pin."""
        return self.blocks_us["crocoddyl"] / self.blocks_us["hmpc_pin"]


def crocoddyl_rows(compares: list[tuple[Scenario, float, list[CompareRow]]],
                   settings: Settings) -> list[CrocoddylRow]:  # fmt: skip
    """The Crocoddyl rows of the peers' table: the alternated steps (:func:`crocoddyl_steps`)
    beside the tracking of the comparison's closed-loop runs (``compares``, from
    ``benchmarks.comparisons.bench_compare``)."""
    out = []
    for scenario, _, rows in compares:
        log(f"  crocoddyl step, {scenario.name}: alternating with the package's")
        blocks = crocoddyl_steps(scenario, settings.crocoddyl_iterations, settings.peer_blocks,
                                 settings.peer_duration)  # fmt: skip
        rms = {r.controller: (float(r.rms.max()) if r.rms is not None and r.complete else None)
               for r in rows}  # fmt: skip
        out.append(CrocoddylRow(scenario.name, settings.crocoddyl_iterations, blocks, rms))
    return out


def crocoddyl_table(rows: list[CrocoddylRow]) -> str:
    """The Crocoddyl table (Markdown)."""
    lines = [
        "| arm | Box-FDDP iterations per step | crocoddyl step [µs] | hmpc_pin step [µs] | "
        "**crocoddyl / hmpc_pin** (range) | worst RMS e: crocoddyl / hmpc_pin | "
        "crocoddyl / hmpc_pin without its NDO |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        ratio = r.ratio()
        croc, base, off = r.rms.get("crocoddyl"), r.rms.get("hmpc"), r.rms.get("hmpc, no NDO")
        track = f"{croc / base:.1f}" if croc and base else "n/a"
        track_off = f"{croc / off:.2f}" if croc and off else "n/a"
        lines.append(
            f"| {r.scenario} | {r.iterations} | {_us(np.median(r.blocks_us['crocoddyl']))} | "
            f"{_us(np.median(r.blocks_us['hmpc_pin']))} | **{_ratio(np.median(ratio))}** "
            f"({_ratio(ratio.min())}–{_ratio(ratio.max())}) | {track} | {track_off} |"
        )
    return "\n".join(lines)


def _us(x: float) -> str:
    return f"{x:.1f}" if x < 100 else f"{x:.0f}"


def _ratio(x: float) -> str:
    return f"{x:.2f}" if x < 10 else f"{x:.0f}"


def qp_table(cases: list[PeerCase]) -> str:
    """The CasADi table (Markdown): per scenario and solver, the median call, the package's,
    their ratio (median over blocks, range) and the solution checks."""
    lines = [
        "| arm | setting | layout (package / peers) | bounds active | solver | median [µs] "
        "| hmpc_pin [µs] | **solver / hmpc_pin** (range) | max \\|ΔU\\| [rad/s²] | max \\|M Δv₀\\| "
        "[N·m] | KKT residual |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for c in cases:
        p = c.problem
        head = (f"| {p.scenario.arm} | {p.scenario.label} | {p.layout} / {peer_layout(p)} | "
                f"{p.active:.0%} of steps |")  # fmt: skip
        base = c.median_us("hmpc_pin")
        lines.append(f"{head} hmpc_pin (JointQPs) | {_us(base)} | {_us(base)} | 1 | | | "
                     f"{c.residual['hmpc_pin']:.0e} |")  # fmt: skip
        for name in c.blocks_us:
            if name == "hmpc_pin":
                continue
            r = c.ratios(name)
            check = (f"{c.diff[name]:.0e} | {c.torque[name]:.0e} | {c.residual[name]:.0e}"
                     if name in c.diff else "| |")  # fmt: skip
            lines.append(
                f"{head} {name} | {_us(c.median_us(name))} | {_us(base)} | "
                f"**{_ratio(np.median(r))}** ({_ratio(r.min())}–{_ratio(r.max())}) | {check} |"
            )
        for name, why in c.failed.items():
            lines.append(f"{head} {name} | failed: {why} | | | | | |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Run the comparison and print its tables; exit 0 (1 if a peer solves another
    problem, 2 when CasADi is missing)."""
    parser = argparse.ArgumentParser(prog="python benchmarks/peers.py",
                                     description=__doc__.split("\n\n")[0])  # fmt: skip
    parser.add_argument("--blocks", type=int, default=5, help="alternating blocks (default 5)")
    parser.add_argument("--quick", action="store_true", help="2 blocks, shorter sequences")
    args = parser.parse_args(argv)
    if casadi is None:
        print(f"benchmarks/peers.py {EXTRA_MESSAGE}", file=sys.stderr)
        return 2
    blocks = 2 if args.quick else args.blocks
    try:
        cases = qp_peers(blocks=blocks, steps_scale=0.25 if args.quick else 1.0)
    except AssertionError as exc:
        print(f"benchmarks/peers.py: {exc}", file=sys.stderr)
        return 1
    print(qp_table(cases))
    try:
        steps = step_peers(blocks=blocks, steps_scale=0.25 if args.quick else 1.0)
    except AssertionError as exc:
        print(f"benchmarks/peers.py: {exc}", file=sys.stderr)
        return 1
    print()
    print(step_table(steps))
    if not crocoddyl_mpc.AVAILABLE:
        print(f"\nThe Crocoddyl comparison {EXTRA_MESSAGE}", file=sys.stderr)
        return 0
    settings = Settings(peer_blocks=blocks)
    duration = 2.0 if args.quick else settings.compare_duration
    compares = [(sc, duration, bench_compare(sc, duration, settings))
                for sc in (planar3_scenario(), panda_scenario())]  # fmt: skip
    print()
    print(crocoddyl_table(crocoddyl_rows(compares, settings)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
