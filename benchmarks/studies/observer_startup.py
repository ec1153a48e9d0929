"""The observer's start-up transient on the paper's runs: what causes it.

Measures, on the three paper scenarios (hmpc + chen observer, c = 100), the peak
|d − d̂| over the first second and when it happens, and varies one suspect at a time:
the control period Ts (the observer is updated once per period: discretisation), the
plant step, the observer's discrete form, and the start-up torque (starting on the
reference, q0 = r(0), removes the 1 rad initial error and its ~2 000 N·m torque).

Usage: python benchmarks/studies/observer_startup.py
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np

import hmpc_pin
from hmpc_pin.experiment.build import Experiment
from hmpc_pin.experiment.config import load_config

CONFIGS = Path(hmpc_pin.__file__).parent / "data" / "configs"


def variants(cfg):
    cc, sim = cfg.controller, cfg.simulation
    obs = cc.observer
    yield "paper (Ts 0.01, plant 1 ms, implicit)", cfg
    for Ts in (0.005, 0.002):
        yield f"Ts = {Ts:g}", replace(cfg, controller=replace(cc, Ts=Ts))
    yield "plant step 0.1 ms", replace(cfg, plant=replace(cfg.plant, dt=0.0001))
    yield (
        "explicit observer",
        replace(cfg, controller=replace(cc, observer=replace(obs, discretization="explicit"))),
    )
    yield "start on the reference (q0 = r(0))", replace(cfg, simulation=replace(sim, q0=None))


def main() -> None:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args()
    print(
        "| scenario | variant | peak |d − d̂| in 0–1 s [N·m] (at t [s]) per joint | "
        "peak |τ| in 0–1 s [N·m] | RMS d − d̂ 1–10 s [N·m] |"
    )
    print("|---|---|---|---|---|")
    for name in ("paper_friction", "paper_external", "paper_combined"):
        for label, cfg in variants(load_config(CONFIGS / f"{name}.toml")):
            try:
                r = Experiment.from_config(cfg).run()
            except hmpc_pin.SimulationError as exc:
                print(f"| {name} | {label} | run failed: {str(exc).split(':')[0]} | | |")
                continue
            early = r.t < 1.0
            w = np.abs(r.observer_error)
            peak = w[early].max(axis=0)
            when = r.t[early][np.argmax(w[early], axis=0)]
            tau = np.abs(r.tau[early]).max(axis=0)
            late = np.sqrt(np.mean(r.observer_error[~early] ** 2, axis=0))
            cells = ", ".join(f"{p:.1f} ({t:.2f})" for p, t in zip(peak, when, strict=True))
            print(
                f"| {name} | {label} | {cells} | {', '.join(f'{x:.0f}' for x in tau)} | "
                f"{', '.join(f'{x:.2f}' for x in late)} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
