"""Refactoring check: the outputs of every shipped config before and after a speed-up.

A speed-up must not change results beyond floating-point rounding or the QP solver's
tolerance. Record the outputs of the code as it was, change the code, then compare:

    python benchmarks/tools/refactor_check.py record /tmp/before      # on the old code
    python benchmarks/tools/refactor_check.py compare /tmp/before     # on the new code

``record`` runs every ``hmpc_pin/data/configs/*.toml``
(``Experiment.from_config(...).run()``) and a short sweep (4 samples of
``paper_combined``, both variants, noise and delay), and writes each run's result arrays
to ``<dir>/<config>.npz`` and the sweep rows to ``<dir>/sweep.json``. ``compare`` reruns
them and prints, per config and array, the largest difference divided by max(1, the
array's largest magnitude); exit 1 if any exceeds ``--tol`` (default 1e-9: the solver's
``eps_abs``) or a run's completion changed. This is the one place saved outputs are
used: tests compare against independent computations instead.

``--backend python|native`` (``compare``, code with ``hmpc_pin.native``) runs every config
with that ``backend`` in ``[controller]`` and ``[plant]`` where it applies: the Python path
must stay bit-identical to code from before the native kernels, the native one within
``--tol``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks.tools import saved_outputs  # noqa: E402
from hmpc_pin.apps.sweep import run_sweep  # noqa: E402
from hmpc_pin.exceptions import SimulationError  # noqa: E402
from hmpc_pin.experiment.build import Experiment  # noqa: E402
from hmpc_pin.experiment.config import load_config  # noqa: E402
from hmpc_pin.sim.result import RESULT_ARRAYS  # noqa: E402

CONFIGS = sorted((ROOT / "hmpc_pin" / "data" / "configs").glob("*.toml"))
SWEEP_SAMPLES = 4


BACKEND: str | None = None


def with_backend(config):
    """``config`` with :data:`BACKEND` where it applies (hmpc controller, RK4 plant)."""
    if BACKEND is None:
        return config
    from dataclasses import replace

    cc, pc = config.controller, config.plant
    if cc.kind == "hmpc":
        cc = replace(cc, backend=BACKEND)
    if pc.engine == "pinocchio" and pc.integrator == "rk4":
        pc = replace(pc, backend=BACKEND)
    return replace(config, controller=cc, plant=pc)


def run_config(path: Path) -> dict[str, np.ndarray]:
    """The result arrays of one config's run (a run that stops keeps its partial result)."""
    experiment = Experiment.from_config(with_backend(load_config(path)))
    try:
        result = experiment.run()
    except SimulationError as exc:
        result = exc.result
    out = {name: np.asarray(getattr(result, name)) for name in RESULT_ARRAYS}
    out["complete"] = np.array(result.complete)
    return out


def run_sweep_rows() -> list[dict]:
    """Rows of a short sweep of the paper's combined scenario (both variants)."""
    config = with_backend(load_config(ROOT / "configs" / "paper_combined.toml"))
    return run_sweep(config, SWEEP_SAMPLES, 0, jobs=1, progress=False).rows


def runs() -> saved_outputs.Runs:
    """Every config's run by its name, each a thunk returning its arrays."""
    return {path.stem: lambda p=path: run_config(p) for path in CONFIGS}


def record(folder: Path) -> int:
    saved_outputs.record(folder, runs())
    (folder / "sweep.json").write_text(json.dumps(run_sweep_rows(), indent=1))
    print("recorded sweep")
    return 0


def compare(folder: Path, tol: float) -> int:
    failed, worst_all = saved_outputs.compare(folder, runs(), tol)
    old_rows = json.loads((folder / "sweep.json").read_text())
    new_rows = json.loads(json.dumps(run_sweep_rows()))
    worst = 0.0 if len(old_rows) == len(new_rows) else np.inf
    for a, b in zip(old_rows, new_rows, strict=False):
        for key, value in a.items():
            if isinstance(value, float):
                worst = max(worst, saved_outputs.difference(np.array(value), np.array(b[key])))
            elif value != b.get(key):
                worst = np.inf
    failed |= saved_outputs.row(f"sweep ({SWEEP_SAMPLES} samples × 2)", worst, tol)
    print(f"largest difference over all configs {worst_all:.2e} (tolerance {tol:g})")
    return 1 if failed else 0


def main(argv: list[str] | None = None) -> int:
    parser = saved_outputs.parser(__doc__, 1e-9)
    parser.add_argument("--backend", choices=("python", "native", "auto"))
    args = parser.parse_args(argv)
    global BACKEND
    BACKEND = args.backend
    if args.action == "record":
        return record(args.folder)
    return compare(args.folder, args.tol)


if __name__ == "__main__":
    raise SystemExit(main())
