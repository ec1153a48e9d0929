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
and the simulated plant: the plant loop (:func:`~hmpc_pin.sim.simulate.simulate`) is
unchanged. The plant state is known at the control instants; in between, the angle is the
cubic Hermite interpolant of the angles and velocities at the two instants around it (the
torque is constant over a period, so the motion there is smooth); before the start the arm
moves at its initial velocity, :math:`q(t) = q_0 + t\\,\\dot q_0` (at rest at its initial
state when :math:`\\dot q_0 = 0`): a run started in motion is not seen standing still.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from ..controllers.base import ControllerWrapper
from ..exceptions import ConfigError

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
        return 2.0 * np.pi / self.counts

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
            raise ConfigError("cutoff", f"expected a cutoff > 0 [Hz] (inf: none), got "
                              f"{self.cutoff!r}")  # fmt: skip
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
                "sensing.rate", f"the control period Ts = {Ts:g} s is not a whole number of "
                f"interface periods 1/{self.rate:g} Hz; choose a rate that divides 1/Ts",
            )  # fmt: skip
        return m

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


class _History:
    """The plant's states at the control instants; the angle at any past time by cubic
    Hermite interpolation. Before the start the arm moved at its initial velocity:
    :math:`q(t) = q_0 + t\\,\\dot q_0`, :math:`\\dot q(t) = \\dot q_0` for :math:`t \\le 0`
    (at rest when :math:`\\dot q_0 = 0`), so that a run started in motion is not seen
    standing still for its first latency."""

    def __init__(self, Ts: float, keep: int):
        self.Ts = Ts
        self.states: deque = deque(maxlen=keep)
        self.k0 = 0  # the control index of states[0]
        self.k = 0  # the control index of the newest state

    def reset(self, q0: np.ndarray, dq0: np.ndarray) -> None:
        self.states.clear()
        self.states.append((np.array(q0, float), np.array(dq0, float)))
        self.k0 = 0
        self.k = 0

    def push(self, q: np.ndarray, dq: np.ndarray) -> None:
        if len(self.states) == self.states.maxlen:
            self.k0 += 1
        self.states.append((np.array(q, float), np.array(dq, float)))
        self.k += 1

    def angle(self, t: float) -> np.ndarray:
        """q(t) [rad] for t <= the newest instant."""
        s = t / self.Ts
        if s <= 0 or self.k == 0:
            q0, v0 = self._at(0)
            return q0 + min(t, 0.0) * v0
        j = min(math.floor(s), self.k - 1)
        q0, v0 = self._at(j)
        q1, v1 = self._at(j + 1)
        x = s - j
        h = self.Ts
        x2, x3 = x * x, x * x * x
        return ((2 * x3 - 3 * x2 + 1) * q0 + (x3 - 2 * x2 + x) * h * v0
                + (-2 * x3 + 3 * x2) * q1 + (x3 - x2) * h * v1)  # fmt: skip

    def velocity(self, t: float) -> np.ndarray:
        """q̇(t) [rad/s]: the derivative of the same interpolant."""
        s = t / self.Ts
        if s <= 0 or self.k == 0:
            return self._at(0)[1]
        j = min(math.floor(s), self.k - 1)
        q0, v0 = self._at(j)
        q1, v1 = self._at(j + 1)
        x = s - j
        h = self.Ts
        x2 = x * x
        return ((6 * x2 - 6 * x) * q0 / h + (3 * x2 - 4 * x + 1) * v0
                + (-6 * x2 + 6 * x) * q1 / h + (3 * x2 - 2 * x) * v1)  # fmt: skip

    def _at(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        i = max(k - self.k0, 0)
        return self.states[min(i, len(self.states) - 1)]


class SensedController(ControllerWrapper):
    """A controller that sees the arm through :class:`Sensing` and whose torque passes the
    interface's torque filter.

    At each control instant :math:`t_k` the interface has sampled the arm at
    :math:`t_k - L - iT_\\mathrm{if}`; the encoder quantises each angle, the finite
    difference (and its filter) turns the stream of angles into velocities, noise is
    added, and the measurement ``delay`` periods old is handed to the controller. The
    torque it returns is filtered at the interface rate and held (as the mean over the
    period) by the plant.

    Args:
        controller: The wrapped controller.
        sensing: The :class:`Sensing` model.
        rng: The noise source; seed it for reproducible runs.
    """

    def __init__(self, controller, sensing: Sensing, rng: np.random.Generator | None = None):
        super().__init__(controller)
        self.sensing = sensing
        self.rng = rng if rng is not None else np.random.default_rng()
        Ts = float(controller.Ts)
        self._m = sensing.ticks(Ts)
        self._Tif = sensing.period
        keep = math.ceil(sensing.latency.seconds / Ts) + 3
        self._history = _History(Ts, keep)
        self._buffer: deque = deque(maxlen=sensing.delay.periods + 1)
        self._vel_filter = None if sensing.velocity is None else sensing.velocity.filter()
        self._tau_filter = None if sensing.torque is None else sensing.torque.filter()

    def reset(self, q0: np.ndarray, dq0: np.ndarray) -> None:
        """Start a run at ``(q0, dq0)``, moving at ``dq0`` before it; the filters start
        settled there."""
        q0 = np.asarray(q0, float)
        dq0 = np.asarray(dq0, float)
        self._history.reset(q0, dq0)
        self._k = 0
        self._started = False
        self._q_prev = None  # the last reported angle (finite difference)
        self._dq_filt = np.array(dq0, float)
        self._tau_f = None
        self._buffer.clear()
        self._buffer.append(self._measure())
        self.controller.reset(*self._buffer[0])

    def _sample(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """One interface sample of the arm at time t: (reported angle, velocity)."""
        s = self.sensing
        q = self._history.angle(t)
        q_rep = s.encoder(q) if s.encoder is not None else np.array(q, float)
        if s.velocity is None:
            return q_rep, self._history.velocity(t)
        if self._q_prev is None:
            dq = self._history.velocity(t)  # the first sample: no difference yet
            self._dq_filt = dq
        else:
            dq = (q_rep - self._q_prev) / self._Tif
            if self._vel_filter is not None:
                dq = self._vel_filter.step(self._dq_filt, dq)
            self._dq_filt = dq
        self._q_prev = q_rep
        return q_rep, dq

    def _measure(self) -> tuple[np.ndarray, np.ndarray]:
        """The measurement handed over at the current control instant (before the delay)."""
        s = self.sensing
        t_now = self._k * self._history.Ts
        t_meas = t_now - s.latency.seconds
        # The interface samples since the last control instant (one at the start).
        count = 1 if self._k == 0 else self._m
        for i in range(count - 1, -1, -1):
            q_rep, dq = self._sample(t_meas - i * self._Tif)
        n = len(q_rep)
        if s.noise.q or s.noise.dq:
            noise = self.rng.standard_normal(2 * n)
            q_rep = q_rep + s.noise.q * noise[:n]
            dq = dq + s.noise.dq * noise[n:]
        return q_rep, dq

    def step(self, t: float, q: np.ndarray, dq: np.ndarray, reference) -> np.ndarray:
        """Record the plant state, measure it as the interface does, call the controller,
        filter its torque."""
        if self._started:
            self._history.push(q, dq)
            self._k = self._history.k
            self._buffer.append(self._measure())
        self._started = True
        q_m, dq_m = self._buffer[0]
        tau = self.controller.step(t, q_m, dq_m, reference)
        return self._filter_torque(np.asarray(tau, dtype=float))

    def _filter_torque(self, tau: np.ndarray) -> np.ndarray:
        flt = self._tau_filter
        if flt is None:
            return tau
        if self._tau_f is None:
            self._tau_f = tau.copy()  # the filter starts settled at the first command
            return tau
        a = flt.gain
        total = np.zeros_like(tau)
        y = self._tau_f
        for _ in range(self._m):
            y = a * tau + (1.0 - a) * y
            total += y
        self._tau_f = y
        return total / self._m

    def __getattr__(self, name):  # v, tau, observer, ... of the wrapped controller
        if name == "controller":
            raise AttributeError(name)
        return getattr(self.controller, name)
