"""The closed loop's benchmarks: the paper's 10 s run (with the plant alone as its floor)
and memory over long runs, each in a fresh process."""

from __future__ import annotations

import contextlib
import json
import subprocess
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks._fixtures import (  # noqa: E402
    PAPER_CONFIG,
    MiB,
    Settings,
    log,
)
from benchmarks.harness import LOOP_ORACLE, per_step_oracle  # noqa: E402
from benchmarks.ratios import aba_floor  # noqa: E402
from benchmarks.steps import GravityCompensation  # noqa: E402
from hmpc_pin.experiment.build import Experiment  # noqa: E402
from hmpc_pin.experiment.config import load_config  # noqa: E402


@dataclass
class SimResult:
    """Wall times of the paper's 10 s scenario [s].

    Attributes:
        build: ``Experiment.from_config`` wall times [s].
        run: ``Experiment.run()`` wall times [s].
        plant_only: The same simulation with :class:`GravityCompensation` instead of
            the MPC [s] (plant integration, disturbance and loop overhead).
        duration: Simulated time [s]. complete: Whether every run finished.
    """

    build: list[float]
    run: list[float]
    plant_only: list[float]
    duration: float
    complete: bool
    aba_only: list[float] = field(default_factory=list)

    @property
    def median(self) -> float:
        """Median wall time of ``run()`` [s]."""
        return float(np.median(self.run))

    @property
    def rtf(self) -> float:
        """Real-time factor: simulated time / median wall time."""
        return self.duration / self.median


def plant_floor(plant, periods: int) -> float:
    """Wall time [s] of the plant alone over ``periods`` control periods, τ = 0 held from
    rest at zero: the native plant's ``advance`` calls (kernel, disturbance table), or for
    the Python plant its ``4 · substeps · periods`` bare ``pin.aba`` calls."""
    if not getattr(plant, "native", False):
        return aba_floor(plant, 4 * plant.substeps * periods)
    n = plant.nq
    plant.reset(np.zeros(n), np.zeros(n))
    tau = np.zeros(n)
    start = time.perf_counter()
    for _ in range(periods):
        plant.advance(tau)
    return time.perf_counter() - start


def bench_simulation(settings: Settings) -> SimResult:
    """Wall time of ``Experiment.from_config(cfg)`` and of ``.run()`` on the paper scenario."""
    cfg = load_config(PAPER_CONFIG)
    build, run, plant_only, aba_only = [], [], [], []
    complete = True
    for _ in range(settings.sim_repeats):
        t0 = time.perf_counter()
        exp = Experiment.from_config(cfg)
        t1 = time.perf_counter()
        result = exp.run()
        t2 = time.perf_counter()
        build.append(t1 - t0)
        run.append(t2 - t1)
        complete &= bool(result.complete)
        t0 = time.perf_counter()
        replace(exp, controller=GravityCompensation(exp.robot, exp.controller.Ts)).run()
        plant_only.append(time.perf_counter() - t0)
        plant = exp.make_plant()
        periods = round(cfg.simulation.duration / exp.controller.Ts)
        aba_only.append(plant_floor(plant, periods))
    out = SimResult(build, run, plant_only, cfg.simulation.duration, complete, aba_only)
    log(
        f"  10 s simulation: median {out.median:.3f} s, real-time factor {out.rtf:.1f}; "
        f"with tau = G(q) instead of the MPC {np.median(plant_only):.3f} s"
    )
    return out


def run_memory_child(duration: float, every: float) -> dict:
    """Run ``benchmarks/memory.py`` in a fresh interpreter and return its JSON result."""
    cmd = [sys.executable, "-m", "benchmarks.memory", "--duration", str(duration)]
    cmd += ["--every", str(every)]
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{proc.stderr}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


@dataclass
class MemoryResult:
    """RSS figures [bytes] of the 10 s run and of the soak."""

    peak: dict
    soak: dict

    @property
    def soak_rss(self) -> np.ndarray:
        """Sampled RSS of the soak [bytes]."""
        return np.array([s[1] for s in self.soak["samples"]], dtype=float)

    @property
    def growth_start(self) -> float:
        """Simulated time of the sample the growth is measured from [s]: the second one
        (after the first interval, once every buffer of the run exists)."""
        samples = self.soak["samples"]
        return float(samples[min(1, len(samples) - 1)][0])

    @property
    def soak_growth(self) -> float:
        """RSS growth from the sample at :attr:`growth_start` to the last [bytes]."""
        rss = self.soak_rss
        return float(rss[-1] - rss[min(1, rss.size - 1)])


def bench_memory(settings: Settings) -> MemoryResult:
    """Peak RSS of the 10 s scenario and RSS over the soak, each in a fresh process."""
    peak = run_memory_child(10.0, 0.0)
    log(f"  peak RSS of the 10 s run: {peak['peak_rss'] / MiB:.1f} MiB")
    soak = run_memory_child(settings.soak_duration, settings.soak_every)
    out = MemoryResult(peak, soak)
    rss = out.soak_rss / MiB
    log(
        f"  soak {settings.soak_duration:g} s: RSS first {rss[0]:.1f}, last {rss[-1]:.1f}, "
        f"max {rss.max():.1f} MiB"
    )
    return out


def ab_loops(rounds: int, config: Path = PAPER_CONFIG, oracle: Path = LOOP_ORACLE) -> dict:
    """The paper's 10 s run per step in Python and in compiled chunks
    (the oracle of ``tests/reference/loop.py``, loaded from the file ``oracle``, and
    ``Experiment.run``), alternating in this process, beside
    the plant's period alone over the same 1000 periods (the compiled loop's floor).

    Returns:
        Medians [s] of each and the median over rounds of python / compiled.
    """
    per_step = per_step_oracle(oracle)
    exp = Experiment.from_config(load_config(config))
    periods = round(exp.config.simulation.duration / exp.controller.Ts)
    exp.run()  # warm
    times: dict[str, list[float]] = {"python": [], "compiled": [], "plant": []}
    for _ in range(rounds):
        for loop in ("python", "compiled"):
            start = time.perf_counter()
            with per_step() if loop == "python" else contextlib.nullcontext():
                result = exp.run()
            times[loop].append(time.perf_counter() - start)
            assert result.complete and result.loop == {"python": "per-step"}.get(loop, loop)
        times["plant"].append(plant_floor(exp.make_plant(), periods))
    py, co, pl = (np.array(times[k]) for k in ("python", "compiled", "plant"))
    out = {
        "python_s": float(np.median(py)),
        "compiled_s": float(np.median(co)),
        "plant_s": float(np.median(pl)),
        "speedup": float(np.median(py / co)),
        "compiled_over_plant": float(np.median(co / pl)),
        "rounds": rounds,
    }
    print(
        f"paper 10 s run: per step {out['python_s'] * 1e3:.1f} ms, compiled "
        f"{out['compiled_s'] * 1e3:.1f} ms, python/compiled {out['speedup']:.2f} "
        f"(rounds: {np.round(py / co, 2)}); the plant's periods alone "
        f"{out['plant_s'] * 1e3:.1f} ms (compiled / plant {out['compiled_over_plant']:.2f})"
    )
    return out


if __name__ == "__main__":
    import argparse

    parser = argparse.ArgumentParser(description=ab_loops.__doc__)
    parser.add_argument("--rounds", type=int, default=15)
    parser.add_argument("--config", type=Path, default=PAPER_CONFIG)
    parser.add_argument(
        "--oracle",
        type=Path,
        default=LOOP_ORACLE,
        metavar="PATH",
        help="the per-step loop oracle's file [tests/reference/loop.py of this clone]",
    )
    args = parser.parse_args()
    json.dump(ab_loops(args.rounds, args.config, args.oracle), sys.stdout)
    print()
