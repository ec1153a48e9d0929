"""``[sweep.sensing]``: the arm's interface as the sweep models it (``hmpc_pin.sim.sensing``).

The defaults are a realistic torque-controlled arm, each number from a shipping driver
(the guide "Sensing and latency" gives the sources): absolute encoders of 2^19 counts per
revolution, a 1 kHz interface (libfranka's control loop, UR's RTDE at 500 Hz), the
velocity a backward finite difference of the quantised angle at that rate, the measurement
one interface cycle old (1 ms), and libfranka's default 100 Hz first-order filter on the
commanded torque.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...exceptions import ConfigError
from ._fields import _array, _float, _int, _set


@dataclass(frozen=True, eq=False)
class SensingConfig:
    """The interface model of a sweep: what the controller sees, what the drives apply.

    Attributes:
        rate: Interface rate [Hz] (default 1000, libfranka); the control period must be a
            whole number of interface periods.
        encoder_counts: Encoder counts per revolution, one value or one per joint
            (default 2^19 = 524288; 0: exact angles).
        velocity: ``"finite-difference"`` (default: the backward difference of the
            quantised angle at the interface rate) or ``"exact"``.
        velocity_filter: Cutoff of a first-order low-pass on that velocity [Hz]
            (default 0: none).
        latency: Age of the measurement [s] (default 0.001: one 1 kHz cycle; a fraction
            of the control period allowed).
        torque_filter: Cutoff of the interface's first-order low-pass on the commanded
            torque [Hz] (default 100, libfranka's ``kDefaultCutoffFrequency``; 0: none).
        q_noise: White noise on each angle [rad] (default 0: the encoder's quantisation
            is the angle noise).
        dq_noise: White noise on each velocity [rad/s] (default 0).
        delay: Extra delay in whole control periods (default 0).
    """

    rate: float = 1000.0
    encoder_counts: np.ndarray | float = 2.0**19
    velocity: str = "finite-difference"
    velocity_filter: float = 0.0
    latency: float = 0.001
    torque_filter: float = 100.0
    q_noise: float = 0.0
    dq_noise: float = 0.0
    delay: int = 0

    def __post_init__(self):
        _set(self, "rate", _float("rate", self.rate, positive=True))
        _set(self, "encoder_counts", _array("encoder_counts", self.encoder_counts, nonneg=True))
        if self.velocity not in ("finite-difference", "exact"):
            raise ConfigError(
                "velocity", f"expected 'finite-difference' or 'exact', got {self.velocity!r}"
            )
        for name in ("velocity_filter", "latency", "torque_filter", "q_noise", "dq_noise"):
            _set(self, name, _float(name, getattr(self, name), nonneg=True))
        if self.velocity == "exact" and self.velocity_filter:
            raise ConfigError(
                "velocity_filter", "applies only to velocity = 'finite-difference'; remove it"
            )
        _set(self, "delay", _int("delay", self.delay, minimum=0))

    def model(self, n: int, parts: tuple[str, ...] = ("sensing", "latency")):
        """The :class:`~hmpc_pin.sim.sensing.Sensing` of this table for ``n`` joints.

        Args:
            n: Number of joints.
            parts: ``"sensing"`` (encoder, velocity estimate, white noise) and/or
                ``"latency"`` (latency, whole-period delay, torque filter); a part left
                out is ideal.

        Raises:
            ConfigError: ``encoder_counts`` has a length other than ``n``.
        """
        from ...sim import sensing as s

        counts = self.encoder_counts
        if counts.ndim == 1 and counts.shape != (n,):
            raise ConfigError(
                "sweep.sensing.encoder_counts",
                f"has {counts.shape[0]} entries but the robot has {n} joints",
            )
        counts = np.where(np.broadcast_to(counts, (n,)) == 0, math.inf, counts)
        period = 1.0 / self.rate
        kw: dict = {"rate": self.rate}
        if "sensing" in parts:
            kw["encoder"] = None if np.all(np.isinf(counts)) else s.Encoder(counts)
            if self.velocity == "finite-difference":
                cutoff = self.velocity_filter or math.inf
                kw["velocity"] = s.FiniteDifference(period, cutoff)
            kw["noise"] = s.WhiteNoise(self.q_noise, self.dq_noise)
        if "latency" in parts:
            kw["latency"] = s.Latency(self.latency)
            kw["delay"] = s.PeriodDelay(self.delay)
            if self.torque_filter:
                kw["torque"] = s.TorqueFilter(self.torque_filter, period)
        return s.Sensing(**kw)
