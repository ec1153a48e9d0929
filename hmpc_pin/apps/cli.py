"""Command-line interface: ``hmpc-pin run | compare | sweep | reproduce | replay | init |
check | realtime | identify | tune | ros | ros-arm | configs | examples | native`` (also
``python -m hmpc_pin``).

Exit codes: 0 on success, 2 on bad input (one-line message on stderr, no
traceback, checked before any run: no output file), 1 when a run fails (e.g.
diverges) — what was computed up to the failure is still written, with
``complete = False`` in the ``.npz`` — and 130 on Ctrl-C (SIGINT): one line
``interrupted at …`` on stderr, what was computed so far written as for a failure.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from .. import _startup
from ..exceptions import (
    ConfigError,
    HmpcError,
    OutputError,
    RunInterrupted,
    SimulationError,
    VizError,
)
from .packaged import CONFIG_HELP

if TYPE_CHECKING:
    from ..experiment.config import ExperimentConfig

# The library is imported by the command that runs, not here: ``hmpc-pin --help`` (and a
# command's bad flag) loads neither numpy nor Pinocchio.

__all__ = ["build_parser", "main", "write_csv"]  # noqa: F822 (write_csv: __getattr__)


def __getattr__(name: str):
    """``write_csv`` and ``live_view`` of :mod:`hmpc_pin.apps.run`, re-exported on first use
    (PEP 562; importing the command line loads no library)."""
    if name in ("write_csv", "live_view"):
        from . import run

        return getattr(run, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2
EXIT_INTERRUPTED = 130  # 128 + SIGINT, the shell's convention for Ctrl-C


def _out_dir(path: Path, option: str = "--out") -> Path:
    """Create ``path`` and check it is a writable directory, or raise :class:`OutputError`
    naming ``option``. The first side effect of a command: it ends the start-up (Ctrl-C
    raises :class:`KeyboardInterrupt` from here on, :mod:`hmpc_pin._startup`)."""
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


def _out_file(path: Path, option: str) -> Path:
    """Check, before any run, that the file ``path`` can be written: its folder is created
    and writable and ``path`` is not a directory; raise :class:`OutputError` naming
    ``option`` otherwise."""
    if path.is_dir():
        raise OutputError(path, "is a directory", option, what="output file")
    _out_dir(path.parent if str(path.parent) else Path("."), option)
    return path


def _interrupted(exc: KeyboardInterrupt) -> int:
    """Print the one line of a Ctrl-C (where it stopped, the files kept) and return 130."""
    where = getattr(exc, "where", "") or "set-up, before any run (nothing written)"
    files = getattr(exc, "files", ())
    kept = f"; wrote {', '.join(str(f) for f in files)}" if files else ""
    print(f"interrupted at {where}{kept}", file=sys.stderr)
    return EXIT_INTERRUPTED


def _with_reference(config: ExperimentConfig, file: Path | None) -> ExperimentConfig:
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


def _checked_duration(duration: float | None) -> float | None:
    """``--duration`` checked: ``None`` or a number of seconds > 0."""
    if duration is not None and not (math.isfinite(duration) and duration > 0):
        raise ConfigError("--duration", f"expected a number of seconds > 0, got {duration!r}")
    return duration


def _checked_priority(priority: int | str | None) -> int | str | None:
    """``--priority`` checked: ``None``, 0 (off), a ``SCHED_FIFO`` priority 1..99 or
    ``"auto"``."""
    if priority is not None and priority != "auto" and not 0 <= priority <= 99:  # type: ignore[operator]
        raise ConfigError("--priority", f"expected 0 (off) or 1..99, or auto, got {priority}")
    return priority


def _with_overrides(
    config: ExperimentConfig,
    no_ndo: bool,
    duration: float | None,
    compensation: str | None = None,
    reference: Path | None = None,
) -> ExperimentConfig:
    from ..experiment.build import with_controller
    from ..experiment.config import COMPENSATIONS

    config = _with_reference(config, reference)
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
    if _checked_duration(duration) is not None:
        config = replace(config, simulation=replace(config.simulation, duration=duration))
    return config


def _config(path: Path) -> ExperimentConfig:
    """The experiment config of ``path`` (:func:`~hmpc_pin.experiment.config.load_config`)."""
    from ..experiment.config import load_config

    try:
        return load_config(path)
    except ConfigError as exc:
        exc.loading = True  # the file's own value (not an option's): see _as_option
        raise


def cmd_run(args) -> int:
    if args.figures:  # matplotlib is imported beside the run (the command line only)
        from .figure_worker import start

        start()
    from ..experiment.build import Experiment

    config = _with_overrides(
        _config(args.config), args.no_ndo, args.duration, args.compensation, args.reference
    )
    if not args.speed > 0:
        raise ConfigError("--speed", f"expected a number > 0, got {args.speed!r}")
    experiment = Experiment.from_config(config)  # bad input stops here: nothing written
    if args.replay is not None:  # Meshcat and the meshes, before the run and any file
        _check_meshes(config, "--replay")
    warn = _warn_thresholds(args)
    for flag, value in (("--wait", args.wait), ("--keep-open", args.keep_open)):
        if value and not args.viz:
            raise ConfigError(flag, "applies to the live view only; add --viz or drop " + flag)
    stem = config.name
    if args.compensation is not None:
        stem += f"_{args.compensation}"
    if args.no_ndo and not config.name.endswith("_no_ndo"):
        stem += "_no_ndo"
    _refuse_earlier_run(args.out, stem, args.force)
    out = _out_dir(args.out)  # every option checked: the first thing written
    if args.replay is not None:
        _out_file(args.replay, "--replay")
    views: list = []  # the live view, opened by run_one once the experiment is built
    try:
        return _run_and_report(args, config, out, stem, warn, views, experiment)
    finally:
        for view in views:
            view.close()


def _refuse_earlier_run(out: Path, stem: str, force: bool) -> None:
    """Refuse, before the run, to replace an earlier run's files ``<stem>.npz`` /
    ``.csv`` in ``out`` without ``--force`` (as ``init`` keeps an existing config): a
    run's data may be what a later command reads (``--reference``, ``identify``)."""
    earlier = [out / f"{stem}{ext}" for ext in (".npz", ".csv") if (out / f"{stem}{ext}").exists()]
    if earlier and not force:
        raise ConfigError(
            "--out",
            f"{earlier[0]} exists (an earlier run's); pass --force to replace its files, or "
            "another --out",
        )


def _open_view(experiment, args, views: list):
    """The live view of ``--viz`` (``None`` when it cannot start: the run goes on), waiting
    for a browser with ``--wait``; kept in ``views`` for the caller to close."""
    from .run import live_view

    view = live_view(experiment.robot, args.speed, experiment.obstacle)
    if view is None:
        return None
    views.append(view)
    if args.wait:
        print(f"waiting for a browser at {view.url} (Ctrl-C to stop)", flush=True)
        view.wait_for_browser()
    return view


def _run_and_report(args, config, out, stem, warn, views: list, experiment=None) -> int:
    from .run import after_the_run, run_one

    open_view = (lambda exp: _open_view(exp, args, views)) if args.viz else None
    experiment, result, files, failure = run_one(
        config,
        out,
        stem,
        open_view=open_view,
        experiment=experiment,
        figures=False,
        progress=args.progress,
    )
    with after_the_run(config.name, files):
        return _report(args, config, out, stem, warn, views, experiment, result, files, failure)


def _report(args, config, out, stem, warn, views, experiment, result, files, failure) -> int:
    from ..experiment.build import uses_observer
    from .metrics import compute_metrics, contact_lines, format_metrics, run_warnings
    from .run import draw_figures

    view = views[0] if views else None
    observer = uses_observer(config.controller)
    label = config.controller.label
    about = f"{config.description} " if config.description else ""
    print(f"{config.name}: {about}({label}, observer {'on' if observer else 'off'})")
    if args.reference is not None:
        print(f"reference: the trajectory of {args.reference} (--reference), not the config's")
    if config.reference.kind == "waypoints":
        ref = experiment.reference
        print(
            f"waypoints retimed by TOPP-RA: motion of {ref.duration:.3f} s "
            f"(t = {ref.t_start:g} to {ref.t_end:.3f} s)"
        )
    if result.t[-1] >= 1.0:
        print(format_metrics(compute_metrics(result), result.joint_names, result))
    for line in contact_lines(result):
        print(line)
    timing = getattr(result, "step_time", None)
    median = f" (median {timing['median_us']:.0f} µs)" if timing else ""
    slow = [f"{w}{median}" for w in result.meta.get("warnings", ())]
    touch = result.meta.get("first_contact")
    if touch is None:
        touch = (result.meta.get("collision") or {}).get("detected_at")
    for line in slow + run_warnings(result, **warn):
        if touch is not None and line.startswith("tracking error"):
            line += f"; expected once the arm touches something (contact at t = {touch:.3f} s)"
        print(f"warning: {line}", file=sys.stderr)
    if args.figures:  # after the table: it is what one reads
        label = "with NDO" if observer else "without NDO"
        draw_figures(config, result, out, stem, files, error_label=label)
    if args.replay is not None and len(result.t) > 1:
        files.append(_replay(experiment.robot, result, args.replay))
    for f in files:
        print(f"wrote {f}")
    if view is not None and args.keep_open:
        print(f"live view kept open at {view.url}; Ctrl-C to close", flush=True)
        view.hold()
    if failure:
        print(f"error: run failed: {failure}", file=sys.stderr)
        return EXIT_FAILED
    return EXIT_OK


def _replay(robot, result, path: Path, option: str = "--replay") -> Path:
    from .viz import export_replay

    _out_file(path, option)
    return export_replay(robot, result, path)


def _check_meshes(config: ExperimentConfig, option: str) -> None:
    """Load the visual geometry of the config's arm before the run, so that a missing
    mesh is bad input naming the mesh and ``option`` (no run, no file)."""
    from ..experiment.build import load_robot_config
    from .viz import require_meshcat, visual_model

    try:
        require_meshcat()
        visual_model(load_robot_config(config.robot))
    except VizError as exc:
        raise VizError(f"{option}: {exc}; or run without {option}") from None


def _warn_thresholds(args) -> dict:
    """The ``--warn-error`` threshold [rad] checked (a number > 0) before the run."""
    value = args.warn_error
    if not (math.isfinite(value) and value > 0):
        raise ConfigError("--warn-error", f"expected a tracking error in rad > 0, got {value!r}")
    return {"error_threshold": float(value)}


def cmd_replay(args) -> int:
    from .runfile import load_run, run_robot

    result = load_run(args.result, "RESULT")
    robot = run_robot(result, str(args.urdf) if args.urdf else None, "RESULT")
    path = _replay(robot, result, args.out, "--out")
    print(f"wrote {path} ({path.stat().st_size / 1e6:.1f} MB)")
    return EXIT_OK


def cmd_compare(args) -> int:
    from .compare import compare, ism_gain_hint, markdown_table, parse_controllers
    from .metrics import run_warnings

    config = _with_overrides(_config(args.config), False, args.duration, reference=args.reference)
    controllers = parse_controllers(args.controllers, config)
    out = _out_dir(args.out)
    warn = _warn_thresholds(args)
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


def cmd_reproduce(args) -> int:
    from .report import reproduce

    out = _out_dir(args.out)
    ok = reproduce(out, configs_dir=args.configs, progress=not args.quiet)
    return EXIT_OK if ok else EXIT_FAILED


def cmd_sweep(args) -> int:
    from .sweep import check_options, run_sweep

    config = _with_overrides(_config(args.config), False, args.duration, reference=args.reference)
    if args.controllers is not None:
        from .compare import parse_controllers

        kinds = parse_controllers(args.controllers, config)
        config = replace(config, sweep=replace(config.sweep, variants=kinds))
    jobs = args.jobs if args.jobs is not None else (os.cpu_count() or 1)
    options = {"jobs": jobs, "executor": args.executor, "scheduler": args.scheduler}
    config = check_options(config, args.samples, args.seed, **options)  # before --out exists
    out = _out_dir(args.out)
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


def cmd_tune(args) -> int:
    """``hmpc-pin tune CONFIG`` (:mod:`hmpc_pin.apps.tune`): exit 2 naming the extra
    ``tune`` without Optuna, before anything runs."""
    from .tune import _optuna, check_args
    from .tune import cmd_tune as run_tune

    _optuna()
    config = _with_overrides(_config(args.config), False, args.duration)
    check_args(args, config)  # every option, before --out is created
    return run_tune(args, config, _out_dir(args.out))


def cmd_init(args) -> int:
    """``hmpc-pin init ROBOT``: write a commented config that runs as written."""
    from ..experiment.config import WorkspaceConfig
    from ..experiment.init import plant_step_hint, write_config

    if args.list:
        _print_init_names()
        return EXIT_OK
    if args.robot is None:
        raise ConfigError("ROBOT", "give a URDF path or a robot name (--list lists the names)")
    duration = _checked_duration(args.duration)  # None: long enough to identify friction
    try:
        workspace = WorkspaceConfig(
            height=0.0 if args.plane_height is None else args.plane_height,
            margin=0.02 if args.margin is None else args.margin,
        )
    except ConfigError as exc:
        flag = {"height": "--plane-height", "margin": "--margin"}[exc.key]
        raise ConfigError(flag, exc.message) from None
    path = write_config(
        args.robot,
        args.out,
        duration,
        overwrite=args.force,
        workspace=workspace,
        plane_given=args.plane_height is not None,
    )
    print(f"wrote {path}; run it with: hmpc-pin run {path}")
    lines = path.read_text(encoding="utf-8").splitlines()
    start = next((k for k, ln in enumerate(lines) if ln.startswith("# Friction identif")), None)
    if start is not None:  # what a run needs for `identify` (the file's comment)
        block = []
        for ln in lines[start:]:
            if not ln.startswith("#"):
                break
            block.append(ln[2:].strip())
        print(" ".join(block).replace("FILE", str(path)))
    hint = plant_step_hint("\n".join(lines))
    if hint is not None:
        print(hint, file=sys.stderr)
    return EXIT_OK


def _print_init_names() -> None:
    """``init --list``: the shipped arms and example-robot-data's arms (with so100/so101,
    which it mounts on a floating base: :data:`~hmpc_pin.model.robot.MOUNTED_ARMS`)."""
    from ..data import robot_names
    from ..model.robot import example_robot_names

    about = {"planar3": "the paper's arm", "fr3": "Franka Research 3, franka_description"}
    for name in sorted(robot_names(), key=lambda x: x != "planar3"):
        print(f"{name}  ({about.get(name, 'a packaged arm')}, shipped with hmpc_pin)")
    for name in example_robot_names():
        print(f"{name}  (example-robot-data)")
    print("or the path of any fixed-base arm's .urdf file")


def cmd_check(args) -> int:
    """``hmpc-pin check CONFIG``: per-joint figures; exit 1 with one line per problem."""
    from .check import check_config

    report = check_config(_config(args.config), engines=not args.no_engine)
    print(report.format())
    for line in report.warnings:
        print(f"warning: {line}", file=sys.stderr)
    for line in report.problems:
        print(f"problem: {line}")
    if report.problems:
        return EXIT_FAILED
    print("no problem found")
    return EXIT_OK


def cmd_realtime(args) -> int:
    from ..experiment.build import Experiment, brake_settings
    from .realtime import ArmView, format_tracking, run_realtime, with_realtime

    config = _with_overrides(_config(args.config), False, args.duration)
    if args.rate is not None and not (math.isfinite(args.rate) and args.rate > 0):
        raise ConfigError("--rate", f"expected a rate [Hz] > 0, got {args.rate!r}")
    priority = _checked_priority(args.priority)
    try:
        config = with_realtime(
            config,
            rate=args.rate,
            gc=False if args.no_gc else None,
            priority=priority,
            spin=args.spin,
            watchdog=args.watchdog,
            max_misses=args.max_misses,
        )
    except ConfigError as exc:  # a flag's value checked by [realtime]: name the flag
        raise ConfigError(f"--{exc.key.replace('_', '-')}", exc.message) from None
    experiment = Experiment.from_config(config)  # bad input stops here: nothing written
    brake_settings(config, 1.0 / config.realtime.rate)  # (the safe torque's brake too)
    out = _out_dir(args.out)
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

    return _report_realtime(start, config, "commanded", format_tracking)


def _report_realtime(start, config: ExperimentConfig, safe: str, *formats) -> int:
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


def cmd_ros(args) -> int:
    """``hmpc-pin ros``: the controller as a ROS 2 node (:mod:`hmpc_pin.apps.ros`)."""
    from ..ros.node import import_ros
    from .realtime import format_tracking
    from .ros import build_ros, check_run_length, format_ros, run_ros

    import_ros("hmpc-pin ros")  # the extra, before anything else
    config = _ros_config(args, _with_overrides(_config(args.config), False, args.duration))
    key = "--duration" if args.duration is not None else "simulation.duration"
    check_run_length(config.simulation.duration, config.ros.rate, key)
    namespace, node = _ros_node_name(config, args.ros_args)  # (checks its -p, before rclpy)
    # [ros] rate against Ts, the brake, [ros] gravity: bad input stops here, nothing written
    built = build_ros(config)  # built once, run below
    out = _out_dir(args.out)
    print(
        f"{config.name}: {config.description} ({config.controller.label}) as ROS 2 node "
        f"{namespace}/{node} for {config.simulation.duration:g} s, "
        f"paced by {config.ros.joint_states} at {config.ros.rate:g} Hz",
        flush=True,
    )
    return _report_realtime(
        lambda: run_ros(config, out, ros_args=args.ros_args, built=built),
        config,
        "published",
        format_ros,
        format_tracking,
    )


def _ros_node_name(config: ExperimentConfig, ros_args: list[str] | None) -> tuple[str, str]:
    """The controller node's namespace and name as rclpy will set them (``-r __ns:=``,
    ``-r __node:=`` of ``--ros-args`` over ``[ros]``), once every ``-p`` of ``ros_args``
    is checked to name one of the node's parameters (:mod:`hmpc_pin.apps.ros_args`)."""
    from .ros import config_parameters
    from .ros_args import check_parameters, parse_ros_args

    given = parse_ros_args(ros_args, config.ros.node)
    check_parameters(given.parameters, config_parameters(config))
    namespace = config.ros.namespace if given.namespace is None else given.namespace
    return namespace.rstrip("/"), given.node or config.ros.node


def _ros_config(args, config: ExperimentConfig) -> ExperimentConfig:
    """``--namespace`` and ``--priority`` of the ROS commands applied to ``config``."""
    from .realtime import with_realtime
    from .ros import with_namespace

    priority = _checked_priority(args.priority)
    try:
        config = with_realtime(
            config,
            priority=priority,
            watchdog=getattr(args, "watchdog", None),
            max_misses=getattr(args, "max_misses", None),
        )
    except ConfigError as exc:  # a flag's value checked by [realtime]: name the flag
        raise ConfigError(f"--{exc.key.replace('_', '-')}", exc.message) from None
    return with_namespace(config, args.namespace)


def cmd_ros_arm(args) -> int:
    """``hmpc-pin ros-arm``: the config's plant as a ROS 2 node (:mod:`hmpc_pin.apps.ros`)."""
    from ..ros.node import import_ros
    from .ros import run_ros_arm

    import_ros("hmpc-pin ros-arm")
    _checked_duration(args.duration)
    config = _ros_config(args, _config(args.config))
    counts = run_ros_arm(config, args.duration, args.ros_args, args.real_time_factor)
    return EXIT_INTERRUPTED if counts["interrupted"] else EXIT_OK


def cmd_ros_trajectory(args) -> int:
    """``hmpc-pin ros-trajectory`` (:mod:`hmpc_pin.apps.ros_client`)."""
    from ..ros.node import import_ros
    from .ros_client import run_trajectory

    import_ros("hmpc-pin ros-trajectory")
    return run_trajectory(args, _config(args.config))


def cmd_ros_lifecycle(args) -> int:
    """``hmpc-pin ros-lifecycle`` (:mod:`hmpc_pin.apps.ros_client`)."""
    from .ros_client import run_lifecycle

    return run_lifecycle(args)


def cmd_ros_params(args) -> int:
    """``hmpc-pin ros-params`` (:mod:`hmpc_pin.apps.ros_client`)."""
    from .ros_client import run_params

    return run_params(args)


def cmd_native(args) -> int:
    """``hmpc-pin native``: where the compiled core is and what it was built against."""
    from .. import native
    from ..exceptions import NativeError

    if args.build:
        print(
            "warning: `hmpc-pin native --build` is deprecated since 0.3: the compiled "
            "core is built when the package is installed",
            file=sys.stderr,
        )
    try:
        info = native.build_info()
    except NativeError as exc:
        print(f"native kernels: not available: {exc.reason}", file=sys.stderr)
        return EXIT_FAILED
    print(f"native kernels: {info['path']}")
    print(
        f"  built against pinocchio {info['pinocchio']}, proxsuite {info['proxsuite']} "
        f"({info['compiler']}, {info['build_type']})"
    )
    return 0


# ------------------------------------------------------------------------------ parser
def _add_reference_option(parser) -> None:
    parser.add_argument(
        "--reference",
        type=Path,
        metavar="FILE",
        help="track this joint trajectory (.csv: t, one column per joint [, dq_<joint>]; "
        "or .npz) instead of the config's reference",
    )


def _add_warn_option(parser) -> None:
    from .metrics import DEFAULT_ERROR_THRESHOLD

    parser.add_argument(
        "--warn-error",
        type=float,
        default=DEFAULT_ERROR_THRESHOLD,
        metavar="RAD",
        help="warn when max |e| after 1 s exceeds RAD (a warning is also printed when the "
        f"plant clips the torque) [{DEFAULT_ERROR_THRESHOLD:g}]",
    )


def _run_arguments(run) -> None:
    """``hmpc-pin run``."""
    from ..experiment.config import COMPENSATIONS

    run.description = (
        "Run one experiment: print the metrics table; write .npz, .csv and PNG "
        "figures (tracking, disturbance estimate, log tracking error)."
    )
    run.add_argument("config", type=Path, help=CONFIG_HELP)
    run.add_argument("--out", type=Path, default=Path("out"), help="output directory [out]")
    run.add_argument(
        "--no-ndo",
        action="store_true",
        help="run without disturbance compensation (the baseline; files named *_no_ndo)",
    )
    run.add_argument(
        "--compensation",
        default=None,
        metavar="NAME",
        help="replace the config's compensation: "
        + ", ".join(COMPENSATIONS)
        + " (files named *_<NAME>)",
    )
    run.add_argument("--duration", type=float, help="simulated time [s] (overrides the config)")
    _add_reference_option(run)
    run.add_argument(
        "--replay", type=Path, metavar="HTML", help="also write a self-contained Meshcat replay"
    )
    run.add_argument(
        "--viz", action="store_true", help="animate the arm live in Meshcat (prints the URL)"
    )
    run.add_argument(
        "--speed", type=float, default=1.0, help="live view: simulated s per real s [1]"
    )
    run.add_argument(
        "--wait",
        action="store_true",
        help="live view: start the run only once a browser has opened the URL",
    )
    run.add_argument(
        "--keep-open",
        action="store_true",
        help="live view: keep serving it after the run (files written) until Ctrl-C",
    )
    run.add_argument(
        "--force",
        action="store_true",
        help="replace an earlier run's files of the same name in --out (else exit 2)",
    )
    run.add_argument(
        "--no-figures",
        dest="figures",
        action="store_false",
        help="write the data files only (.npz, .csv; no PNG figures, which take most of a "
        "short run's time; the .npz holds every array they draw)",
    )
    run.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="a progress bar on stderr [on a terminal, once the run takes over 2 s]",
    )
    _add_warn_option(run)
    run.set_defaults(func=cmd_run)


def _replay_arguments(rpl) -> None:
    """``hmpc-pin replay``."""
    rpl.description = (
        "Turn a result .npz written by `run` into one HTML file that plays the "
        "run as a Meshcat animation (play/pause/scrub), with no server and no network."
    )
    rpl.add_argument("result", type=Path, help="result .npz")
    rpl.add_argument("--out", type=Path, default=Path("replay.html"), help="HTML file to write")
    rpl.add_argument("--urdf", help="URDF of the arm (default: the one named in the result)")
    rpl.set_defaults(func=cmd_replay)


def _compare_arguments(cmp_) -> None:
    """``hmpc-pin compare``."""
    from ..experiment.config import CONTROLLER_KINDS

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
    cmp_.add_argument("--duration", type=float, help="simulated time [s] (overrides the config)")
    _add_reference_option(cmp_)
    cmp_.add_argument("--quiet", action="store_true", help="no progress bar")
    _add_warn_option(cmp_)
    cmp_.set_defaults(func=cmd_compare)


def _reproduce_arguments(rep) -> None:
    """``hmpc-pin reproduce``."""
    rep.description = (
        "Run every experiment of the paper's Section 5 (with and without the "
        "observer), draw Figures 3(b) and 4-10, and write a Markdown report comparing "
        "the numbers with the paper's claims."
    )
    rep.add_argument("--out", type=Path, default=Path("out/reproduce"), help="output directory")
    rep.add_argument(
        "--configs",
        type=Path,
        default=None,
        help="directory holding the paper_*.toml configs [the packaged ones]",
    )
    rep.add_argument("--quiet", action="store_true", help="no progress bar")
    rep.set_defaults(func=cmd_reproduce)


def _sweep_arguments(swp) -> None:
    """``hmpc-pin sweep``."""
    from ..experiment.config import CONTROLLER_KINDS

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
    _add_reference_option(swp)
    swp.add_argument("--out", type=Path, default=Path("out"), help="output directory [out]")
    swp.add_argument("--quiet", action="store_true", help="no progress bar")
    swp.set_defaults(func=cmd_sweep)


def _init_arguments(ini) -> None:
    """``hmpc-pin init`` (docs, "Your own arm")."""
    ini.description = (
        "Write a TOML experiment that runs as written: a sine per joint around "
        "the reference posture (SRDF, else mid-range) inside the position and velocity "
        "limits, moved where the whole sine keeps every link above the mounting plane and "
        "clear of the others (the URDF's collision geometry), inertia-scaled disturbances, "
        "an observer valid for the arm, gripper/finger "
        "joints locked. Exit 2 with one line when the URDF cannot be controlled."
    )
    ini.add_argument(
        "robot", nargs="?", help="URDF path or robot name (planar3, ur5, panda, ...; --list)"
    )
    ini.add_argument(
        "--list", action="store_true", help="list the robot names init accepts and exit"
    )
    ini.add_argument("--out", type=Path, default=None, help="TOML file to write [<name>.toml]")
    ini.add_argument(
        "--duration",
        type=float,
        help="simulated time [s] [long enough for `identify`: the pulses, then a period]",
    )
    ini.add_argument("--force", action="store_true", help="overwrite an existing --out file")
    ini.add_argument(
        "--plane-height",
        type=float,
        default=None,
        metavar="M",
        help="height of the mounting plane (the table) in the URDF's root frame, which no "
        "moving link's collision geometry may cross [m] [0]",
    )
    ini.add_argument(
        "--margin",
        type=float,
        default=None,
        metavar="M",
        help="clearance every moving link keeps above the plane [m] [0.02]",
    )
    ini.set_defaults(func=cmd_init)


def _identify_arguments(idf) -> None:
    """``hmpc-pin identify`` (:mod:`hmpc_pin.apps.identify`)."""
    from .identify import identify_arguments

    identify_arguments(idf)


def cmd_plot(args) -> int:
    from .plot import figures, save

    _, figs = figures(args.file, args.run)  # bad input stops here: nothing written
    out = _out_dir(args.out if args.out is not None else args.file.parent)
    for path in save(args.file, figs, out):
        print(f"wrote {path}")
    if not figs:
        print(f"{args.file}: nothing to draw (no finite arrays)")
    return EXIT_OK


def _plot_arguments(plt) -> None:
    """``hmpc-pin plot`` (:mod:`hmpc_pin.apps.plot`)."""
    from .plot import plot_arguments

    plot_arguments(plt)
    plt.set_defaults(func=cmd_plot)


def _tune_arguments(tun) -> None:
    """``hmpc-pin tune`` (:mod:`hmpc_pin.apps.tune`)."""
    from .tune import tune_arguments

    tune_arguments(tun)
    tun.set_defaults(func=cmd_tune)


def _check_arguments(chk) -> None:
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
    chk.set_defaults(func=cmd_check)


def _realtime_arguments(rt) -> None:
    """``hmpc-pin realtime``."""
    from .realtime import add_stop_options, priority_value, spin_value

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
    rt.add_argument(
        "--viz",
        action="store_true",
        help="live Meshcat view of the arm, drawn by a separate process",
    )
    rt.add_argument("--out", type=Path, default=Path("out"), help="output directory [out]")
    rt.set_defaults(func=cmd_realtime)


def cmd_franka(args) -> int:
    """``hmpc-pin franka``: the controller on a Franka arm (:mod:`hmpc_pin.apps.franka`)."""
    from ..experiment.build import Experiment
    from .franka import FrankaOptions, format_driver, load_thresholds, run_franka
    from .realtime import format_tracking

    config = _with_overrides(_config(args.config), False, args.duration)
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
    out = _out_dir(args.out)
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

    return _report_realtime(start, config, "commanded", format_tracking, driver)


def _franka_arguments(parser) -> None:
    """``hmpc-pin franka`` (:mod:`hmpc_pin.apps.franka`)."""
    from .franka import franka_arguments

    franka_arguments(parser)
    parser.set_defaults(func=cmd_franka)


def _ros_arguments(ros) -> None:
    """``hmpc-pin ros`` (:mod:`hmpc_pin.apps.ros`)."""
    from .ros import ros_arguments

    ros_arguments(ros)
    ros.set_defaults(func=cmd_ros)


def _ros_arm_arguments(arm) -> None:
    """``hmpc-pin ros-arm`` (:mod:`hmpc_pin.apps.ros`)."""
    from .ros import ros_arm_arguments

    ros_arm_arguments(arm)
    arm.set_defaults(func=cmd_ros_arm)


def _configs_arguments(cfg) -> None:
    """``hmpc-pin configs`` (:mod:`hmpc_pin.apps.packaged`)."""
    from .packaged import configs_arguments

    configs_arguments(cfg)


def _examples_arguments(exa) -> None:
    """``hmpc-pin examples`` (:mod:`hmpc_pin.apps.packaged`)."""
    from .packaged import examples_arguments

    examples_arguments(exa)


def _ros_client_arguments(kind: str):
    """The arguments of ``ros-trajectory``, ``ros-lifecycle`` or ``ros-params``."""

    def arguments(parser) -> None:
        from . import ros_client

        getattr(ros_client, f"{kind}_arguments")(parser)
        parser.set_defaults(func=globals()[f"cmd_ros_{kind}"])

    return arguments


def _native_arguments(nat) -> None:
    """``hmpc-pin native``."""
    nat.description = (
        "Print where hmpc_pin's compiled core (the RK4 plant's period and the "
        "MPC step) is installed and what it was built against. It is built when the "
        "package is built (pip install); exit 1 if it cannot be loaded here."
    )
    nat.add_argument(
        "--build",
        action="store_true",
        help="deprecated since 0.3 (the core is built at install time): same as without it",
    )
    nat.set_defaults(func=cmd_native)


#: The commands in the order of ``hmpc-pin --help``: name -> (one-line help, the function
#: that gives its parser its description, arguments and ``func``). A command's arguments
#: are built only when it is the one that runs (:func:`build_parser`), so that
#: ``hmpc-pin --help`` and each command import only what they need.
COMMANDS = {
    "run": ("run one experiment from a TOML config", _run_arguments),
    "replay": ("write a self-contained Meshcat HTML replay of a saved run", _replay_arguments),
    "plot": (
        "draw the figures of a saved run, timing, sweep table or identification",
        _plot_arguments,
    ),
    "compare": ("run several controllers on one experiment and compare them", _compare_arguments),
    "reproduce": ("run every paper experiment and write DIR/report.md", _reproduce_arguments),
    "sweep": (
        "Monte Carlo robustness sweep of an experiment (with and without NDO)",
        _sweep_arguments,
    ),
    "init": (
        "write a commented config for any arm (URDF path or example-robot-data name)",
        _init_arguments,
    ),
    "identify": (
        "identify joint friction (or collision thresholds) from a saved run",
        _identify_arguments,
    ),
    "tune": (
        "tune observer gain, Q, R, N (and Ts) on the sweep's perturbed plants (Optuna)",
        _tune_arguments,
    ),
    "check": (
        "check a config's arm before running it (observer, damping, torque, engines)",
        _check_arguments,
    ),
    "realtime": (
        "run the controller in real time against an arm in a separate process",
        _realtime_arguments,
    ),
    "franka": (
        "run the controller on a Franka FR3 or Panda over libfranka at 1 kHz (extra: franka)",
        _franka_arguments,
    ),
    "ros": (
        "run the controller as a ROS 2 node against /joint_states (extra: ros)",
        _ros_arguments,
    ),
    "ros-arm": (
        "run the config's plant as a ROS 2 node (joint states out, efforts in; extra: ros)",
        _ros_arm_arguments,
    ),
    "configs": (
        "list the packaged configs, or write an editable copy of one",
        _configs_arguments,
    ),
    "examples": (
        "list the packaged example scripts, or write a copy of one",
        _examples_arguments,
    ),
    "ros-trajectory": (
        "send a new reference to the `ros` node's ~/joint_trajectory (extra: ros)",
        _ros_client_arguments("trajectory"),
    ),
    "ros-lifecycle": (
        "change or get the lifecycle state of the `ros` node (extra: ros)",
        _ros_client_arguments("lifecycle"),
    ),
    "ros-params": (
        "print the parameters of the `ros` node (extra: ros)",
        _ros_client_arguments("params"),
    ),
    "native": (
        "report the compiled core (built when the package was installed)",
        _native_arguments,
    ),
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
    for name, (help_, arguments) in COMMANDS.items():
        command = sub.add_parser(name, help=help_)
        if commands is None or name in commands:
            arguments(command)
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
        return _interrupted(exc)
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
