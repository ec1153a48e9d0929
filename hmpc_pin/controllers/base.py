"""The controller protocol, and a base for wrappers that change one thing about a controller.

A controller runs at the control period :math:`T_s`: :meth:`Controller.step` reads the
measured state at :math:`t_k` and returns the torque held over :math:`[t_k, t_k + T_s)`.
:func:`~hmpc_pin.sim.simulate.simulate` (and any loop that drives an arm) needs only
this protocol.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

__all__ = ["AppliedTorque", "Controller", "ControllerWrapper", "register_config_builder"]

FloatArray = NDArray[np.float64]


@runtime_checkable
class Controller(Protocol):
    """A joint-torque controller at a fixed period.

    Attributes:
        Ts: Control period [s].
        disturbance_estimate: :math:`\\hat d_k` [N·m], shape (n,), of the last step
            (zeros without compensation).
    """

    @property
    def Ts(self) -> float: ...

    @property
    def disturbance_estimate(self) -> FloatArray: ...

    def reset(self, q0: FloatArray, dq0: FloatArray) -> None:
        """Start a run at ``q0`` [rad], ``dq0`` [rad/s], each (n,)."""
        ...

    def step(self, t: float, q: FloatArray, dq: FloatArray, reference: object) -> FloatArray:
        """Torque :math:`\\tau_k` [N·m], (n,), for the state measured at ``t`` [s];
        ``reference`` is a :class:`~hmpc_pin.tasks.base.Reference` (or anything
        :func:`~hmpc_pin.tasks.base.as_reference` adapts)."""
        ...


class ControllerWrapper:
    """Base of wrappers that keep a controller's interface (``Ts``, ``reset``, ``step``,
    ``disturbance_estimate``) and change one thing, e.g. timing or measurement.

    Subclasses override :meth:`reset` and/or :meth:`step`; the rest is delegated.
    """

    def __init__(self, controller: Controller):
        self.controller = controller

    def loop_port(self, reference: object) -> Any:
        """``None``: the compiled loop calls the wrapper as a whole (its ``step``), not the
        wrapped controller's port (a wrapper that hands its controller's port over, with
        its own part attached, overrides this)."""
        return None

    @property
    def Ts(self) -> float:
        """Control period [s] of the wrapped controller."""
        return self.controller.Ts

    @property
    def disturbance_estimate(self) -> FloatArray:
        """The wrapped controller's disturbance estimate [N·m]."""
        return self.controller.disturbance_estimate

    @property
    def compensation(self) -> Any:
        """The wrapped controller's compensation (behind a collision reaction, its gate);
        ``AttributeError`` when it has none, so that ``getattr(c, "compensation", None)``
        sees through every wrapper."""
        inner: Any = self.controller  # any controller may have one; the protocol does not
        return inner.compensation

    @compensation.setter
    def compensation(self, value: Any) -> None:
        inner: Any = self.controller
        inner.compensation = value

    def reset(self, q0: FloatArray, dq0: FloatArray) -> None:
        """Reset the wrapped controller."""
        self.controller.reset(q0, dq0)

    def step(self, t: float, q: FloatArray, dq: FloatArray, reference: object) -> FloatArray:
        """The wrapped controller's step [N·m]."""
        return self.controller.step(t, q, dq, reference)


#: ``(config type, builder)`` of the deprecated call ``Controller(robot, config)``
#: (:func:`register_config_builder`); ``None`` until the builder registers.
_CONFIG_BUILDER: tuple[type, Callable[..., tuple[Any, ...]]] | None = None


def register_config_builder(config_type: type, builder: Callable[..., tuple[Any, ...]]) -> None:
    """Register how a ``[controller]`` table of type ``config_type`` becomes a controller's
    constructor arguments: ``builder(robot, config)`` returns those after ``robot``.

    The experiment builder registers itself when imported (it imports the controllers, not
    the other way round), for the call of version 0.1 ``HierarchicalMPC(robot,
    ControllerConfig)``; a config cannot exist before it is imported (importing
    :mod:`hmpc_pin.experiment` imports the builder first).
    """
    global _CONFIG_BUILDER
    _CONFIG_BUILDER = (config_type, builder)


def config_parts(config: object, robot: Any, who: str, expected: str) -> tuple[Any, ...]:
    """The constructor arguments after ``robot`` that the registered builder makes of a
    ``[controller]`` table (the deprecated call ``Controller(robot, config)``), with a
    :class:`DeprecationWarning` naming the replacement.

    Raises:
        InterfaceError: ``config`` is neither ``expected`` (the settings class the caller
            takes) nor a registered ``[controller]`` table.
    """
    import warnings

    from ..exceptions import InterfaceError

    registered = _CONFIG_BUILDER
    if registered is None or not isinstance(config, registered[0]):
        raise InterfaceError(
            config,
            expected,
            "or build a controller from a ControllerConfig with "
            "hmpc_pin.make_controller(robot, config)",
        )
    warnings.warn(
        f"{who}(robot, ControllerConfig) is deprecated since 0.2; use "
        "hmpc_pin.make_controller(robot, config)",
        DeprecationWarning,
        stacklevel=4,
    )
    return registered[1](robot, config)


def not_reset(controller: object) -> Exception:
    """The error of a controller's ``step`` before its ``reset`` (the estimate, the
    integral and the previous torque would be a former run's or undefined)."""
    from ..exceptions import SimulationError

    return SimulationError(
        f"{type(controller).__name__}.step before reset: call reset(q0, dq0) with the "
        "initial state first"
    )


class AppliedTorque:
    r"""Mixin of the controllers whose compensation needs the torque the arm applied.

    An arm applies :math:`\mathrm{clip}(\tau, -\tau_{\max}, \tau_{\max})`, not the
    commanded :math:`\tau`, while its drives saturate. A disturbance observer fed the
    commanded torque attributes the clipped part to the disturbance and winds up (measured:
    :math:`\hat d` of about -430 N·m against a true :math:`|d| < 1` N·m on a saturating
    arm). With :attr:`effort_limit` set (the experiment builder sets it to the plant's
    limits), the compensation gets the clipped torque of the last period.

    Attributes:
        effort_limit: :math:`\tau_{\max}` [N·m], shape (n,) (inf: none), or ``None``:
            the compensation gets the commanded torque.
        tau: The commanded torque of the last step [N·m].
    """

    tau: FloatArray
    # (-limit, limit, output buffer), made once when the limit is set: no allocation per step.
    _effort: tuple[FloatArray, FloatArray, FloatArray] | None = None

    @property
    def effort_limit(self) -> FloatArray | None:
        """:math:`\\tau_{\\max}` [N·m], or ``None``."""
        return None if self._effort is None else self._effort[1]

    @effort_limit.setter
    def effort_limit(self, limit: FloatArray | None) -> None:
        if limit is None:
            self._effort = None
            return
        upper = np.array(limit, dtype=float)
        self._effort = (-upper, upper, np.empty_like(upper))

    def _applied(self) -> FloatArray:
        r""":math:`\mathrm{clip}(\tau_{k-1}, -\tau_{\max}, \tau_{\max})` [N·m] (a buffer
        rewritten at every step; the compensation reads it within ``update``)."""
        effort = self._effort
        if effort is None:
            return self.tau
        return np.clip(self.tau, effort[0], effort[1], out=effort[2])
