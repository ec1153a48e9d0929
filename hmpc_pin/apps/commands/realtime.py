"""``hmpc-pin realtime``: run the controller in real time against an arm in a separate process.
Its arguments (``add_arguments``) and its entry point (``main``).
"""

from __future__ import annotations

import math
from pathlib import Path

from ...exceptions import ConfigError
from ..common import (
    add_force_option,
    add_inner_law_option,
    checked_priority,
    inner_law_value,
    out_dir,
    read_config,
    realtime_files,
    refuse_earlier_files,
    report_realtime,
    warn_rivals,
    with_overrides,
)
from ..packaged import CONFIG_HELP

__all__ = ["add_arguments", "main"]


def add_arguments(rt) -> None:
    """``hmpc-pin realtime``."""
    from ..realtime import add_stop_options, priority_value, spin_value

    rt.description = (
        "Run the experiment's controller at a fixed rate (absolute deadlines, "
        "garbage collection in the slack) against its plant stepping in wall-clock time in "
        "a separate process, as a driver would; print and save the latency statistics "
        "(median, p99, p99.9, max, misses) with the tracking metrics. Safe stop (gravity "
        "compensation + damping) on Ctrl-C (exit 130), a fault, k consecutive missed "
        "deadlines or a watchdog timeout (exit 1), the run saved with complete = false."
    )
    rt.add_argument("config", type=Path, help=CONFIG_HELP)
    rt.add_argument("--rate", type=float, help="interface rate [Hz] (overrides realtime.rate)")
    rt.add_argument("--duration", type=float, help="run length [s] (overrides the config)")
    rt.add_argument(
        "--spin",
        type=spin_value,
        metavar="S",
        help="busy-wait S seconds before each deadline instead of sleeping, e.g. 2e-4; "
        "auto: the stretch from the measured wake-ups; 0: sleep (overrides realtime.spin)",
    )
    rt.add_argument(
        "--no-gc",
        action="store_true",
        help="leave Python's garbage collector as it is (for comparison)",
    )
    rt.add_argument(
        "--priority",
        type=priority_value,
        metavar="N",
        help="SCHED_FIFO priority 1-99 of the loop and the arm process (needs root or an "
        "rtprio limit); auto: 80 where permitted, else normal (overrides realtime.priority)",
    )
    add_stop_options(rt)
    add_inner_law_option(rt, "whole-step")
    rt.add_argument(
        "--viz",
        action="store_true",
        help="live Meshcat view of the arm, drawn by a separate process",
    )
    rt.add_argument("--out", type=Path, default=Path("out"), help="output directory [out]")
    add_force_option(rt)


def main(args) -> int:
    from ...experiment.build import Experiment
    from ...experiment.inner_law import chosen_inner_law
    from ...experiment.realtime import brake_settings
    from ..realtime import ArmView, format_tracking, run_realtime, with_realtime

    config = with_overrides(read_config(args.config), False, args.duration)
    if args.rate is not None and not (math.isfinite(args.rate) and args.rate > 0):
        raise ConfigError("--rate", f"expected a rate [Hz] > 0, got {args.rate!r}")
    priority = checked_priority(args.priority)
    law = None if args.inner_law is None else inner_law_value(args.inner_law)
    try:
        config = with_realtime(
            config,
            rate=args.rate,
            gc=False if args.no_gc else None,
            priority=priority,
            spin=args.spin,
            watchdog=args.watchdog,
            max_misses=args.max_misses,
            inner_law=law,
        )
    except ConfigError as exc:  # a flag's value checked by [realtime]: name the flag
        raise ConfigError(f"--{exc.key.replace('_', '-')}", exc.message) from None
    experiment = Experiment.from_config(config)  # bad input stops here: nothing written
    brake_settings(config, 1.0 / config.realtime.rate)  # (the safe torque's brake too)
    chosen_inner_law(experiment, 1.0 / config.realtime.rate, "realtime", law)
    refuse_earlier_files(args.out, realtime_files(f"{config.name}_realtime"), args.force)
    out = out_dir(args.out)
    warn_rivals()  # another real-time process stalls this run: said before it starts
    about = f"{config.description} " if config.description else ""
    print(
        f"{config.name}: {about}({config.controller.label}) in real time at "
        f"{config.realtime.rate:g} Hz for {config.simulation.duration:g} s against an arm "
        "process",
        flush=True,
    )

    def ready() -> None:  # the readiness line (scripts and tests wait for it)
        print("arm process ready; running (Ctrl-C: safe stop, partial run saved)", flush=True)

    def start():
        return run_realtime(
            config, out, viz=ArmView if args.viz else None, experiment=experiment, ready=ready
        )

    return report_realtime(start, config, "commanded", format_tracking)
