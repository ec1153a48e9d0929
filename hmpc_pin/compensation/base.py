"""The compensation protocol: the disturbance estimate :math:`\\hat d` a controller cancels.

The inverse-dynamics law of every controller of the package is (Eq 4)

.. math::  \\tau_k = M(q_k)\\,v_k + C(q_k,\\dot q_k)\\dot q_k + G(q_k) - \\hat d_k,

and a *compensation* supplies :math:`\\hat d_k` [N·m]. The controller holds exactly one
(:class:`NoCompensation` for none) and, at every control instant after the first,
calls :meth:`Compensation.update` with the measured state, the dynamics terms it has
already computed and what it held over the period that just ended. Implementations:
the NDO of Eq 13 (:class:`~hmpc_pin.compensation.observers.DisturbanceObserver`, Chen's
:math:`Y` or :math:`Y = I`), the generalized-momentum observer
(:class:`~hmpc_pin.compensation.observers.MomentumObserver`) and integral sliding mode
(:class:`~hmpc_pin.compensation.ism.IntegralSlidingMode`, ± boundary layer).

The compiled control step advances the compensation through its Compensation port
(``cpp/include/hmpc/interfaces.hpp``), which decides once, for every compensation, which
model, torque and acceleration :meth:`Compensation.update` is given (the observer's model at
the period's end or start, the torque beyond the joint dynamics, with a latency the measured
interval). Optionally, a compensation offers ``compiled_port()``: the compiled object the
step advances in its place without Python (``hmpc_pin._core.NDO``, the NDO of Eq 13), or
``None`` for an estimate that stays zero. Any other (the momentum observer, ISM, any user
class, or a subclass of ``hmpc_pin._core.Compensation``) is called by the step through the
port's trampoline, with the M and :math:`C\\dot q + G` it computed.
:func:`step_compensation` decodes this, once, for the step (and the tuples of
``compiled_form()`` of 0.3, with a :class:`DeprecationWarning`).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "Compensation",
    "NoCompensation",
    "StepCompensation",
    "check_compensation",
    "step_compensation",
    "warn_chen_validity",
]

FloatArray = NDArray[np.float64]


@runtime_checkable
class Compensation(Protocol):
    """A disturbance estimate advanced once per control period.

    Attributes:
        estimate: The current estimate :math:`\\hat d_k` [N·m], shape (n,); zeros after
            :meth:`reset`.
    """

    estimate: FloatArray

    def reset(self, q0: FloatArray, dq0: FloatArray) -> None:
        """Start a run at the state ``q0`` [rad], ``dq0`` [rad/s], each (n,); estimate 0."""
        ...

    def update(
        self,
        M: FloatArray,
        nle: FloatArray,
        q: FloatArray,
        dq: FloatArray,
        tau: FloatArray,
        v: FloatArray,
    ) -> FloatArray:
        """Advance one control period; return the new estimate :math:`\\hat d_k` [N·m].

        Args:
            M: :math:`M(q_k)` [kg·m²], (n, n), at the measured state.
            nle: :math:`C(q_k,\\dot q_k)\\dot q_k + G(q_k)` [N·m], (n,).
            q: Measured joint positions :math:`q_k` [rad], (n,).
            dq: Measured joint velocities :math:`\\dot q_k` [rad/s], (n,).
            tau: Torque held over the period that just ended, :math:`\\tau_{k-1}` [N·m].
            v: Outer-loop acceleration held over it, :math:`v_{k-1}` [rad/s²] (without
                the compensation's own part).
        """
        ...


class NoCompensation:
    """:math:`\\hat d = 0`: inverse dynamics and the outer loop only (the "no NDO" baseline)."""

    def __init__(self, n: int):
        self.n = int(n)
        self.estimate: FloatArray = np.zeros(self.n)

    def reset(self, q0: FloatArray, dq0: FloatArray) -> None:
        """Nothing to reset; the estimate stays zero."""
        self.estimate = np.zeros(self.n)

    def compiled_port(self) -> None:
        """``None``: the control step keeps :math:`\\hat d = 0` without calling
        :meth:`update`."""
        return None

    def compiled_form(self) -> tuple[str]:
        """Deprecated since 0.3: :meth:`compiled_port`; ``("zero",)``."""
        warnings.warn(
            "compiled_form() is deprecated since 0.3; call compiled_port()",
            DeprecationWarning,
            stacklevel=2,
        )
        return ("zero",)

    def update(
        self,
        M: FloatArray,
        nle: FloatArray,
        q: FloatArray,
        dq: FloatArray,
        tau: FloatArray,
        v: FloatArray,
    ) -> FloatArray:
        """Return zeros [N·m]."""
        return self.estimate


@dataclass(frozen=True)
class StepCompensation:
    """What the compiled step advances for a compensation (:func:`step_compensation`).

    Attributes:
        port: The object behind the step's Compensation port: a compiled observer
            (``hmpc_pin._core.NDO``), the compensation itself (called from the step through
            the port's trampoline), or ``None`` (no compensation: :math:`\\hat d = 0`).
        compiled: Whether the step advances it without calling Python.
    """

    port: Any
    compiled: bool


def step_compensation(compensation: object) -> StepCompensation:
    """The compensation as the compiled step takes it: its ``compiled_port()`` if it has one
    (compiled), else (0.3) its ``compiled_form()`` tuple decoded with a
    :class:`DeprecationWarning`, else itself, called through the port's trampoline. The one
    place a compensation's form is decoded."""
    own = getattr(compensation, "compiled_port", None)
    if callable(own):
        return StepCompensation(own(), True)
    legacy = getattr(compensation, "compiled_form", None)
    if callable(legacy):
        warnings.warn(
            f"{type(compensation).__name__}.compiled_form() is deprecated since 0.3; define "
            "compiled_port() returning the compiled observer (or None: no estimate)",
            DeprecationWarning,
            stacklevel=2,
        )
        form = legacy()
        if form is not None:
            return StepCompensation(form[1] if form[0] == "ndo" else None, True)
    return StepCompensation(compensation, False)


def check_compensation(compensation: object, robot: Any, Ts: float, who: str) -> None:
    """Check that ``compensation`` fits a controller of ``robot`` with period ``Ts`` [s]:
    its estimate has one entry per joint, its own period (attribute ``Ts``, if it has one)
    is ``Ts``; warn when Chen's observer (Eq 28–30, proven for planar serial arms only)
    is used on another arm. The controllers call this when built, so that the library
    refuses and warns as a config file does.

    Raises:
        DimensionError: The estimate's shape is not ``(robot.nq,)``.
        ConfigError: The compensation's period differs from ``Ts``.
    """
    from ..exceptions import ConfigError, DimensionError

    n = robot.nq
    estimate: Any = getattr(compensation, "estimate", None)
    shape = np.shape(estimate) if estimate is not None else None
    if shape != (n,):
        raise DimensionError(
            f"{who}: the compensation {type(compensation).__name__} estimates {shape} "
            f"torques but robot {robot.name!r} has {n} joints; build it for n = {n}"
        )
    period = getattr(compensation, "Ts", None)
    if period is not None and not math.isclose(float(period), float(Ts), rel_tol=1e-9):
        raise ConfigError(
            f"{who}.compensation.Ts",
            f"the compensation's period {float(period):g} s differs from the controller's "
            f"Ts = {float(Ts):g} s; build it with the controller's period",
        )
    warn_chen_validity(robot, getattr(compensation, "kind", None), stacklevel=3)


def warn_chen_validity(robot: Any, kind: object, stacklevel: int = 2) -> None:
    """Warn (:class:`~hmpc_pin.exceptions.ValidityWarning`) when the compensation ``kind``
    is ``"chen"`` (Chen's :math:`Y`, Eq 28–30, proven for planar serial arms only) and
    ``robot`` is not a planar serial chain; ``stacklevel`` as :func:`warnings.warn`'s,
    counted from the caller."""
    from ..exceptions import ValidityWarning

    if kind == "chen" and not robot.is_planar_chain():
        warnings.warn(
            f"compensation 'chen' (Chen's observer, Eq 28-30) is proven for planar serial "
            f"arms only, and robot {robot.name!r} is not one; use compensation = 'general' "
            "(Y = I, valid on any arm for gain c above general_gain_bound) or 'momentum'",
            ValidityWarning,
            stacklevel=stacklevel + 1,
        )
