"""``[controller]`` and its tables ``[controller.observer]``, ``[controller.constraints]``,
``[controller.ism]``, ``[controller.computed_torque]`` (``[controller.friction]`` is
:mod:`hmpc_pin.experiment.config.friction`); the controller × compensation names."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ...checks import mpc_fields
from ...compensation.observers import DEFAULT_DISCRETIZATION, DEFAULT_GAIN
from ...compensation.registry import REGISTRY, compensation_names, compensation_spec
from ...controllers.hierarchical import MPCSettings, check_settings
from ...controllers.registry import MPC_KEYS, controller_names, controller_spec
from ...controllers.registry import REGISTRY as CONTROLLER_REGISTRY
from ...exceptions import ConfigError
from ...mpc.condensed import StateLimits
from ..combos import HMPC_ONLY, applies
from ._fields import _array, _bool, _choice, _float, _section, _set
from .friction import FrictionModelConfig
from .legacy import KIND_ALIASES, resolve_compensation

#: Controllers (``[controller] kind``): the outer loop on top of inverse dynamics; the
#: names of the registry (:data:`~hmpc_pin.controllers.registry.REGISTRY`).
CONTROLLERS = controller_names()
#: Compensations (``[controller] compensation``): the disturbance estimate cancelled; the
#: names of the registry (:data:`~hmpc_pin.compensation.registry.REGISTRY`).
COMPENSATIONS = compensation_names()
#: Compensations advanced inside the compiled step (the others are called from Python
#: between its two compiled halves); kept for callers of version 0.2.
NATIVE_COMPENSATIONS = tuple(name for name, spec in REGISTRY.items() if spec.compiled)


def parse_combination(name: str, key: str = "controller") -> tuple[str, str | None]:
    """``"controller+compensation"``, a 0.1 alias or a bare controller → the pair.

    A bare controller gives ``(controller, None)``: its compensation is decided by the
    caller (the config's, or the controller's registered
    :attr:`~hmpc_pin.controllers.registry.ControllerSpec.default_compensation`).

    Raises:
        ConfigError: Unknown controller or compensation, naming ``key``.
    """
    if not isinstance(name, str):
        raise ConfigError(key, f"expected a controller name string, got {name!r}")
    if name in KIND_ALIASES:
        return KIND_ALIASES[name]
    controller, plus, compensation = name.partition("+")
    if controller not in CONTROLLERS:
        raise ConfigError(
            key,
            f"unknown controller {controller!r}; expected one of {CONTROLLERS} (optionally "
            f"'+' one of {COMPENSATIONS}, e.g. 'hmpc+momentum') or one of "
            f"{tuple(KIND_ALIASES)}",
        )
    if not plus:
        return controller, None
    compensation_spec(compensation, key)  # one error naming every registered name
    return controller, compensation


@dataclass(frozen=True, eq=False)
class ObserverConfig:
    """Disturbance observer settings (Section 3.2, Eq 28–30), for the compensations
    ``"chen"``, ``"general"`` and ``"momentum"``.

    Attributes:
        gain: Observer gain c (the paper does not give it; 100 is this project's choice,
            docs, "Decisions"); for ``"momentum"`` the gain K_O [1/s]. ``None`` when ``bandwidth``
            is given.
        bandwidth: The observer's bandwidth ω [1/s], one value or one per joint, instead
            of ``gain`` (not both): the rate at which each joint's estimation error decays
            (``"general"``: cY = diag(ω) M(q0); ``"momentum"``: K_O = ω; not for
            ``"chen"``, whose Y is fixed). Checked against the rule of
            :mod:`hmpc_pin.compensation.bandwidth` (a warning names the joints above it).
        discretization: ``"implicit"`` (backward Euler, stable for any c) or ``"explicit"``
            (not for ``"momentum"``, which is always semi-implicit).
        model_at: Where the observer's model M, C q̇ + G is evaluated over the period that
            just ended: ``"end"`` (the new measurement: Eq 13 as the paper discretises
            it) or ``"start"`` (the state the torque held over the period was computed
            from; what ``hmpc-pin init`` writes). ``"start"`` makes the estimate the
            correction Eq (4) needs for the next period. The controller's setting
            :attr:`~hmpc_pin.controllers.mpc_settings.MPCSettings.model_at`: its default
            and its check are that class's.
        enabled: Version 0.1 key, with ``kind = "hmpc"`` only: ``false`` means
            compensation ``"none"`` (the whole table is then switched off). Superseded
            by ``[controller] compensation``.
        kind: Version 0.1 key, with ``kind = "hmpc"`` only: the observer
            (``"chen"``, ``"general"``, ``"momentum"``). Superseded by
            ``[controller] compensation``.
    """

    gain: float | None = None
    discretization: str = DEFAULT_DISCRETIZATION
    enabled: bool | None = None
    kind: str | None = None
    bandwidth: np.ndarray | None = None
    model_at: str = MPCSettings.model_at

    def __post_init__(self):
        _set(self, "model_at", check_settings({"model_at": self.model_at})["model_at"])
        if self.enabled is not None:
            _set(self, "enabled", _bool("enabled", self.enabled))
        if self.kind is not None:
            _set(self, "kind", _choice("kind", self.kind, compensation_names(table="observer")))
        if self.bandwidth is not None:
            if self.gain is not None:
                raise ConfigError(
                    "bandwidth", "give the observer's gain or its bandwidth, not both"
                )
            _set(self, "bandwidth", _array("bandwidth", self.bandwidth, positive=True))
        else:
            gain = DEFAULT_GAIN if self.gain is None else self.gain
            _set(self, "gain", _float("gain", gain, positive=True))
        _set(
            self,
            "discretization",
            _choice("discretization", self.discretization, ("implicit", "explicit")),
        )


@dataclass(frozen=True, eq=False)
class ConstraintConfig:
    """Joint limits as soft state constraints of every joint's MPC (``joint_mpc`` docstring).

    By default the limits come from the URDF (``<limit lower upper velocity>``);
    each can be overridden here per joint (or one value for all joints). A URDF
    velocity limit of 0 means "not given" and is not enforced.

    Attributes:
        enabled: Impose the limits on the predicted states (default ``True``).
        position: Impose the position limits.
        velocity: Impose the velocity limits.
        lower, upper: Position limits [rad or m] overriding the URDF's; ``None`` keeps the URDF's.
        velocity_limit: Velocity limit [rad/s] overriding the URDF's; ``None`` keeps it.
        slack_weight: Quadratic weight ρ₂ on the slack [1/rad²] (compare with Q = 50).
        slack_linear_weight: Linear (exact-penalty) weight ρ₁ on the slack [1/rad].
    """

    enabled: bool = True
    position: bool = True
    velocity: bool = True
    lower: np.ndarray | None = None
    upper: np.ndarray | None = None
    velocity_limit: np.ndarray | None = None
    slack_weight: float = StateLimits.slack_weight
    slack_linear_weight: float = StateLimits.slack_linear_weight

    def __post_init__(self):
        for name in ("enabled", "position", "velocity"):
            _set(self, name, _bool(name, getattr(self, name)))
        for name in ("lower", "upper"):
            if getattr(self, name) is not None:
                _set(self, name, _array(name, getattr(self, name)))
        if self.velocity_limit is not None:
            _set(
                self, "velocity_limit", _array("velocity_limit", self.velocity_limit, positive=True)
            )
        _set(self, "slack_weight", _float("slack_weight", self.slack_weight, positive=True))
        _set(
            self,
            "slack_linear_weight",
            _float("slack_linear_weight", self.slack_linear_weight, nonneg=True),
        )

    def overrides(self, n: int) -> dict[str, np.ndarray | None]:
        """The per-joint overrides ``lower``, ``upper``, ``velocity_limit`` broadcast to
        ``n`` joints (``None`` where the URDF's value is kept).

        Raises:
            ConfigError: An override has a length other than ``n``.
        """
        out: dict[str, np.ndarray | None] = {}
        for name in ("lower", "upper", "velocity_limit"):
            value = getattr(self, name)
            if value is not None and value.ndim == 1 and value.shape != (n,):
                raise ConfigError(
                    f"controller.constraints.{name}",
                    f"has {value.shape[0]} entries but the robot has {n} joints",
                )
            out[name] = None if value is None else np.broadcast_to(value, (n,)).astype(float)
        return out


@dataclass(frozen=True, eq=False)
class ISMConfig:
    """Integral sliding mode loop of ``hmpc-ism`` / ``hmpc-ism-bl``
    (:mod:`hmpc_pin.compensation.ism`).

    Attributes:
        gain: Switching gain K [rad/s²], above the bound of the matched disturbance
            :math:`|M^{-1}d|` (SPEC §4: 200 for the paper's arm and disturbances).
        boundary_layer: Width φ [rad/s] of the saturation that replaces sgn(σ) in
            ``hmpc-ism-bl`` (default ``None``: :math:`\\varphi = K T_s`, the amplitude of
            the discrete-time chattering of σ).
    """

    gain: float = 200.0
    boundary_layer: float | None = None

    def __post_init__(self):
        _set(self, "gain", _float("gain", self.gain, positive=True))
        if self.boundary_layer is not None:
            _set(
                self, "boundary_layer", _float("boundary_layer", self.boundary_layer, positive=True)
            )

    def width(self, Ts: float) -> float:
        """The boundary-layer width φ [rad/s] for the control period ``Ts`` [s]."""
        return self.boundary_layer if self.boundary_layer is not None else self.gain * Ts


@dataclass(frozen=True, eq=False)
class ComputedTorqueConfig:
    """Outer loop of ``computed-torque`` and ``computed-torque-pid`` (``computed_torque`` module).

    By default the PD gains are the MPC's own unconstrained state-feedback gain (so both
    loops have the same closed-loop poles, i.e. the same bandwidth) and the integral gain
    gives the PID loop its fastest decay (:mod:`hmpc_pin.controllers.computed_torque`).

    Attributes:
        kp: Proportional gain [1/s²]; ``None`` for the MPC-equivalent gain.
        kd: Derivative gain [1/s]; ``None`` for the MPC-equivalent gain.
        ki: Integral gain [1/s³] of ``computed-torque-pid``; ``None`` for the default.
    """

    kp: float | None = None
    kd: float | None = None
    ki: float | None = None

    def __post_init__(self):
        for name in ("kp", "kd", "ki"):
            if getattr(self, name) is not None:
                _set(self, name, _float(name, getattr(self, name), positive=True))


@dataclass(frozen=True, eq=False)
class ControllerConfig:
    """The controller: an outer loop × a disturbance compensation (docs, "Controllers").

    Every default is the paper's value (Section 4): ``ControllerConfig()`` is the
    paper's scheme, ``hmpc`` × ``chen``. A table that does not apply to the chosen
    pair (``observer`` without an observer, ``ism`` without ISM, ``computed_torque``
    or ``constraints`` with the other controller) is a :class:`ConfigError` naming it.
    After validation ``kind`` and ``compensation`` hold the resolved pair and exactly
    the applicable tables are set (the others are ``None``). The MPC's settings are the
    controller's own, :class:`~hmpc_pin.controllers.mpc_settings.MPCSettings`: each default
    and each check is stated there, once, and read here.

    Attributes:
        kind: The controller, one of :data:`CONTROLLERS` (default ``"hmpc"``), or a
            version-0.1 name of :data:`KIND_ALIASES` (``"hmpc-ism"`` = ``hmpc`` × ``ism``).
        compensation: One of :data:`COMPENSATIONS`; default
            :data:`~hmpc_pin.experiment.config.legacy.DEFAULT_COMPENSATION` of the controller
            (for ``hmpc`` written the 0.1 way, the ``observer.enabled``/``observer.kind``
            keys decide).
        Ts: Control period [s] (paper: 0.01).
        N: Prediction horizon [steps] (paper: 10).
        Nc: Control horizon [steps], 1 <= Nc <= N (paper: 1).
        Q: State weight on [q − r, q̇ − ṙ], diagonal or 2×2 (paper: diag(50, 0)).
        R: Input weight, > 0 (paper: 1e-6).
        P: Terminal weight (paper: 2Q = diag(100, 0)).
        v_min, v_max: Bounds of the commanded acceleration v [rad/s²], scalar or per joint
            (paper: −100, 100).
        observer: :class:`ObserverConfig` (compensations ``chen``, ``general``, ``momentum``).
        constraints: :class:`ConstraintConfig` (``hmpc``: joint limits as soft constraints).
        eps_abs: ProxSuite absolute tolerance (``hmpc``; unset: MPCSettings').
        max_iter: ProxSuite iteration cap per solve (``hmpc``; unset: MPCSettings').
        qp_layout: ``"auto"`` (default: ``"joint"``, measured faster for every n and Nc),
            ``"block"`` (the n joint QPs as one block-diagonal ProxSuite QP, one solve per
            step) or ``"joint"`` (one QP per joint, with its exact shortcuts) (``hmpc``;
            :func:`hmpc_pin.mpc.condensed.resolve_layout`).
        backend: Deprecated since 0.3, without effect (``hmpc``): the step is always the
            compiled one, :mod:`hmpc_pin.native`; ``"auto"`` and ``"native"`` load silently,
            ``"python"`` with a :class:`DeprecationWarning`, anything else is an error.
        ism: :class:`ISMConfig` (compensations ``ism``, ``ism-bl``).
        joint_dynamics: Compensate the URDF's joint damping and Coulomb friction in the
            inverse dynamics, :math:`\\tau \\mathrel{+}= b\\dot q + f\\,\\mathrm{sgn}\\,\\dot q`,
            with the zero-order-hold gain of the damped joints (``hmpc``; default ``true``;
            no effect on an arm whose URDF declares none).
        computed_torque: :class:`ComputedTorqueConfig` (``computed-torque*``).
        latency: Age of the measurements the controller receives [s] (``hmpc``;
            default 0). With L > 0 the compensation is fed the torque applied over the
            interval its measurements span and the MPC and the inverse dynamics start from
            the state predicted over L (guide "Sensing and latency"); a fraction of Ts is
            allowed.
        friction: :class:`~hmpc_pin.experiment.config.friction.FrictionModelConfig`: the
            arm's friction, compensated feed-forward (every pair; ``None``: none).
    """

    kind: str = "hmpc"
    compensation: str | None = None
    Ts: float = MPCSettings.Ts
    N: int = MPCSettings.N
    Nc: int = MPCSettings.Nc
    Q: np.ndarray = field(default_factory=lambda: MPCSettings.default("Q"))
    R: float = MPCSettings.R
    P: np.ndarray = field(default_factory=lambda: MPCSettings.default("P"))
    v_min: np.ndarray = MPCSettings.v_min
    v_max: np.ndarray = MPCSettings.v_max
    observer: ObserverConfig | None = None
    constraints: ConstraintConfig | None = None
    eps_abs: float | None = None
    max_iter: int | None = None
    qp_layout: str | None = None
    backend: str | None = None
    ism: ISMConfig | None = None
    computed_torque: ComputedTorqueConfig | None = None
    latency: float | None = None
    friction: FrictionModelConfig | None = None
    joint_dynamics: bool | None = None

    def __post_init__(self):
        fields = mpc_fields(
            self.Ts, self.N, self.Nc, self.Q, self.R, self.P, self.v_min, self.v_max
        )  # fmt: skip  (the checks of MPCSettings too)
        for name, value in fields.items():
            _set(self, name, value)
        for name, cls in (
            ("observer", ObserverConfig),
            ("constraints", ConstraintConfig),
            ("ism", ISMConfig),
            ("computed_torque", ComputedTorqueConfig),
            ("friction", FrictionModelConfig),
        ):
            value = getattr(self, name)
            if isinstance(value, dict):
                _set(self, name, _section(cls, value, name))
            elif value is not None and not isinstance(value, cls):
                raise ConfigError(name, f"expected a table, got {value!r}")
        self._resolve()

    def _resolve(self) -> None:
        """Resolve ``kind``/``compensation`` to one pair; reject tables that do not apply."""
        if self.compensation is not None:
            compensation_spec(self.compensation)  # one error naming every registered name
        controller, alias_comp = parse_combination(self.kind, "kind")
        if "+" in self.kind:
            raise ConfigError(
                "kind",
                f"{self.kind!r}: give the controller in kind and the compensation in "
                "compensation (e.g. kind = 'hmpc', compensation = 'momentum')",
            )
        comp, obs = resolve_compensation(
            self.kind, controller, alias_comp, self.compensation, self.observer
        )
        # The tables of the pair; any other given table is an error.
        spec = compensation_spec(comp)
        if applies("observer", controller, comp):
            obs = obs if obs is not None else ObserverConfig()
            if (obs.enabled, obs.kind) != (None, None):  # 0.1 keys, now resolved
                obs = replace(obs, enabled=None, kind=None)
            if not spec.bandwidth and obs.bandwidth is not None:
                takes = tuple(n for n, s in REGISTRY.items() if s.bandwidth)
                raise ConfigError(
                    "observer.bandwidth",
                    f"does not apply to compensation {comp!r} "
                    f"({spec.summary}: its Y is fixed); give gain, or use a compensation of "
                    f"{takes}",
                )
            if obs.discretization not in spec.discretizations:
                raise ConfigError(
                    "observer.discretization",
                    f"compensation {comp!r} ({spec.summary}) has only the form(s) "
                    f"{spec.discretizations}; remove the key or set it to one of them",
                )
        elif obs is not None:
            self._not_applicable("observer", controller, comp)
        ism = self.ism
        if applies("ism", controller, comp):
            ism = ism if ism is not None else ISMConfig()
            if not spec.boundary_layer and ism.boundary_layer is not None:
                takes = tuple(n for n, s in REGISTRY.items() if s.boundary_layer)
                raise ConfigError(
                    "ism.boundary_layer",
                    f"applies only to compensation(s) {takes} (the pure sign law has none)",
                )
        elif ism is not None:
            self._not_applicable("ism", controller, comp)
        ct = self.computed_torque
        if applies("computed_torque", controller, comp):
            ct = ct if ct is not None else ComputedTorqueConfig()
            if not controller_spec(controller).pid and ct.ki is not None:
                pid = " or ".join(repr(n) for n, c in CONTROLLER_REGISTRY.items() if c.pid)
                raise ConfigError("computed_torque.ki", f"applies only to kind = {pid}")
            for name in HMPC_ONLY:
                if getattr(self, name) is not None and not applies(name, controller, comp):
                    self._not_applicable(name, controller, comp)
        else:
            if ct is not None:
                self._not_applicable("computed_torque", controller, comp)
            if self.constraints is None:
                _set(self, "constraints", ConstraintConfig())
            # the settings of the MPC: MPCSettings' defaults where not given, its checks
            given = {name: getattr(self, name) for name in MPC_KEYS}
            given = {k: MPCSettings.default(k) if v is None else v for k, v in given.items()}
            for name, value in check_settings(given).items():
                _set(self, name, value)
        _set(self, "kind", controller)
        _set(self, "compensation", comp)
        _set(self, "observer", obs)
        _set(self, "ism", ism)
        _set(self, "computed_torque", ct)

    @staticmethod
    def _not_applicable(name: str, controller: str, comp: str) -> None:
        raise ConfigError(
            name,
            f"does not apply to {controller} × {comp}; remove it, or choose a controller "
            "and compensation it applies to (docs, Controllers)",
        )

    @property
    def label(self) -> str:
        """``"controller+compensation"``, e.g. ``"hmpc+chen"``: the name of the pair."""
        return f"{self.kind}+{self.compensation}"

    def bounds(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """``(v_min, v_max)`` broadcast to ``n`` joints; raises if a vector has the wrong length."""
        out = []
        for name in ("v_min", "v_max"):
            arr = getattr(self, name)
            if arr.ndim == 1 and arr.shape != (n,):
                raise ConfigError(
                    f"controller.{name}",
                    f"has {arr.shape[0]} entries but the robot has {n} joints",
                )
            out.append(np.broadcast_to(arr, (n,)).astype(float))
        return out[0], out[1]
