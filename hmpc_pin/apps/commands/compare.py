"""``hmpc-pin compare``: run several controllers on one experiment and compare them. Its
arguments (``add_arguments``) and its entry point (``main``).
"""

from __future__ import annotations

import sys
from pathlib import Path

from ..common import (
    EXIT_FAILED,
    EXIT_OK,
    add_force_option,
    add_reference_option,
    add_warn_option,
    out_dir,
    read_config,
    refuse_earlier_files,
    warn_thresholds,
    with_overrides,
)
from ..packaged import CONFIG_HELP

__all__ = ["add_arguments", "main"]


def add_arguments(cmp_) -> None:
    """``hmpc-pin compare``."""
    from ...experiment.config import CONTROLLER_KINDS

    cmp_.description = (
        "Run the controllers (docs, 'Controllers') on the same robot, plant, "
        "reference, disturbances and MPC settings; print and write a Markdown + CSV table "
        "(tracking error, settling, observer error, effort, chattering, constraint "
        "violations, step time) and figures."
    )
    cmp_.add_argument("config", type=Path, help=CONFIG_HELP)
    cmp_.add_argument(
        "--controllers",
        help="comma-separated controllers, each controller+compensation (e.g. hmpc+momentum) "
        "or a 0.1 name [all: " + ",".join(CONTROLLER_KINDS) + "]",
    )
    cmp_.add_argument("--out", type=Path, default=Path("out"), help="output directory [out]")
    add_force_option(cmp_)
    cmp_.add_argument("--duration", type=float, help="simulated time [s] (overrides the config)")
    add_reference_option(cmp_)
    cmp_.add_argument("--quiet", action="store_true", help="no progress bar")
    add_warn_option(cmp_)


def main(args) -> int:
    from ..compare import compare, ism_gain_hint, markdown_table, parse_controllers
    from ..metrics import run_warnings

    config = with_overrides(
        read_config(args.config), False, args.duration, reference=args.reference
    )
    controllers = parse_controllers(args.controllers, config)
    warn = warn_thresholds(args)
    stem = f"{config.name}_compare"
    refuse_earlier_files(args.out, (f"{stem}.md", f"{stem}.csv"), args.force)
    out = out_dir(args.out)
    comp, files = compare(config, out, controllers, progress=not args.quiet, **warn)

    print(f"{config.name}: {config.description}")
    print(markdown_table(comp))
    for kind, run in comp.runs.items():
        for line in run_warnings(run.result, **warn):
            print(f"warning: {kind}: {line}", file=sys.stderr)
    for f in files:
        print(f"wrote {f}")
    failed = [k for k, r in comp.runs.items() if r.failure]
    for kind in failed:  # each failure with its reason (and what to change, where known)
        print(f"error: {kind}: {comp.runs[kind].failure}", file=sys.stderr)
        hint = ism_gain_hint(config, comp.runs[kind])
        if hint is not None:
            print(f"note: {hint}", file=sys.stderr)
    if failed:
        print(f"error: runs failed: {', '.join(failed)} (partial results kept)", file=sys.stderr)
        return EXIT_FAILED
    return EXIT_OK
