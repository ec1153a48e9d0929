"""``hmpc-pin tune CONFIG``: search the controller's settings on the sweep's perturbed plants.

Each trial (Optuna, Optuna's ``TPESampler`` seeded with ``seed``) proposes
the observer gain :math:`c` (log-uniform on :math:`[c_0/10, 5c_0]`), the MPC weights
:math:`Q = \\mathrm{diag}(q_p, q_v)` (log-uniform :math:`q_p \\in [1, 10^4]`,
:math:`q_v \\in [10^{-4}, 10^2]`, terminal weight :math:`P = 2Q` as the paper's),
:math:`R \\in [10^{-8}, 10^{-3}]` (log) and the horizon :math:`N \\in [5, 30]`; with
``ts`` also the period :math:`T_s` among the given values, and with ``observers`` the
observer (``chen``, ``general``, ``momentum``). It runs the config's
controller on ``samples`` plants of the sweep (:mod:`hmpc_pin.apps.sweep`: link masses,
friction and pulse amplitudes drawn from ``[sweep]``, with its measurement noise and
delay; the same draws for every trial) and scores

.. math::

    J = p_{95}\\big(\\max_i \\mathrm{RMS}_i\\big)\\,\\Big(1 + w_s\\,\\bar s +
    w_{tv}\\,\\max\\big(0, \\overline{TV}/\\overline{TV}_0 - 1\\big)\\Big),

the 95th percentile over the samples of the worst joint's RMS error after
``sweep.after`` (a run that is not bounded scores more than any bounded one:
:func:`.run_score`), :math:`\\bar s`
the mean fraction of periods with a saturated torque, :math:`\\overline{TV}` the mean
torque total variation per second (:func:`~hmpc_pin.apps.sweep.torque_effort`) and
:math:`\\overline{TV}_0` that of the config as given, which is always the first trial.

The study is kept in an SQLite file (Optuna's RDB storage): running the command again
with the same ``--out`` resumes it. Ctrl-C writes the best config and the report of the
trials that finished, then exits 130. The best trial is written as a config, and the
shipped and tuned configs are compared on ``holdout`` other samples (another seed).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from .._startup import DeferredInterrupt
from ..compensation.registry import compensation_names
from ..exceptions import ConfigError, ExtraError, RunInterrupted
from ..experiment.config import ExperimentConfig
from .cluster import local_cluster
from .packaged import CONFIG_HELP
from .sweep import run_sweep
from .tune_objective import SATURATION_WEIGHT, TV_WEIGHT, objective_value, run_score
from .tune_report import shown_params, write_report, write_tuned
from .tune_space import (
    apply_params,
    current_params,
    format_param,
    own_params,
    search_space,
    suggest,
)

# the search space (.tune_space), the objective (.tune_objective) and what tune writes
# (.tune_report) are re-exported here
__all__ = [
    "SATURATION_WEIGHT",
    "TV_WEIGHT",
    "TuneResult",
    "apply_params",
    "current_params",
    "objective_value",
    "run_score",
    "search_space",
    "tune",
    "tune_arguments",
]


def _optuna():
    try:
        import optuna
    except ImportError as exc:
        raise ExtraError("tune", "hmpc-pin tune (Optuna)") from exc
    return optuna


#: Largest seed: Optuna's sampler seeds a NumPy ``RandomState`` (32 bits).
MAX_SEED = 2**32 - 1


def check_options(
    config: ExperimentConfig,
    *,
    trials,
    samples,
    seed,
    jobs,
    ts=None,
    observers=None,
    holdout=None,
    holdout_seed=None,
    executor="local",
    scheduler=None,
    duration_key: str = "simulation.duration",
) -> tuple[int, int]:
    """Check every option of :func:`tune` against ``config``, each error naming its own
    option, before anything is created (the command line calls it before ``--out``).

    Returns:
        ``(holdout, holdout_seed)`` with their defaults filled in (``samples``, ``seed + 1``).

    Raises:
        ConfigError: The first bad option (``--trials``, ``--samples``, ``--seed``,
            ``--jobs``, ``--holdout``, ``--holdout-seed``, ``--ts``, ``--observers``,
            ``duration_key``), an option that does not apply (``--scheduler`` without
            the dask executor, ``--holdout-seed`` with ``--holdout 0``), or a config that
            no trial could build.
    """
    if scheduler is not None and executor != "dask":  # an option that does not apply
        raise ConfigError(
            "--scheduler",
            f"applies to --executor dask only (got --executor "
            f"{executor}); add --executor dask or drop it",
        )
    if holdout_seed is not None and holdout == 0:
        raise ConfigError(
            "--holdout-seed",
            "seeds the held-out samples, and --holdout 0 "
            "draws none; drop it or set --holdout N >= 1",
        )
    holdout = samples if holdout is None else holdout
    if holdout_seed is None and isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
        holdout_seed = (seed + 1) % (MAX_SEED + 1)
    for key, value, low, high in (
        ("--trials", trials, 1, None),
        ("--samples", samples, 1, None),
        ("--seed", seed, 0, MAX_SEED),
        ("--jobs", jobs, 1, None),
        ("--holdout", holdout, 0, None),
        ("--holdout-seed", holdout_seed, 0, MAX_SEED),
    ):
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, np.integer))
            or value < low
            or (high is not None and value > high)
        ):
            within = (
                f"an integer in [{low}, {high}]" if high is not None else f"an integer >= {low}"
            )
            raise ConfigError(key, f"expected {within}, got {value!r}")
    if ts is not None and not (ts and all(np.isfinite(v) and v > 0 for v in ts)):
        raise ConfigError("--ts", f"expected control periods [s] > 0, got {ts!r}")
    if config.source is None:
        raise ConfigError(
            "CONFIG", "tune needs a config loaded from a file (it writes a tuned copy of it)"
        )
    duration, after = config.simulation.duration, config.sweep.after
    if not duration > after:
        raise ConfigError(
            duration_key,
            f"expected a simulated time longer than sweep.after = "
            f"{after:g} s (the error is scored after it), got {duration:g} s; "
            "lengthen it or lower [sweep] after",
        )
    space = search_space(config, ts, observers)
    from ..experiment.build import Experiment

    for params in (
        current_params(config, space),
        {k: s[-1] if s[0] != "choice" else s[1][-1] for k, s in space.items()},
    ):
        with warnings.catch_warnings():  # a range's end may warn; only errors matter here
            warnings.simplefilter("ignore")
            Experiment.from_config(apply_params(config, params))  # bad input before any trial
    return int(holdout), int(holdout_seed)


def _evaluate(config, samples, seed, jobs, executor, scheduler) -> list[dict]:
    """The sweep rows of ``config``'s own controller on ``samples`` plants.

    Raises:
        KeyboardInterrupt: Ctrl-C stopped the sweep (its partial rows score nothing).
    """
    config = replace(config, sweep=replace(config.sweep, variants=(config.controller.label,)))
    result = run_sweep(
        config, samples, seed, jobs=jobs, executor=executor, scheduler=scheduler, progress=False
    )
    if result.interrupted:
        raise KeyboardInterrupt
    return result.rows


@dataclass
class TuneResult:
    """What ``tune`` wrote and measured.

    Attributes:
        study: The Optuna study. best: The best trial's parameters. config: The tuned
        config. files: The files written. holdout: ``{"shipped": parts, "tuned": parts}``
        (:func:`objective_value`'s parts on the held-out samples), or ``None``.
    """

    study: object
    best: dict
    config: ExperimentConfig
    files: list
    holdout: dict | None


def tune(
    config: ExperimentConfig,
    out: Path,
    *,
    trials: int,
    samples: int = 8,
    seed: int = 0,
    jobs: int = 1,
    executor: str = "local",
    scheduler: str | None = None,
    ts: tuple[float, ...] | None = None,
    observers: tuple[str, ...] | None = None,
    holdout: int | None = None,
    holdout_seed: int | None = None,
    progress: bool = True,
    objective=None,
) -> TuneResult:
    """Run (or resume) the study of ``config`` in ``out``; write the tuned config, the
    study and the report.

    Args:
        config: The config to tune (its ``[sweep]`` table draws the plants).
        out: Folder of ``<name>_tune.db``, ``<name>_tuned.toml``, ``<name>_tune.md`` and
            the two figures.
        trials: Trials to add to the study (>= 1).
        samples: Sweep samples per trial (>= 1). seed: Seed of the sampler and the samples.
        jobs, executor, scheduler: As :func:`~hmpc_pin.apps.sweep.run_sweep`.
        ts: Control periods [s] to choose from (``None``: keep the config's).
        observers: Observers to choose from (``"chen"``, ``"general"``, ``"momentum"``;
            ``None``: keep the config's).
        holdout: Samples of the final comparison (0: none; default ``samples``).
        holdout_seed: Their seed (default ``seed + 1``).
        objective: ``objective(config) -> (value, parts)`` instead of the sweep's (tests).

    Raises:
        ExtraError: Optuna is not installed (extra ``tune``). ConfigError: bad options
            (:func:`check_options`, before anything is written).
        RunInterrupted: Ctrl-C: the tuned config and the report of the trials that
            finished were written first (:attr:`~hmpc_pin.exceptions.RunInterrupted.files`;
            none if no trial finished); the study resumes from its file.
    """
    optuna = _optuna()
    holdout, holdout_seed = check_options(
        config,
        trials=trials,
        samples=samples,
        seed=seed,
        jobs=jobs,
        ts=ts,
        observers=observers,
        holdout=holdout,
        holdout_seed=holdout_seed,
        executor=executor,
        scheduler=scheduler,
    )
    with DeferredInterrupt() as sigint:
        return _tune(
            optuna, config, out, sigint, trials, samples, seed, jobs, executor, scheduler,
            ts, observers, holdout, holdout_seed, progress, objective,
        )  # fmt: skip


def _tune(
    optuna, config, out, sigint, trials, samples, seed, jobs, executor, scheduler, ts,
    observers, holdout, holdout_seed, progress, objective,
) -> TuneResult:  # fmt: skip
    """:func:`tune` once its options are checked, under ``sigint``
    (:class:`DeferredInterrupt`)."""
    space = search_space(config, ts, observers)
    name = config.name
    storage = f"sqlite:///{(out / f'{name}_tune.db').resolve()}"
    optuna.logging.set_verbosity(optuna.logging.ERROR)  # a failed trial is ours to report
    study = optuna.create_study(
        study_name=name,
        storage=storage,
        direction="minimize",
        load_if_exists=True,
        sampler=optuna.samplers.TPESampler(
            seed=(seed + len_trials(optuna, storage, name)) % (MAX_SEED + 1)
        ),
    )
    if not study.trials:
        study.enqueue_trial(current_params(config, space))
        study.set_user_attr("samples", samples)
        study.set_user_attr("seed", seed)
    elif study.user_attrs.get("samples") != samples or study.user_attrs.get("seed") != seed:
        raise ConfigError(
            "--samples/--seed",
            f"the study in {out} was run with --samples "
            f"{study.user_attrs.get('samples')} --seed {study.user_attrs.get('seed')}; resume "
            "it with the same, or write to another --out",
        )

    def evaluate(cfg: ExperimentConfig):
        if objective is not None:
            return sigint.evaluating(objective, cfg)
        rows = sigint.evaluating(_evaluate, cfg, samples, seed, jobs, executor, scheduler)
        return objective_value(
            rows,
            cfg.sweep.error_bound,
            study.user_attrs.get("tv0"),
            duration=cfg.simulation.duration,
        )

    def run_trial(trial):
        params = suggest(trial, space)
        if trial.number == 0:  # the config as given, its own values (a Q_velocity of 0 too)
            params = own_params(config, space)
            trial.set_user_attr("ran", params)  # the sampler's record is the nearest point
        value, parts = evaluate(apply_params(config, params))
        if "tv0" not in study.user_attrs and "torque_tv" in parts:  # trial 0: as given
            study.set_user_attr("tv0", parts["torque_tv"])
        for k, v in parts.items():
            trial.set_user_attr(k, v)
        return value

    cluster = None
    if executor == "dask" and scheduler is None and objective is None:
        cluster = local_cluster(jobs)  # one cluster for every trial, not one per trial
        scheduler = cluster.scheduler_address
    db = out / f"{name}_tune.db"
    stopped = None  # where Ctrl-C stopped the call, in words
    comparison = None
    try:
        try:
            sigint.check()
            study.optimize(run_trial, n_trials=trials, show_progress_bar=progress)
            sigint.check()  # a Ctrl-C kept back while the last trial was recorded
        except KeyboardInterrupt:
            finished = sum(t.state.name == "COMPLETE" for t in study.trials)
            stopped = (
                f"trial {len(study.trials) - 1} of the study ({finished} finished; run "
                "again with the same --out to resume it)"
            )
        if not any(t.state.name == "COMPLETE" for t in study.trials):
            raise RunInterrupted(f"{stopped}: no trial finished, no config written", files=[db])
        best = shown_params(study.best_trial, study)
        tuned = apply_params(config, best)  # what the best trial ran
        files = [write_tuned(config, tuned, best, study, out)]
        if holdout and objective is None and stopped is None:
            try:
                comparison = {}
                for label, cfg in (("shipped", config), ("tuned", tuned)):
                    rows = sigint.evaluating(
                        _evaluate, cfg, holdout, holdout_seed, jobs, executor, scheduler
                    )
                    comparison[label] = objective_value(
                        rows,
                        cfg.sweep.error_bound,
                        study.user_attrs.get("tv0"),
                        duration=cfg.simulation.duration,
                    )[1]
            except KeyboardInterrupt:
                comparison = None
                stopped = f"the held-out comparison, after {len(study.trials)} trials"
    finally:
        if cluster is not None:
            cluster.close()
    files += write_report(
        config, study, best, out, comparison, samples, seed, holdout, holdout_seed, stopped, space
    )
    files.insert(1, db)
    if stopped is not None:
        raise RunInterrupted(stopped, files=files)
    return TuneResult(study, best, tuned, files, comparison)


def len_trials(optuna, storage: str, name: str) -> int:
    """Trials already in the stored study (0 if none): a resumed study's sampler is seeded
    ``seed + len`` so that its continuation is reproducible too."""
    try:
        return len(optuna.load_study(study_name=name, storage=storage).trials)
    except KeyError:
        return 0


def _periods(text: str) -> tuple[float, ...]:
    try:
        return tuple(float(v) for v in text.split(","))
    except ValueError as exc:
        raise ConfigError("--ts", f"expected comma-separated periods [s], got {text!r}") from exc


def _jobs(args) -> int:
    import os

    return args.jobs if args.jobs is not None else (os.cpu_count() or 1)


def check_args(args, config: ExperimentConfig) -> None:
    """Every option of ``hmpc-pin tune`` checked against ``config``, each error naming
    its own flag, before anything is created (:func:`check_options`)."""
    check_options(
        config,
        trials=args.trials,
        samples=args.samples,
        seed=args.seed,
        jobs=_jobs(args),
        ts=_periods(args.ts) if args.ts else None,
        observers=tuple(args.observers.split(",")) if args.observers else None,
        holdout=args.holdout,
        holdout_seed=args.holdout_seed,
        executor=args.executor,
        scheduler=args.scheduler,
        duration_key="--duration" if args.duration is not None else "simulation.duration",
    )


def cmd_tune(args, config: ExperimentConfig, out: Path) -> int:
    """``hmpc-pin tune CONFIG`` once the command line has checked the config, the options
    (:func:`check_args`) and ``out``: run or resume the study; print the held-out
    comparison."""
    result = tune(
        config,
        out,
        trials=args.trials,
        samples=args.samples,
        seed=args.seed,
        jobs=_jobs(args),
        executor=args.executor,
        scheduler=args.scheduler,
        ts=_periods(args.ts) if args.ts else None,
        observers=tuple(args.observers.split(",")) if args.observers else None,
        holdout=args.holdout,
        holdout_seed=args.holdout_seed,
        progress=not args.quiet,
    )
    study = result.study
    print(
        f"{config.name}: {len(study.trials)} trials; best trial {study.best_trial.number}, "
        f"J = {study.best_value:.4g}: "
        + ", ".join(f"{k} = {format_param(v)}" for k, v in result.best.items())
    )
    if result.holdout:
        s, t = result.holdout["shipped"]["p95_rms"], result.holdout["tuned"]["p95_rms"]
        print(
            f"held-out samples: p95 worst-joint RMS {s:.4g} rad as given, {t:.4g} rad tuned "
            f"(ratio {s / t:.3g})"
        )
    for f in result.files:
        print(f"wrote {f}")
    return 0


def tune_arguments(tun):
    """The ``tune`` subcommand's description and arguments (the command line sets its
    ``func`` and its one-line help, ``hmpc_pin.apps.cli.COMMANDS``)."""
    tun.description = (
        "Search the observer gain, the MPC weights Q (P = 2Q) and R, the "
        "horizon N and, with --ts, the control period to minimise the 95th percentile of "
        "the worst joint's RMS error over the sweep's perturbed plants (with its noise and "
        "delay), penalised by torque saturation and total variation. Optuna's TPE sampler "
        "seeded with --seed; the study is kept in DIR/<name>_tune.db (run again to resume). "
        "Writes DIR/<name>_tuned.toml and a report with the history and importance plots, "
        "and compares both configs on held-out samples. Needs the extra hmpc_pin[tune]."
    )
    tun.add_argument("config", type=Path, help=CONFIG_HELP)
    tun.add_argument(
        "--trials", type=int, required=True, help="trials to run (added to a resumed study)"
    )
    tun.add_argument("--samples", type=int, default=8, help="sweep samples per trial [8]")
    tun.add_argument("--seed", type=int, default=0, help="seed of the sampler and samples [0]")
    tun.add_argument("--jobs", type=int, default=None, help="worker processes [all cores]")
    tun.add_argument(
        "--executor",
        choices=("local", "dask"),
        default="local",
        help="each trial's samples on local processes or Dask [local]",
    )
    tun.add_argument("--scheduler", help="with --executor dask: a running scheduler's address")
    tun.add_argument(
        "--ts", metavar="T1,T2,...", help="also choose the control period among these [s]"
    )
    tun.add_argument(
        "--observers",
        metavar="NAME,...",
        help="also choose the observer: " + ", ".join(compensation_names(table="observer")),
    )
    tun.add_argument(
        "--holdout",
        type=int,
        default=None,
        help="held-out samples of the comparison (0: none) [--samples]",
    )
    tun.add_argument("--holdout-seed", type=int, default=None, help="their seed [--seed + 1]")
    tun.add_argument("--duration", type=float, help="simulated time [s] (overrides the config)")
    tun.add_argument("--out", type=Path, default=Path("out"), help="output directory [out]")
    tun.add_argument("--quiet", action="store_true", help="no progress bar")
    return tun
