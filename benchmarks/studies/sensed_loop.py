"""Runs with parts written in Python, on the compiled loop and on the per-step loop.

``sensed``: the paper's combined scenario behind
:class:`~hmpc_pin.sim.sensing.SensedController` with the sweep's realistic interface
(``[sweep.sensing]`` defaults: 2^19-count encoders, the velocity a finite difference at
1 kHz, 1 ms latency, the 100 Hz torque filter), the controller told the latency. The
measurement is the same compiled port in both loops; the per-step loop calls it, the
controller and the plant from Python once per period. Rounds alternate the two loops; the
table gives the median wall time of each and their ratio, and
checks that the two runs' arrays are identical.

``python-controller``: the same scenario with computed torque and the momentum observer (a
controller without a compiled step: the compiled loop calls it through its Controller port).

    python benchmarks/studies/sensed_loop.py [--case sensed|python-controller] [--rounds 5]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks._fixtures import PAPER_CONFIG  # noqa: E402
from hmpc_pin import ControllerConfig, make_controller  # noqa: E402
from hmpc_pin.experiment.build import Experiment  # noqa: E402
from hmpc_pin.experiment.config import load_config  # noqa: E402
from hmpc_pin.experiment.config.sensing import SensingConfig  # noqa: E402
from hmpc_pin.sim.result import RESULT_ARRAYS  # noqa: E402
from hmpc_pin.sim.sensing import SensedController  # noqa: E402


def sensed_run(loop: str, duration: float, case: str = "sensed"):
    """One run of the paper's scenario on ``loop``: (wall time [s], result)."""
    experiment = Experiment.from_config(load_config(PAPER_CONFIG))
    if case == "sensed":
        sensing = SensingConfig()
        experiment.controller.set_latency(sensing.latency)
        model = sensing.model(experiment.robot.nq)
        rng = np.random.default_rng(0)
        experiment.controller = SensedController(experiment.controller, model, rng)
    else:
        config = ControllerConfig(kind="computed-torque", compensation="momentum")
        experiment.controller = make_controller(experiment.robot, config)
    start = time.perf_counter()
    result = experiment.run(duration, loop=loop)
    return time.perf_counter() - start, result


def measure(rounds: int, duration: float, case: str = "sensed") -> dict[str, list[float]]:
    """Wall times per loop over ``rounds`` alternating rounds; asserts identical arrays."""
    times: dict[str, list[float]] = {"compiled": [], "python": []}
    for _ in range(rounds):
        results = {}
        for loop in times:
            wall, results[loop] = sensed_run(loop, duration, case)
            assert results[loop].loop == loop and results[loop].complete
            times[loop].append(wall)
        for name in RESULT_ARRAYS:
            a, b = getattr(results["compiled"], name), getattr(results["python"], name)
            assert np.array_equal(a, b, equal_nan=True), f"{name} differs between the loops"
    return times


def table(times: dict[str, list[float]], duration: float, case: str = "sensed") -> str:
    c, p = np.median(times["compiled"]), np.median(times["python"])
    return "\n".join(
        [
            f"{case} paper_combined, {duration:g} s simulated, {len(times['python'])} rounds",
            "| loop | median [s] |",
            "|---|---|",
            f"| per step (python) | {p:.3f} |",
            f"| compiled | {c:.3f} |",
            f"| per step / compiled | **{p / c:.2f}** |",
            "arrays identical between the loops: yes",
        ]
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--duration", type=float, default=10.0)
    parser.add_argument("--case", choices=("sensed", "python-controller"), default="sensed")
    args = parser.parse_args(argv)
    print(table(measure(args.rounds, args.duration, args.case), args.duration, args.case))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
