"""The worst step at 1 kHz with a long horizon: Panda, Ts = 1 ms, N = Nc = 100, the default
soft joint limits (the URDF's position and velocity limits as soft state constraints).

Three variants, timed in alternating blocks (A, B, C, A, B, C, …), each block restarting
its controller:

- ``closed loop``: the states of a closed loop started 0.2 rad off on every joint (the
  plant is the feedback-linearised arm, q̈ = v exactly, Eq 24, so that only the controller is
  timed; recorded once and replayed, the answers being exact); the first steps open an
  activation of every joint's soft QP;
- ``stalled arm``: the arm held still 0.2 rad off its reference at every step (stalled
  against something, or a plan it cannot follow): every joint's soft QP at every step;
- ``on the reference``: the reference's own states (no soft QP).

Per block: the median step, the worst step by the wall clock and the worst step by the
thread's CPU time (``time.thread_time_ns``: less of the preemption, which on a loaded
machine makes most of the wall clock's worst). Over blocks: the costliest step, the largest
over the steps of each step's median over blocks (a step costly in every block, such as an
activation's first, not one preempted once). The other figures are the medians over
blocks, the ratios the medians over blocks of the per-block ratios to ``on the
reference``'s median step (the costliest step's: to the median of those medians). Also
printed: how the soft QPs were answered (the soft active-set shortcut, whose answers pass
the soft QP's KKT test, or ProxSuite) and the shortcut's guesses that did not answer.

With ``--soft-step-exchanges K``: the soft exchanges bounded to K per step
(``JointQPs.soft_step_exchanges``; spread over the joints, a joint reached with none left
answers the fallback, counted, and resumes at the next step); ``--soft-step-work W``: the
bound W // N (``JointQPs.soft_step_work``); printed beside the counters: the fallbacks,
the exchanges and the most in a step.

Run: ``python benchmarks/studies/worst_step.py [--blocks 7] [--steps 100]
[--soft-step-exchanges 16] [--soft-step-work 1600]``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks._fixtures import HOMES, PANDA_LOCKED, load_arm  # noqa: E402
from benchmarks.studies.long_horizon_soft import OFFSET, closed_loop  # noqa: E402
from benchmarks.studies.long_horizon_soft import controller as _controller  # noqa: E402

TS, N = 0.001, 100  # [s], horizon


def _stats(ctrl) -> np.ndarray:
    """(soft QPs solved, answered by the shortcut, failed guesses: pivot, exchanges, KKT;
    fallbacks, exchanges, the most exchanges in a step)."""
    s = ctrl.qps._core.stats
    return np.array([0, s.soft_active_set_solves, s.soft_fail_pivot, s.soft_fail_exchanges,
                     s.soft_fail_kkt, s.soft_fallbacks, s.soft_exchanges, 0])  # fmt: skip


def alternate(variants: dict, blocks: int) -> dict[str, dict[str, np.ndarray]]:
    """Per variant, per block: step times [µs] by the wall clock and the thread's CPU time,
    and the soft-QP counters summed over the block."""
    wall, cpu = time.perf_counter_ns, time.thread_time_ns
    out: dict = {name: {"wall": [], "cpu": [], "stats": []} for name in variants}
    for _ in range(blocks):
        for name, (ctrl, ref, (t, q, dq)) in variants.items():
            calls = [(float(t[i]), q[i].copy(), dq[i].copy()) for i in range(len(t))]
            ctrl.reset(q[0], dq[0])
            step = ctrl.step
            w, c = np.empty(len(calls)), np.empty(len(calls))
            before = _stats(ctrl)
            solved = most = 0
            core = ctrl.qps._core
            for j, (ti, qi, dqi) in enumerate(calls):
                e0 = core.stats.soft_exchanges
                c0, w0 = cpu(), wall()
                step(ti, qi, dqi, ref)
                w1, c1 = wall(), cpu()
                w[j], c[j] = (w1 - w0) / 1e3, (c1 - c0) / 1e3
                solved += ctrl.qps.constrained
                most = max(most, core.stats.soft_exchanges - e0)
            stats = _stats(ctrl) - before
            stats[0], stats[7] = solved, most
            out[name]["wall"].append(w)
            out[name]["cpu"].append(c)
            out[name]["stats"].append(stats)
    return {name: {k: np.array(v) for k, v in d.items()} for name, d in out.items()}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--blocks", type=int, default=7)
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument(
        "--soft-step-work",
        type=int,
        default=None,
        help="JointQPsOptions.soft_step_work (exchanges × N per step; default: the package's)",
    )
    parser.add_argument(
        "--soft-step-exchanges",
        type=int,
        default=None,
        help="JointQPsOptions.soft_step_exchanges (default: the package's)",
    )
    args = parser.parse_args()
    print("command: python benchmarks/studies/worst_step.py " + " ".join(sys.argv[1:]))
    print(f"load average at start: {' '.join(f'{x:.2f}' for x in os.getloadavg())}\n")
    arm = load_arm("panda", "panda", HOMES["panda"], "general", PANDA_LOCKED)
    robot, ref = arm.robot, arm.reference()

    def controller(robot, Ts, N):
        ctrl = _controller(robot, Ts, N)
        if args.soft_step_exchanges is not None:
            ctrl.qps._core.options.soft_step_exchanges = args.soft_step_exchanges
        if args.soft_step_work is not None:
            ctrl.qps._core.options.soft_step_work = args.soft_step_work
        return ctrl

    loop_ctrl = controller(robot, TS, N)
    opts = loop_ctrl.qps._core.options
    budget = opts.soft_step_exchanges
    if budget < 0 and opts.soft_step_work >= 0:
        budget = max(1, opts.soft_step_work // N)
    states, _, _ = closed_loop(loop_ctrl, ref, TS, args.steps)
    t = states[0]
    q_ref, dq_ref = ref.sample_many(t)
    stalled = (t, np.repeat(q_ref[:1] + OFFSET, len(t), axis=0), np.zeros_like(dq_ref))
    variants = {
        "closed loop": (loop_ctrl, ref, states),
        "stalled arm": (controller(robot, TS, N), ref, stalled),
        "on the reference": (controller(robot, TS, N), ref, (t, q_ref, dq_ref)),
    }
    res = alternate(variants, args.blocks)
    base = np.median(res["on the reference"]["wall"], axis=1)
    print(f"Panda, Ts = {TS * 1e3:g} ms, N = Nc = {N}, default soft limits, {OFFSET} rad off: "
          f"{args.steps} steps per block, {args.blocks} blocks, soft exchanges per step "
          f"{'unbounded' if budget < 0 else f'at most {budget}'}\n")  # fmt: skip
    print("| variant | median step [µs] | / on the reference | worst step, wall [µs] | "
          "worst step, thread CPU [µs] | costliest step, wall [µs] | costliest / on the reference "
          "|")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    for name, r in res.items():
        med = np.median(r["wall"], axis=1)
        worst_w = r["wall"].max(axis=1)
        worst_c = r["cpu"].max(axis=1)
        costliest = np.median(r["wall"], axis=0).max()
        print(f"| {name} | {np.median(med):.0f} | {np.median(med / base):.2f} | "
              f"{np.median(worst_w):.0f} | {np.median(worst_c):.0f} | {costliest:.0f} | "
              f"{costliest / np.median(base):.1f} |")  # fmt: skip
    print()
    for name, r in res.items():
        s = r["stats"].sum(axis=0)
        if s[0]:
            print(f"{name}: soft QPs solved {s[0]}, by the shortcut {s[1]}, by ProxSuite "
                  f"{s[0] - s[1] - s[5]}; guesses that did not answer: pivot {s[2]}, exchanges "
                  f"{s[3]}, KKT {s[4]}; fallbacks {s[5]}; exchanges {s[6]}, at most "
                  f"{r['stats'][:, 7].max()} in a step")  # fmt: skip
    print(f"\nload average at end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
