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
    each step, the compiled step's own (its ``gradients`` view)."""
    grads = []
    ctrl.reset(q[0], dq[0])
    for i in range(len(t)):
        ctrl.step(float(t[i]), q[i], dq[i], reference)
        grads.append(ctrl._core.gradients.copy())
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


# The grid of the "auto" layout's decision (hmpc_pin.mpc.condensed.resolve_layout): the box QPs
# and, with soft limits, the soft QPs of the joints whose prediction leaves the limits, both
# layouts on the same gradient and state sequences, alternating block by block.

#: Joints, control horizons, Ts [s] and the horizon N = max(N_MIN, Nc) of the grid.
GRID_N = (2, 3, 4, 5, 6, 7)
GRID_NC = (1, 5, 20)
GRID_TS, N_MIN = 0.01, 10
#: The sine tracked by every joint (amplitude [rad], period [s]); the kick off it every
#: KICK_EVERY steps [rad] (bounds active) or none (bounds inactive: the closed loop on the
#: reference, where every box QP's unconstrained minimiser lies inside the box).
AMPLITUDE, PERIOD, KICK, KICK_EVERY = 0.3, 10.0, 0.6, 20
#: Soft limits: position ±LIMIT [rad] around the sine's centre, velocity VEL_LIMIT [rad/s].
LIMIT, VEL_LIMIT = 0.7, 2.0


@dataclass
class GridCase:
    """One grid point: median step of the QP layer [µs] per layout (median over blocks),
    the joint layout's time over the block layout's (median of the per-block ratios, with its
    range over blocks), the share of steps with an active bound (box-only solution at a
    bound) and with a soft QP, and the largest difference of the two layouts' solutions."""

    n: int
    Nc: int
    bounds: bool
    soft: bool
    median_us: dict[str, float]
    ratio: float
    ratio_range: tuple[float, float]
    active_share: float
    soft_share: float
    max_diff: float


def grid_problem(n: int, Nc: int, bounds: bool, soft: bool, steps: int, seed: int = 0):
    """The condensed MPC, v bounds, limits and the (G, x0) sequence of a closed loop of n
    double integrators (q̈ = v exactly, Eq 20–24) under the per-joint layout, tracking phase-
    shifted sines; kicked ±KICK rad every KICK_EVERY steps when ``bounds``."""
    from hmpc_pin.mpc.condensed import CondensedMPC, StateLimits

    N = max(N_MIN, Nc)
    Ts = GRID_TS
    mpc = CondensedMPC(Ts, N, Nc, np.diag([50.0, 0.0]), 1e-6, np.diag([100.0, 0.0]))
    v = np.full(n, 100.0)
    limits = None
    if soft:
        limits = StateLimits(np.full(n, -LIMIT), np.full(n, LIMIT), np.full(n, VEL_LIMIT))
    names = tuple(f"j{i}" for i in range(n))
    qps = JointQPs(mpc, -v, v, names, limits=limits, layout="joint")
    phase = np.random.default_rng(seed).uniform(0, 2 * np.pi, n)
    w = 2 * np.pi / PERIOD

    def ref_at(k: int) -> np.ndarray:
        t = Ts * (k + np.arange(1, N + 1))[:, None]
        r = AMPLITUDE * np.sin(w * t + phase)
        dr = AMPLITUDE * w * np.cos(w * t + phase)
        out = np.empty((2 * N, n))
        out[0::2], out[1::2] = r, dr
        return out

    x = np.vstack([AMPLITUDE * np.sin(phase), AMPLITUDE * w * np.cos(phase)])
    Gs, xs, active, soft_steps = [], [], 0, 0
    for k in range(steps):
        if bounds and k % KICK_EVERY == 0 and k:
            x[0] += KICK * (-1.0) ** (k // KICK_EVERY)
        G = mpc.gradient(x, ref_at(k))
        Gs.append(G)
        xs.append(x.copy())
        qps.solve(G, x)
        U = qps.solution
        active += bool(np.any(np.abs(U) >= 100.0 - 1e-9))
        soft_steps += qps.constrained > 0
        vk = U[0]
        x = np.vstack([x[0] + Ts * x[1] + 0.5 * Ts * Ts * vk, x[1] + Ts * vk])
    return mpc, v, limits, names, np.array(Gs), np.array(xs), active / steps, soft_steps / steps


def grid_case(n, Nc, bounds, soft, steps: int = 400, blocks: int = 7, warmup: int = 20):
    """Time both layouts on one grid point (module docstring of the grid)."""
    mpc, v, limits, names, Gs, xs, active, soft_share = grid_problem(n, Nc, bounds, soft, steps)
    qps = {
        lay: JointQPs(mpc, -v, v, names, limits=limits, layout=lay) for lay in ("block", "joint")
    }
    calls = [
        (np.ascontiguousarray(G), x[0].copy(), x[1].copy()) for G, x in zip(Gs, xs, strict=True)
    ]
    per_block: dict[str, list[float]] = {lay: [] for lay in qps}
    clock = time.perf_counter_ns
    for _ in range(blocks):
        for lay, qp in qps.items():
            solve = qp._core.solve
            samples = np.empty(len(calls))
            for k, (G, q, dq) in enumerate(calls):
                t0 = clock()
                solve(G, q, dq)
                samples[k] = clock() - t0
            per_block[lay].append(float(np.median(samples[warmup:])) / 1e3)
    ratios = np.array(per_block["joint"]) / np.array(per_block["block"])
    diff = 0.0
    for G, x in zip(Gs, xs, strict=True):
        U = []
        for qp in qps.values():
            qp.solve(G, x)
            U.append(qp.solution.copy())
        diff = max(diff, float(np.abs(U[0] - U[1]).max()))
    return GridCase(n, Nc, bounds, soft, {k: float(np.median(v)) for k, v in per_block.items()},
                    float(np.median(ratios)), (float(ratios.min()), float(ratios.max())),
                    active, soft_share, diff)  # fmt: skip


def grid_table(cases: list[GridCase]) -> str:
    lines = [
        "| n | Nc | bounds | soft limits | steps with a bound active | steps with a soft QP "
        "| block [µs] | joint [µs] | **joint / block** (range) | max \\|ΔU\\| [rad/s²] |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for c in cases:
        lines.append(
            f"| {c.n} | {c.Nc} | {'active' if c.bounds else 'inactive'} | "
            f"{'on' if c.soft else 'off'} | {c.active_share:.0%} | {c.soft_share:.0%} | "
            f"{c.median_us['block']:.1f} | {c.median_us['joint']:.1f} | **{c.ratio:.2f}** "
            f"({c.ratio_range[0]:.2f}–{c.ratio_range[1]:.2f}) | {c.max_diff:.0e} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """``python benchmarks/qp_layouts.py [--blocks 7] [--steps 400] [--n 2 3 ...] [--Nc 1 5 20]``:
    the grid of the "auto" layout's decision, as a markdown table."""
    import argparse
    import os
    import sys

    p = argparse.ArgumentParser(description=main.__doc__)
    p.add_argument("--blocks", type=int, default=7)
    p.add_argument("--steps", type=int, default=400)
    p.add_argument("--n", type=int, nargs="+", default=list(GRID_N))
    p.add_argument("--Nc", type=int, nargs="+", default=list(GRID_NC))
    args = p.parse_args(argv)
    print("command: python benchmarks/qp_layouts.py " + " ".join(sys.argv[1:]))
    print(f"load average at start: {' '.join(f'{x:.2f}' for x in os.getloadavg())}\n")
    cases = []
    for Nc in args.Nc:
        for n in args.n:
            for bounds in (False, True):
                for soft in (False, True):
                    cases.append(grid_case(n, Nc, bounds, soft, args.steps, args.blocks))
                    print(grid_table(cases[-1:]).splitlines()[-1], flush=True)
    print()
    print(grid_table(cases))
    print(f"\nload average at end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
