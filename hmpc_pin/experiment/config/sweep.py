"""``[sweep]``: the Monte Carlo robustness sweep."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...exceptions import ConfigError
from ._fields import _array, _float, _int, _set


def _range(key: str, value) -> np.ndarray:
    """A factor range ``[low, high]`` with 0 < low <= high (``[1, 1]`` switches it off)."""
    arr = _array(key, value, positive=True)
    if arr.shape != (2,) or arr[0] > arr[1]:
        raise ConfigError(key, f"expected [low, high] with 0 < low <= high, got {arr.tolist()}")
    return arr


@dataclass(frozen=True, eq=False)
class SweepConfig:
    """Monte Carlo robustness sweep (``hmpc-pin sweep``): what is drawn per sample.

    Every factor is drawn independently from a uniform distribution ``U(low, high)``;
    ``[1.0, 1.0]`` switches a perturbation off. Only the *plant* is perturbed: the
    controller keeps the nominal model (it does not know the mismatch).

    Attributes:
        mass: Factor range on each plant link's mass and rotational inertia (one factor
            per link, centre of mass unchanged: a uniformly denser or lighter link).
        friction: Factor range per joint on the viscous and Coulomb coefficients (and on
            the MuJoCo plant's joint frictionloss and damping)
            (one factor per joint for both).
        disturbance: Factor range per joint on the Gaussian pulse amplitude.
        q_noise: Standard deviation of the white noise added to each measured joint
            angle [rad] (issue 7: 1e-3).
        dq_noise: Standard deviation of the noise on each measured joint velocity [rad/s]
            (SPEC §4's prototype: 1e-2; 0 for none).
        delay: Measurement delay in control periods (the controller at t_k sees the
            state measured at t_{k-delay}; 0 for none).
        after: Metrics (RMS, max error) are taken over t >= after [s].
        error_bound: A run counts as *bounded* when it completes (no divergence, no
            non-finite value, no solver failure) and its max |q − r| after ``after``
            stays <= error_bound [rad].
        rms_target: The pass mark on the worst joint's RMS error after ``after`` [rad]
            reported in the summary (issue 7: 1e-2).
        variants: Controllers run on every sample, each a controller × compensation
            pair (:func:`~hmpc_pin.experiment.config.controller.parse_combination`:
            ``"hmpc+momentum"``, a 0.1 name such as
            ``"hmpc-ism"``, a bare controller for its default compensation), or
            ``"ndo"`` (the config's pair; its compensation must be an observer) and
            ``"no-ndo"`` (the config's controller without compensation). Two variants
            that are the same pair are an error. Default: the config's pair and, when it
            has a compensation, the same controller without.
    """

    mass: np.ndarray = field(default_factory=lambda: np.array([0.8, 1.2]))
    friction: np.ndarray = field(default_factory=lambda: np.array([0.5, 2.0]))
    disturbance: np.ndarray = field(default_factory=lambda: np.array([0.5, 2.0]))
    q_noise: float = 1e-3
    dq_noise: float = 1e-2
    delay: int = 1
    after: float = 1.0
    error_bound: float = 1.0
    rms_target: float = 1e-2
    variants: tuple[str, ...] | None = None

    def __post_init__(self):
        for name in ("mass", "friction", "disturbance"):
            _set(self, name, _range(name, getattr(self, name)))
        _set(self, "q_noise", _float("q_noise", self.q_noise, nonneg=True))
        _set(self, "dq_noise", _float("dq_noise", self.dq_noise, nonneg=True))
        _set(self, "delay", _int("delay", self.delay, minimum=0))
        _set(self, "after", _float("after", self.after, nonneg=True))
        _set(self, "error_bound", _float("error_bound", self.error_bound, positive=True))
        _set(self, "rms_target", _float("rms_target", self.rms_target, positive=True))
        variants = self.variants
        if variants is None:
            return
        if (
            not isinstance(variants, (list, tuple))
            or not variants
            or not all(isinstance(v, str) for v in variants)
            or len(set(variants)) != len(variants)
        ):
            raise ConfigError(
                "variants", f"expected a non-empty list of distinct names, got {variants!r}"
            )
        _set(self, "variants", tuple(variants))
