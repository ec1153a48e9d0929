"""``hmpc-pin check``: check a config's arm before running it (observer, damping, torque,
engines). Its arguments (``add_arguments``) and its entry point (``main``).
"""

from __future__ import annotations

import sys
from pathlib import Path

from ..common import EXIT_FAILED, EXIT_OK, read_config
from ..packaged import CONFIG_HELP

__all__ = ["add_arguments", "main"]


def add_arguments(chk) -> None:
    """``hmpc-pin check``."""
    chk.description = (
        "Before anything runs on an arm, per joint: the observer bandwidth "
        "times Ts and its margin under the bandwidth rule for the latency the controller is not "
        "told about, the URDF damping's time "
        "constant against Ts, the torque headroom along the reference, and (with MuJoCo "
        "installed) the model against MuJoCo's. A problem is what `run` would show (with the "
        "change that fixes it), a warning what matters on a real arm. Exit 0 when no "
        "problem is found, 1 with one line per problem, 2 on bad input."
    )
    chk.add_argument("config", type=Path, help=CONFIG_HELP)
    chk.add_argument(
        "--no-engine", action="store_true", help="do not compare the model against MuJoCo"
    )


def main(args) -> int:
    """``hmpc-pin check CONFIG``: per-joint figures; exit 1 with one line per problem."""
    from ..check import check_config

    report = check_config(read_config(args.config), engines=not args.no_engine)
    print(report.format())
    for line in report.warnings:
        print(f"warning: {line}", file=sys.stderr)
    for line in report.problems:
        print(f"problem: {line}")
    if report.problems:
        return EXIT_FAILED
    print("no problem found")
    return EXIT_OK
