"""A sweep with the interface model against its work: ``hmpc-pin sweep`` and its runs.

For a config, every block measures, one after the other:

* the wall time of ``hmpc-pin sweep <config> --samples K --jobs 1 --out <tmp> --quiet``
  (a fresh process: imports, config, URDF, every run of samples × variants × conditions,
  the table and files);
* the same with ``--jobs 2`` (two worker processes);
* with ``--dask``: the same with ``--executor dask --jobs 2`` (a local Dask cluster of two
  workers); Dask's overhead per run is (its wall − the ``--jobs 2`` wall) / runs;
* the wall time of a fresh ``python -c "import numpy, pinocchio, proxsuite, matplotlib"``;
* the same runs in this process, one :func:`~hmpc_pin.apps.sweep.run_sample` each (build,
  run, row), summed.

Ratios per block: ``jobs 1`` wall / (imports + the in-process runs), and ``jobs 1`` /
``jobs 2`` (the speed-up of two workers); the table gives the medians of the ratios beside
the median absolute times. Blocks alternate the measurements so that a shared machine
loads each alike. The share of the runs that went through the compiled loop is counted
(every run does since the ports).

Usage: python benchmarks/studies/sweep_overhead.py [--config panda_sine] [--samples 8] [--repeats 3]
       [--dask]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks.studies.cli_overhead import IMPORTS, PYTHON, command, wall  # noqa: E402
from hmpc_pin.apps.sweep import draw_samples, resolve_variants, run_sample  # noqa: E402
from hmpc_pin.experiment.config import load_config  # noqa: E402


def in_process(config, samples: int, seed: int = 0) -> tuple[float, int]:
    """(seconds, runs): every run of the sweep in this process, one ``run_sample`` each."""
    config = replace(config, sweep=replace(config.sweep, variants=resolve_variants(config)))
    params = draw_samples(config, samples, seed)
    tasks = [(p, v, c) for p in params for v in config.sweep.variants
             for c in config.sweep.conditions]  # fmt: skip
    t0 = time.perf_counter()
    for p, v, c in tasks:
        run_sample(config, p, v, c)
    return time.perf_counter() - t0, len(tasks)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="panda_sine")
    parser.add_argument("--samples", type=int, default=8)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--dask", action="store_true", help="also the Dask executor (extra)")
    args = parser.parse_args()
    config = load_config(args.config)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        base = [*command(), "sweep", args.config, "--samples", str(args.samples), "--quiet"]
        for block in range(args.repeats):
            one = wall([*base, "--jobs", "1", "--out", os.path.join(tmp, f"a{block}")])
            two = wall([*base, "--jobs", "2", "--out", os.path.join(tmp, f"b{block}")])
            dask = np.nan
            if args.dask:
                out = os.path.join(tmp, f"d{block}")
                dask = wall([*base, "--executor", "dask", "--jobs", "2", "--out", out])
            imports = wall([PYTHON, "-c", IMPORTS])
            runs, count = in_process(config, args.samples)
            rows.append((one, two, imports, runs, dask))
            print(f"block {block}: jobs 1 {one:.2f} s, jobs 2 {two:.2f} s, dask {dask:.2f} s, "
                  f"imports {imports:.2f} s, {count} runs in process {runs:.2f} s",
                  flush=True)  # fmt: skip
    a = np.array(rows)
    ratio = a[:, 0] / (a[:, 2] + a[:, 3])
    speedup = a[:, 0] / a[:, 1]
    med = np.median(a, axis=0)
    print(f"\n{args.config}, {args.samples} samples ({count} runs), {args.repeats} blocks, "
          f"load {os.getloadavg()[0]:.2f}")  # fmt: skip
    print("| jobs 1 [s] | jobs 2 [s] | imports [s] | runs in process [s] | "
          "jobs 1 / (imports + runs) | jobs 1 / jobs 2 |")  # fmt: skip
    print("|---:|---:|---:|---:|---:|---:|")
    print(f"| {med[0]:.2f} | {med[1]:.2f} | {med[2]:.2f} | {med[3]:.2f} | "
          f"{np.median(ratio):.2f} ({ratio.min():.2f}–{ratio.max():.2f}) | "
          f"{np.median(speedup):.2f} ({speedup.min():.2f}–{speedup.max():.2f}) |")  # fmt: skip
    if args.dask:
        per_run = (a[:, 4] - a[:, 1]) / count
        print(f"Dask (local cluster, 2 workers): {med[4]:.2f} s; over --jobs 2 "
              f"{1e3 * np.median(per_run):.0f} ms per run ({1e3 * per_run.min():.0f}–"
              f"{1e3 * per_run.max():.0f}), cluster start included")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
