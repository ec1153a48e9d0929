"""What the commands of :mod:`hmpc_pin.apps.commands` share: the exit codes, the checks of
the output paths and of the common options (each error naming its option), the options
several commands take, and the report of a real-time run.

Light to import (no numpy, no Pinocchio): the library is imported by the function that
needs it, so that ``hmpc-pin COMMAND --help`` loads only what that command's arguments need.
"""

from __future__ import annotations

import math
import sys
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from .. import _startup
from ..exceptions import ConfigError, OutputError

if TYPE_CHECKING:
    from ..experiment.config import ExperimentConfig

__all__ = [
    "EXIT_BAD_INPUT",
    "EXIT_FAILED",
    "EXIT_INTERRUPTED",
    "EXIT_OK",
    "add_force_option",
    "add_inner_law_option",
    "add_reference_option",
    "add_warn_option",
    "checked_duration",
    "checked_priority",
    "inner_law_value",
    "interrupted",
    "out_dir",
    "out_file",
    "read_config",
    "realtime_files",
    "refuse_earlier_files",
    "report_realtime",
    "ros_config",
    "warn_rivals",
    "warn_thresholds",
    "with_overrides",
    "with_reference",
    "write_replay",
]

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2
EXIT_INTERRUPTED = 130  # 128 + SIGINT, the shell's convention for Ctrl-C


def out_dir(path: Path, option: str = "--out") -> Path:
    """Create ``path`` and check it is a writable directory, or raise :class:`OutputError`
    naming ``option``. The first side effect of a command: it ends the start-up (Ctrl-C
    raises :class:`KeyboardInterrupt` from here on, ``hmpc_pin._startup``)."""
    _startup.end()
    if path.exists() and not path.is_dir():
        raise OutputError(path, "is a file", option)
    try:
        path.mkdir(parents=True, exist_ok=True)
        probe = path / ".hmpc_pin_write_test"
        probe.write_text("")
        probe.unlink()
    except OSError as exc:
        raise OutputError(path, f"is not writable ({exc.strerror or exc})", option) from exc
    return path


def warn_rivals() -> None:
    """Warn (:class:`~hmpc_pin.exceptions.RealtimeWarning`, one line each) of the other
    processes running real-time threads on this machine, before a real-time run starts
    (:mod:`hmpc_pin.realtime.machine`); the run goes on."""
    import warnings

    from ..exceptions import RealtimeWarning
    from ..realtime.machine import rival_warnings

    for line in rival_warnings():
        warnings.warn(line, RealtimeWarning, stacklevel=2)


def out_file(path: Path, option: str) -> Path:
    """Check, before any run, that the file ``path`` can be written: its folder is created
    and writable and ``path`` is not a directory; raise :class:`OutputError` naming
    ``option`` otherwise."""
    if path.is_dir():
        raise OutputError(path, "is a directory", option, what="output file")
    out_dir(path.parent if str(path.parent) else Path("."), option)
    return path


def interrupted(exc: KeyboardInterrupt) -> int:
    """Print the one line of a Ctrl-C (where it stopped, the files kept) and return 130."""
    where = getattr(exc, "where", "") or "set-up, before any run (nothing written)"
    files = getattr(exc, "files", ())
    kept = f"; wrote {', '.join(str(f) for f in files)}" if files else ""
    print(f"interrupted at {where}{kept}", file=sys.stderr)
    return EXIT_INTERRUPTED


def with_reference(config: ExperimentConfig, file: Path | None) -> ExperimentConfig:
    """``config`` with its reference replaced by the trajectory file ``file`` (``--reference``)."""
    from ..experiment.config import ReferenceConfig, TrajectoryConfig

    if file is None:
        return config
    if file.suffix.lower() not in (".csv", ".npz"):
        raise ConfigError(
            "--reference",
            f"{str(file)!r}: expected a .csv or .npz trajectory file (docs, Tutorials)",
        )
    if not file.is_file():
        raise ConfigError("--reference", f"{str(file)!r} not found; pass a .csv or .npz file")
    ref = ReferenceConfig(kind="trajectory", trajectory=TrajectoryConfig(file=file.resolve()))
    return replace(config, reference=ref)


def checked_duration(duration: float | None) -> float | None:
    """``--duration`` checked: ``None`` or a number of seconds > 0."""
    if duration is not None and not (math.isfinite(duration) and duration > 0):
        raise ConfigError("--duration", f"expected a number of seconds > 0, got {duration!r}")
    return duration


def checked_priority(priority: int | str | None) -> int | str | None:
    """``--priority`` checked: ``None``, 0 (off), a ``SCHED_FIFO`` priority 1..99 or
    ``"auto"``."""
    if priority is not None and priority != "auto" and not 0 <= priority <= 99:  # type: ignore[operator]
        raise ConfigError("--priority", f"expected 0 (off) or 1..99, or auto, got {priority}")
    return priority


def with_overrides(
    config: ExperimentConfig,
    no_ndo: bool,
    duration: float | None,
    compensation: str | None = None,
    reference: Path | None = None,
) -> ExperimentConfig:
    from ..experiment.build import with_controller
    from ..experiment.config import COMPENSATIONS

    config = with_reference(config, reference)
    if compensation is not None:
        if compensation not in COMPENSATIONS:
            raise ConfigError(
                "--compensation", f"expected one of {COMPENSATIONS}, got {compensation!r}"
            )
        config = with_controller(config, compensation=compensation)
    if no_ndo:
        if config.controller.compensation == "none":
            raise ConfigError(
                "--no-ndo",
                f"{config.name} already runs {config.controller.label} (no compensation); "
                "drop --no-ndo",
            )
        config = with_controller(config, observer=False)
    if checked_duration(duration) is not None:
        config = replace(config, simulation=replace(config.simulation, duration=duration))
    return config


def read_config(path: Path) -> ExperimentConfig:
    """The experiment config of ``path`` (:func:`~hmpc_pin.experiment.config.load_config`)."""
    from ..experiment.config import load_config

    try:
        return load_config(path)
    except ConfigError as exc:
        exc.loading = True  # the file's own value (not an option's): see _as_option
        raise


def refuse_earlier_files(out: Path, names, force: bool) -> None:
    """Refuse, before the run, to replace an earlier run's files (``names`` in ``out``)
    without ``--force``, as ``init`` keeps an existing config: a run's data may be what a
    later command reads (``--reference``, ``identify``, ``plot``). Every command that
    writes run files (``run``, ``compare``, ``sweep``, ``realtime``, ``ros``,
    ``franka``) calls it with the data files it writes.

    Raises:
        ConfigError: (``--out``) naming the first such file and ``--force``.
    """
    earlier = [out / name for name in names if (out / name).exists()]
    if earlier and not force:
        raise ConfigError(
            "--out",
            f"{earlier[0]} exists (an earlier run's); pass --force to replace its files, or "
            "another --out",
        )


def add_reference_option(parser) -> None:
    parser.add_argument(
        "--reference",
        type=Path,
        metavar="FILE",
        help="track this joint trajectory (.csv: t, one column per joint [, dq_<joint>]; "
        "or .npz) instead of the config's reference",
    )


def add_force_option(parser) -> None:
    """``--force``: replace an earlier run's files in ``--out`` (:func:`refuse_earlier_files`)."""
    parser.add_argument(
        "--force",
        action="store_true",
        help="replace an earlier run's files of the same name in --out (else exit 2)",
    )


def add_inner_law_option(parser, default: str) -> None:
    """``--inner-law``, the one option of ``realtime``, ``ros`` and ``franka`` that chooses
    how the controller runs under the faster arm (over ``[realtime] inner_law``;
    :mod:`hmpc_pin.experiment.inner_law`); checked by :func:`inner_law_value` in the
    command (exit 2, one line). ``default`` says in words what ``auto`` is there."""
    parser.add_argument(
        "--inner-law",
        metavar="LAW",
        help="how the controller runs when Ts is a multiple of the arm's period: whole-step "
        "(the whole step every Ts, its torque held in between), every-cycle (the MPC every "
        "Ts, inverse dynamics and the disturbance observer every cycle), threaded (the same "
        "with the MPC in a compiled thread, its latest plan used within 2 Ts) or auto "
        f"({default}) (overrides realtime.inner_law)",
    )


def inner_law_value(text: str) -> str:
    """``--inner-law``'s value, checked (``"held"``, the name of earlier versions, is
    ``"whole-step"``).

    Raises:
        ConfigError: Not one of the laws, named ``--inner-law``.
    """
    from ..experiment.config.realtime import INNER_LAWS

    value = "whole-step" if text == "held" else text
    if value not in INNER_LAWS:
        raise ConfigError("--inner-law", f"expected one of {', '.join(INNER_LAWS)}, got {text!r}")
    return value


def add_warn_option(parser) -> None:
    from .metrics import DEFAULT_ERROR_THRESHOLD

    parser.add_argument(
        "--warn-error",
        type=float,
        default=DEFAULT_ERROR_THRESHOLD,
        metavar="RAD",
        help="warn when max |e| after 1 s exceeds RAD (a warning is also printed when the "
        f"plant clips the torque) [{DEFAULT_ERROR_THRESHOLD:g}]",
    )


def warn_thresholds(args) -> dict:
    """The ``--warn-error`` threshold [rad] checked (a number > 0) before the run."""
    value = args.warn_error
    if not (math.isfinite(value) and value > 0):
        raise ConfigError("--warn-error", f"expected a tracking error in rad > 0, got {value!r}")
    return {"error_threshold": float(value)}


def realtime_files(stem: str) -> tuple[str, ...]:
    """The files :func:`~hmpc_pin.apps.realtime.save_run` writes for ``stem``."""
    return (f"{stem}.npz", f"{stem}_timing.npz", f"{stem}.json")


def report_realtime(start, config: ExperimentConfig, safe: str, *formats) -> int:
    """Run a real-time command and report it: ``start()`` returns ``(run, files)``;
    print the run's summary, each ``format(run)``, the files written and the stop;
    ``safe``: what became of the safe torque ("commanded", "published").

    Returns:
        The exit code: 0 the whole run, 130 interrupted (also at start-up, before the first
        cycle: nothing run or written), 1 another safe stop.
    """
    try:
        run, files = start()
    except KeyboardInterrupt as exc:  # before the loop took over SIGINT: nothing ran yet
        print(
            str(exc)
            or "interrupted at start-up, before the first cycle; nothing was run or written",
            file=sys.stderr,
        )
        return EXIT_INTERRUPTED
    print(run.summary())
    for format_run in formats:
        print(format_run(run))
    for f in files:
        print(f"wrote {f}")
    if run.stop is None:
        if not run.complete:  # to the end, but periods without a state from the arm
            print(f"error: {run.result.message}; run saved (complete = false)", file=sys.stderr)
            return EXIT_FAILED
        return EXIT_OK
    if run.stop["cause"] in ("interrupted", "deactivated"):  # stopped from outside
        sent = "nothing sent to the arm" if run.stop["safe_tau"] is None else f"safe torque {safe}"
        print(
            f"{run.stop['cause']} at t={run.stop['t']:.3f} s of "
            f"{config.simulation.duration:g} s; {sent}, partial run saved "
            "(complete = false)",
            file=sys.stderr,
        )
        return EXIT_INTERRUPTED
    print(f"error: {run.stop['reason']}; partial run saved (complete = false)", file=sys.stderr)
    return EXIT_FAILED


def write_replay(robot, result, path: Path, option: str = "--replay") -> Path:
    from .viz import export_replay

    out_file(path, option)
    return export_replay(robot, result, path)


def ros_config(args, config: ExperimentConfig) -> ExperimentConfig:
    """``--namespace``, ``--priority`` (and ``hmpc-pin ros``'s ``--inner-law``) of the ROS
    commands applied to ``config``."""
    from .realtime import with_realtime
    from .ros import with_namespace

    priority = checked_priority(args.priority)
    law = getattr(args, "inner_law", None)
    try:
        config = with_realtime(
            config,
            priority=priority,
            watchdog=getattr(args, "watchdog", None),
            max_misses=getattr(args, "max_misses", None),
            inner_law=None if law is None else inner_law_value(law),
        )
    except ConfigError as exc:  # a flag's value checked by [realtime]: name the flag
        raise ConfigError(f"--{exc.key.replace('_', '-')}", exc.message) from None
    return with_namespace(config, args.namespace)
