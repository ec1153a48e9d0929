"""The stick-slip plant against the per-stage sign law, at rest and in a closed loop.

An arm at rest sticks at every joint: the stick-slip law (``[plant] coulomb =
"stick-slip"``) then holds it with the closed form of the holding torques (one RNEA at
q̇ = 0 per position) instead of solving the stuck joints' algebra at every stage. Four
scenarios on a config's plant (its disturbance, its step), each timed for both laws in one
process, the laws alternating block by block so that a shared machine loads each alike:

- ``hanging``: at rest in the pose of least gravity torque (joint 0 at 0, ±π/2 or π, the
  others at 0: the arm hanging) with τ = 0, ``--periods`` periods from t = 6 s (after the
  shipped configs' torque pulses);
- ``held``: at rest at q = 0.3 rad per joint with τ = G(q) + ½ of each joint's Coulomb
  level (every joint stuck, its holding torque half its friction), from t = 6 s;
- ``falling``: from rest at q = 0 with τ = 0 from t = 0, the pulses included: a planar arm
  lies horizontal there, falls, swings and comes to rest joint by joint (some joints stuck
  while others move for most of the run);
- ``closed loop``: the config's experiment run as configured (``Experiment.run``).

Printed per scenario: the median over blocks of (stick-slip / sign) beside the absolute
medians of each law, and how far the stick-slip plant moved from its start (0: it stayed at
rest; an arm whose friction does not hold it, or whose pulses push it, moves).

Usage: python benchmarks/studies/plant_at_rest.py [--config paper_combined] [--periods 1000]
       [--blocks 7]
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from hmpc_pin.experiment.build import Experiment  # noqa: E402
from hmpc_pin.experiment.config import load_config  # noqa: E402
from hmpc_pin.sim.plants import friction_in, split_disturbance  # noqa: E402

LAWS = ("stick-slip", "sign")


def _experiments(name: str) -> dict[str, Experiment]:
    config = load_config(ROOT / "configs" / f"{name}.toml")
    return {
        law: Experiment.from_config(replace(config, plant=replace(config.plant, coulomb=law)))
        for law in LAWS
    }


def _coulomb_levels(plant) -> np.ndarray:
    """Each joint's Coulomb level [N·m]: the joint's own F plus the disturbance's b."""
    n = plant.n
    F = plant.joint_dynamics[1] if plant.joint_dynamics is not None else np.zeros(n)
    split = split_disturbance(plant.disturbance, n)
    ab = split[1] if split is not None else friction_in(plant.disturbance, n)
    return F + (ab[1] if ab is not None else 0.0)


def _hanging(robot) -> np.ndarray:
    """The pose of least gravity torque among joint 0 at 0, ±π/2, π (the others at 0)."""
    poses = [np.r_[a, np.zeros(robot.nq - 1)] for a in (0.0, np.pi / 2, -np.pi / 2, np.pi)]
    return min(poses, key=lambda q: float(np.abs(robot.gravity_torque(q)).max()))


#: max |q − q0| [rad] at the end of the last timed scenario of each law (0: it stayed put).
MOVED: dict[str, float] = {}


def _held(experiment, q0: np.ndarray, tau: np.ndarray, periods: int, t0: float) -> float:
    """Seconds for ``periods`` periods of a fresh plant from rest at ``q0`` at ``t0``, τ
    held (how far it moved: :data:`MOVED`)."""
    plant = experiment.make_plant()
    plant.reset(q0, np.zeros_like(q0), t0)
    start = time.perf_counter()
    for _ in range(periods):
        q, _ = plant.advance(tau)
    elapsed = time.perf_counter() - start
    MOVED[plant.coulomb] = float(np.abs(q - q0).max())
    return elapsed


def _closed_loop(experiment) -> float:
    t0 = time.perf_counter()
    experiment.run()
    return time.perf_counter() - t0


def bench(name: str, periods: int, blocks: int) -> list[tuple[str, float, float, float, float]]:
    experiments = _experiments(name)
    probe = experiments["stick-slip"].make_plant()
    n, robot = probe.n, probe.robot
    q_held = np.full(n, 0.3)
    tau_held = robot.gravity_torque(q_held) + 0.5 * _coulomb_levels(probe)
    q_hanging, zero = _hanging(robot), np.zeros(n)
    scenarios = {
        "hanging": lambda e: _held(e, q_hanging, zero, periods, 6.0),
        "held": lambda e: _held(e, q_held, tau_held, periods, 6.0),
        "falling": lambda e: _held(e, zero, zero, periods, 0.0),
        "closed loop": _closed_loop,
    }
    rows = []
    for scenario, fn in scenarios.items():
        MOVED.clear()
        for law in LAWS:  # warm-up (imports, first builds), untimed
            fn(experiments[law])
        times: dict[str, list[float]] = {law: [] for law in LAWS}
        for b in range(blocks):
            for law in LAWS if b % 2 == 0 else LAWS[::-1]:
                times[law].append(fn(experiments[law]))
        a, s = np.array(times["stick-slip"]), np.array(times["sign"])
        moved = MOVED.get("stick-slip", float("nan"))
        rows.append((scenario, float(np.median(a / s)), float(np.median(a)), float(np.median(s)),
                     moved))  # fmt: skip
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="paper_combined")
    parser.add_argument("--periods", type=int, default=1000)
    parser.add_argument("--blocks", type=int, default=7)
    args = parser.parse_args()
    print(f"{args.config}: {args.periods} periods at rest, {args.blocks} alternating blocks")
    print("| scenario | stick-slip / sign (median of ratios) | stick-slip | sign "
          "| stick-slip max abs(q - q0) |")  # fmt: skip
    print("|---|---:|---:|---:|---:|")
    for scenario, ratio, a, s, moved in bench(args.config, args.periods, args.blocks):
        far = "-" if np.isnan(moved) else f"{moved:.2g} rad"
        print(f"| {scenario} | {ratio:.2f}x | {a * 1e3:.1f} ms | {s * 1e3:.1f} ms | {far} |",
              flush=True)  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
