"""The settings of the per-joint MPC (Section 4) and of the step around it:
:class:`~hmpc_pin.controllers.mpc_settings.MPCSettings` (every default the paper's value,
each checked by one function shared with the ``[controller]`` table,
:func:`~hmpc_pin.controllers.mpc_settings.check_settings`) and the soft joint limits of
each MPC's prediction (:func:`~hmpc_pin.controllers.mpc_settings.state_limits`)."""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable
from dataclasses import MISSING, dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..checks import as_bool, as_choice, as_float, as_int, as_latency, mpc_fields
from ..exceptions import ConfigError
from ..model.robot import Robot
from ..mpc.condensed import StateLimits
from ..native import BACKENDS

__all__ = [
    "MODEL_AT",
    "QP_LAYOUTS",
    "MPCSettings",
    "check_settings",
    "state_limits",
]

FloatArray = NDArray[np.float64]

#: The values of :attr:`MPCSettings.qp_layout` (:func:`~hmpc_pin.mpc.condensed.resolve_layout`).
QP_LAYOUTS = ("auto", "block", "joint")
#: The values of :attr:`MPCSettings.model_at` (``[controller.observer] model_at``).
MODEL_AT = ("end", "start")

#: The check of each setting of :class:`MPCSettings` besides the MPC's weights
#: (:func:`~hmpc_pin.checks.mpc_fields`): ``check(key, value)`` → the value, or a
#: :class:`~hmpc_pin.exceptions.ConfigError` naming ``key``.
_CHECKS: dict[str, Callable[[str, Any], Any]] = {
    "eps_abs": lambda key, value: as_float(key, value, positive=True),
    "max_iter": lambda key, value: as_int(key, value, minimum=1),
    "qp_layout": lambda key, value: as_choice(key, value, QP_LAYOUTS),
    "backend": lambda key, value: as_choice(key, value, BACKENDS),
    "latency": as_latency,
    "joint_dynamics": as_bool,
    "model_at": lambda key, value: as_choice(key, value, MODEL_AT),
}


def check_settings(values: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """The settings of :class:`MPCSettings` in ``values`` (by field name, besides the
    MPC's weights) checked: the one check of each, for the settings class and the
    ``[controller]`` table alike (a value refused in a file is refused in code, with the
    same error).

    Args:
        values: Field name → value, any subset of ``eps_abs``, ``max_iter``,
            ``qp_layout``, ``backend``, ``latency``, ``joint_dynamics``, ``model_at``.
        prefix: Put before every key in the errors (``"MPCSettings."``).

    Raises:
        ConfigError: The first value that is wrong, naming ``prefix + name``.
    """
    return {name: _CHECKS[name](prefix + name, value) for name, value in values.items()}


@dataclass(frozen=True)
class MPCSettings:
    """Settings of the per-joint MPC (Section 4; every default is the paper's value).

    Built from the ``[controller]`` table by :mod:`hmpc_pin.experiment.build`; the
    controller never sees the TOML schema.

    Attributes:
        Ts: Control period [s] (paper: 0.01).
        N: Prediction horizon [steps] (paper: 10).
        Nc: Control horizon [steps], 1 <= Nc <= N (paper: 1).
        Q: State weight on :math:`[q - r, \\dot q - \\dot r]`, 2×2 (paper: diag(50, 0)).
        R: Input weight, > 0 (paper: 1e-6).
        P: Terminal weight, 2×2 (paper: diag(100, 0)).
        v_min, v_max: Bounds of the commanded acceleration [rad/s²], scalar or (n,)
            (paper: ∓100).
        eps_abs: ProxSuite absolute tolerance.
        max_iter: ProxSuite iteration cap per solve.
        qp_layout: ``"auto"`` (``"joint"``: measured faster for every n and Nc),
            ``"block"`` (one block-diagonal QP) or ``"joint"`` (one QP per joint);
            :func:`~hmpc_pin.mpc.condensed.resolve_layout`.
        backend: Deprecated since 0.3 and without effect: the step is always compiled
            (:mod:`hmpc_pin.native`). ``"auto"`` and ``"native"`` are accepted silently,
            ``"python"`` with a :class:`DeprecationWarning`.
        latency: The age L [s] of the measurement handed to
            :meth:`~hmpc_pin.controllers.hierarchical.HierarchicalMPC.step`
            (0: none; a fraction of Ts allowed). With L > 0 the compensation is fed the
            torque applied over the interval its two measurements span, and the MPC and the
            inverse dynamics start from the state predicted over L (the guide
            "Sensing and latency"). L = 0 is the latency-free step, bit for bit.
        joint_dynamics: Compensate the model's joint damping and Coulomb friction
            (:attr:`~hmpc_pin.model.robot.Robot.joint_damping`, ``joint_friction``, the
            URDF's ``<dynamics>``): :math:`C\\dot q + G` becomes
            :math:`C\\dot q + G + B\\dot q + F\\,\\mathrm{sgn}\\,\\dot q` in the observer and
            Eq (4), and a damped joint's acceleration gets its zero-order-hold gain
            (computed in the compiled step, see ``cpp/src/step.cpp``). Default ``True``.
        model_at: Where the compensation's model :math:`M,\\ C\\dot q + G` is
            evaluated over the period that just ended (one of :data:`MODEL_AT`;
            ``[controller.observer] model_at``): ``"end"`` (default; the new
            measurement, Eq 13's backward Euler as the paper discretises it) or ``"start"``
            (the state the torque held over the period was computed from; with a latency,
            the previous measurement). With the torque held over :math:`T_s` the plant's
            :math:`C\\dot q + G` drifts by :math:`\\dot n T_s` over a period; at the end the
            estimate carries :math:`+\\dot n T_s/2` where Eq (4) of the next period needs
            :math:`-\\dot n T_s/2`, doubling the error it should cancel; at the start it is
            the residual of the model the held torque used, which Eq (4) applies with the
            right sign (the guide "Joint dynamics", observer model). ``hmpc-pin init``
            writes ``"start"``. Its name in 0.2, ``observer_model``, is still accepted as a
            keyword and readable, with a :class:`DeprecationWarning`.
    """

    Ts: float = 0.01
    N: int = 10
    Nc: int = 1
    Q: FloatArray = field(default_factory=lambda: np.diag([50.0, 0.0]))
    R: float = 1e-6
    P: FloatArray = field(default_factory=lambda: np.diag([100.0, 0.0]))
    v_min: FloatArray | float = -100.0
    v_max: FloatArray | float = 100.0
    eps_abs: float = 1e-9
    max_iter: int = 1000
    qp_layout: str = "auto"
    backend: str = "auto"
    latency: float = 0.0
    joint_dynamics: bool = True
    model_at: str = "end"

    def __post_init__(self):
        # The same checks and errors as the [controller] table (hmpc_pin.checks).
        fields = mpc_fields(
            self.Ts,
            self.N,
            self.Nc,
            self.Q,
            self.R,
            self.P,
            self.v_min,
            self.v_max,
            prefix="MPCSettings.",
        )
        fields.update(
            check_settings({name: getattr(self, name) for name in _CHECKS}, "MPCSettings.")
        )
        for name, value in fields.items():
            object.__setattr__(self, name, value)

    @staticmethod
    def default(name: str) -> Any:
        """The default of the field ``name`` (a fresh copy of an array): the one place each
        default is stated, read by the ``[controller]`` table and
        :class:`~hmpc_pin.controllers.computed_torque.CTSettings`."""
        spec = MPCSettings.__dataclass_fields__[name]
        if spec.default_factory is not MISSING:
            return spec.default_factory()
        return spec.default

    def bounds(self, n: int) -> tuple[FloatArray, FloatArray]:
        """``(v_min, v_max)`` [rad/s²] broadcast to ``n`` joints.

        Raises:
            ConfigError: A per-joint bound has a length other than ``n``.
        """
        out = []
        for name in ("v_min", "v_max"):
            arr = np.asarray(getattr(self, name), dtype=float)
            if arr.ndim == 1 and arr.shape != (n,):
                raise ConfigError(
                    f"MPCSettings.{name}",
                    f"has {arr.shape[0]} entries but the "
                    f"robot has {n} joints; give one value or {n}",
                )
            out.append(np.broadcast_to(arr, (n,)).astype(float))
        return out[0], out[1]


def _observer_model(self: MPCSettings) -> str:
    """Deprecated since 0.3: :attr:`MPCSettings.model_at`."""
    warnings.warn(
        "MPCSettings.observer_model is deprecated since 0.3; read model_at",
        DeprecationWarning,
        stacklevel=2,
    )
    return self.model_at


def _with_observer_model(generated: Callable[..., None]) -> Callable[..., None]:
    """The constructor taking ``observer_model``, the name of ``model_at`` in 0.2, with
    a :class:`DeprecationWarning` (not a field: ``dataclasses.replace`` never passes it)."""

    @functools.wraps(generated)
    def init(self: MPCSettings, *args: Any, observer_model: Any = None, **kwargs: Any) -> None:
        if observer_model is not None:
            warnings.warn(
                "MPCSettings(observer_model=...) is deprecated since 0.3; write model_at "
                "(the name of [controller.observer] model_at)",
                DeprecationWarning,
                stacklevel=2,
            )
            if "model_at" in kwargs:
                raise ConfigError(
                    "MPCSettings.observer_model",
                    "is the deprecated name of model_at; give model_at only",
                )
            kwargs["model_at"] = observer_model
        generated(self, *args, **kwargs)

    return init


MPCSettings.__init__ = _with_observer_model(MPCSettings.__init__)  # type: ignore[method-assign]
MPCSettings.observer_model = property(_observer_model)  # type: ignore[attr-defined]


def state_limits(
    robot: Robot,
    *,
    lower: FloatArray | None = None,
    upper: FloatArray | None = None,
    velocity: FloatArray | None = None,
    position_on: bool = True,
    velocity_on: bool = True,
    slack_weight: float = StateLimits.slack_weight,
    slack_linear_weight: float = StateLimits.slack_linear_weight,
) -> StateLimits:
    """The joint limits imposed on each MPC's prediction as soft state constraints.

    Each of ``lower``, ``upper`` [rad or m] and ``velocity`` [rad/s] overrides the
    URDF's (shape (n,)); a URDF velocity limit <= 0 means none. A part switched off is
    ±inf. The caller (the experiment builder) has checked shapes and lower < upper.
    """
    n = robot.nq
    inf = np.full(n, np.inf)
    lo = np.array(robot.lower if lower is None else lower, dtype=float)
    hi = np.array(robot.upper if upper is None else upper, dtype=float)
    vel = (
        np.where(robot.velocity_limit > 0, robot.velocity_limit, inf)
        if velocity is None
        else np.array(velocity, dtype=float)
    )
    if not position_on:
        lo, hi = -inf, inf.copy()
    if not velocity_on:
        vel = inf.copy()
    return StateLimits(
        lo, hi, vel, slack_weight=slack_weight, slack_linear_weight=slack_linear_weight
    )
