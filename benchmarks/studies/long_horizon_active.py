"""Long horizons with active constraints: Panda at Ts = 1 ms, N = Nc = 100 (one QP per
joint), away from the reference so that the acceleration bounds (and, with the URDF limits
on, the soft joint limits) are active.

Three ways of solving the box QPs, alternated in one process (A, B, C, A, B, C, ...):

- ``previous``: ProxSuite warm-started from the last solution as it stands, no active-set
  shortcut (``shift = False``, ``active_set_iter = -1``; the solver's use before 0.3);
- ``shifted``: ProxSuite warm-started from the last primal and dual solution shifted one step
  along the horizon, no active-set shortcut (``active_set_iter = -1``);
- ``default``: the active-set shortcut (the last solution's active set shifted one step
  along the horizon, then as it stands, refined by a few active-set exchanges; answered only
  when the KKT test passes), ProxSuite warm-started as in ``previous`` otherwise.

Cases: the measured state held ``offset`` away from the reference's (every step sees the
same error), and a closed loop started 0.2 rad off on every joint (the plant is the
feedback-linearised arm, the double integrator of Eq 24, so only the controller is timed).
Per round and case: the median step; the figures are the medians over rounds of the
per-round medians and of the per-round ratios (``previous / default``, and ``default`` over
the same round's inactive step, offset 0).

Run: ``python benchmarks/studies/long_horizon_active.py [--rounds 5] [--steps 100]``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks._fixtures import HOMES, PANDA_LOCKED, load_arm  # noqa: E402
from hmpc_pin.compensation.observers import DisturbanceObserver  # noqa: E402
from hmpc_pin.controllers.hierarchical import HierarchicalMPC, MPCSettings  # noqa: E402

STRATEGIES = {"previous": (False, -1), "shifted": (True, -1), "default": (False, 4)}


def run_case(arm, strategy: str, case: str, steps: int, limits) -> tuple[float, dict]:
    """Median step [µs] of one case, with the solver paths' counts per step."""
    ref, robot = arm.reference(), arm.robot
    Ts = 0.001
    ctrl = HierarchicalMPC(robot, MPCSettings(Ts=Ts, N=100, Nc=100),
                           DisturbanceObserver(robot.nq, Ts, 100.0, "general"),
                           limits=limits)  # fmt: skip
    core = ctrl.qps._core
    core.shift, core.active_set_iter = STRATEGIES[strategy]
    t = Ts * np.arange(steps)
    q_ref, dq_ref = ref.sample_many(t)
    ctrl.reset(q_ref[0], dq_ref[0])
    offset = 0.2 if case == "closed loop" else float(case)
    q, dq = q_ref[0] + offset, dq_ref[0].copy()
    times, soft = [], 0
    for i in range(steps):
        if case != "closed loop":
            q, dq = q_ref[i] + offset, dq_ref[i]
        start = time.perf_counter_ns()
        ctrl.step(float(t[i]), q, dq, ref)
        times.append(time.perf_counter_ns() - start)
        soft += ctrl.qps.constrained
        if case == "closed loop":  # the feedback-linearised arm: q̈ = v, exactly (Eq 24)
            v = ctrl.v
            q, dq = q + Ts * dq + 0.5 * Ts * Ts * v, dq + Ts * v
    calls = steps * robot.nq
    counts = {"shortcut": core.unconstrained_solves / calls,
              "active set": core.active_set_solves / calls,
              "cold": core.cold_solves, "soft": soft / steps}  # fmt: skip
    return float(np.median(times)) / 1e3, counts


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument(
        "--limits-steps",
        type=int,
        default=10,
        help="steps of the soft-limit cases (each ≈ 0.1 s with the limits active)",
    )
    args = parser.parse_args()
    arm = load_arm("panda", "panda", HOMES["panda"], "general", PANDA_LOCKED)
    print(f"Panda, Ts = 1 ms, N = Nc = 100; {args.rounds} rounds, strategies alternated\n")
    for limits, cases, steps, rounds in (
        (None, ("0.0", "0.05", "0.2", "closed loop"), args.steps, args.rounds),
        ("urdf", ("0.0", "0.2", "closed loop"), args.limits_steps, 1),
    ):
        med: dict = {}
        counts: dict = {}
        for _ in range(rounds):
            for case in cases:
                for strategy in STRATEGIES:
                    m, c = run_case(arm, strategy, case, steps, limits)
                    med.setdefault((case, strategy), []).append(m)
                    counts[(case, strategy)] = c
        print(f"soft joint limits {'on' if limits else 'off'} ({steps} steps, {rounds} rounds)\n")
        print("| case | strategy | median step [µs] | previous / this | this / inactive "
              "step | shortcut | active set | soft QPs per step |")  # fmt: skip
        print("|---|---|---|---|---|---|---|---|")
        for case in cases:
            for strategy in STRATEGIES:
                times = np.array(med[(case, strategy)])
                speedup = np.median(np.array(med[(case, "previous")]) / times)
                inactive = np.median(times / np.array(med[("0.0", strategy)]))
                c = counts[(case, strategy)]
                label = case if case == "closed loop" else f"held {case} rad off"
                print(
                    f"| {label} | {strategy} | {np.median(times):.0f} | {speedup:.1f} | "
                    f"{inactive:.1f} | {c['shortcut']:.0%} | {c['active set']:.0%} | "
                    f"{c['soft']:.1f} |"
                )
        print()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
