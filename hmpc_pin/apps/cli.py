"""Command-line interface: ``hmpc-pin run | compare | sweep | reproduce | replay | init |
check | realtime | identify | tune | ros | ros-arm | configs | examples | native`` (also
``python -m hmpc_pin``).

Each command is a module of :mod:`hmpc_pin.apps.commands` exporting the same two entry
points: ``add_arguments(parser)`` (its description and arguments) and ``main(args) -> int``
(its exit code); :data:`COMMANDS` registers them, :mod:`hmpc_pin.apps.common` holds what
they share.

Exit codes: 0 on success, 2 on bad input (one-line message on stderr, no
traceback, checked before any run: no output file), 1 when a run fails (e.g.
diverges) — what was computed up to the failure is still written, with
``complete = False`` in the ``.npz`` — and 130 on Ctrl-C (SIGINT): one line
``interrupted at …`` on stderr, what was computed so far written as for a failure.
"""

from __future__ import annotations

import argparse
import os
import sys
from importlib import import_module

from .. import _startup
from ..exceptions import ConfigError, HmpcError, SimulationError
from .common import (  # noqa: F401 (the names the commands shared when they lived here)
    EXIT_BAD_INPUT,
    EXIT_FAILED,
    EXIT_INTERRUPTED,
    EXIT_OK,
    interrupted,
)
from .common import checked_duration as _checked_duration  # noqa: F401
from .common import checked_priority as _checked_priority  # noqa: F401
from .common import out_dir as _out_dir  # noqa: F401
from .common import out_file as _out_file  # noqa: F401
from .common import read_config as _config  # noqa: F401
from .common import realtime_files as _realtime_files  # noqa: F401
from .common import refuse_earlier_files as _refuse_earlier_files  # noqa: F401
from .common import report_realtime as _report_realtime  # noqa: F401
from .common import with_overrides as _with_overrides  # noqa: F401
from .common import with_reference as _with_reference  # noqa: F401

# The library is imported by the command that runs, not here: ``hmpc-pin --help`` (and a
# command's bad flag) loads neither numpy nor Pinocchio.

__all__ = ["COMMANDS", "build_parser", "main", "write_csv"]  # noqa: F822 (write_csv: __getattr__)


def __getattr__(name: str):
    """``write_csv`` and ``live_view`` of :mod:`hmpc_pin.apps.run`, and each command's
    ``main`` under its earlier name ``cmd_<command>`` (e.g. ``cmd_run``), imported on first
    use (PEP 562; importing the command line loads no library)."""
    if name in ("write_csv", "live_view"):
        from . import run

        return getattr(run, name)
    if name.startswith("cmd_") and name[4:] in {m for _, m in COMMANDS.values()}:
        return import_module(f"{__package__}.commands.{name[4:]}").main
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


#: The commands in the order of ``hmpc-pin --help``: name -> (one-line help, the module of
#: :mod:`hmpc_pin.apps.commands` exporting its ``add_arguments`` and ``main``). A command's
#: module is imported only when it is the one that runs (:func:`build_parser`), so that
#: ``hmpc-pin --help`` and each command import only what they need.
COMMANDS = {
    "run": ("run one experiment from a TOML config", "run"),
    "replay": ("write a self-contained Meshcat HTML replay of a saved run", "replay"),
    "plot": ("draw the figures of a saved run, timing, sweep table or identification", "plot"),
    "compare": ("run several controllers on one experiment and compare them", "compare"),
    "reproduce": ("run every paper experiment and write DIR/report.md", "reproduce"),
    "sweep": ("Monte Carlo robustness sweep of an experiment (with and without NDO)", "sweep"),
    "init": ("write a commented config for any arm (URDF path or example-robot-data name)", "init"),
    "identify": ("identify joint friction (or collision thresholds) from a saved run", "identify"),
    "tune": (
        "tune observer gain, Q, R, N (and Ts) on the sweep's perturbed plants (Optuna)",
        "tune",
    ),
    "check": (
        "check a config's arm before running it (observer, damping, torque, engines)",
        "check",
    ),
    "realtime": (
        "run the controller in real time against an arm in a separate process",
        "realtime",
    ),
    "franka": (
        "run the controller on a Franka FR3 or Panda over libfranka at 1 kHz (extra: franka)",
        "franka",
    ),
    "ros": ("run the controller as a ROS 2 node against /joint_states (extra: ros)", "ros"),
    "ros-arm": (
        "run the config's plant as a ROS 2 node (joint states out, efforts in; extra: ros)",
        "ros_arm",
    ),
    "configs": ("list the packaged configs, or write an editable copy of one", "configs"),
    "examples": ("list the packaged example scripts, or write a copy of one", "examples"),
    "ros-trajectory": (
        "send a new reference to the `ros` node's ~/joint_trajectory (extra: ros)",
        "ros_trajectory",
    ),
    "ros-lifecycle": (
        "change or get the lifecycle state of the `ros` node (extra: ros)",
        "ros_lifecycle",
    ),
    "ros-params": ("print the parameters of the `ros` node (extra: ros)", "ros_params"),
    "native": ("report the compiled core (built when the package was installed)", "native"),
}


def build_parser(commands=None) -> argparse.ArgumentParser:
    """The ``hmpc-pin`` parser with one subcommand per command of ``COMMANDS`` (the
    docs' CLI reference is generated from it).

    Args:
        commands: The commands whose arguments are built (the others have their name and
            one-line help only, all ``hmpc-pin --help`` shows); ``None``: all of them.
    """
    parser = argparse.ArgumentParser(
        prog="hmpc-pin",
        description="Hierarchical multiloop MPC with a nonlinear disturbance observer "
        "(Li et al. 2022) on Pinocchio + ProxSuite.",
        epilog="Exit codes: 0 success, 1 a run failed (partial results kept), 2 bad input, "
        "130 interrupted by Ctrl-C (partial results kept; realtime: safe torque first).",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, (help_, module) in COMMANDS.items():
        command = sub.add_parser(name, help=help_)
        if commands is None or name in commands:
            entry = import_module(f"{__package__}.commands.{module}")
            entry.add_arguments(command)
            command.set_defaults(func=entry.main)
    return parser


def _command(argv: list[str]) -> tuple[str, ...]:
    """The command ``argv`` names (its first word not an option), if it is one of
    ``COMMANDS``: the only one whose arguments :func:`main` builds."""
    word = next((a for a in argv if not a.startswith("-")), None)
    return (word,) if word in COMMANDS else ()


def _print_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """Warnings as one line ``warning: ...`` on stderr (no source line)."""
    print(f"warning: {message}", file=sys.stderr)


#: Config keys a command-line option overrides: a value refused once built (e.g. a
#: duration too long for the memory) is named by the option the user typed.
OPTION_KEYS = {"simulation.duration": "--duration"}


def _as_option(exc: HmpcError, argv: list[str]) -> HmpcError:
    """``exc``, naming the option instead of the config key when the value came from it."""
    option = OPTION_KEYS.get(getattr(exc, "key", ""))
    if option is None or not any(a == option or a.startswith(option + "=") for a in argv):
        return exc
    if getattr(exc, "loading", False):
        return exc  # refused while the file was read, before the option applied
    return ConfigError(option, exc.message)  # type: ignore[attr-defined]


def main(argv=None) -> int:
    """Entry point of ``hmpc-pin``; returns the exit code."""
    import warnings

    previous = _startup.guard()  # Ctrl-C before the first side effect: exit 130 at once
    try:
        argv = sys.argv[1:] if argv is None else list(argv)
        args = build_parser(_command(argv)).parse_args(argv)
        printed: set[str] = set()

        def show_once(message, category, *rest, **kw) -> None:
            """Each warning once: the arm's URDF is loaded for the controller and for the
            plant (and again per variant), each load warning alike."""
            if str(message) not in printed:
                printed.add(str(message))
                _print_warning(message, category, *rest, **kw)

        with warnings.catch_warnings():
            warnings.showwarning = show_once
            code = args.func(args)
        sys.stdout.flush()  # a closed pipe raises here, not at the interpreter's exit
        return code
    except BrokenPipeError:  # the reader stopped (`hmpc-pin check ... | head`): not an error
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # the exit's flush writes nowhere
        return EXIT_OK
    except KeyboardInterrupt as exc:
        return interrupted(exc)
    except HmpcError as exc:
        if isinstance(exc, SimulationError):  # a run failure, not bad input
            print(f"error: {exc}", file=sys.stderr)
            return EXIT_FAILED
        print(f"error: {_as_option(exc, argv)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    finally:
        _startup.restore(previous)


if __name__ == "__main__":
    raise SystemExit(main())
