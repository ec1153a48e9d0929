"""What ``hmpc-pin tune`` writes (:mod:`hmpc_pin.apps.tune`): the best trial as a config
(``<name>_tuned.toml``), and the report of the study (``<name>_tune.md``, with its history
and parameter-importance figures)."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np

from ..compensation.registry import compensation_spec
from ..experiment.config import load_config
from ..experiment.config.write import write_config
from .tune_objective import SATURATION_WEIGHT, TV_WEIGHT
from .tune_space import format_param, sampler_record

__all__ = ["shown_params", "write_report", "write_tuned"]


def shown_params(trial, study) -> dict:
    """A trial's parameters as they ran: the config's own for trial 0 (the config as
    given, recorded by the sampler at the nearest point of its space:
    :func:`~hmpc_pin.apps.tune_space.current_params`), else the sampled ones. A study of
    an earlier version kept trial 0's in the study."""
    if "ran" in trial.user_attrs:
        return dict(trial.user_attrs["ran"])
    if trial.user_attrs.get("as_given") and "as_given" in study.user_attrs:
        return dict(study.user_attrs["as_given"])
    return dict(trial.params)


def write_tuned(config, tuned, best, study, out: Path) -> Path:
    """Write the best trial as ``out/<name>_tuned.toml``: the config's own file with its
    ``[controller]`` table's tuned keys (Q, P, R, N, Ts, the observer's gain or bandwidth,
    the observer when the study chose it), and check that it loads.

    Args:
        config: The config tuned. tuned: It with the best trial's parameters
            (:func:`~hmpc_pin.apps.tune_space.apply_params`). best: Those parameters.
        study: The Optuna study (its best trial is named in the header). out: The folder.

    Returns:
        The path written.
    """
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


def write_report(
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
) -> list[Path]:
    """Write the study's report ``out/<name>_tune.md`` and its figures (the optimisation
    history; the parameters' importance from two finished trials on).

    Args:
        config: The config tuned. study: The Optuna study. best: The best trial's
            parameters (:func:`shown_params`). out: The folder.
        comparison: ``{"shipped": parts, "tuned": parts}`` on the held-out samples
            (:func:`~hmpc_pin.apps.tune_objective.objective_value`'s parts), or ``None``.
        samples, seed: The sweep samples per trial and their seed.
        holdout, holdout_seed: The held-out samples and their seed.
        stopped: Where Ctrl-C stopped the study, in words (``None``: it finished).
        space: The search space (:func:`~hmpc_pin.apps.tune_space.search_space`), for
            where the sampler recorded trial 0.

    Returns:
        The report's path, then the figures'.
    """
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
    moved = sampler_record(config, space or {})
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
        + ", ".join(f"{k} = {format_param(v)}" for k, v in best.items()),
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
        shown = shown_params(t, study)
        vals = " | ".join(format_param(shown.get(k, math.nan)) for k in best)
        lines.append(
            f"| {t.number} | {t.value:.4g} | {t.user_attrs.get('p95_rms', math.nan):.4g} | {vals} |"
        )
    lines += ["", *(f"![{p.stem}]({p.name})" for p in files), ""]
    path = out / f"{name}_tune.md"
    path.write_text("\n".join(lines), encoding="utf-8")
    return [path, *files]
