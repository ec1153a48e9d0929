"""The n joint QPs of one step solved three ways, timed on the same gradient sequence.

Issue 6 asks to batch the n identical-Hessian joint QPs and to measure the options:

- ``block``: one block-diagonal ProxSuite dense QP of n·Nc variables with box bounds, one
  ``update(g)`` + ``solve()`` per step (``JointQPs(layout="block")``, the default);
- ``joint``: n separate box-constrained QPs, n ``update`` + ``solve`` calls
  (``JointQPs(layout="joint")``);
- ``BatchQP``: ProxSuite's ``proxqp.dense.BatchQP`` with one QP per joint, n ``update``
  calls and one ``proxqp.dense.solve_in_parallel`` (1 and 2 threads). ``init_qp_in_place``
  has no box-constraint option, so each joint's bounds are n_in = Nc inequality rows
  C = I (in proxsuite 0.8.0, ``BatchQP.insert`` of a box-constrained QP left the batch
  empty: ``size() == 0``).

All with the package's solver settings (``benchmarks._fixtures.new_qp``), warm-started, the box
QPs only (no state limits). The gradients are those of a closed-loop run of the
controller, recorded from ``HierarchicalMPC.step``, so the warm starts see what they see
in a run.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from proxsuite import proxqp

import hmpc_pin
from benchmarks._fixtures import new_qp
from hmpc_pin.mpc.condensed import JointQPs

__all__ = ["LayoutTiming", "record_gradients", "time_layouts"]

#: Settings copied from the package's QP onto the BatchQP members (before ``init``).
_SETTINGS = (
    "initial_guess",
    "eps_abs",
    "eps_rel",
    "max_iter",
    "verbose",
    "check_duality_gap",
    "eps_duality_gap_abs",
    "eps_duality_gap_rel",
    "eps_primal_inf",
    "eps_dual_inf",
)


@dataclass
class LayoutTiming:
    """Median time per step [µs] of each way (median over blocks of the block medians),
    its ratio to the block QP's (median over blocks of the per-block ratio; the ways
    alternate block by block), and the largest difference of its solutions from the block
    QP's over the sequence."""

    arm: str
    n: int
    Nc: int
    steps: int
    median_us: dict[str, float]
    max_diff: dict[str, float]
    ratio: dict[str, float] = field(default_factory=dict)
    blocks: int = 1


def record_gradients(ctrl: hmpc_pin.HierarchicalMPC, t, q, dq, reference) -> np.ndarray:
    """The QP gradients (steps, n, Nc) that ``ctrl.step`` computes along the states: after
    each step, the step's stack [q; q̇; r_1..r_N; ṙ_1..ṙ_N] times its gradient map."""
    grads = []
    ctrl.reset(q[0], dq[0])
    for i in range(len(t)):
        ctrl.step(float(t[i]), q[i], dq[i], reference)
        grads.append(np.ascontiguousarray(ctrl._stack.T @ ctrl._FT))
    return np.array(grads)


def _batch(mpc, v_min, v_max, eps_abs, max_iter):
    n, Nc = v_min.size, mpc.Nc
    batch = proxqp.dense.BatchQP(n)
    template = new_qp(Nc, 0, eps_abs, max_iter).settings
    qps = []
    for i in range(n):
        qp = batch.init_qp_in_place(Nc, 0, Nc)
        for name in _SETTINGS:
            setattr(qp.settings, name, getattr(template, name))
        qp.init(mpc.H, np.zeros(Nc), None, None, np.eye(Nc),
                np.full(Nc, v_min[i]), np.full(Nc, v_max[i]))  # fmt: skip
        qp.solve()
        qps.append(qp)
    return batch, qps


def time_layouts(
    arm: str, ctrl: hmpc_pin.HierarchicalMPC, grads: np.ndarray, warmup: int, blocks: int = 3
) -> LayoutTiming:
    """Time the three ways on ``grads`` (steps, n, Nc), alternating ``blocks`` times over
    the whole sequence; the first ``warmup`` calls of each block untimed."""
    cfg = ctrl.settings
    n, Nc = ctrl.n, ctrl.mpc.Nc
    v_min, v_max = cfg.bounds(n)
    names = tuple(ctrl.robot.joint_names)
    kw = {"eps_abs": cfg.eps_abs, "max_iter": cfg.max_iter}
    block = JointQPs(ctrl.mpc, v_min, v_max, names, layout="block", **kw)
    joint = JointQPs(ctrl.mpc, v_min, v_max, names, layout="joint", **kw)
    batch, batch_qps = _batch(ctrl.mpc, v_min, v_max, **kw)

    def solution(qps):
        def run(G):
            qps.solve(G)
            return qps.solution.copy()  # (Nc, n)

        return run

    def batch_solution(threads):
        def run(G):
            _batch_step(batch, batch_qps, G, threads)
            return np.array([qp.results.x for qp in batch_qps]).T  # (Nc, n)

        return run

    ways = {
        "block": solution(block),
        "joint": solution(joint),
        "BatchQP, 1 thread": batch_solution(1),
        "BatchQP, 2 threads": batch_solution(2),
    }
    # Timed: the solver calls alone (update + solve; for BatchQP the n updates and
    # solve_in_parallel); the solutions are compared in a separate pass afterwards.
    timed = {
        "block": block.solve,
        "joint": joint.solve,
        "BatchQP, 1 thread": lambda G: _batch_step(batch, batch_qps, G, 1),
        "BatchQP, 2 threads": lambda G: _batch_step(batch, batch_qps, G, 2),
    }
    per_block: dict[str, list[float]] = {name: [] for name in timed}
    for _ in range(blocks):
        for name, fn in timed.items():
            samples = []
            for k, G in enumerate(grads):
                start = time.perf_counter_ns()
                fn(G)
                if k >= warmup:
                    samples.append(time.perf_counter_ns() - start)
            per_block[name].append(float(np.median(samples)) / 1e3)
    base = np.array(per_block["block"])
    median = {name: float(np.median(v)) for name, v in per_block.items()}
    ratio = {name: float(np.median(np.array(v) / base)) for name, v in per_block.items()}
    diff = dict.fromkeys(ways, 0.0)
    for G in grads[-50:]:
        ref = ways["block"](G)
        for name in ways:
            if name != "block":
                diff[name] = max(diff[name], float(np.abs(ways[name](G) - ref).max()))
    del diff["block"]
    return LayoutTiming(arm, n, Nc, len(grads) - warmup, median, diff, ratio, blocks)


def _batch_step(batch, qps, G, threads):
    for i, qp in enumerate(qps):
        qp.update(g=G[i])
    proxqp.dense.solve_in_parallel(batch, threads)
