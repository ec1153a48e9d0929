"""``[sweep]``: the Monte Carlo robustness sweep."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...exceptions import ConfigError
from ._fields import _array, _bool, _float, _int, _section, _set
from .sensing import SensingConfig

#: The sweep's conditions: what each run of a sample perturbs.
CONDITIONS = ("sensing", "latency", "plant", "all")
#: The parts of the interface model each condition switches on
#: (:meth:`~hmpc_pin.experiment.config.sensing.SensingConfig.model`).
CONDITION_PARTS = {
    "sensing": ("sensing",),
    "latency": ("latency",),
    "plant": (),
    "all": ("sensing", "latency"),
}


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
        sensing: The arm's interface (:class:`~hmpc_pin.experiment.config.sensing.SensingConfig`,
            table ``[sweep.sensing]``): encoders, velocity estimate,
            latency, torque filter. Default: the realistic model of that class.
        conditions: What each sample is run under, a subset of :data:`CONDITIONS`:
            ``"sensing"`` (the interface's angles and velocities, white noise; exact
            timing, nominal plant), ``"latency"`` (latency, whole-period delay and torque
            filter; exact state, nominal plant), ``"plant"`` (the drawn mass, friction and
            pulse factors; exact measurement), ``"all"`` (everything together). Default:
            all four.
        known_latency: The ``hmpc`` variants are told the modelled latency (latency plus
            delay), as the real-time loop measures it, and compensate it (default true);
            false: they keep ``[controller] latency``.
        q_noise: Version 0.3 key: white noise on each angle [rad]. Any of ``q_noise``,
            ``dq_noise``, ``delay`` selects the earlier model (white noise and a delay
            in whole periods, defaults 1e-3 rad, 1e-2 rad/s, 1 period) instead of
            ``[sweep.sensing]``; giving both is an error.
        dq_noise: Version 0.3 key: white noise on each velocity [rad/s].
        delay: Version 0.3 key: measurement delay in whole control periods.
        after: Metrics (RMS, max error) are taken over t >= after [s].
        error_bound: A run counts as *bounded* when it completes (no divergence, no
            non-finite value, no solver failure) and its max |q − r| after ``after``
            stays <= error_bound [rad].
        rms_target: The pass mark on the worst joint's RMS error after ``after`` [rad]
            reported in the summary (default 1e-2).
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
    sensing: SensingConfig | None = None
    conditions: tuple[str, ...] = CONDITIONS
    known_latency: bool = True
    q_noise: float | None = None
    dq_noise: float | None = None
    delay: int | None = None
    after: float = 1.0
    error_bound: float = 1.0
    rms_target: float = 1e-2
    variants: tuple[str, ...] | None = None

    def __post_init__(self):
        for name in ("mass", "friction", "disturbance"):
            _set(self, name, _range(name, getattr(self, name)))
        for name in ("q_noise", "dq_noise"):
            if getattr(self, name) is not None:
                _set(self, name, _float(name, getattr(self, name), nonneg=True))
        if self.delay is not None:
            _set(self, "delay", _int("delay", self.delay, minimum=0))
        if isinstance(self.sensing, dict):
            _set(self, "sensing", _section(SensingConfig, self.sensing, "sensing"))
        elif self.sensing is not None and not isinstance(self.sensing, SensingConfig):
            raise ConfigError("sensing", f"expected a table, got {self.sensing!r}")
        if self.legacy and self.sensing is not None:
            raise ConfigError(
                "sensing",
                "give either [sweep.sensing] or the earlier keys q_noise, "
                "dq_noise, delay of [sweep], not both (the table supersedes them: "
                "[sweep.sensing] q_noise, dq_noise, delay)",
            )
        conditions = self.conditions
        if (
            not isinstance(conditions, (list, tuple))
            or not conditions
            or len(set(conditions)) != len(conditions)
            or any(c not in CONDITIONS for c in conditions)
        ):
            raise ConfigError(
                "conditions",
                f"expected a non-empty list of distinct names of {CONDITIONS}, got {conditions!r}",
            )
        _set(self, "conditions", tuple(conditions))
        _set(self, "known_latency", _bool("known_latency", self.known_latency))
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

    @property
    def legacy(self) -> bool:
        """Whether the earlier measurement model (keys ``q_noise``, ``dq_noise``, ``delay``)
        is used instead of ``[sweep.sensing]``."""
        return any(v is not None for v in (self.q_noise, self.dq_noise, self.delay))

    @property
    def interface(self) -> SensingConfig:
        """The ``[sweep.sensing]`` table, or its defaults."""
        return self.sensing if self.sensing is not None else SensingConfig()

    def legacy_measurement(self) -> tuple[float, float, int]:
        """``(q_noise, dq_noise, delay)`` of the earlier model, unset keys at their 0.3
        defaults (1e-3 rad, 1e-2 rad/s, 1 period)."""
        return (
            1e-3 if self.q_noise is None else self.q_noise,
            1e-2 if self.dq_noise is None else self.dq_noise,
            1 if self.delay is None else self.delay,
        )
