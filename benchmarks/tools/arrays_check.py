"""Refactoring check at floating-point identity: every array of every shipped config.

A restructuring of the engine (files moved, errors translated, settings typed) must not change
a single result beyond the last bit of a reordered sum. Record on the code as it was, change
the code, then compare:

    python benchmarks/tools/arrays_check.py record /tmp/before      # on the old code
    python benchmarks/tools/arrays_check.py compare /tmp/before     # on the new code

``record`` runs every shipped config (``hmpc_pin/data/configs/*.toml`` and any
``configs/*.toml`` that differs from it) for its shipped duration (``--duration`` shortens
every run alike), once as configured and once on the per-step oracle loop
(``tests/reference/loop.py``, loaded from its file: ``--oracle``), and
a few runs with the interface models of ``hmpc_pin.sim.sensing`` (the 0.3 white noise and
whole-period delay, and the realistic encoder, finite difference, latency and torque filter),
seeded. Each run's arrays (:data:`~hmpc_pin.sim.result.RESULT_ARRAYS`, the task-space arrays,
``extra``), its completion and its message go to ``<dir>/<name>.npz``. ``compare`` reruns
them and asserts that the same arrays exist and that each is equal to ``--tol`` (default
1e-12) relative to max(1, the array's largest magnitude), NaN where NaN; exit 1 otherwise.
Saved outputs are used only here: tests compare against independent computations.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks.harness import LOOP_ORACLE, per_step_oracle  # noqa: E402
from benchmarks.tools import saved_outputs  # noqa: E402
from hmpc_pin.controllers.wrappers import MeasuredController  # noqa: E402
from hmpc_pin.exceptions import SimulationError  # noqa: E402
from hmpc_pin.experiment.build import Experiment  # noqa: E402
from hmpc_pin.experiment.config import load_config  # noqa: E402
from hmpc_pin.experiment.config.sensing import SensingConfig  # noqa: E402
from hmpc_pin.sim.result import RESULT_ARRAYS, TASK_ARRAYS  # noqa: E402
from hmpc_pin.sim.sensing import SensedController  # noqa: E402

#: The per-step oracle's ``per_step()`` (:func:`main` loads it from ``--oracle``).
per_step = None


def shipped_configs() -> list[Path]:
    """The package's configs, then those of ``configs/`` whose text differs."""
    shipped = sorted((ROOT / "hmpc_pin" / "data" / "configs").glob("*.toml"))
    texts = {p.read_bytes() for p in shipped}
    extra = [p for p in sorted((ROOT / "configs").glob("*.toml")) if p.read_bytes() not in texts]
    return shipped + extra


def _legacy(experiment: Experiment) -> None:
    rng = np.random.default_rng(7)
    experiment.controller = MeasuredController(
        experiment.controller, q_noise=1e-3, dq_noise=1e-2, delay=1, rng=rng
    )


def _realistic(experiment: Experiment) -> None:
    model = SensingConfig(q_noise=1e-4, dq_noise=1e-3, delay=1).model(experiment.robot.nq)
    experiment.controller = SensedController(
        experiment.controller, model, np.random.default_rng(11)
    )


#: Runs with an interface model: (name, config stem, wrapper of the built experiment).
SENSED: tuple[tuple[str, str, Callable[[Experiment], None]], ...] = (
    ("paper_combined+legacy_noise_delay", "paper_combined", _legacy),
    ("paper_combined+sensing", "paper_combined", _realistic),
    ("panda_sine+sensing", "panda_sine", _realistic),
    ("ur5_sine+legacy_noise_delay", "ur5_sine", _legacy),
)


def _arrays(result) -> dict[str, np.ndarray]:
    out = {name: np.asarray(getattr(result, name)) for name in RESULT_ARRAYS}
    tasks = {n: getattr(result, n) for n in TASK_ARRAYS}
    out.update({n: np.asarray(v) for n, v in tasks.items() if v is not None})
    out.update({f"extra_{k}": np.asarray(v) for k, v in sorted(result.extra.items())})
    out["complete"] = np.array(result.complete)
    out["message"] = np.array(result.message)
    return out


def _run(experiment: Experiment, duration: float | None, loop: str) -> dict[str, np.ndarray]:
    try:
        with per_step() if loop == "python" else contextlib.nullcontext():
            result = experiment.run(duration)
    except SimulationError as exc:
        result = exc.result
    return _arrays(result)


def runs(duration: float | None) -> dict[str, Callable[[], dict[str, np.ndarray]]]:
    """Every run by name, each a thunk returning its arrays."""
    out: dict[str, Callable[[], dict[str, np.ndarray]]] = {}
    configs = shipped_configs()
    for path in configs:
        name = f"configs.{path.stem}" if path.parent == ROOT / "configs" else path.stem
        for loop in ("auto", "python"):
            out[f"{name}@{loop}"] = lambda p=path, lp=loop: _run(
                Experiment.from_config(load_config(p)), duration, lp
            )
    by_stem = {p.stem: p for p in configs}
    for name, stem, wrap in SENSED:

        def thunk(p=by_stem[stem], w=wrap) -> dict[str, np.ndarray]:
            experiment = Experiment.from_config(load_config(p))
            w(experiment)
            return _run(experiment, duration, "auto")

        out[name] = thunk
    return out


def main(argv: list[str] | None = None) -> int:
    parser = saved_outputs.parser(__doc__, 1e-12)
    parser.add_argument(
        "--duration", type=float, default=None, help="simulated time of every run [s]"
    )
    parser.add_argument(
        "--oracle",
        type=Path,
        default=LOOP_ORACLE,
        metavar="PATH",
        help="the per-step loop oracle's file [tests/reference/loop.py of this clone]",
    )
    args = parser.parse_args(argv)
    global per_step
    per_step = per_step_oracle(args.oracle)
    if args.action == "record":
        saved_outputs.record(args.folder, runs(args.duration))
        return 0
    failed, worst = saved_outputs.compare(args.folder, runs(args.duration), args.tol)
    print(f"largest difference {worst:.2e} (tolerance {args.tol:g})")
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
