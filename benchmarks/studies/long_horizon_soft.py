"""Long horizons with the default soft joint limits active: Panda started 0.2 rad off its
reference, at Ts = 1 ms, N = Nc = 100 and at Ts = 10 ms, N = Nc = 50 (one QP per joint).

Per scenario, the controller (the URDF's position and velocity limits as soft state
constraints, the default) steps along

- ``soft limits active``: the states of a closed loop started 0.2 rad off on every joint (the
  plant is the feedback-linearised arm, q̈ = v exactly, Eq 24, so that only the controller is
  timed); its predictions leave the velocity limits, so every joint's soft QP is solved;
- ``on the reference``: the reference's own states (the limits' fast path: no soft QP);
- with ``--proxsuite``, also ``soft limits active, ProxSuite only``: the same states with the
  soft active-set shortcut off (``JointQPs.soft_active_set_iter = -1``: every soft QP solved
  from scratch by ProxSuite, the solver's use before).

The closed loop's states are recorded once and replayed (the solutions are exact, so the
replay is the closed loop). The variants alternate block by block (A, B, C, A, B, C, …),
each block restarting its controller; per block the median step over all steps and over
the steps that solved soft QPs (the recording's); the figures are the medians over blocks
of the per-block ratios (to ``on the reference``'s median over all its steps), beside the
medians of the blocks' absolute medians. Also printed: the largest difference of the
accelerations v between the shortcut and ProxSuite along the states, and how the soft QPs
were answered.

Run: ``python benchmarks/studies/long_horizon_soft.py [--blocks 7] [--proxsuite]``.
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
from hmpc_pin.compensation.observers import DisturbanceObserver  # noqa: E402
from hmpc_pin.controllers.hierarchical import HierarchicalMPC, MPCSettings  # noqa: E402

#: (Ts [s], N = Nc, closed-loop steps timed per block)
SCENARIOS = ((0.001, 100, 100), (0.01, 50, 30))
OFFSET = 0.2  # [rad]


def _soft_failures(qps) -> tuple[int, int, int]:
    """The soft shortcut's guesses that did not answer: (pivot, exchanges, KKT) so far."""
    stats = qps._core.stats
    return stats.soft_fail_pivot, stats.soft_fail_exchanges, stats.soft_fail_kkt


def controller(robot, Ts: float, N: int) -> HierarchicalMPC:
    """Panda's controller with the default soft joint limits (the URDF's)."""
    settings = MPCSettings(Ts=Ts, N=N, Nc=N)
    return HierarchicalMPC(robot, settings, DisturbanceObserver(robot.nq, Ts, 100.0, "general"))


def closed_loop(ctrl: HierarchicalMPC, ref, Ts: float, steps: int):
    """States (t, q, dq) of the closed loop started OFFSET rad off, the soft QPs solved at
    each step, and its accelerations v (steps, n)."""
    t = Ts * np.arange(steps)
    q_ref, dq_ref = ref.sample_many(t)
    ctrl.reset(q_ref[0], dq_ref[0])
    q, dq = q_ref[0] + OFFSET, dq_ref[0].copy()
    qs, dqs, vs, soft = [], [], [], []
    for i in range(steps):
        qs.append(q.copy())
        dqs.append(dq.copy())
        ctrl.step(float(t[i]), q, dq, ref)
        soft.append(ctrl.qps.constrained)
        v = ctrl.v.copy()
        vs.append(v)
        q, dq = q + Ts * dq + 0.5 * Ts * Ts * v, dq + Ts * v
    return (t, np.array(qs), np.array(dqs)), np.array(soft), np.array(vs)


def alternate(variants: dict, states: dict, blocks: int) -> dict[str, np.ndarray]:
    """Per variant, the step times [µs] of each block (blocks, steps): every variant's
    controller restarted and stepped along its states, the variants in turn."""
    clock = time.perf_counter_ns
    out: dict[str, list[np.ndarray]] = {name: [] for name in variants}
    for _ in range(blocks):
        for name, (ctrl, ref) in variants.items():
            t, q, dq = states[name]
            calls = [(float(t[i]), q[i].copy(), dq[i].copy()) for i in range(len(t))]
            ctrl.reset(q[0], dq[0])
            step = ctrl.step
            samples = np.empty(len(calls))
            for j, (ti, qi, dqi) in enumerate(calls):
                t0 = clock()
                step(ti, qi, dqi, ref)
                samples[j] = clock() - t0
            out[name].append(samples / 1e3)
    return {name: np.array(v) for name, v in out.items()}


def replay_v(ctrl: HierarchicalMPC, ref, states) -> np.ndarray:
    """The accelerations v of ``ctrl`` along recorded states."""
    t, q, dq = states
    ctrl.reset(q[0], dq[0])
    out = []
    for i in range(len(t)):
        ctrl.step(float(t[i]), q[i], dq[i], ref)
        out.append(ctrl.v.copy())
    return np.array(out)


def scenario(arm, Ts: float, N: int, steps: int, blocks: int, proxsuite: bool) -> None:
    robot, ref = arm.robot, arm.reference()
    active = controller(robot, Ts, N)
    states, soft, v_loop = closed_loop(active, ref, Ts, steps)
    t = states[0]
    q_ref, dq_ref = ref.sample_many(t)
    variants = {
        "soft limits active": (active, ref),
        "on the reference": (controller(robot, Ts, N), ref),
    }
    by_name = {"soft limits active": states, "on the reference": (t, q_ref, dq_ref)}
    if proxsuite:
        plain = controller(robot, Ts, N)
        plain.qps.soft_active_set_iter = -1
        variants["soft limits active, ProxSuite only"] = (plain, ref)
        by_name["soft limits active, ProxSuite only"] = states
    qps = active.qps
    before = (qps.soft_active_set_solves, _soft_failures(qps))
    times = alternate(variants, by_name, blocks)
    base = np.median(times["on the reference"], axis=1)  # per block
    mask = soft > 0
    print(f"Ts = {Ts * 1e3:g} ms, N = Nc = {N}: {steps} steps per block, {blocks} blocks; "
          f"closed loop from {OFFSET} rad off: soft QPs solved at {mask.sum()} of {steps} "
          f"steps, {soft[mask].mean():.1f} per such step (of {robot.nq} joints)\n")  # fmt: skip
    print("| variant | steps | median step [µs] | / step on the reference "
          "(median of block ratios) | worst step [µs] (median over blocks) |")  # fmt: skip
    print("|---|---|---|---|---|")
    for name, samples in times.items():
        rows = [("all", samples)]
        if name != "on the reference":
            rows.append(("with soft QPs", samples[:, mask]))
        for label, x in rows:
            med = np.median(x, axis=1)
            worst = np.median(x.max(axis=1))
            print(f"| {name} | {label} | {np.median(med):.0f} | {np.median(med / base):.1f} "
                  f"| {worst:.0f} |")  # fmt: skip
    solved = qps.soft_active_set_solves - before[0]
    fails = np.subtract(_soft_failures(qps), before[1])
    print(f"\nsoft QPs answered by the soft active-set shortcut: {solved} of "
          f"{blocks * soft.sum()} (guesses that did not answer: pivot {fails[0]}, "
          f"exchanges {fails[1]}, KKT {fails[2]})")  # fmt: skip
    if proxsuite:
        v_plain = replay_v(plain, ref, states)
        print(f"largest |v(shortcut) − v(ProxSuite)| along the closed loop: "
              f"{np.abs(v_loop - v_plain).max():.2e} rad/s²")  # fmt: skip
    print()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--blocks", type=int, default=7)
    parser.add_argument(
        "--proxsuite",
        action="store_true",
        help="also time the soft QPs solved by ProxSuite alone (slow)",
    )
    args = parser.parse_args()
    print("command: python benchmarks/studies/long_horizon_soft.py " + " ".join(sys.argv[1:]))
    print(f"load average at start: {' '.join(f'{x:.2f}' for x in os.getloadavg())}\n")
    arm = load_arm("panda", "panda", HOMES["panda"], "general", PANDA_LOCKED)
    for Ts, N, steps in SCENARIOS:
        scenario(arm, Ts, N, steps, args.blocks, args.proxsuite)
    print(f"load average at end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
