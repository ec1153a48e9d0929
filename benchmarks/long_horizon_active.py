"""Long horizons with active constraints: Panda at Ts = 1 ms, N = Nc = 100 (one QP per
joint), the measured state held a fixed offset away from the reference so that the
acceleration bounds (and, with the URDF limits on, the soft joint limits) are active.

BENCHMARKS.md's long-horizon figure is measured on the reference's own states, where every
joint takes the unconstrained shortcut. This script shows the other end: how long a step
takes when ProxSuite has to solve 100-variable QPs with many active bounds (and 400-row
soft-limit QPs, solved cold). Median over 100 steps, both layouts of limits.

Run: ``python benchmarks/long_horizon_active.py``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks._fixtures import HOMES, PANDA_LOCKED, load_arm  # noqa: E402
from hmpc_pin.compensation.observers import DisturbanceObserver  # noqa: E402
from hmpc_pin.controllers.hierarchical import HierarchicalMPC, MPCSettings  # noqa: E402


def main() -> int:
    arm = load_arm("panda", "panda", HOMES["panda"], "general", PANDA_LOCKED)
    ref, robot = arm.reference(), arm.robot
    Ts = 0.001
    t = Ts * np.arange(100)
    q, dq = ref.sample_many(t)
    print("| soft joint limits | offset [rad] | median step [µs] | joints solved by the "
          "shortcut | soft QPs per step |")  # fmt: skip
    print("|---|---|---|---|---|")
    for limits in ("urdf", None):
        for offset in (0.0, 0.05, 0.2):
            ctrl = HierarchicalMPC(robot, MPCSettings(Ts=Ts, N=100, Nc=100),
                                   DisturbanceObserver(robot.nq, Ts, 100.0, "general"),
                                   limits=limits)  # fmt: skip
            ctrl.reset(q[0], dq[0])
            times, soft = [], 0
            for i in range(len(t)):
                start = time.perf_counter_ns()
                ctrl.step(float(t[i]), q[i] + offset, dq[i], ref)
                times.append(time.perf_counter_ns() - start)
                soft += ctrl._core.constrained if ctrl.native else ctrl.qps.constrained
            count = ctrl._core.unconstrained_solves if ctrl.native else (
                ctrl.qps.unconstrained_solves)  # fmt: skip
            print(f"| {'on' if limits else 'off'} | {offset} | {np.median(times) / 1e3:.0f} | "
                  f"{count / (len(t) * robot.nq):.0%} | {soft / len(t):.1f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
