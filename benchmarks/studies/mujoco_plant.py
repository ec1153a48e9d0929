"""The paper's 10 s combined run on the MuJoCo plant against the Pinocchio RK4 plant.

Three settings of the same closed loop (HMPC + Chen's NDO, Ts = 10 ms, plant step 1 ms,
10 s simulated), built by ``Experiment.from_config``:

* ``rk4``: ``configs/paper_combined.toml``, Pinocchio's ABA integrated by RK4, friction
  and pulses as the disturbance formula (the floor of the comparison);
* ``mujoco``: ``configs/paper_combined_mujoco.toml``, MuJoCo (implicitfast), the arm's own
  joint friction (frictionloss + damping) and the pulses as generalized forces;
* ``mujoco-formula``: ``paper_combined.toml`` with ``[plant] engine = "mujoco"``: the
  same friction formula called in Python at every MuJoCo step.

For each, two wall times: the whole ``Experiment.run()`` and the plant alone (the sum of
its ``advance`` calls inside that run). The settings run in alternating blocks in one
process; each block gives a ratio to the ``rk4`` run of the same block, and the table
reports the median of those ratios beside the absolute medians.

Run from the repository root: ``python benchmarks/studies/mujoco_plant.py [--blocks 7]``.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from hmpc_pin.experiment.build import Experiment
from hmpc_pin.experiment.config import PlantConfig, load_config

ROOT = Path(__file__).resolve().parents[2]


class _TimedPlant:
    """A plant whose ``advance`` calls are timed (everything else delegated)."""

    def __init__(self, plant):
        self.plant = plant
        self.advance_ns = 0

    def advance(self, tau):
        start = time.perf_counter_ns()
        out = self.plant.advance(tau)
        self.advance_ns += time.perf_counter_ns() - start
        return out

    def __getattr__(self, name):
        return getattr(self.plant, name)


def settings() -> dict:
    """The three experiment configs, by name."""
    base = load_config(ROOT / "configs" / "paper_combined.toml")
    return {
        "rk4": base,
        "mujoco": load_config(ROOT / "configs" / "paper_combined_mujoco.toml"),
        "mujoco-formula": replace(base, plant=PlantConfig(engine="mujoco")),
    }


def run_once(config) -> tuple[float, float, float]:
    """``(run wall time [s], plant wall time [s], worst-joint RMS after 1 s [rad])``."""
    exp = Experiment.from_config(config)
    plant = _TimedPlant(exp.make_plant())
    exp.make_plant = lambda: plant
    start = time.perf_counter()
    result = exp.run()
    wall = time.perf_counter() - start
    e = result.error[result.t >= 1.0]
    return wall, plant.advance_ns / 1e9, float(np.sqrt(np.mean(e * e, axis=0)).max())


def measure(blocks: int) -> dict:
    """Alternating blocks; per setting the absolute times and the ratios to ``rk4``."""
    configs = settings()
    for config in configs.values():  # warm-up: imports, MuJoCo compile cache
        run_once(replace(config, simulation=replace(config.simulation, duration=1.5)))
    rows = {name: {"run": [], "plant": [], "rms": []} for name in configs}
    for _ in range(blocks):
        block = {name: run_once(config) for name, config in configs.items()}
        for name, (wall, plant, rms) in block.items():
            rows[name]["run"].append(wall)
            rows[name]["plant"].append(plant)
            rows[name]["rms"].append(rms)
            rows[name].setdefault("run_ratio", []).append(wall / block["rk4"][0])
            rows[name].setdefault("plant_ratio", []).append(plant / block["rk4"][1])
    return rows


def table(rows: dict, blocks: int) -> str:
    """The Markdown table of :func:`measure`'s rows."""
    lines = [
        f"{blocks} alternating blocks, medians; ratios: median over blocks of the ratio to "
        "rk4 in the same block",
        "",
        "| plant | run() [s] | run / rk4 | plant advance [s] | plant / rk4 "
        "| worst RMS (t≥1 s) [rad] |",
        "|---|---|---|---|---|---|",
    ]
    for name, r in rows.items():
        lines.append(
            f"| {name} | {np.median(r['run']):.3f} | {np.median(r['run_ratio']):.2f} | "
            f"{np.median(r['plant']):.3f} | {np.median(r['plant_ratio']):.2f} | "
            f"{np.median(r['rms']):.2e} |"
        )
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--blocks", type=int, default=7, help="alternating blocks [7]")
    args = parser.parse_args(argv)
    print(table(measure(args.blocks), args.blocks))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
