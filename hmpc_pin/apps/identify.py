"""``hmpc-pin identify RUN.npz``: friction (or, with ``--thresholds``, collision
thresholds) from a saved run, written as the config table that uses it."""

from __future__ import annotations

from pathlib import Path

from ..exceptions import ConfigError
from ..experiment.config.write import write_config
from ..experiment.schema import load_config
from ..identification import fit_friction, learn_thresholds
from ..sim.result import Result

__all__ = ["add_identify_parser", "cmd_identify", "load_run"]


def load_run(path: Path) -> Result:
    """The run saved at ``path``, or one :class:`ConfigError` naming it."""
    if not path.is_file():
        raise ConfigError("RUN", f"{str(path)!r} not found; pass a .npz written by `hmpc-pin "
                          "run` or `hmpc-pin realtime`")  # fmt: skip
    try:
        return Result.load(path)
    except (OSError, ValueError, KeyError) as exc:
        raise ConfigError("RUN", f"{str(path)!r} is not a hmpc_pin result: {exc}") from exc


def _robot(result: Result, urdf: str | None):
    from ..model.robot import load_robot

    source = urdf or result.meta.get("urdf")
    if not source:
        raise ConfigError("--urdf", "the run does not name its URDF; pass --urdf PATH")
    return load_robot(
        source,
        gravity=result.meta.get("gravity", 9.81),
        locked_joints=result.meta.get("locked_joints") if not urdf else None,
    )


def observer_model(result: Result, robot):
    """The :class:`~hmpc_pin.identification.friction.ObserverModel` of the run's
    observer (recorded in its ``meta``, else read from the config it names), or ``None``
    when the run had no observer or does not say which."""
    from ..identification import ObserverModel

    om = result.meta.get("observer_model")
    if om is None and result.meta.get("config") and Path(result.meta["config"]).is_file():
        cc = load_config(result.meta["config"]).controller
        if cc.observer is not None and cc.compensation in ("chen", "general", "momentum"):
            om = {"kind": cc.compensation, "gain": cc.observer.gain, "Ts": cc.Ts,
                  "discretization": cc.observer.discretization}  # fmt: skip
    if om is None:
        return None
    return ObserverModel(om["kind"], float(om["gain"]), float(om["Ts"]), robot,
                         om.get("discretization", "implicit") == "implicit")  # fmt: skip


def _table(toml_text: str) -> tuple[str, dict]:
    """The one table of a snippet written by the identification: (dotted name, keys)."""
    import tomllib

    raw = tomllib.loads(toml_text)
    name, body = next(iter(raw.items()))
    while all(isinstance(v, dict) for v in body.values()) and len(body) == 1:
        sub, body = next(iter(body.items()))
        name = f"{name}.{sub}"
    return name, body


FRICTION_OPTIONS = {"source": "observer", "urdf": None, "velocity_threshold": 0.01,
                    "confidence": 0.95}  # fmt: skip
THRESHOLD_OPTIONS = {"false_alarm": 0.01, "horizon": 60.0, "block": 1.0, "safety": 1.25,
                     "method": "gumbel"}  # fmt: skip


def _options(args) -> None:
    """Fill the defaults of the chosen mode; an option of the other mode is an error."""
    mine, other = ((THRESHOLD_OPTIONS, FRICTION_OPTIONS) if args.thresholds
                   else (FRICTION_OPTIONS, THRESHOLD_OPTIONS))  # fmt: skip
    for key in other:
        if getattr(args, key) is not None:
            flag = "--" + key.replace("_", "-")
            raise ConfigError(flag, "applies to " + ("friction identification only; drop it "
                              "or --thresholds" if args.thresholds else "--thresholds only; "
                              "add --thresholds or drop it"))  # fmt: skip
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
    _options(args)
    result = load_run(args.run)
    config = load_config(args.config) if args.config is not None else None  # checked first
    if args.thresholds:
        fit = learn_thresholds(
            result, false_alarm=args.false_alarm, horizon=args.horizon, block=args.block,
            safety=args.safety, after=args.after if args.after is not None else 0.0,
            method=args.method,
            run=args.run.name,
        )  # fmt: skip
        suffix = "collision"
        print(f"{args.run.name}: collision thresholds on |d_hat|, false alarm <= "
              f"{args.false_alarm:g} per {args.horizon:g} s, safety x{args.safety:g}")  # fmt: skip
        for name, thr, peak in zip(fit.names, fit.threshold, fit.peak, strict=True):
            print(f"  {name}: threshold {thr:.4g} N·m (peak |d_hat| in the run {peak:.4g})")
    else:
        robot = _robot(result, args.urdf)
        observer = observer_model(result, robot) if args.source == "observer" else None
        if args.source == "observer" and observer is None:
            raise ConfigError("--source", "the run does not say which observer ran (no "
                              "observer_model in its meta); use --source dynamics")  # fmt: skip
        fit = fit_friction(
            result, source=args.source, robot=robot, observer=observer,
            after=args.after if args.after is not None else 0.5,
            velocity_threshold=args.velocity_threshold, confidence=args.confidence,
            run=args.run.name,
        )  # fmt: skip
        suffix = "friction"
        print(f"{args.run.name}: friction d = -(a q̇ + b sgn q̇) from the {args.source} "
              "(source)")  # fmt: skip
        print(fit.table())
    text = fit.toml()
    out = args.out or args.run.with_name(f"{args.run.stem}_{suffix}.toml")
    _out_file(out)
    if config is None:
        out.write_text(text, encoding="utf-8")
    else:
        name, body = _table(text)
        header = "\n".join(line[2:] for line in text.splitlines() if line.startswith("# "))
        write_config(config.source, {name: body}, out, header=header)
        load_config(out)  # the written config loads (the table is valid for it)
    print(f"wrote {out}" + (f" ({args.config} with [{_table(text)[0]}])" if config else ""))
    return 0


def add_identify_parser(sub) -> None:
    """The ``identify`` subcommand."""
    idf = sub.add_parser(
        "identify",
        help="identify joint friction (or collision thresholds) from a saved run",
        description="Fit each joint's viscous and Coulomb friction, d = -(a q̇ + b sgn q̇), "
        "from a run saved by `run` or `realtime` (least squares with confidence intervals) "
        "and write it as the [controller.friction] table, fed forward by the controller. "
        "With --thresholds, learn the [collision] thresholds on |d_hat| of a contact-free "
        "run at a stated false-alarm probability instead. Exit 2 with one line when the run "
        "does not excite a joint enough.",
    )
    idf.add_argument("run", type=Path, help="result .npz of a run")
    idf.add_argument("--out", type=Path, default=None,
                     help="TOML file [RUN_friction.toml / RUN_collision.toml]")  # fmt: skip
    idf.add_argument("--config", type=Path, default=None,
                     help="write this config with the table set, not the table alone")  # fmt: skip
    idf.add_argument("--after", type=float, default=None,
                     help="skip samples before this time [s] [0.5; thresholds: 0]")  # fmt: skip
    fr = idf.add_argument_group("friction")
    fr.add_argument("--source", choices=("observer", "dynamics", "regressor"), default=None,
                    help="observer: the estimate d_hat through the observer's dynamics; "
                    "dynamics: the model's inverse dynamics (Pinocchio's regressor) against the "
                    "applied torque; regressor: the same with the rigid-body parameters "
                    "fitted too [observer]")  # fmt: skip
    fr.add_argument("--urdf", help="the arm's URDF [the run's]")
    fr.add_argument("--velocity-threshold", type=float, default=None, metavar="RAD_S",
                    help="leave out samples slower than this [rad/s] [0.01]")  # fmt: skip
    fr.add_argument("--confidence", type=float, default=None,
                    help="level of the confidence intervals [0.95]")  # fmt: skip
    th = idf.add_argument_group("collision thresholds")
    th.add_argument("--thresholds", action="store_true",
                    help="learn [collision] thresholds instead of friction")  # fmt: skip
    th.add_argument("--false-alarm", type=float, default=None, metavar="P",
                    help="false-alarm probability over --horizon, all joints [0.01]")  # fmt: skip
    th.add_argument("--horizon", type=float, default=None, metavar="S",
                    help="the time over which --false-alarm holds [s] [60]")  # fmt: skip
    th.add_argument("--block", type=float, default=None, metavar="S",
                    help="block of the block maxima [s] [1]")  # fmt: skip
    th.add_argument("--safety", type=float, default=None,
                    help="factor >= 1 on the fitted quantile [1.25]")  # fmt: skip
    th.add_argument("--method", choices=("gumbel", "gev"), default=None,
                    help="extreme-value fit: gumbel (conservative: at most the stated rate) "
                    "or gev (calibrated on long runs of hundreds of blocks) [gumbel]")  # fmt: skip
    idf.set_defaults(func=cmd_identify)
