"""The plant step chosen by its error (``[plant] tolerance``) against the fixed 1 ms step.

For each config: the experiment with its fixed ``plant.dt`` (1 ms) and the same with
``plant.tolerance`` (the step chosen once, at the first plant of a fresh build in each
block; its calibration timed apart, median over blocks),
both with the stick-slip Coulomb law; blocks alternate the two runs (fixed, chosen, fixed,
chosen, ...) so that a shared machine loads each alike; the speed-up is the median over
blocks of fixed / chosen, printed beside the absolute medians, and with the calibration
(a run of its own experiment pays it once): median fixed / (median chosen + calibration).
Accuracy: each run against
a fine one (step Ts/100, the same law): the largest state error max|q − q_fine| [rad] and
the relative change of the tracking RMS (after 1 s, over the joints).

Usage: python benchmarks/studies/plant_step.py [--configs paper_friction paper_external
       paper_combined paper_cartesian panda_sine] [--tolerance 1e-4] [--blocks 5]
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

PAPER = ("paper_friction", "paper_external", "paper_combined", "paper_cartesian")


def _with_plant(config, **kw):
    return replace(config, plant=replace(config.plant, **kw))


def _rms(result) -> float:
    """Tracking RMS [rad] after 1 s over every joint."""
    e = (result.q - result.q_ref)[result.t >= 1.0]
    return float(np.sqrt(np.mean(e**2)))


def _timed(experiment) -> tuple[float, object]:
    t0 = time.perf_counter()
    result = experiment.run()
    return time.perf_counter() - t0, result


def bench(name: str, tolerance: float, blocks: int) -> dict:
    config = load_config(ROOT / "configs" / f"{name}.toml")
    Ts = config.controller.Ts
    fixed = Experiment.from_config(config)
    chosen_config = _with_plant(config, dt=None, tolerance=tolerance)
    fine = Experiment.from_config(_with_plant(config, dt=Ts / 100))
    q_fine = fine.run()
    t_fixed, t_chosen, t_cal = [], [], []
    for _ in range(blocks):
        chosen = Experiment.from_config(chosen_config)  # a fresh build: its calibration
        t0 = time.perf_counter()
        h = chosen.make_plant().h
        t_cal.append(time.perf_counter() - t0)
        a, r_fixed = _timed(fixed)
        b, r_chosen = _timed(chosen)
        t_fixed.append(a)
        t_chosen.append(b)
    calibration = float(np.median(t_cal))
    t_fixed, t_chosen = np.array(t_fixed), np.array(t_chosen)
    rms_fine = _rms(q_fine)
    return {
        "config": name,
        "h": h,
        "speedup": float(np.median(t_fixed / t_chosen)),
        "with_calibration": float(np.median(t_fixed) / (np.median(t_chosen) + calibration)),
        "fixed_s": float(np.median(t_fixed)),
        "chosen_s": float(np.median(t_chosen)),
        "calibration_s": calibration,
        "err_fixed": float(np.abs(r_fixed.q - q_fine.q).max()),
        "err_chosen": float(np.abs(r_chosen.q - q_fine.q).max()),
        "rms_fixed": (_rms(r_fixed) - rms_fine) / rms_fine,
        "rms_chosen": (_rms(r_chosen) - rms_fine) / rms_fine,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--configs", nargs="+", default=[*PAPER, "panda_sine"])
    parser.add_argument("--tolerance", type=float, default=1e-4)
    parser.add_argument("--blocks", type=int, default=5)
    args = parser.parse_args()
    print(f"tolerance {args.tolerance:g} rad, {args.blocks} alternating blocks")
    print("| config | chosen step | speed-up (median of ratios) | fixed 1 ms run | chosen run "
          "| calibration | speed-up with it | max abs(q - q_fine) fixed / chosen "
          "| tracking RMS vs fine fixed / chosen |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|")
    for name in args.configs:
        r = bench(name, args.tolerance, args.blocks)
        print(f"| {r['config']} | {r['h'] * 1e3:.3g} ms | {r['speedup']:.2f}x "
              f"| {r['fixed_s']:.3f} s | {r['chosen_s']:.3f} s | {r['calibration_s']:.3f} s "
              f"| {r['with_calibration']:.2f}x "
              f"| {r['err_fixed']:.2e} / {r['err_chosen']:.2e} rad "
              f"| {r['rms_fixed']:+.2e} / {r['rms_chosen']:+.2e} |", flush=True)  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
