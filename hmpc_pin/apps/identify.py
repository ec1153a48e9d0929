"""``hmpc-pin identify RUN.npz``: friction (or, with ``--thresholds``, collision
thresholds) from a saved run, written as the config table that uses it."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from ..exceptions import ConfigError
from ..experiment.config import load_config
from ..experiment.config.write import write_config
from ..identification import fit_friction, learn_thresholds
from ..identification.friction import PULSE_SIGMAS
from ..sim.result import Result
from .runfile import load_run, run_robot

__all__ = ["cmd_identify", "identify_arguments", "load_run"]


def observer_model(result: Result, robot):
    """The :class:`~hmpc_pin.identification.observer_model.ObserverModel` of the observer that
    ran (recorded in the run's ``meta``: its matrix, period and discretization; files of
    older versions record kind and gain, or are read from the config they name), or
    ``None`` when the run had no observer or does not say which.

    Raises:
        ConfigError: The record is there but unusable (the message says what to do).
    """
    from ..experiment.controllers import make_compensation
    from ..identification import ObserverModel

    n = robot.nq
    om = result.meta.get("observer_model")
    if om is not None:
        return ObserverModel.from_record(om, robot, n)
    config = result.meta.get("config")
    if config and Path(config).is_file():  # an older file without a record
        cc = load_config(config).controller
        if cc.observer is not None:
            return ObserverModel.of(make_compensation(robot, cc), robot, cc.observer.model_at)
    return None


def _unmodelled(result: Result, after: float) -> tuple[str, float]:
    """The disturbances besides friction that the run's config (``meta["config"]``, when
    the file is still there) adds within the samples fitted (from ``after`` [s] on), in
    words (``[disturbance.pulse]``), or ``""``; and the time [s] after which they are
    negligible (:data:`PULSE_SIGMAS` deviations past the last centre; 0 when none)."""
    from ..exceptions import HmpcError

    source = result.meta.get("config")
    if not source or not Path(source).is_file() or "franka" in result.meta:
        return "", 0.0  # (on a Franka arm the config's simulated disturbances are not applied)
    try:
        pulse = load_config(source).disturbance.pulse
    except HmpcError:
        return "", 0.0
    if pulse is None:
        return "", 0.0
    n = result.q.shape[1]
    amplitude = np.broadcast_to(np.asarray(pulse.amplitude, dtype=float), (n,))
    center = np.broadcast_to(np.asarray(pulse.center, dtype=float), (n,))
    sigma = np.broadcast_to(np.asarray(pulse.sigma, dtype=float), (n,))
    live = (amplitude != 0) & (center + PULSE_SIGMAS * sigma > after)
    if not np.any(live):
        return "", 0.0
    at = ", ".join(f"{c:g}" for c in np.unique(center[live]))
    until = float(np.max(center[live] + PULSE_SIGMAS * sigma[live]))
    return f"disturbance pulses ([disturbance.pulse] of {source}, at t = {at} s)", until


def _table(toml_text: str) -> tuple[str, dict]:
    """The one table of a snippet written by the identification: (dotted name, keys)."""
    import tomllib

    raw = tomllib.loads(toml_text)
    name, body = next(iter(raw.items()))
    while all(isinstance(v, dict) for v in body.values()) and len(body) == 1:
        sub, body = next(iter(body.items()))
        name = f"{name}.{sub}"
    return name, body


FRICTION_OPTIONS = {
    "source": "observer",
    "urdf": None,
    "velocity_threshold": 0.01,
    "confidence": 0.95,
}
THRESHOLD_OPTIONS = {
    "false_alarm": 0.01,
    "horizon": 60.0,
    "block": 1.0,
    "safety": 1.25,
    "method": "gumbel",
}


def _options(args) -> None:
    """Fill the defaults of the chosen mode; an option of the other mode is an error."""
    mine, other = (
        (THRESHOLD_OPTIONS, FRICTION_OPTIONS)
        if args.thresholds
        else (FRICTION_OPTIONS, THRESHOLD_OPTIONS)
    )
    for key in other:
        if getattr(args, key) is not None:
            flag = "--" + key.replace("_", "-")
            raise ConfigError(
                flag,
                "applies to "
                + (
                    "friction identification only; drop it or --thresholds"
                    if args.thresholds
                    else "--thresholds only; add --thresholds or drop it"
                ),
            )
    for key, default in mine.items():
        if getattr(args, key) is None:
            setattr(args, key, default)


def _out_file(path: Path) -> Path:
    """``--out``: a file whose folder exists and is writable (checked before any work)."""
    from ..exceptions import OutputError

    if path.is_dir():
        raise OutputError(path, "is a directory", "--out", what="output file")
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise OutputError(folder, "is not writable (no such directory)", "--out")
    return path


def cmd_identify(args) -> int:
    """Fit, write the table (or the config with it), then print the report: the file is
    written before anything goes to stdout, so a closed pipe (``| head``) loses nothing."""
    _options(args)
    result = load_run(args.run)
    t0, t1 = float(result.t[0]), float(result.t[-1])
    if args.after is not None and not args.after < t1:
        raise ConfigError(
            "--after",
            f"{args.after:g} s is past the end of the run (its samples "
            f"span t = {t0:g} to {t1:g} s, {t1 - t0:g} s); pass a time before "
            f"{t1:g} s",
        )
    config = load_config(args.config) if args.config is not None else None  # checked first
    suffix = "collision" if args.thresholds else "friction"
    out = _out_file(args.out or args.run.with_name(f"{args.run.stem}_{suffix}.toml"))
    if args.thresholds:
        fit = learn_thresholds(
            result,
            false_alarm=args.false_alarm,
            horizon=args.horizon,
            block=args.block,
            safety=args.safety,
            after=args.after if args.after is not None else 0.0,
            method=args.method,
            run=args.run.name,
        )
        report = [
            f"{args.run.name}: collision thresholds on |d_hat|, false alarm <= "
            f"{args.false_alarm:g} per {args.horizon:g} s, safety x{args.safety:g}"
        ]
        rows = zip(fit.names, fit.threshold, fit.peak, strict=True)
        report += [
            f"  {name}: threshold {thr:.4g} N·m (peak |d_hat| in the run {peak:.4g})"
            for name, thr, peak in rows
        ]
        text = fit.toml()
        robot_estimate = result.extra.get("tau_ext_hat_filtered")
        if robot_estimate is not None:  # a Franka run: the robot's own estimate too
            report += _franka_thresholds(args, result, robot_estimate, out)
    else:
        robot = run_robot(result, args.urdf)
        observer = observer_model(result, robot) if args.source == "observer" else None
        if args.source == "observer" and observer is None:
            raise ConfigError(
                "--source",
                "the run does not say which observer ran (no "
                "observer_model in its meta); use --source dynamics",
            )
        friction = fit_friction(
            result,
            source=args.source,
            robot=robot,
            observer=observer,
            after=args.after if args.after is not None else 0.5,
            velocity_threshold=args.velocity_threshold,
            confidence=args.confidence,
            run=args.run.name,
        )
        unmodelled, until = _unmodelled(result, args.after if args.after is not None else 0.5)
        friction = replace(friction, unmodelled=unmodelled, unmodelled_until=until)
        report = [
            f"{args.run.name}: friction d = -(a q̇ + b sgn q̇) from the {args.source} (source)",
            friction.table(),
        ]
        text = friction.toml()
    if config is None:
        out.write_text(text, encoding="utf-8")
    else:
        name, body = _table(text)
        header = "\n".join(line[2:] for line in text.splitlines() if line.startswith("# "))
        write_config(config.source or args.config, {name: body}, out, header=header)
        load_config(out)  # the written config loads (the table is valid for it)
    report.append(f"wrote {out}" + (f" ({args.config} with [{_table(text)[0]}])" if config else ""))
    print("\n".join(report))
    return 0


def _franka_thresholds(args, result, robot_estimate, out: Path) -> list[str]:
    """Fit the same thresholds on the robot's own external torque estimate
    (``tau_ext_hat_filtered`` of a ``hmpc-pin franka`` run) and write them as the JSON
    ``hmpc-pin franka --thresholds`` sends with ``set_collision_behavior``: ``upper`` (the
    robot's collision reflex) the learned threshold, ``lower`` (its contact flag) half of it.

    Returns:
        The report's lines.
    """
    import json

    keep = np.all(np.isfinite(robot_estimate), axis=1)
    own = replace(
        result,
        **{name: getattr(result, name)[keep] for name in ("t", "q", "dq", "tau", "d", "q_ref")},
        d_hat=robot_estimate[keep],
        dq_ref=result.dq_ref[keep],
        tau_applied=None,
        ee_pos=None,
        extra={},
    )
    fit = learn_thresholds(
        own,
        false_alarm=args.false_alarm,
        horizon=args.horizon,
        block=args.block,
        safety=args.safety,
        after=args.after if args.after is not None else 0.0,
        method=args.method,
        run=args.run.name,
    )
    upper = [float(x) for x in fit.threshold]
    data = {
        "robot_estimate": {
            "source": "tau_ext_hat_filtered",
            "lower": [0.5 * x for x in upper],
            "upper": upper,
            "peak": [float(x) for x in fit.peak],
            "false_alarm": fit.false_alarm,
            "horizon": fit.horizon,
            "safety": fit.safety,
            "run": args.run.name,
        }
    }
    path = out.with_name(out.stem + "_franka.json")
    path.write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
    lines = [f"{args.run.name}: the robot's own estimate tau_ext_hat_filtered, the same fit:"]
    lines += [
        f"  {name}: collision (upper) {thr:.4g} N·m, contact (lower) {0.5 * thr:.4g} "
        f"(peak {peak:.4g})"
        for name, thr, peak in zip(fit.names, upper, fit.peak, strict=True)
    ]
    lines.append(f"wrote {path} (hmpc-pin franka --thresholds {path.name})")
    return lines


def identify_arguments(idf) -> None:
    """The ``identify`` subcommand's description and arguments (its one-line help is the
    command line's, ``hmpc_pin.apps.cli.COMMANDS``)."""
    idf.description = (
        "Fit each joint's viscous and Coulomb friction, d = -(a q̇ + b sgn q̇), "
        "from a run saved by `run` or `realtime` (least squares with confidence intervals) "
        "and write it as the [controller.friction] table, fed forward by the controller. "
        "From the observer, the intervals where a joint is stuck (a holding torque, not "
        "the friction law) and 5 of the observer's time constants after each are left "
        "out; a note under the table says how many samples. A negative coefficient (friction "
        "feeding energy in) is written as 0, with a note naming it; torque pulses of the "
        "run's config within the samples are named with the --after past them. "
        "With --thresholds, learn the [collision] thresholds on |d_hat| of a contact-free "
        "run at a stated false-alarm probability instead. Exit 2 with one line when the run "
        "does not excite a joint enough."
    )
    idf.add_argument("run", type=Path, help="result .npz of a run")
    idf.add_argument(
        "--out", type=Path, default=None, help="TOML file [RUN_friction.toml / RUN_collision.toml]"
    )
    idf.add_argument(
        "--config",
        type=Path,
        default=None,
        help="write this config with the table set, not the table alone",
    )
    idf.add_argument(
        "--after",
        type=float,
        default=None,
        help="skip samples before this time [s] [0.5; thresholds: 0]",
    )
    fr = idf.add_argument_group("friction")
    fr.add_argument(
        "--source",
        choices=("observer", "dynamics", "regressor"),
        default=None,
        help="observer: the estimate d_hat through the observer's dynamics; "
        "dynamics: the model's inverse dynamics (Pinocchio's regressor) against the "
        "applied torque; regressor: the same with the rigid-body parameters "
        "fitted too [observer]",
    )
    fr.add_argument("--urdf", help="the arm's URDF [the run's]")
    fr.add_argument(
        "--velocity-threshold",
        type=float,
        default=None,
        metavar="RAD_S",
        help="leave out samples slower than this [rad/s] [0.01]",
    )
    fr.add_argument(
        "--confidence", type=float, default=None, help="level of the confidence intervals [0.95]"
    )
    th = idf.add_argument_group("collision thresholds")
    th.add_argument(
        "--thresholds", action="store_true", help="learn [collision] thresholds instead of friction"
    )
    th.add_argument(
        "--false-alarm",
        type=float,
        default=None,
        metavar="P",
        help="false-alarm probability over --horizon, all joints [0.01]",
    )
    th.add_argument(
        "--horizon",
        type=float,
        default=None,
        metavar="S",
        help="the time over which --false-alarm holds [s] [60]",
    )
    th.add_argument(
        "--block", type=float, default=None, metavar="S", help="block of the block maxima [s] [1]"
    )
    th.add_argument(
        "--safety", type=float, default=None, help="factor >= 1 on the fitted quantile [1.25]"
    )
    th.add_argument(
        "--method",
        choices=("gumbel", "gev"),
        default=None,
        help="extreme-value fit: gumbel (conservative: at most the stated rate) "
        "or gev (calibrated on long runs of hundreds of blocks) [gumbel]",
    )
