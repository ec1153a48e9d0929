"""``hmpc-pin sweep``: Monte Carlo robustness sweep of an experiment (with and without NDO).
Its arguments (``add_arguments``) and its entry point (``main``).
"""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path

from ...exceptions import RunInterrupted
from ..common import (
    EXIT_OK,
    add_force_option,
    add_reference_option,
    out_dir,
    read_config,
    refuse_earlier_files,
    with_overrides,
)
from ..packaged import CONFIG_HELP

__all__ = ["add_arguments", "main"]


def add_arguments(swp) -> None:
    """``hmpc-pin sweep``."""
    from ...experiment.config import CONTROLLER_KINDS

    swp.description = (
        "Draw K plant perturbations from the config's [sweep] table (link "
        "mass/inertia, friction and disturbance amplitudes) and run each with every "
        "controller variant under each of sweep.conditions: the interface's sensing "
        "([sweep.sensing]: encoders, finite-difference velocity, noise), its timing "
        "(latency, delay, torque filter), the drawn plant, and all together; write "
        "DIR/<name>_sweep.csv (one row per sample, variant and condition) and "
        "DIR/<name>_sweep.md (summary), and print the summary."
    )
    swp.add_argument("config", type=Path, help=CONFIG_HELP)
    swp.add_argument("--samples", type=int, default=100, help="number of samples K [100]")
    swp.add_argument("--seed", type=int, default=0, help="root seed [0]")
    swp.add_argument("--jobs", type=int, default=None, help="worker processes [all cores]")
    swp.add_argument(
        "--executor",
        choices=("local", "dask"),
        default="local",
        help="local processes or a Dask cluster (extra hmpc_pin[cluster]) [local]",
    )
    swp.add_argument(
        "--scheduler",
        help="with --executor dask: address of a running scheduler "
        "(default: a local cluster of --jobs processes)",
    )
    swp.add_argument(
        "--controllers",
        help="comma-separated controller names to sweep instead of sweep.variants "
        "(e.g. " + ",".join(CONTROLLER_KINDS[:4]) + ")",
    )
    swp.add_argument("--duration", type=float, help="simulated time [s] (overrides the config)")
    add_reference_option(swp)
    swp.add_argument("--out", type=Path, default=Path("out"), help="output directory [out]")
    add_force_option(swp)
    swp.add_argument("--quiet", action="store_true", help="no progress bar")


def main(args) -> int:
    from ..sweep import check_options, run_sweep

    config = with_overrides(
        read_config(args.config), False, args.duration, reference=args.reference
    )
    if args.controllers is not None:
        from ..compare import parse_controllers

        kinds = parse_controllers(args.controllers, config)
        config = replace(config, sweep=replace(config.sweep, variants=kinds))
    jobs = args.jobs if args.jobs is not None else (os.cpu_count() or 1)
    options = {"jobs": jobs, "executor": args.executor, "scheduler": args.scheduler}
    config = check_options(config, args.samples, args.seed, **options)  # before --out exists
    names = (f"{config.name}_sweep.csv", f"{config.name}_sweep.md")
    refuse_earlier_files(args.out, names, args.force)
    out = out_dir(args.out)
    result = run_sweep(
        config,
        args.samples,
        args.seed,
        jobs=jobs,
        executor=args.executor,
        scheduler=args.scheduler,
        progress=not args.quiet,
    )
    files = result.write(out) if result.rows else ()
    print(result.summary_markdown(), end="")
    for f in files:
        print(f"wrote {f}")
    if result.interrupted:
        raise RunInterrupted(
            f"{result.finished_samples} of {result.samples} samples "
            f"({len(result.rows)} of {result.planned_runs} runs) of the sweep",
            files=files,
        )
    return EXIT_OK
