"""``hmpc-pin franka``: run the controller on a Franka FR3 or Panda over libfranka at 1 kHz
(extra: franka). Its arguments (``add_arguments``) and its entry point (``main``).
"""

from __future__ import annotations

import math

from ...exceptions import ConfigError
from ..common import (
    add_force_option,
    out_dir,
    read_config,
    realtime_files,
    refuse_earlier_files,
    report_realtime,
    warn_rivals,
    with_overrides,
)

__all__ = ["add_arguments", "main"]


def add_arguments(parser) -> None:
    """``hmpc-pin franka`` (:mod:`hmpc_pin.apps.franka`)."""
    from ..franka import franka_arguments

    franka_arguments(parser)
    add_force_option(parser)


def main(args) -> int:
    """``hmpc-pin franka``: the controller on a Franka arm (:mod:`hmpc_pin.apps.franka`)."""
    from ...experiment.build import Experiment
    from ...experiment.inner_law import chosen_inner_law
    from ..franka import FrankaOptions, format_driver, load_thresholds, run_franka
    from ..realtime import format_tracking

    config = with_overrides(read_config(args.config), False, args.duration)
    if not (math.isfinite(args.max_move) and args.max_move > 0):
        raise ConfigError("--max-move", f"expected a distance [rad] > 0, got {args.max_move!r}")
    if not (math.isfinite(args.model_tolerance) and args.model_tolerance > 0):
        raise ConfigError(
            "--model-tolerance", f"expected a fraction > 0, got {args.model_tolerance!r}"
        )
    thresholds = None if args.thresholds is None else load_thresholds(args.thresholds)
    options = FrankaOptions(
        args.robot_ip,
        realtime=args.realtime,
        recover=args.recover,
        max_move=args.max_move,
        model_tolerance=args.model_tolerance,
        thresholds=thresholds,
        inner_law=args.inner_law,
    )
    experiment = Experiment.from_config(config)  # bad input stops here: nothing written
    chosen_inner_law(experiment, 1e-3, "franka", options.inner_law)
    stem = f"{config.name}_franka"
    names = (*realtime_files(stem), f"{stem}_cycles.npz")
    refuse_earlier_files(args.out, names, args.force)
    out = out_dir(args.out)
    warn_rivals()  # another real-time process stalls this run: said before it starts
    print(
        f"{config.name}: {config.controller.label} on the Franka arm at {args.robot_ip} for "
        f"{config.simulation.duration:g} s (1 kHz torque control)",
        flush=True,
    )

    def ready() -> None:  # the readiness line (scripts and tests wait for it)
        print("torque control running (Ctrl-C: safe stop, partial run saved)", flush=True)

    summary: dict = {}

    def start():
        run, files, found = run_franka(config, options, out, experiment=experiment, ready=ready)
        summary.update(found)
        return run, files

    def driver(run) -> str:
        return format_driver(summary)

    return report_realtime(start, config, "commanded", format_tracking, driver)
