"""The compensations by name: the one registry of ``[controller] compensation``.

Each entry (:class:`CompensationSpec`) says what the name is: the class built, the
``[controller]`` table that configures it, its design matrix :math:`Y` (the NDOs, Eq 28),
what its table accepts, and how it is built from that table. Everything that needs to know
the compensations reads them here (qpsolvers' pattern: one dict filled where the
implementations are imported, a name decoded once):
the configuration (the names ``compensation`` accepts, which table applies, which keys of
it), the builder (:func:`build_compensation`), ``hmpc-pin identify`` (the observer's
:math:`Y`), ``hmpc-pin tune`` (the observers a trial may choose) and the benchmarks.

The tables are read by attribute (``gain``, ``bandwidth``, ``discretization`` of
``[controller.observer]``; ``gain`` and ``width(Ts)`` of ``[controller.ism]``), so that this
layer imports nothing of the configuration.

Example:
    >>> from hmpc_pin.compensation.registry import REGISTRY, compensation_spec
    >>> tuple(REGISTRY)
    ('chen', 'general', 'momentum', 'ism', 'ism-bl', 'none')
    >>> compensation_spec("chen").Y(2)
    array([[1., 0.],
           [1., 1.]])
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np

from ..exceptions import ConfigError
from .bandwidth import bandwidth_posture, observer_cY
from .base import Compensation, NoCompensation
from .ism import IntegralSlidingMode
from .observers import DisturbanceObserver, MomentumObserver, observer_matrix

__all__ = [
    "REGISTRY",
    "CompensationSpec",
    "build_compensation",
    "compensation_names",
    "compensation_spec",
]

#: The ``[controller]`` tables a compensation may be configured by.
TABLES = ("observer", "ism")


@dataclass(frozen=True)
class CompensationSpec:
    """What a compensation name stands for.

    Attributes:
        name: The name ``[controller] compensation`` takes.
        cls: The class :attr:`build` returns (a
            :class:`~hmpc_pin.compensation.base.Compensation`).
        table: The ``[controller]`` table that configures it, ``"observer"`` or ``"ism"``,
            or ``None`` (no settings).
        summary: One line for messages and the docs.
        Y: For an NDO (Eq 13), its constant design matrix :math:`Y(n)`, (n, n), with
            :math:`p = cY\\dot q` and :math:`L = cYM^{-1}` (Eq 28–30); ``None`` for the
            others (the momentum observer's gain is its bandwidth :math:`K_O` itself).
        compiled: Advanced by the compiled control step without Python (the others are
            called from the step through its Compensation port).
        bandwidth: Its table accepts ``bandwidth`` instead of ``gain`` (not Chen's NDO,
            whose :math:`Y` is fixed).
        discretizations: The values ``[controller.observer] discretization`` may take.
        boundary_layer: Its table accepts ``[controller.ism] boundary_layer`` (ISM with
            the saturation, ``ism-bl``).
        build: ``build(robot, Ts, table, posture)`` → the compensation for ``robot`` at the
            control period ``Ts`` [s] with the settings of ``table`` (``None`` when
            :attr:`table` is), a bandwidth made exact at the posture ``posture`` [rad].
    """

    name: str
    cls: type
    table: str | None
    summary: str
    build: Callable[..., Compensation]
    Y: Callable[[int], np.ndarray] | None = None
    compiled: bool = False
    bandwidth: bool = False
    discretizations: tuple[str, ...] = ()
    boundary_layer: bool = False

    @property
    def observer(self) -> bool:
        """Whether it is an observer (configured by ``[controller.observer]``)."""
        return self.table == "observer"


def _joint_bandwidth(table: Any, n: int) -> np.ndarray:
    """``table.bandwidth`` broadcast to ``n`` joints [1/s].

    Raises:
        ConfigError: A per-joint bandwidth of another length than ``n``.
    """
    w = np.asarray(table.bandwidth, dtype=float)
    if w.ndim == 1 and w.shape != (n,):
        raise ConfigError(
            "controller.observer.bandwidth",
            f"has {w.shape[0]} entries but the robot has {n} joints",
        )
    return np.broadcast_to(w, (n,)).astype(float)


def _ndo(name: str, robot: Any, Ts: float, table: Any, posture: np.ndarray) -> Compensation:
    """The NDO of Eq 13 with the design ``name``: :math:`cY = c\\,Y` of the gain, or with a
    bandwidth :math:`cY = \\mathrm{diag}(\\omega)M(q_0)` (the general design)."""
    n = robot.nq
    if table.bandwidth is not None:
        cY = observer_cY(_joint_bandwidth(table, n), robot.mass_matrix(posture))
        return DisturbanceObserver(n, Ts, 1.0, "general", table.discretization, cY=cY)
    return DisturbanceObserver(n, Ts, table.gain, name, table.discretization)


def _momentum(robot: Any, Ts: float, table: Any, posture: np.ndarray) -> Compensation:
    """The momentum observer with :math:`K_O` = the gain, or the bandwidth per joint."""
    if table.bandwidth is not None:
        return MomentumObserver(robot, Ts, _joint_bandwidth(table, robot.nq))
    return MomentumObserver(robot, Ts, table.gain)


def _ism(layer: bool, robot: Any, Ts: float, table: Any, posture: np.ndarray) -> Compensation:
    """Integral sliding mode, with the boundary layer ``table.width(Ts)`` if ``layer``."""
    return IntegralSlidingMode(robot.nq, Ts, table.gain, table.width(Ts) if layer else None)


def _none(robot: Any, Ts: float, table: Any, posture: np.ndarray) -> Compensation:
    return NoCompensation(robot.nq)


_BOTH = ("implicit", "explicit")

#: Name → :class:`CompensationSpec`, in the order the docs and messages list them.
REGISTRY: dict[str, CompensationSpec] = {
    spec.name: spec
    for spec in (
        CompensationSpec(
            name="chen",
            cls=DisturbanceObserver,
            table="observer",
            summary="the paper's NDO, Chen's Y (Eq 28-30; planar serial arms)",
            build=partial(_ndo, "chen"),
            Y=partial(observer_matrix, "chen"),
            compiled=True,
            discretizations=_BOTH,
        ),
        CompensationSpec(
            name="general",
            cls=DisturbanceObserver,
            table="observer",
            summary="the NDO with Y = I (any arm, gain above general_gain_bound)",
            build=partial(_ndo, "general"),
            Y=partial(observer_matrix, "general"),
            compiled=True,
            bandwidth=True,
            discretizations=_BOTH,
        ),
        CompensationSpec(
            name="momentum",
            cls=MomentumObserver,
            table="observer",
            summary="De Luca's generalized-momentum observer (semi-implicit)",
            build=_momentum,
            bandwidth=True,
            discretizations=("implicit",),
        ),
        CompensationSpec(
            name="ism",
            cls=IntegralSlidingMode,
            table="ism",
            summary="integral sliding mode, sign law",
            build=partial(_ism, False),
        ),
        CompensationSpec(
            name="ism-bl",
            cls=IntegralSlidingMode,
            table="ism",
            summary="integral sliding mode with a boundary layer",
            build=partial(_ism, True),
            boundary_layer=True,
        ),
        CompensationSpec(
            name="none",
            cls=NoCompensation,
            table=None,
            summary="no compensation (d^ = 0)",
            build=_none,
            compiled=True,
        ),
    )
}


def compensation_names(*, table: str | bool | None = True) -> tuple[str, ...]:
    """The registered names, in order; with ``table`` given (``"observer"``, ``"ism"`` or
    ``None``) those configured by that table only."""
    if table is True:
        return tuple(REGISTRY)
    return tuple(name for name, spec in REGISTRY.items() if spec.table == table)


def compensation_spec(name: object, key: str = "compensation") -> CompensationSpec:
    """The entry of ``name``.

    Raises:
        ConfigError: ``name`` is not registered: one message naming ``key`` and every
            registered name.
    """
    spec = REGISTRY.get(name) if isinstance(name, str) else None
    if spec is None:
        raise ConfigError(key, f"unknown compensation {name!r}; expected one of {tuple(REGISTRY)}")
    return spec


def build_compensation(
    name: str, robot: Any, Ts: float, table: Any = None, posture: np.ndarray | None = None
) -> Compensation:
    """The compensation ``name`` for ``robot`` at the control period ``Ts`` [s], with the
    settings of its ``table`` (the validated ``[controller.observer]`` or
    ``[controller.ism]``; ``None`` when it has none) and a bandwidth made exact at
    ``posture`` [rad] (default
    :func:`~hmpc_pin.compensation.bandwidth.bandwidth_posture`).

    Raises:
        ConfigError: ``name`` is not registered, its table is missing, or a bandwidth has
            the wrong length.
    """
    spec = compensation_spec(name)
    if spec.table is not None and table is None:
        raise ConfigError(
            f"controller.{spec.table}",
            f"compensation {name!r} needs its [controller.{spec.table}] settings; pass them",
        )
    q0 = bandwidth_posture(robot) if posture is None else posture
    return spec.build(robot, Ts, table, q0)
