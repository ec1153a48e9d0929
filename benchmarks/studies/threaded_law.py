"""The two-rate law's cycle with the MPC in the cycle or in its compiled thread.

Panda (``panda_sine``'s arm and reference), the arm's period P = 1 ms, the MPC every
Ts = 10 ms with a long horizon (``--horizon`` N, ``--nc`` Nc; default 100, 10), the default
soft joint limits, a closed loop against the package's RK4 plant from 0.2 rad off on every
joint. Two laws, timed in alternating blocks (A, B, A, B, ...), each block a new run of
``--cycles`` cycles:

- ``synchronous``: :class:`~hmpc_pin.realtime.inner_law.InnerLawEveryCycle`, the MPC's
  whole step inside the cycle that needs it (every 10th);
- ``threaded``: :class:`~hmpc_pin.realtime.threaded_law.InnerLawThreaded`, the MPC in
  its compiled planner thread, the cycle taking the latest plan within 2 Ts.

The cycles are paced at 1 kHz (a sleep, then a spin of the last 200 µs), as the arm's
clock would. Per law: the compute of ``law.step`` per cycle (the plant excluded) over every
cycle but the first of every block: p50, p99, max [µs], for all cycles and for the MPC's
cycles (the first cycle apart: the run's set-up); the worst joint's
RMS error over the last half of each run (the median over blocks) [rad]; the threaded
law's brake fallbacks. Load average printed. Wall clock on a shared machine: a
measurement, not a test.

Run: ``python benchmarks/studies/threaded_law.py [--blocks 4] [--cycles 2000]``.
"""

from __future__ import annotations

import argparse
import os
import time
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def _run(kind, robot, settings, q0, reference, cycles):
    from hmpc_pin.compensation.observers import default_observer
    from hmpc_pin.controllers.hierarchical import HierarchicalMPC
    from hmpc_pin.sim import RK4Plant

    law = kind(HierarchicalMPC(robot, settings), default_observer(robot.nq, 1e-3), 1e-3, None)
    plant = RK4Plant(robot, Ts=1e-3, dt=1e-3)
    q = np.asarray(q0, dtype=float) + 0.2
    dq = np.zeros(robot.nq)
    plant.reset(q, dq)
    law.reset(q, dq)
    dt = np.empty(cycles)
    err = np.empty((cycles, robot.nq))
    clock = time.perf_counter_ns
    start = clock()
    for k in range(cycles):
        t = k * 1e-3
        due = start + k * 1_000_000  # paced at 1 kHz: sleep, then spin the last 200 us
        if due - clock() > 300_000:
            time.sleep((due - clock() - 200_000) * 1e-9)
        while clock() < due:
            pass
        t0 = clock()
        tau = law.step(t, q, dq, reference)
        dt[k] = (clock() - t0) * 1e-3
        err[k] = q - reference.sample(t)[0]
        q, dq = plant.advance(tau)
    fallbacks = getattr(law, "fallbacks", 0)
    if hasattr(law, "close"):
        law.close()
    rms = np.sqrt(np.mean(err[cycles // 2 :] ** 2, axis=0)).max()
    return dt, rms, fallbacks, law.mpc_every


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--blocks", type=int, default=4)
    parser.add_argument("--cycles", type=int, default=2000)
    parser.add_argument("--horizon", type=int, default=100)
    parser.add_argument("--nc", type=int, default=10)
    args = parser.parse_args()
    warnings.simplefilter("ignore")

    from hmpc_pin.experiment.build import Experiment
    from hmpc_pin.experiment.config import load_config
    from hmpc_pin.realtime.inner_law import InnerLawEveryCycle
    from hmpc_pin.realtime.threaded_law import InnerLawThreaded

    exp = Experiment.from_config(load_config(ROOT / "configs" / "panda_sine.toml"))
    settings = replace(exp.controller.settings, Ts=0.01, N=args.horizon, Nc=args.nc)
    laws = {"synchronous": InnerLawEveryCycle, "threaded": InnerLawThreaded}
    times = {name: [] for name in laws}
    rms = {name: [] for name in laws}
    falls = {name: 0 for name in laws}
    m = 10
    for _ in range(args.blocks):
        for name, kind in laws.items():
            dt, e, f, m = _run(kind, exp.robot, settings, exp.q0, exp.reference, args.cycles)
            times[name].append(dt)
            rms[name].append(e)
            falls[name] += f
    print(
        f"panda, P = 1 ms, Ts = 10 ms, N = {args.horizon}, Nc = {args.nc}, "
        f"{args.blocks} blocks of {args.cycles} cycles"
    )
    for name in laws:
        dt = np.concatenate(times[name])
        mpc = np.concatenate([np.arange(args.cycles) % m == 0] * args.blocks)
        first = np.concatenate([np.arange(args.cycles) == 0] * args.blocks)
        start = dt[first].max()  # the first cycle (the run's set-up)
        dt, mpc = dt[~first], mpc[~first]
        p = np.percentile(dt, [50, 99])
        q = np.percentile(dt[mpc], [50, 99])
        print(
            f"  {name:12s} all cycles p50 {p[0]:.0f}, p99 {p[1]:.0f}, max {dt.max():.0f} us; "
            f"MPC cycles p50 {q[0]:.0f}, p99 {q[1]:.0f}, max {dt[mpc].max():.0f} us; "
            f"worst joint RMS {np.median(rms[name]):.3e} rad; fallbacks {falls[name]}; "
            f"first cycle (max over blocks) {start:.0f} us"
        )
    print(f"  load average: {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
