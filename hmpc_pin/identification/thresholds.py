"""Collision thresholds learned from a contact-free run (``hmpc-pin identify --thresholds``).

The collision watch (:class:`~hmpc_pin.controllers.wrappers.CollisionReaction`) flags a
collision at the first instant with :math:`|\\hat d_i| > \\bar d_i` on some joint. Without
contact, :math:`\\hat d` holds what is left of the friction, the model error and the
measurement noise: a threshold is a quantile of its maximum.

Derivation. Cut the run's residual :math:`|\\hat d_i|` into blocks of :math:`B` seconds and
take each block's maximum :math:`M`. By the extreme-value theorem, the maximum of many
weakly dependent samples is Gumbel-distributed,
:math:`P(M \\le x) = \\exp(-e^{-(x-\\mu)/\\beta})`; :math:`\\mu, \\beta` are fitted by
maximum likelihood (:func:`scipy.stats.gumbel_r.fit`). Over a horizon :math:`H` there are
:math:`H/B` blocks, so the probability of no false alarm on joint i is
:math:`P(M \\le x)^{H/B}`. Asking at most :math:`\\alpha` for the whole arm and splitting it
over the :math:`n` joints (Bonferroni: :math:`\\alpha/n` each) gives

.. math::

    \\bar d_i = s\\,\\Big[\\mu_i - \\beta_i \\ln\\Big(-\\frac{B}{H}\\ln\\big(1 -
    \\tfrac{\\alpha}{n}\\big)\\Big)\\Big],

with a safety factor :math:`s \\ge 1` against what one run cannot show (another posture,
temperature, payload). The bracket is never taken below the learning run's own peak
:math:`\\max_k |\\hat d_{i,k}|` (``floor_at_peak``): the run is contact-free, so a threshold
it crosses is wrong, and a residual that is not stationary (a move, then rest) has block
maxima whose fit lies below its peak.

``method = "gumbel"`` (default) fixes the extreme-value shape at 0. The maximum of a
light-tailed residual (Gaussian noise, a bounded friction residue) converges to it from
the bounded side, so the Gumbel quantile lies above the true one: with :math:`s = 1` the
false-alarm probability over :math:`H` is *at most* :math:`\\alpha` (measured on a Gaussian
AR(1) residual: 0.035 for :math:`\\alpha = 0.2`), and a run of a minute is enough.
``method = "gev"`` also fits the shape :math:`\\xi` (:func:`scipy.stats.genextreme`):
calibrated (0.19 for :math:`\\alpha = 0.2`) when the run holds hundreds of blocks, but
from a minute's 60 blocks the shape is uncertain and the rate can exceed
:math:`\\alpha` (0.35 measured): use it only on long runs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..exceptions import ConfigError
from ..sim.result import Result

__all__ = ["CollisionThresholds", "gumbel_threshold", "learn_thresholds"]


@dataclass(frozen=True)
class CollisionThresholds:
    """Learned thresholds and what they were learned with.

    Attributes:
        names: The joints. threshold: :math:`\\bar d` per joint [N·m].
        peak: The largest :math:`|\\hat d_i|` of the learning run [N·m].
        loc, scale: The fitted :math:`\\mu_i, \\beta_i` [N·m].
        false_alarm: :math:`\\alpha` over ``horizon`` [s]. block: :math:`B` [s].
        safety: :math:`s`. run: The learning run's name.
    """

    names: tuple[str, ...]
    threshold: np.ndarray
    peak: np.ndarray
    loc: np.ndarray
    scale: np.ndarray
    false_alarm: float
    horizon: float
    block: float
    safety: float
    method: str = "gumbel"
    run: str = ""

    def toml(self) -> str:
        """The ``[collision]`` table, with how it was derived as comments."""
        lines = [
            f"# Collision thresholds learned by `hmpc-pin identify --thresholds` from "
            f"{self.run or 'a contact-free run'}: false-alarm probability <= "
            f"{self.false_alarm:g} per {self.horizon:g} s over all joints ({self.method} fit of "
            f"{self.block:g} s block maxima of |d_hat|), safety factor {self.safety:g}",
        ]
        for name, thr, peak in zip(self.names, self.threshold, self.peak, strict=True):
            lines.append(f"#   {name}: threshold {thr:.4g} N·m (run's peak |d_hat| {peak:.4g})")
        lines += [
            "[collision]",
            f"threshold = [{', '.join(f'{v:.6g}' for v in self.threshold)}]   # [N·m]",
        ]
        return "\n".join(lines) + "\n"


#: Extreme-value fits of the block maxima (module docstring).
METHODS = ("gumbel", "gev")


def gumbel_threshold(
    residual: np.ndarray,
    samples_per_block: int,
    *,
    false_alarm: float,
    blocks_per_horizon: float,
    method: str = "gumbel",
) -> tuple[float, float, float]:
    """The Gumbel quantile of one joint (module docstring, without :math:`s` and with
    :math:`\\alpha` already split): ``(threshold, loc, scale)``.

    Args:
        residual: :math:`|\\hat d_i|` samples [N·m].
        samples_per_block: Samples per block.
        false_alarm: Probability of a false alarm over the horizon, this joint.
        blocks_per_horizon: :math:`H/B`.
    """
    from scipy.stats import genextreme, gumbel_r

    m = len(residual) // samples_per_block
    maxima = np.abs(residual[: m * samples_per_block]).reshape(m, samples_per_block).max(axis=1)
    if np.ptp(maxima) == 0:  # a constant residual: the Gumbel scale is 0
        return float(maxima[0]), float(maxima[0]), 0.0
    p_block = (1.0 - false_alarm) ** (1.0 / blocks_per_horizon)
    if method == "gev":
        shape, loc, scale = genextreme.fit(maxima)
        return float(genextreme.ppf(p_block, shape, loc, scale)), float(loc), float(scale)
    loc, scale = gumbel_r.fit(maxima)
    return float(gumbel_r.ppf(p_block, loc, scale)), float(loc), float(scale)


def learn_thresholds(
    result: Result,
    *,
    false_alarm: float = 0.01,
    horizon: float = 60.0,
    block: float = 1.0,
    safety: float = 1.25,
    after: float = 0.0,
    method: str = "gumbel",
    floor_at_peak: bool = True,
    run: str = "",
) -> CollisionThresholds:
    """Thresholds on :math:`|\\hat d|` from a contact-free run (module docstring).

    Args:
        result: A run without contact, with an observer.
        false_alarm: :math:`\\alpha`, over all joints, in (0, 1).
        horizon: :math:`H` [s]: the time over which :math:`\\alpha` holds.
        block: :math:`B` [s] (shortened to a tenth of the run if the run is shorter
            than 10 blocks).
        safety: :math:`s \\ge 1`.
        after: Samples before this time [s] are left out (0: the watch runs from the
            start, so the observer's start-up is part of what it must not flag).

    Raises:
        ConfigError: A bad option, or a run too short (fewer than 10 blocks of 10
            samples) or without an observer estimate.
    """
    for key, value, ok in (
        ("--false-alarm", false_alarm, 0 < false_alarm < 1),
        ("--horizon", horizon, np.isfinite(horizon) and horizon > 0),
        ("--block", block, np.isfinite(block) and block > 0),
        ("--safety", safety, np.isfinite(safety) and safety >= 1),
    ):
        if not ok:
            expected = {"--false-alarm": "a probability in (0, 1)", "--safety": "a factor >= 1"}
            raise ConfigError(
                key, f"expected {expected.get(key, 'a duration [s] > 0')}, got {value!r}"
            )
    if method not in METHODS:
        raise ConfigError("--method", f"expected one of {METHODS}, got {method!r}")
    t = result.t
    use = t >= after - 1e-12
    r = np.abs(result.d_hat[use])
    if not np.any(r):
        raise ConfigError(
            "RUN",
            "its observer estimate d_hat is zero throughout: learn the "
            "thresholds from a run with an observer",
        )
    Ts = float(np.median(np.diff(t))) if len(t) > 1 else math.nan
    span = len(r) * Ts
    block = min(block, span / 10)
    per_block = round(block / Ts) if Ts > 0 else 0
    if per_block < 10:
        raise ConfigError(
            "RUN",
            f"{span:.3g} s of samples after t = {after:g} s is too short "
            "to learn thresholds: record at least 100 control periods "
            "(a minute or more is better)",
        )
    block = per_block * Ts
    n = r.shape[1]
    out = [
        gumbel_threshold(
            r[:, i],
            per_block,
            false_alarm=false_alarm / n,
            blocks_per_horizon=horizon / block,
            method=method,
        )
        for i in range(n)
    ]
    thr, loc, scale = (np.array(v) for v in zip(*out, strict=True))
    names = result.joint_names or tuple(f"joint{i + 1}" for i in range(n))
    return CollisionThresholds(
        names=tuple(names),
        threshold=safety * (np.maximum(thr, r.max(axis=0)) if floor_at_peak else thr),
        peak=r.max(axis=0),
        loc=loc,
        scale=scale,
        false_alarm=false_alarm,
        horizon=horizon,
        block=block,
        safety=safety,
        method=method,
        run=run,
    )
