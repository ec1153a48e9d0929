"""The parameters ``hmpc-pin tune`` searches (:mod:`hmpc_pin.apps.tune`): their ranges, the
config's own values and a trial's parameters set into a config.

The space (:func:`search_space`): the MPC weights :math:`Q = \\mathrm{diag}(q_p, q_v)`
(log-uniform :math:`q_p \\in [1, 10^4]`, :math:`q_v \\in [10^{-4}, 10^2]`, terminal weight
:math:`P = 2Q`), :math:`R \\in [10^{-8}, 10^{-3}]` (log), the horizon :math:`N \\in [5, 30]`
(an MPC), the observer's gain :math:`c` or bandwidth (log-uniform on a tenth to five
times the config's), and on request the period :math:`T_s` and the observer.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..compensation.registry import compensation_names
from ..controllers.registry import controller_spec
from ..exceptions import ConfigError
from ..experiment.config import ExperimentConfig

__all__ = [
    "apply_params",
    "current_params",
    "format_param",
    "own_params",
    "sampler_record",
    "search_space",
    "suggest",
]


def format_param(v) -> str:
    """A parameter's value as the report prints it (4 significant digits; a name as is)."""
    return v if isinstance(v, str) else f"{v:.4g}"


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


def own_params(config: ExperimentConfig, space: dict) -> dict:
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
    """The point of ``space`` nearest the config's own values (``own_params``): each
    clipped into its range, the nearest period of ``Ts``, the first observer of
    ``compensation`` when the config's is not listed. The sampler records trial 0 there
    (Optuna refuses a value outside the space); the report says where it differs from
    what ran."""
    out = {}
    for name, v in own_params(config, space).items():
        spec = space[name]
        if name == "compensation":
            out[name] = v if v in spec[1] else spec[1][0]
        elif spec[0] == "choice":
            out[name] = min(spec[1], key=lambda c, v=v: abs(c - v))
        else:
            out[name] = type(v)(min(max(v, spec[1]), spec[2]))
    return out


def sampler_record(config: ExperimentConfig, space: dict) -> list[str]:
    """Where the sampler's record of trial 0 (:func:`current_params`) differs from what it
    ran (:func:`own_params`), and ``P = 2Q`` when the config's ``P`` is not: in words."""
    own, near = own_params(config, space), current_params(config, space)
    lines = [
        f"{k} = {format_param(near[k])} (ran {format_param(own[k])})"
        for k in space
        if near[k] != own[k]
    ]
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


def suggest(trial, space: dict) -> dict:
    """The parameters an Optuna ``trial`` proposes in ``space`` (:func:`search_space`)."""
    out = {}
    for name, spec in space.items():
        if spec[0] == "log":
            out[name] = trial.suggest_float(name, spec[1], spec[2], log=True)
        elif spec[0] == "int":
            out[name] = trial.suggest_int(name, spec[1], spec[2])
        else:
            out[name] = trial.suggest_categorical(name, list(spec[1]))
    return out
