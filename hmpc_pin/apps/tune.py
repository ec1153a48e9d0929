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
:func:`run_score`), :math:`\\bar s`
the mean fraction of periods with a saturated torque, :math:`\\overline{TV}` the mean
torque total variation per second (:func:`~hmpc_pin.apps.sweep.torque_effort`) and
:math:`\\overline{TV}_0` that of the config as given, which is always the first trial.

The study is kept in an SQLite file (Optuna's RDB storage): running the command again
with the same ``--out`` resumes it. Ctrl-C writes the best config and the report of the
trials that finished, then exits 130. The best trial is written as a config, and the
shipped and tuned configs are compared on ``holdout`` other samples (another seed).
"""

from __future__ import annotations

import math
import signal
import threading
import warnings
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..compensation.registry import compensation_names, compensation_spec
from ..controllers.registry import controller_spec
from ..exceptions import ConfigError, ExtraError, RunInterrupted, install_command
from ..experiment.config import ExperimentConfig, load_config
from ..experiment.config.write import write_config
from .packaged import CONFIG_HELP
from .sweep import run_sweep

__all__ = [
    "TuneResult",
    "apply_params",
    "objective_value",
    "run_score",
    "search_space",
    "tune",
    "tune_arguments",
]

#: Weights of the penalties (module docstring): saturation, total variation.
SATURATION_WEIGHT = 1.0
TV_WEIGHT = 0.1


def _optuna():
    try:
        import optuna
    except ImportError as exc:
        raise ExtraError("tune", "hmpc-pin tune (Optuna)") from exc
    return optuna


def search_space(
    config: ExperimentConfig,
    ts: tuple[float, ...] | None = None,
    observers: tuple[str, ...] | None = None,
) -> dict:
    """The parameters a trial proposes: name → ``("log", low, high)``, ``("int", low,
    high)`` or ``("choice", values)``.

    Raises:
        ConfigError: ``observers`` names no observer, or the config has none.
    """
    cc = config.controller
    names = compensation_names(table="observer")
    if observers:
        bad = [o for o in observers if o not in names]
        if bad or cc.compensation not in names:
            raise ConfigError(
                "--observers",
                f"expected observers of {names} for a config "
                f"with an observer; got {observers!r} for {cc.label}",
            )
    space: dict = {
        "Q_position": ("log", 1.0, 1e4),
        "Q_velocity": ("log", 1e-4, 1e2),
        "R": ("log", 1e-8, 1e-3),
    }
    if controller_spec(cc.kind).mpc:
        space["N"] = ("int", 5, 30)
    if cc.compensation in names and cc.observer.bandwidth is not None:
        w0 = _bandwidth_scale(cc)  # the largest joint's; the others keep their ratio to it
        space["observer_bandwidth"] = ("log", w0 / 10, w0 * 5)
    elif cc.compensation in names:
        c0 = cc.observer.gain
        space["observer_gain"] = ("log", c0 / 10, c0 * 5)
    if ts:
        space["Ts"] = ("choice", tuple(float(v) for v in ts))
    if observers:
        space["compensation"] = ("choice", tuple(observers))
    return space


def _bandwidth_scale(cc) -> float:
    """The largest joint bandwidth [1/s] of an observer given by its bandwidth: the
    parameter ``observer_bandwidth`` a trial proposes (every joint scaled with it)."""
    return float(np.max(cc.observer.bandwidth))


def _own_params(config: ExperimentConfig, space: dict) -> dict:
    """The config's own values of the parameters of ``space``, not clipped: what trial 0
    (the config as given) runs, through :func:`apply_params` like every trial."""
    cc = config.controller
    own = {
        "Q_position": float(cc.Q[0, 0]),
        "Q_velocity": float(cc.Q[1, 1]),
        "R": float(cc.R),
        "N": int(cc.N),
        "Ts": float(cc.Ts),
        "compensation": cc.compensation,
        "observer_gain": None if cc.observer is None else cc.observer.gain,
        "observer_bandwidth": None
        if cc.observer is None or cc.observer.bandwidth is None
        else _bandwidth_scale(cc),
    }
    return {k: own[k] for k in space}


def current_params(config: ExperimentConfig, space: dict) -> dict:
    """The point of ``space`` nearest the config's own values (``_own_params``): each
    clipped into its range, the nearest period of ``Ts``, the first observer of
    ``compensation`` when the config's is not listed. The sampler records trial 0 there
    (Optuna refuses a value outside the space); the report says where it differs from
    what ran."""
    out = {}
    for name, v in _own_params(config, space).items():
        spec = space[name]
        if name == "compensation":
            out[name] = v if v in spec[1] else spec[1][0]
        elif spec[0] == "choice":
            out[name] = min(spec[1], key=lambda c, v=v: abs(c - v))
        else:
            out[name] = type(v)(min(max(v, spec[1]), spec[2]))
    return out


def _sampler_record(config: ExperimentConfig, space: dict) -> list[str]:
    """Where the sampler's record of trial 0 (:func:`current_params`) differs from what it
    ran (:func:`_own_params`), and ``P = 2Q`` when the config's ``P`` is not: in words."""
    own, near = _own_params(config, space), current_params(config, space)
    lines = [f"{k} = {_cell(near[k])} (ran {_cell(own[k])})" for k in space if near[k] != own[k]]
    cc = config.controller
    Q = np.diag([cc.Q[0, 0], cc.Q[1, 1]])
    if not (np.array_equal(cc.Q, Q) and np.array_equal(cc.P, 2 * Q)):
        lines.append("P = 2Q, diagonal Q like every trial (the config's P or Q differ)")
    return lines


def apply_params(config: ExperimentConfig, params: dict) -> ExperimentConfig:
    """``config`` with a trial's parameters set (``P = 2Q``; another observer with
    ``compensation``)."""
    if "compensation" in params:
        from ..experiment.build import with_controller

        config = with_controller(config, compensation=params["compensation"])
    cc = config.controller
    Q = np.diag([params.get("Q_position", cc.Q[0, 0]), params.get("Q_velocity", cc.Q[1, 1])])
    new = replace(
        cc,
        Q=Q,
        P=2 * Q,
        R=float(params.get("R", cc.R)),
        N=int(params.get("N", cc.N)),
        Ts=float(params.get("Ts", cc.Ts)),
    )
    if "observer_gain" in params:
        new = replace(new, observer=replace(cc.observer, gain=float(params["observer_gain"])))
    if "observer_bandwidth" in params:  # every joint scaled: the per-joint shape is kept
        w = cc.observer.bandwidth * (float(params["observer_bandwidth"]) / _bandwidth_scale(cc))
        new = replace(new, observer=replace(cc.observer, bandwidth=w))
    return replace(config, controller=new)


def _suggest(trial, space: dict) -> dict:
    out = {}
    for name, spec in space.items():
        if spec[0] == "log":
            out[name] = trial.suggest_float(name, spec[1], spec[2], log=True)
        elif spec[0] == "int":
            out[name] = trial.suggest_int(name, spec[1], spec[2])
        else:
            out[name] = trial.suggest_categorical(name, list(spec[1]))
    return out


def run_score(row: dict, error_bound: float, duration: float | None) -> float:
    """One run's score [rad]: its worst joint's RMS error :math:`e` when bounded;
    otherwise :math:`\\bar e\\,(1 + \\ell) + \\min(e, 10\\bar e)` with :math:`\\bar e` the
    error bound and :math:`\\ell` the fraction of the run it did not finish, so that any
    bounded run ranks before any unbounded one, a later failure before an earlier one,
    and a smaller error before a larger one."""
    rms = float(row["rms_max"])
    if row["bounded"] and np.isfinite(rms):
        return rms
    lost = 1.0 - row["t_end"] / duration if duration and "t_end" in row else 0.0
    rms = min(rms, 10 * error_bound) if np.isfinite(rms) else 10 * error_bound
    return error_bound * (1.0 + min(max(lost, 0.0), 1.0)) + rms


def objective_value(
    rows: list[dict],
    error_bound: float,
    tv0: float | None,
    saturation_weight: float = SATURATION_WEIGHT,
    tv_weight: float = TV_WEIGHT,
    duration: float | None = None,
) -> tuple[float, dict]:
    """:math:`J` of a trial's sweep rows (module docstring, each run scored by
    :func:`run_score`) and its parts."""
    rms = np.array([run_score(r, error_bound, duration) for r in rows])
    p95 = float(np.quantile(rms, 0.95, method="inverted_cdf"))
    sat = float(np.mean([r["saturation"] for r in rows]))
    tv = float(np.mean([r["torque_tv"] for r in rows]))
    excess = max(0.0, tv / tv0 - 1.0) if tv0 else 0.0
    value = p95 * (1.0 + saturation_weight * sat + tv_weight * excess)
    return value, {
        "p95_rms": p95,
        "saturation": sat,
        "torque_tv": tv,
        "bounded": float(np.mean([r["bounded"] for r in rows])),
    }


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


class _DeferredInterrupt:
    """Ctrl-C kept away from the study's database writes.

    A ``KeyboardInterrupt`` raised inside an SQLite write of Optuna's storage leaves its
    transaction open: the next write (the trial marked failed, the report's reads) finds
    "database is locked" and the command ends with a traceback. While installed (main
    thread only), SIGINT raises at once inside :meth:`evaluating` (a trial's sweep, which
    writes nothing), and elsewhere is remembered and raised at the next :meth:`evaluating`
    or :meth:`check`, between writes.
    """

    def __init__(self):
        self.pending = False
        self._evaluating = False
        self._previous = None

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            self._previous = signal.signal(signal.SIGINT, self._handler)
        return self

    def __exit__(self, *exc) -> None:
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)

    def _raise(self, signum=signal.SIGINT, frame=None) -> None:
        previous = self._previous
        if callable(previous) and previous is not signal.default_int_handler:
            previous(signum, frame)  # the command line's handler: it records, then raises
        raise KeyboardInterrupt

    def _handler(self, signum, frame) -> None:
        if self._evaluating:
            self._raise(signum, frame)
        self.pending = True

    def check(self) -> None:
        """Raise :class:`KeyboardInterrupt` when a Ctrl-C was kept back."""
        if self.pending:
            self._raise()

    def evaluating(self, fn, *args):
        """``fn(*args)`` with Ctrl-C raised at once (after one kept back: before it)."""
        self.check()
        self._evaluating = True
        try:
            return fn(*args)
        finally:
            self._evaluating = False


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
    with _DeferredInterrupt() as sigint:
        return _tune(
            optuna, config, out, sigint, trials, samples, seed, jobs, executor, scheduler,
            ts, observers, holdout, holdout_seed, progress, objective,
        )  # fmt: skip


def _tune(
    optuna, config, out, sigint, trials, samples, seed, jobs, executor, scheduler, ts,
    observers, holdout, holdout_seed, progress, objective,
) -> TuneResult:  # fmt: skip
    """:func:`tune` once its options are checked, under ``sigint``
    (:class:`_DeferredInterrupt`)."""
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
        params = _suggest(trial, space)
        if trial.number == 0:  # the config as given, its own values (a Q_velocity of 0 too)
            params = _own_params(config, space)
            trial.set_user_attr("ran", params)  # the sampler's record is the nearest point
        value, parts = evaluate(apply_params(config, params))
        if "tv0" not in study.user_attrs and "torque_tv" in parts:  # trial 0: as given
            study.set_user_attr("tv0", parts["torque_tv"])
        for k, v in parts.items():
            trial.set_user_attr(k, v)
        return value

    cluster = None
    if executor == "dask" and scheduler is None and objective is None:
        cluster = _local_cluster(jobs)  # one cluster for every trial, not one per trial
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
        best = _shown_params(study.best_trial, study)
        tuned = apply_params(config, best)  # what the best trial ran
        files = [_write_tuned(config, tuned, best, study, out)]
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
    files += _report(
        config, study, best, out, comparison, samples, seed, holdout, holdout_seed, stopped, space
    )
    files.insert(1, db)
    if stopped is not None:
        raise RunInterrupted(stopped, files=files)
    return TuneResult(study, best, tuned, files, comparison)


def _shown_params(trial, study) -> dict:
    """A trial's parameters as they ran: the config's own for trial 0 (the config as
    given, recorded by the sampler at the nearest point of its space: :func:`current_params`),
    else the sampled ones. A study of an earlier version kept trial 0's in the study."""
    if "ran" in trial.user_attrs:
        return dict(trial.user_attrs["ran"])
    if trial.user_attrs.get("as_given") and "as_given" in study.user_attrs:
        return dict(study.user_attrs["as_given"])
    return dict(trial.params)


def _local_cluster(jobs: int):
    """A local Dask cluster of ``jobs`` single-threaded worker processes (extra
    ``cluster``), or the sweep's one-line error naming the extra."""
    try:
        from dask.distributed import LocalCluster
    except ImportError as exc:
        raise ConfigError(
            "--executor",
            "dask needs the optional dependency dask.distributed (extra "
            f"hmpc_pin[cluster]); install it with `{install_command('cluster')}` or use "
            "--executor local",
        ) from exc
    return LocalCluster(n_workers=jobs, threads_per_worker=1, processes=True)


def len_trials(optuna, storage: str, name: str) -> int:
    """Trials already in the stored study (0 if none): a resumed study's sampler is seeded
    ``seed + len`` so that its continuation is reproducible too."""
    try:
        return len(optuna.load_study(study_name=name, storage=storage).trials)
    except KeyError:
        return 0


def _write_tuned(config, tuned, best, study, out: Path) -> Path:
    cc = tuned.controller

    def weight(W: np.ndarray) -> list:
        W = np.asarray(W, dtype=float)
        return np.diag(W).tolist() if W[0, 1] == 0 and W[1, 0] == 0 else W.tolist()

    table: dict = {
        "Q": weight(cc.Q),
        "P": weight(cc.P),
        "R": float(cc.R),
        "N": int(cc.N),
        "Ts": float(cc.Ts),
    }
    import tomllib

    raw = tomllib.loads(Path(config.source).read_text(encoding="utf-8"))
    ctrl = dict(raw.get("controller", {}))
    ctrl.update(table)
    if "observer_gain" in best or "observer_bandwidth" in best:
        obs = dict(ctrl.get("observer", {}))
        if cc.observer.bandwidth is not None:
            w = np.atleast_1d(cc.observer.bandwidth)
            obs["bandwidth"] = float(w[0]) if np.all(w == w[0]) else w.tolist()
            obs.pop("gain", None)
        else:
            obs["gain"] = float(cc.observer.gain)
        if "compensation" in best:  # the 0.1 keys would contradict it
            obs.pop("kind", None)
            obs.pop("enabled", None)
            ctrl["compensation"] = cc.compensation
            if len(compensation_spec(cc.compensation).discretizations) == 1:
                obs.pop("discretization", None)  # its one form (the momentum observer's)
        ctrl["observer"] = obs
    path = out / f"{config.name}_tuned.toml"
    header = (
        f"{config.name} tuned by `hmpc-pin tune` (trial {study.best_trial.number} of "
        f"{len(study.trials)}, objective {study.best_value:.4g})\n"
        f"from {config.source}"
    )
    write_config(
        Path(config.source), {"controller": ctrl}, path, header=header, name=f"{config.name}_tuned"
    )
    load_config(path)  # the written config loads
    return path


def _cell(v) -> str:
    return v if isinstance(v, str) else f"{v:.4g}"


def _report(
    config,
    study,
    best,
    out: Path,
    comparison,
    samples,
    seed,
    holdout,
    holdout_seed,
    stopped: str | None = None,
    space: dict | None = None,
):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from optuna.visualization.matplotlib import plot_optimization_history, plot_param_importances

    files = []
    name = config.name

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # optuna marks its matplotlib backend experimental
        ax = plot_optimization_history(study)
        path = out / f"{name}_tune_history.png"
        ax.figure.savefig(path, dpi=100, bbox_inches="tight")
        plt.close(ax.figure)
        files.append(path)
        done = [t for t in study.trials if t.value is not None]
        if len(done) >= 2 and len(best) >= 2:
            try:
                ax = plot_param_importances(study)
                path = out / f"{name}_tune_importance.png"
                ax.figure.savefig(path, dpi=100, bbox_inches="tight")
                plt.close(ax.figure)
                files.append(path)
            except (RuntimeError, ValueError):  # e.g. every trial scored the same
                pass
    finished = [t for t in study.trials if t.value is not None]
    moved = _sampler_record(config, space or {})
    lines = [
        f"# Tuning of {name}: {len(study.trials)} trials ({len(finished)} finished)",
        "",
        *(
            [f"Interrupted (Ctrl-C) at {stopped}: the best of the trials that finished.", ""]
            if stopped
            else []
        ),
        f"Config `{config.source}`; {samples} sweep samples per trial (seed {seed}); "
        f"objective J = p95 worst-joint RMS × (1 + {SATURATION_WEIGHT:g}·saturation + "
        f"{TV_WEIGHT:g}·max(0, TV/TV₀ − 1)); trial 0 is the config as given.",
        "",
        *(
            [
                "Trial 0 ran the config's own values; outside the search space, the sampler "
                "records it at: " + "; ".join(moved) + ".",
                "",
            ]
            if moved
            else []
        ),
        f"Best: trial {study.best_trial.number}, J = {study.best_value:.4g}: "
        + ", ".join(f"{k} = {_cell(v)}" for k, v in best.items()),
        "",
    ]
    if comparison:
        lines += [
            f"## Held-out comparison: {holdout} other samples (seed {holdout_seed})",
            "",
            "p95 over the samples of the worst joint's RMS error [rad]; a run that is not "
            "bounded scores the error bound b times one plus the fraction it did not "
            "finish, plus its RMS error (at most 10 b): above any bounded run.",
            "",
            "| config | p95 worst RMS [rad] | bounded | saturation | torque TV [N·m/s] |",
            "|---|---|---|---|---|",
        ]
        for label, p in comparison.items():
            lines.append(
                f"| {label} | {p['p95_rms']:.4g} | {100 * p['bounded']:.0f} % | "
                f"{100 * p['saturation']:.2f} % | {p['torque_tv']:.4g} |"
            )
        ratio = comparison["shipped"]["p95_rms"] / comparison["tuned"]["p95_rms"]
        lines += ["", f"Shipped / tuned p95: {ratio:.3g}.", ""]
    lines += [
        "## Trials",
        "",
        "| trial | J | p95 RMS [rad] | " + " | ".join(best) + " |",
        "|---|---|---|" + "---|" * len(best),
    ]
    for t in study.trials:
        if t.value is None:
            continue
        shown = _shown_params(t, study)
        vals = " | ".join(_cell(shown.get(k, math.nan)) for k in best)
        lines.append(
            f"| {t.number} | {t.value:.4g} | {t.user_attrs.get('p95_rms', math.nan):.4g} | {vals} |"
        )
    lines += ["", *(f"![{p.stem}]({p.name})" for p in files), ""]
    path = out / f"{name}_tune.md"
    path.write_text("\n".join(lines), encoding="utf-8")
    return [path, *files]


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
        + ", ".join(f"{k} = {_cell(v)}" for k, v in result.best.items())
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
