"""Sensing as an arm's drivers deliver it: encoders, velocity estimates, latency, torque filter.

A real arm's interface samples the joints at its own rate :math:`f_\\mathrm{if}` (1 kHz for
libfranka and UR's RTDE at 500 Hz), and hands the controller

* angles from encoders of :math:`N_j` counts per revolution, i.e. quantised to
  :math:`\\Delta_j = 2\\pi/N_j` [rad] (:class:`Encoder`);
* velocities computed from those angles by a backward finite difference at the interface
  period :math:`T_\\mathrm{if} = 1/f_\\mathrm{if}`, optionally low-passed by a first-order
  filter (:class:`FiniteDifference`, :class:`LowPass`);
* a measurement of the arm as it was :math:`L` seconds earlier (:class:`Latency`; L may
  be a fraction of the control period);

and it low-passes the commanded torque before the drives apply it (libfranka's
``lowpassFilter``, 100 Hz by default: :class:`TorqueFilter`). White Gaussian noise
(:class:`WhiteNoise`) and a delay in whole control periods (:class:`PeriodDelay`) remain.

:class:`Sensing` composes them and :class:`SensedController` puts them between a controller
and the simulated plant, through the compiled measurement port (:meth:`Sensing.compiled`;
the algorithm is written once, in ``cpp/src/measurement.cpp``): the plant loop
(:func:`~hmpc_pin.sim.simulate.simulate`) is unchanged, and runs compiled. The plant state
is known at the control instants; in between, the angle is the cubic Hermite interpolant of
the angles and velocities at the two instants around it (the torque is constant over a
period, so the motion there is smooth); before the start the arm moves at its initial
velocity, :math:`q(t) = q_0 + t\\,\\dot q_0` (at rest at its initial state when
:math:`\\dot q_0 = 0`): a run started in motion is not seen standing still.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..controllers.wrappers import MeasuredController
from ..exceptions import ConfigError
from ..native import load as load_native

__all__ = [
    "Encoder",
    "FiniteDifference",
    "Latency",
    "LowPass",
    "PeriodDelay",
    "SensedController",
    "Sensing",
    "TorqueFilter",
    "WhiteNoise",
    "lowpass_gain",
]


def lowpass_gain(period: float, cutoff: float) -> float:
    """The gain :math:`a = T/(T + 1/(2\\pi f_c))` of libfranka's first-order filter
    :math:`y_i = a x_i + (1 - a) y_{i-1}` at sample period T [s] and cutoff f_c [Hz]
    (``franka::lowpassFilter``); 1 (no filtering) for an infinite cutoff."""
    if math.isinf(cutoff):
        return 1.0
    return period / (period + 1.0 / (2.0 * math.pi * cutoff))


@dataclass(frozen=True)
class Encoder:
    """An absolute encoder of ``counts`` per revolution per joint: the angle it reports is
    :math:`\\Delta\\,\\mathrm{round}(q/\\Delta)`, :math:`\\Delta = 2\\pi/N` [rad].

    Attributes:
        counts: Counts per revolution N, one value or one per joint (inf: exact angle).
    """

    counts: np.ndarray | float

    def __post_init__(self):
        arr = np.asarray(self.counts, dtype=float)
        if arr.ndim > 1 or not np.all(arr > 0) or np.any(np.isnan(arr)):
            raise ConfigError("encoder_counts", f"expected counts > 0 (inf: exact), got {arr!r}")
        object.__setattr__(self, "counts", arr)

    @property
    def step(self) -> np.ndarray:
        """The quantisation step :math:`\\Delta = 2\\pi/N` [rad] (0: exact)."""
        return np.asarray(2.0 * np.pi / self.counts, dtype=float)

    def __call__(self, q: np.ndarray) -> np.ndarray:
        """The reported angle [rad] of the true angle ``q`` [rad]."""
        step = self.step
        exact = step == 0
        if np.all(exact):
            return np.array(q, dtype=float)
        safe = np.where(exact, 1.0, step)
        return np.where(exact, q, safe * np.round(q / safe))


@dataclass(frozen=True)
class LowPass:
    """First-order low-pass at ``cutoff`` [Hz] sampled every ``period`` [s], libfranka's
    form :math:`y_i = a x_i + (1 - a) y_{i-1}`, :math:`a` = :func:`lowpass_gain`.

    Attributes:
        cutoff: f_c [Hz] (> 0; inf: no filter).
        period: Sample period [s].
    """

    cutoff: float
    period: float

    def __post_init__(self):
        if not (self.cutoff > 0):
            raise ConfigError(
                "cutoff", f"expected a cutoff > 0 [Hz] (inf: none), got {self.cutoff!r}"
            )
        if not (math.isfinite(self.period) and self.period > 0):
            raise ConfigError("period", f"expected a period > 0 [s], got {self.period!r}")

    @property
    def gain(self) -> float:
        """a of :func:`lowpass_gain`."""
        return lowpass_gain(self.period, self.cutoff)

    def step(self, y_prev: np.ndarray, x: np.ndarray) -> np.ndarray:
        """One sample: :math:`a x + (1 - a) y_{i-1}`."""
        a = self.gain
        return a * x + (1.0 - a) * y_prev


@dataclass(frozen=True)
class FiniteDifference:
    """The driver's velocity: :math:`\\dot q_i = (\\tilde q_i - \\tilde q_{i-1})/T_\\mathrm{if}`
    of the reported angles, then optionally a :class:`LowPass` at ``cutoff`` [Hz].

    Attributes:
        period: Interface period T_if [s].
        cutoff: Cutoff of the velocity filter [Hz] (inf: none).
    """

    period: float
    cutoff: float = math.inf

    def filter(self) -> LowPass:
        """The velocity filter at the interface period."""
        return LowPass(self.cutoff, self.period)


@dataclass(frozen=True)
class Latency:
    """The measurement handed over at t describes the arm at :math:`t - L`.

    Attributes:
        seconds: L [s] (>= 0; a fraction of the control period allowed).
    """

    seconds: float = 0.0

    def __post_init__(self):
        if not (math.isfinite(self.seconds) and self.seconds >= 0):
            raise ConfigError("latency", f"expected a latency >= 0 [s], got {self.seconds!r}")


@dataclass(frozen=True)
class WhiteNoise:
    """White Gaussian noise added to the reported angle and velocity.

    Attributes:
        q: Standard deviation on each angle [rad].
        dq: Standard deviation on each velocity [rad/s].
    """

    q: float = 0.0
    dq: float = 0.0

    def __post_init__(self):
        for key, value in (("q_noise", self.q), ("dq_noise", self.dq)):
            if not (math.isfinite(value) and value >= 0):
                raise ConfigError(key, f"expected a noise level >= 0, got {value!r}")


@dataclass(frozen=True)
class PeriodDelay:
    """The controller at :math:`t_k` receives the measurement made at :math:`t_{k-d}`
    (before that, the first one).

    Attributes:
        periods: d, whole control periods (>= 0).
    """

    periods: int = 0

    def __post_init__(self):
        if isinstance(self.periods, bool) or int(self.periods) != self.periods or self.periods < 0:
            raise ConfigError("delay", f"expected whole periods >= 0, got {self.periods!r}")


@dataclass(frozen=True)
class TorqueFilter:
    """The interface's filter of the commanded torque: a :class:`LowPass` at ``cutoff``
    [Hz] sampled at the interface period (libfranka: 100 Hz at 1 kHz). Over a control
    period of :math:`m` interface periods the plant holds the mean of the :math:`m`
    filtered samples (the same impulse; exact for :math:`m = 1`).

    Attributes:
        cutoff: f_c [Hz] (inf: none).
        period: Interface period [s].
    """

    cutoff: float
    period: float

    def filter(self) -> LowPass:
        """The filter at the interface period."""
        return LowPass(self.cutoff, self.period)


@dataclass(frozen=True)
class Sensing:
    """The whole sensing and actuation model of an arm's interface.

    Attributes:
        rate: Interface rate f_if [Hz]; the control period must be a whole number of
            interface periods.
        encoder: :class:`Encoder`, or ``None`` for exact angles.
        velocity: :class:`FiniteDifference`, or ``None`` for the exact velocity.
        latency: :class:`Latency`.
        noise: :class:`WhiteNoise`.
        delay: :class:`PeriodDelay`.
        torque: :class:`TorqueFilter`, or ``None``.
    """

    rate: float = 1000.0
    encoder: Encoder | None = None
    velocity: FiniteDifference | None = None
    latency: Latency = Latency()
    noise: WhiteNoise = WhiteNoise()
    delay: PeriodDelay = PeriodDelay()
    torque: TorqueFilter | None = None

    @property
    def period(self) -> float:
        """Interface period :math:`T_\\mathrm{if} = 1/f_\\mathrm{if}` [s]."""
        return 1.0 / self.rate

    def ticks(self, Ts: float) -> int:
        """Interface periods per control period ``Ts`` [s].

        Raises:
            ConfigError: ``Ts`` is not a whole number (>= 1) of interface periods.
        """
        m = round(Ts * self.rate)
        if m < 1 or abs(m - Ts * self.rate) > 1e-6 * max(m, 1):
            raise ConfigError(
                "sensing.rate",
                f"the control period Ts = {Ts:g} s is not a whole number of "
                f"interface periods 1/{self.rate:g} Hz; choose a rate that divides 1/Ts",
            )
        return m

    def compiled(self, Ts: float, rng: np.random.Generator | None):
        """The compiled measurement port of this model at control period ``Ts`` [s]
        (``SensingMeasurement``), its noise drawn from ``rng``.

        Raises:
            ConfigError: ``Ts`` is not a whole number of interface periods, or a filter's
                cutoff is not > 0.
        """
        core = load_native()
        s = core.SensingSettings()
        s.Ts, s.ticks, s.Tif = Ts, self.ticks(Ts), self.period
        s.latency = self.latency.seconds
        s.keep = math.ceil(self.latency.seconds / Ts) + 3
        if self.encoder is not None:
            s.encoder, s.encoder_step = True, np.atleast_1d(self.encoder.step)
        if self.velocity is not None:
            s.finite_difference, s.velocity_gain = True, self.velocity.filter().gain
        s.q_noise, s.dq_noise = self.noise.q, self.noise.dq
        s.delay = self.delay.periods
        if self.torque is not None:
            s.torque_filter, s.torque_gain = True, self.torque.filter().gain
        return core.SensingMeasurement(s, rng)

    @property
    def ideal(self) -> bool:
        """Whether the controller gets the exact state (nothing modelled)."""
        return (
            self.encoder is None
            and self.velocity is None
            and self.latency.seconds == 0
            and self.noise == WhiteNoise()
            and self.delay.periods == 0
            and self.torque is None
        )


class SensedController(MeasuredController):
    """A controller that sees the arm through :class:`Sensing` and whose torque passes the
    interface's torque filter: a :class:`~hmpc_pin.controllers.wrappers.MeasuredController`
    whose port is the compiled interface model (``SensingMeasurement``,
    ``cpp/include/hmpc/measurement.hpp``), so that it runs in the compiled loop.

    At each control instant :math:`t_k` the interface has sampled the arm at
    :math:`t_k - L - iT_\\mathrm{if}`; the encoder quantises each angle, the finite
    difference (and its filter) turns the stream of angles into velocities, noise is
    added, and the measurement ``delay`` periods old is handed to the controller. The
    torque it returns is filtered at the interface rate and held (as the mean over the
    period) by the plant.

    The noise: 2n standard normal draws of ``rng`` per measurement (the angles' first),
    only when a noise level is not 0; the compiled model takes them from ``rng`` itself
    (``rng.standard_normal``, several measurements' rows per call in the compiled loop,
    the unused ones given back at its end), so that a seeded generator gives the stream a
    draw per measurement gives.

    Args:
        controller: The wrapped controller.
        sensing: The :class:`Sensing` model.
        rng: The noise source; seed it for reproducible runs.
    """

    def __init__(self, controller, sensing: Sensing, rng: np.random.Generator | None = None):
        rng = rng if rng is not None else np.random.default_rng()
        super().__init__(controller, measurement=sensing.compiled(float(controller.Ts), rng))
        self.sensing = sensing
        self.rng = rng
        self.q_noise, self.dq_noise = sensing.noise.q, sensing.noise.dq
        self.delay = sensing.delay.periods


def __getattr__(name: str):
    """``Measurement``: the measurement port (``hmpc_pin.native.load().Measurement``),
    loaded with the compiled core on first use. Subclass it in Python (define
    ``reset(q0, dq0)`` and ``measure(t, q, dq)``, each returning the measurement
    ``(q, dq)`` handed over, and optionally ``command(tau)``) and give an instance to
    :class:`~hmpc_pin.controllers.wrappers.MeasuredController` (``measurement=``): it runs
    inside the compiled loop."""
    if name == "Measurement":
        return load_native().Measurement
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
