"""Cost of sampling a 7-joint reference over the MPC horizon, per control step (issue 16).

The controller calls ``reference.sample_many(times, out)`` once per step with the N = 10
horizon instants t_k + jTs into its own buffers, rows 2..N+1 (r) and N+2..2N+1 (ṙ) of one
(2N + 2, 7) array (HierarchicalMPC's stack, reproduced here). Timed here for the references of
the tasks layer on Panda (7 joints), each against the floor of the same process, the
paper's ``SineReference`` (7 joints): blocks of calls alternate between the reference and
the floor, and the ratio of their medians is taken per block; the report gives the median
of those ratios beside the absolute medians. Also timed: what happens once, before a run
(loading and checking the CSV, TOPP-RA retiming, pink's IK of the 10 s circle).

Usage: python benchmarks/studies/reference_sampling.py [--blocks 30] [--calls 2000]
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

import hmpc_pin
from hmpc_pin.experiment.build import Experiment

CONFIGS = Path(__file__).resolve().parents[2] / "configs"


def _block(ref, times_list, out) -> float:
    """Median duration [µs] of ``ref.sample_many`` over one block of horizons."""
    samples = np.empty(len(times_list))
    for i, times in enumerate(times_list):
        t0 = time.perf_counter_ns()
        ref.sample_many(times, out)
        samples[i] = time.perf_counter_ns() - t0
    return float(np.median(samples)) / 1e3


def _once(make) -> tuple[object, float]:
    t0 = time.perf_counter()
    obj = make()
    return obj, time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--blocks", type=int, default=30, help="alternating blocks [30]")
    parser.add_argument("--calls", type=int, default=2000, help="calls per block [2000]")
    args = parser.parse_args()

    def experiment(name, **sim):
        config = hmpc_pin.load_config(CONFIGS / f"{name}.toml")
        return Experiment.from_config(replace(config, simulation=replace(config.simulation,
                                                                         **sim)))  # fmt: skip

    traj_exp, t_traj = _once(lambda: experiment("panda_trajectory"))
    circle_exp, t_circle = _once(lambda: experiment("panda_circle"))
    cubic = traj_exp.reference
    quintic = hmpc_pin.JointTrajectory(cubic.times, *cubic.sample_many(cubic.times),
                                       joint_names=cubic.joint_names)  # fmt: skip
    way = np.array([[0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785],
                    [0.4, -0.5, 0.2, -2.0, 0.3, 1.8, 0.5],
                    [-0.2, -0.6, -0.3, -2.3, 0.2, 1.3, 0.9]])  # fmt: skip
    robot = traj_exp.robot
    waypoints, t_toppra = _once(
        lambda: hmpc_pin.retime_waypoints(way, robot.velocity_limit, 2.0, dt=0.01)
    )
    floor = hmpc_pin.SineReference(7, amplitude=0.3, frequency=0.1, offset=way[0])
    refs = {
        "JointTrajectory, cubic spline (panda_trajectory.csv, 161 samples)": cubic,
        "JointTrajectory, quintic Hermite (same samples + velocities)": quintic,
        f"JointTrajectory from TOPP-RA ({waypoints.times.size} samples)": waypoints,
        "PoseReference (panda_circle, pink IK, 10 ms samples)": circle_exp.reference,
    }
    Ts, N = 0.01, 10
    rng = np.random.default_rng(0)
    starts = rng.uniform(0.0, 9.0, args.calls)
    times_list = [t + Ts * np.arange(1, N + 1) for t in starts]
    stack = np.empty((2 * N + 2, 7))  # HierarchicalMPC's layout: q, q̇, then r and ṙ rows
    out = (stack[2 : N + 2], stack[N + 2 :])
    print("| reference (Panda, 7 joints, N = 10) | median [µs] | floor: sine, median [µs] "
          "| ratio to the floor (median of block ratios) |")  # fmt: skip
    print("|---|---|---|---|")
    for name, ref in refs.items():
        for _ in range(3):  # warm-up
            _block(ref, times_list, out)
            _block(floor, times_list, out)
        mine, base, ratios = [], [], []
        for _ in range(args.blocks):
            a = _block(ref, times_list, out)
            b = _block(floor, times_list, out)
            mine.append(a)
            base.append(b)
            ratios.append(a / b)
        print(f"| {name} | {np.median(mine):.2f} | {np.median(base):.2f} | "
              f"{np.median(ratios):.2f} |")  # fmt: skip
    print()
    # The whole controller step with the sine and with the cubic spline through the sine's
    # 10 ms samples: the same motion, the same states (on the sine), only the reference differs.
    controller = circle_exp.controller
    grid = np.arange(0.0, 12.0 + Ts / 2, Ts)
    spline = hmpc_pin.JointTrajectory(grid, floor.sample_many(grid)[0], boundary="not-a-knot")
    steps = [(float(t), *floor.sample(float(t))) for t in np.arange(0.0, 8.0, Ts)]

    def step_block(ref) -> float:
        controller.reset(steps[0][1], steps[0][2])
        samples = np.empty(len(steps))
        for i, (t, q, dq) in enumerate(steps):
            t0 = time.perf_counter_ns()
            controller.step(t, q, dq, ref)
            samples[i] = time.perf_counter_ns() - t0
        return float(np.median(samples)) / 1e3

    print(
        "| `HierarchicalMPC.step` (Panda, hmpc+general, 800 steps on the sine's states) with "
        "| median [µs] | with the sine itself, median [µs] | ratio (median of block ratios) |"
    )
    print("|---|---|---|---|")
    mine, base, ratios = [], [], []
    for _ in range(max(3, args.blocks // 3)):
        a, b = step_block(spline), step_block(floor)
        mine.append(a)
        base.append(b)
        ratios.append(a / b)
    print(f"| JointTrajectory, cubic spline through the sine's 10 ms samples | "
          f"{np.median(mine):.2f} | {np.median(base):.2f} | "
          f"{np.median(ratios):.2f} |")  # fmt: skip
    print()
    print("| once, before a run | wall time [s] |")
    print("|---|---|")
    print(f"| `Experiment.from_config(panda_trajectory)` (robot, CSV, limit checks) | "
          f"{t_traj:.2f} |")  # fmt: skip
    print(f"| `Experiment.from_config(panda_circle)` (robot, pink IK of 10.12 s at 10 ms, "
          f"checks) | {t_circle:.2f} |")  # fmt: skip
    print(f"| `retime_waypoints` (3 Panda waypoints, TOPP-RA + checks) | {t_toppra:.2f} |")


if __name__ == "__main__":
    main()
