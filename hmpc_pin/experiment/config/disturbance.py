"""``[disturbance]``, ``[disturbance.friction]`` and ``[disturbance.pulse]``."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...exceptions import ConfigError
from ._fields import _array, _choice, _section, _set


@dataclass(frozen=True, eq=False)
class FrictionConfig:
    """Coulomb–viscous friction, Eq (32) (SPEC §3).

    Attributes:
        viscous: a [N·m·s/rad] (paper: 10, 8, 5).
        coulomb: b [N·m] (paper: 3.0, 2.4, 1.8).
        sign: ``"opposing"`` (default, physical): :math:`d = -(a\\dot q + b\\,\\mathrm{sgn}\\,
            \\dot q)`; ``"literal"``: the paper's Eq 32 as printed, :math:`d = +F`, friction
            feeding energy in (the second reading of the paper, docs, "Decisions").
    """

    viscous: np.ndarray = field(default_factory=lambda: np.array([10.0, 8.0, 5.0]))
    coulomb: np.ndarray = field(default_factory=lambda: np.array([3.0, 2.4, 1.8]))
    sign: str = "opposing"

    def __post_init__(self):
        _set(self, "viscous", _array("viscous", self.viscous, nonneg=True))
        _set(self, "coulomb", _array("coulomb", self.coulomb, nonneg=True))
        if self.sign not in FRICTION_SIGNS:
            raise ConfigError("sign", f"expected one of {FRICTION_SIGNS}, got {self.sign!r}")


#: Readings of Eq 32's sign: friction opposing motion, or the paper's d = +F as printed.
FRICTION_SIGNS = ("opposing", "literal")


@dataclass(frozen=True, eq=False)
class PulseConfig:
    """Gaussian-shaped external torque pulse, Eq (33).

    Attributes:
        amplitude: a [N·m] (paper: 10, 8, 0.3).
        center: b [s] (paper: 1, 2, 3).
        sigma: σ [s] (paper: 0.3).
    """

    amplitude: np.ndarray = field(default_factory=lambda: np.array([10.0, 8.0, 0.3]))
    center: np.ndarray = field(default_factory=lambda: np.array([1.0, 2.0, 3.0]))
    sigma: np.ndarray = 0.3

    def __post_init__(self):
        _set(self, "amplitude", _array("amplitude", self.amplitude))
        _set(self, "center", _array("center", self.center))
        _set(self, "sigma", _array("sigma", self.sigma, positive=True))


@dataclass(frozen=True, eq=False)
class DisturbanceConfig:
    """The plant's disturbance: friction, pulse, both (Eq 34) or none.

    Attributes:
        friction: :class:`FrictionConfig` or ``None``.
        pulse: :class:`PulseConfig` or ``None``.
        scale: ``"absolute"`` (coefficients in N·m, the paper's) or ``"inertia"``: every
            coefficient of joint i is multiplied by :math:`M_{ii}(q_0)` [kg·m²], so that
            one set of numbers means the same acceleration-level disturbance on any arm
            (SPEC §4: a 5 N·m torque on a Panda wrist of inertia 0.0065 is 770 rad/s²).
    """

    friction: FrictionConfig | None = None
    pulse: PulseConfig | None = None
    scale: str = "absolute"

    def __post_init__(self):
        _set(self, "scale", _choice("scale", self.scale, ("absolute", "inertia")))
        for name, cls in (("friction", FrictionConfig), ("pulse", PulseConfig)):
            value = getattr(self, name)
            if isinstance(value, dict):
                _set(self, name, _section(cls, value, name))
            elif value is not None and not isinstance(value, cls):
                raise ConfigError(name, f"expected a table, got {value!r}")
