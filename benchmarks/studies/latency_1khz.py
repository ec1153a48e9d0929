"""1 kHz control with a one-cycle latency and the last link lighter than modelled.

For each arm config: Ts = 1 ms, the sweep's default interface model ([sweep.sensing]:
2^19-count encoders, finite-difference velocity at 1 kHz, 1 ms latency, 100 Hz torque
filter), the plant's last link ``--light`` times the model's mass and inertia (others
nominal, friction and pulses at their nominal amplitudes), the config's controller with
the latency compensated (``known``) and not (``unknown``), and the opposite mistake
(``over``: the controller told of a one-cycle latency the interface does not have). Prints
the worst joint's RMS error.

    python benchmarks/studies/latency_1khz.py panda_sine ur5_circle z1_sine --duration 3 --light 0.8
"""

from __future__ import annotations

import argparse
import warnings
from dataclasses import replace

import numpy as np

import hmpc_pin
from hmpc_pin.apps.sweep import SampleParams, run_sample


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("configs", nargs="+")
    parser.add_argument("--duration", type=float, default=3.0)
    parser.add_argument("--light", type=float, default=0.8)
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    print("| config | latency | last link × | worst-joint RMS [rad] | bounded |")
    print("|---|---|---|---|---|")
    for name in args.configs:
        cfg = hmpc_pin.load_config(name)
        n = hmpc_pin.Experiment.from_config(cfg).robot.nq
        for case in ("known", "unknown", "over"):
            sweep = replace(cfg.sweep, known_latency=case == "known", variants=None)
            controller = replace(cfg.controller, Ts=0.001)
            if case == "over":
                sweep = replace(sweep, sensing=replace(sweep.interface, latency=0.0, delay=0))
                controller = replace(controller, latency=0.001)
            c = replace(
                cfg,
                controller=controller,
                simulation=replace(cfg.simulation, duration=args.duration),
                sweep=sweep,
            )
            params = SampleParams(0, (1.0,) * (n - 1) + (args.light,), (1.0,) * n,
                                  (1.0,) * n, 0)  # fmt: skip
            row = run_sample(c, params, "ndo", "all")
            print(f"| {name} | {case} | {args.light:g} | "
                  f"{row['rms_max']:.3e} | {row['bounded']} |")  # fmt: skip
    np.seterr(all="warn")


if __name__ == "__main__":
    main()
