"""``hmpc-pin run``: run one experiment from a TOML config. Its arguments
(``add_arguments``) and its entry point (``main``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from ...exceptions import ConfigError, VizError
from ..common import (
    EXIT_FAILED,
    EXIT_OK,
    add_force_option,
    add_reference_option,
    add_warn_option,
    out_dir,
    out_file,
    read_config,
    refuse_earlier_files,
    warn_thresholds,
    with_overrides,
    write_replay,
)
from ..packaged import CONFIG_HELP

if TYPE_CHECKING:
    from ...experiment.config import ExperimentConfig

__all__ = ["add_arguments", "main"]


def add_arguments(run) -> None:
    """``hmpc-pin run``."""
    from ...experiment.config import COMPENSATIONS

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
    add_reference_option(run)
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
    add_force_option(run)
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
    add_warn_option(run)


def main(args) -> int:
    if args.figures:  # matplotlib is imported beside the run (the command line only)
        from ..figure_worker import start

        start()
    from ...experiment.build import Experiment

    config = with_overrides(
        read_config(args.config), args.no_ndo, args.duration, args.compensation, args.reference
    )
    if not args.speed > 0:
        raise ConfigError("--speed", f"expected a number > 0, got {args.speed!r}")
    experiment = Experiment.from_config(config)  # bad input stops here: nothing written
    if args.replay is not None:  # Meshcat and the meshes, before the run and any file
        _check_meshes(config, "--replay")
    warn = warn_thresholds(args)
    for flag, value in (("--wait", args.wait), ("--keep-open", args.keep_open)):
        if value and not args.viz:
            raise ConfigError(flag, "applies to the live view only; add --viz or drop " + flag)
    stem = config.name
    if args.compensation is not None:
        stem += f"_{args.compensation}"
    if args.no_ndo and not config.name.endswith("_no_ndo"):
        stem += "_no_ndo"
    refuse_earlier_files(args.out, (f"{stem}.npz", f"{stem}.csv"), args.force)
    out = out_dir(args.out)  # every option checked: the first thing written
    if args.replay is not None:
        out_file(args.replay, "--replay")
    views: list = []  # the live view, opened by run_one once the experiment is built
    try:
        return _run_and_report(args, config, out, stem, warn, views, experiment)
    finally:
        for view in views:
            view.close()


def _open_view(experiment, args, views: list):
    """The live view of ``--viz`` (``None`` when it cannot start: the run goes on), waiting
    for a browser with ``--wait``; kept in ``views`` for the caller to close."""
    from ..run import live_view

    view = live_view(experiment.robot, args.speed, experiment.obstacle)
    if view is None:
        return None
    views.append(view)
    if args.wait:
        print(f"waiting for a browser at {view.url} (Ctrl-C to stop)", flush=True)
        view.wait_for_browser()
    return view


def _run_and_report(args, config, out, stem, warn, views: list, experiment=None) -> int:
    from ..run import after_the_run, run_one

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
    from ...experiment.build import uses_observer
    from ..metrics import compute_metrics, contact_lines, format_metrics, run_warnings
    from ..run import draw_figures

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
        files.append(write_replay(experiment.robot, result, args.replay))
    for f in files:
        print(f"wrote {f}")
    if view is not None and args.keep_open:
        print(f"live view kept open at {view.url}; Ctrl-C to close", flush=True)
        view.hold()
    if failure:
        print(f"error: run failed: {failure}", file=sys.stderr)
        return EXIT_FAILED
    return EXIT_OK


def _check_meshes(config: ExperimentConfig, option: str) -> None:
    """Load the visual geometry of the config's arm before the run, so that a missing
    mesh is bad input naming the mesh and ``option`` (no run, no file)."""
    from ...experiment.build import load_robot_config
    from ..viz import require_meshcat, visual_model

    try:
        require_meshcat()
        visual_model(load_robot_config(config.robot))
    except VizError as exc:
        raise VizError(f"{option}: {exc}; or run without {option}") from None
