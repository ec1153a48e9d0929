"""Typed, validated configuration: frozen dataclasses loaded from TOML.

Every controller setting defaults to the paper's value (Section 4), so
``ControllerConfig()`` is the paper's controller. An experiment file
(``configs/*.toml``) has the sections ``[robot]``, ``[controller]``,
``[controller.observer]``, ``[plant]`` (with ``[plant.mujoco]`` and
``[plant.mujoco.obstacle]`` for ``engine = "mujoco"``), ``[reference]``, ``[disturbance]``
(with optional ``[disturbance.friction]`` and ``[disturbance.pulse]``),
``[simulation]``, ``[sweep]``, ``[collision]`` and ``[realtime]``; see
``configs/paper_combined.toml`` for every key (``configs/planar3_contact_mujoco.toml`` for the
MuJoCo and collision tables).

Validation happens here, at the boundary: unknown keys, wrong types, non-finite
numbers, vectors of the wrong length and out-of-range values raise one
:class:`~hmpc_pin.exceptions.ConfigError` naming the key.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, fields, replace
from pathlib import Path

import numpy as np

from ..data import config_names, config_path
from ..exceptions import ConfigError
from ..native import BACKENDS
from ..sim.mujoco import GEOMETRY_SOURCES, MUJOCO_INTEGRATORS
from ..sim.plants import PLANTS
from .combos import HMPC_ONLY, OBSERVERS, applies

__all__ = [
    "CONTROLLER_KINDS",
    "CartesianConfig",
    "CollisionConfig",
    "ComputedTorqueConfig",
    "ConstraintConfig",
    "ControllerConfig",
    "DisturbanceConfig",
    "ExperimentConfig",
    "FrictionConfig",
    "ISMConfig",
    "MuJoCoConfig",
    "ObserverConfig",
    "ObstacleConfig",
    "PlantConfig",
    "PoseConfig",
    "PulseConfig",
    "RealtimeConfig",
    "ReferenceConfig",
    "RobotConfig",
    "SimulationConfig",
    "SweepConfig",
    "TrajectoryConfig",
    "WaypointsConfig",
    "load_config",
]


# ----------------------------------------------------------------- converters
def _float(key: str, value, *, positive: bool = False, nonneg: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ConfigError(key, f"expected a number, got {type(value).__name__} {value!r}")
    x = float(value)
    if not math.isfinite(x):
        raise ConfigError(key, f"expected a finite number, got {x!r}")
    if positive and x <= 0:
        raise ConfigError(key, f"expected a number > 0, got {x!r}")
    if nonneg and x < 0:
        raise ConfigError(key, f"expected a number >= 0, got {x!r}")
    return x


def _int(key: str, value, *, minimum: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ConfigError(key, f"expected an integer, got {type(value).__name__} {value!r}")
    if minimum is not None and value < minimum:
        raise ConfigError(key, f"expected an integer >= {minimum}, got {value!r}")
    return int(value)


def _bool(key: str, value) -> bool:
    if not isinstance(value, bool):
        raise ConfigError(key, f"expected true or false, got {type(value).__name__} {value!r}")
    return value


def _choice(key: str, value, choices: tuple[str, ...]) -> str:
    if value not in choices:
        raise ConfigError(key, f"expected one of {choices}, got {value!r}")
    return value


def _array(key: str, value, *, nonneg: bool = False, positive: bool = False) -> np.ndarray:
    """A finite float scalar or 1-D vector (length checked later against the robot)."""
    items = value.tolist() if isinstance(value, np.ndarray) else value
    if isinstance(items, (list, tuple)):
        if len(items) == 0:
            raise ConfigError(key, "expected a number or a non-empty list of numbers, got []")
        arr = np.array([_float(f"{key}[{i}]", v) for i, v in enumerate(items)], dtype=float)
    else:
        arr = np.array(_float(key, items), dtype=float)
    if positive and np.any(arr <= 0):
        raise ConfigError(key, f"expected values > 0, got {arr.tolist()}")
    if nonneg and np.any(arr < 0):
        raise ConfigError(key, f"expected values >= 0, got {arr.tolist()}")
    return arr


def _weight(key: str, value) -> np.ndarray:
    """A 2×2 PSD weight given as a diagonal [a, b] or a full [[..],[..]] matrix."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ConfigError(key, f"expected [a, b] or a 2x2 matrix, got {value!r}") from exc
    if arr.shape == (2,):
        arr = np.diag(arr)
    if arr.shape != (2, 2):
        raise ConfigError(key, f"expected a diagonal [a, b] or a 2x2 matrix, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ConfigError(key, f"expected finite numbers, got {arr.tolist()}")
    if not np.allclose(arr, arr.T):
        raise ConfigError(key, f"expected a symmetric matrix, got {arr.tolist()}")
    eig = np.linalg.eigvalsh(arr)
    if eig.min() < 0 or eig.max() <= 0:
        raise ConfigError(
            key,
            f"expected a positive semi-definite, non-zero weight, got eigenvalues {eig.tolist()}",
        )
    return arr


def _set(obj, name: str, value) -> None:
    object.__setattr__(obj, name, value)


#: Controllers (``[controller] kind``): the outer loop on top of inverse dynamics.
CONTROLLERS = ("hmpc", "computed-torque", "computed-torque-pid")
#: Compensations (``[controller] compensation``): the disturbance estimate cancelled.
COMPENSATIONS = ("chen", "general", "momentum", "ism", "ism-bl", "none")
#: Compensations advanced inside the compiled step (the others are called from Python
#: between its two compiled halves); kept for callers of version 0.2.
NATIVE_COMPENSATIONS = ("chen", "general", "none")
#: Controller names of version 0.1, each one controller × one compensation.
KIND_ALIASES = {
    "hmpc-none": ("hmpc", "none"),
    "hmpc-momentum": ("hmpc", "momentum"),
    "hmpc-ism": ("hmpc", "ism"),
    "hmpc-ism-bl": ("hmpc", "ism-bl"),
}
#: Every name accepted by ``[controller] kind`` in version 0.1 (still accepted).
CONTROLLER_KINDS = (
    "hmpc",
    "hmpc-none",
    "hmpc-momentum",
    "hmpc-ism",
    "hmpc-ism-bl",
    "computed-torque",
    "computed-torque-pid",
)
#: The compensation a controller has when ``compensation`` is not given.
DEFAULT_COMPENSATION = {"hmpc": "chen", "computed-torque": "none", "computed-torque-pid": "none"}


def parse_combination(name: str, key: str = "controller") -> tuple[str, str | None]:
    """``"controller+compensation"``, a 0.1 alias or a bare controller → the pair.

    A bare controller gives ``(controller, None)``: its compensation is decided by the
    caller (the config's, or :data:`DEFAULT_COMPENSATION`).

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
    if compensation not in COMPENSATIONS:
        raise ConfigError(
            key, f"unknown compensation {compensation!r} in {name!r}; expected one of "
            f"{COMPENSATIONS}",
        )  # fmt: skip
    return controller, compensation


# -------------------------------------------------------------------- sections
@dataclass(frozen=True, eq=False)
class ObserverConfig:
    """Disturbance observer settings (Section 3.2, Eq 28–30), for the compensations
    ``"chen"``, ``"general"`` and ``"momentum"``.

    Attributes:
        gain: Observer gain c (the paper does not give it; 100 is this project's choice,
            README); for ``"momentum"`` the gain K_O [1/s].
        discretization: ``"implicit"`` (backward Euler, stable for any c) or ``"explicit"``
            (not for ``"momentum"``, which is always semi-implicit).
        enabled: Version 0.1 key, with ``kind = "hmpc"`` only: ``false`` means
            compensation ``"none"`` (the whole table is then switched off). Superseded
            by ``[controller] compensation``.
        kind: Version 0.1 key, with ``kind = "hmpc"`` only: the observer
            (``"chen"``, ``"general"``, ``"momentum"``). Superseded by
            ``[controller] compensation``.
    """

    gain: float = 100.0
    discretization: str = "implicit"
    enabled: bool | None = None
    kind: str | None = None

    def __post_init__(self):
        if self.enabled is not None:
            _set(self, "enabled", _bool("enabled", self.enabled))
        if self.kind is not None:
            _set(self, "kind", _choice("kind", self.kind, OBSERVERS))
        _set(self, "gain", _float("gain", self.gain, positive=True))
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
    slack_weight: float = 1e5
    slack_linear_weight: float = 1e4

    def __post_init__(self):
        for name in ("enabled", "position", "velocity"):
            _set(self, name, _bool(name, getattr(self, name)))
        for name in ("lower", "upper"):
            if getattr(self, name) is not None:
                _set(self, name, _array(name, getattr(self, name)))
        if self.velocity_limit is not None:
            _set(self, "velocity_limit", _array("velocity_limit", self.velocity_limit,
                                                positive=True))  # fmt: skip
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
    """Integral sliding mode loop of ``hmpc-ism`` / ``hmpc-ism-bl`` (:mod:`hmpc_pin.ism`).

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
            _set(self, "boundary_layer",
                 _float("boundary_layer", self.boundary_layer, positive=True))  # fmt: skip

    def width(self, Ts: float) -> float:
        """The boundary-layer width φ [rad/s] for the control period ``Ts`` [s]."""
        return self.boundary_layer if self.boundary_layer is not None else self.gain * Ts


@dataclass(frozen=True, eq=False)
class ComputedTorqueConfig:
    """Outer loop of ``computed-torque`` and ``computed-torque-pid`` (``computed_torque`` module).

    By default the PD gains are the MPC's own unconstrained state-feedback gain (so both
    loops have the same closed-loop poles, i.e. the same bandwidth) and the integral gain
    gives the PID loop its fastest decay (:mod:`hmpc_pin.computed_torque`).

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
    """The controller: an outer loop × a disturbance compensation (README "Controllers").

    Every default is the paper's value (Section 4): ``ControllerConfig()`` is the
    paper's scheme, ``hmpc`` × ``chen``. A table that does not apply to the chosen
    pair (``observer`` without an observer, ``ism`` without ISM, ``computed_torque``
    or ``constraints`` with the other controller) is a :class:`ConfigError` naming it.
    After validation ``kind`` and ``compensation`` hold the resolved pair and exactly
    the applicable tables are set (the others are ``None``).

    Attributes:
        kind: The controller, one of :data:`CONTROLLERS` (default ``"hmpc"``), or a
            version-0.1 name of :data:`KIND_ALIASES` (``"hmpc-ism"`` = ``hmpc`` × ``ism``).
        compensation: One of :data:`COMPENSATIONS`; default :data:`DEFAULT_COMPENSATION`
            of the controller (for ``hmpc`` written the 0.1 way, the
            ``observer.enabled``/``observer.kind`` keys decide).
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
        eps_abs: ProxSuite absolute tolerance (``hmpc``).
        max_iter: ProxSuite iteration cap per solve (``hmpc``).
        qp_layout: ``"auto"`` (default: ``"block"`` up to n·Nc = 140 QP variables,
            ``"joint"`` above), ``"block"`` (the n joint QPs as one block-diagonal ProxSuite
            QP, one solve per step; fastest for short horizons) or ``"joint"`` (one QP per
            joint; fastest for long ones) (``hmpc``; :func:`hmpc_pin.mpc.condensed.resolve_layout`).
        backend: Deprecated since 0.3, without effect (``hmpc``): the step is always the
            compiled one, :mod:`hmpc_pin.native`; ``"auto"`` and ``"native"`` load silently,
            ``"python"`` with a :class:`DeprecationWarning`, anything else is an error.
        ism: :class:`ISMConfig` (compensations ``ism``, ``ism-bl``).
        computed_torque: :class:`ComputedTorqueConfig` (``computed-torque*``).
    """

    kind: str = "hmpc"
    compensation: str | None = None
    Ts: float = 0.01
    N: int = 10
    Nc: int = 1
    Q: np.ndarray = field(default_factory=lambda: np.diag([50.0, 0.0]))
    R: float = 1e-6
    P: np.ndarray = field(default_factory=lambda: np.diag([100.0, 0.0]))
    v_min: np.ndarray = -100.0
    v_max: np.ndarray = 100.0
    observer: ObserverConfig | None = None
    constraints: ConstraintConfig | None = None
    eps_abs: float | None = None
    max_iter: int | None = None
    qp_layout: str | None = None
    backend: str | None = None
    ism: ISMConfig | None = None
    computed_torque: ComputedTorqueConfig | None = None

    def __post_init__(self):
        _set(self, "Ts", _float("Ts", self.Ts, positive=True))
        _set(self, "N", _int("N", self.N, minimum=1))
        _set(self, "Nc", _int("Nc", self.Nc, minimum=1))
        if self.Nc > self.N:
            raise ConfigError("Nc", f"{self.Nc=} but {self.N=}; expected 1 <= Nc <= N")
        _set(self, "Q", _weight("Q", self.Q))
        _set(self, "P", _weight("P", self.P))
        _set(self, "R", _float("R", self.R, positive=True))
        _set(self, "v_min", _array("v_min", self.v_min))
        _set(self, "v_max", _array("v_max", self.v_max))
        if self.v_min.shape != self.v_max.shape and self.v_min.ndim and self.v_max.ndim:
            raise ConfigError(
                "v_max", f"{self.v_min.shape=} but {self.v_max.shape=}; give both per joint"
            )
        if np.any(self.v_min >= self.v_max):
            raise ConfigError(
                "v_min",
                f"v_min={self.v_min.tolist()} must be < v_max={self.v_max.tolist()} on every joint",
            )
        for name, cls in (
            ("observer", ObserverConfig),
            ("constraints", ConstraintConfig),
            ("ism", ISMConfig),
            ("computed_torque", ComputedTorqueConfig),
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
            _choice("compensation", self.compensation, COMPENSATIONS)
        controller, alias_comp = parse_combination(self.kind, "kind")
        if "+" in self.kind:
            raise ConfigError(
                "kind", f"{self.kind!r}: give the controller in kind and the compensation in "
                "compensation (e.g. kind = 'hmpc', compensation = 'momentum')",
            )  # fmt: skip
        obs = self.observer
        legacy_keys = [
            k for k in ("enabled", "kind") if obs is not None and getattr(obs, k) is not None
        ]
        if alias_comp is not None:  # a 0.1 name: the compensation is in the name
            if self.compensation is not None and self.compensation != alias_comp:
                raise ConfigError(
                    "compensation",
                    f"{self.compensation!r} contradicts kind = {self.kind!r} (which is "
                    f"hmpc × {alias_comp}); write kind = 'hmpc' with the compensation",
                )
            comp = alias_comp
            if obs is not None and comp == "momentum":
                if obs.enabled is False:
                    raise ConfigError(
                        "observer.enabled",
                        "false, but kind = 'hmpc-momentum' is hmpc × momentum observer; for "
                        "no compensation write compensation = 'none'",
                    )
                if obs.kind not in (None, "momentum"):
                    raise ConfigError(
                        "observer.kind",
                        f"{obs.kind!r}, but kind = 'hmpc-momentum' uses the momentum "
                        "observer; write kind = 'hmpc', compensation = "
                        f"{obs.kind!r} instead",
                    )
        elif self.compensation is not None:
            if legacy_keys:
                raise ConfigError(
                    f"observer.{legacy_keys[0]}",
                    "superseded by [controller] compensation; remove it (compensation = "
                    f"{self.compensation!r} already chooses)",
                )
            comp = self.compensation
        elif controller == "hmpc":  # 0.1 spelling: the observer table decides
            enabled = True if obs is None or obs.enabled is None else obs.enabled
            comp = ((obs.kind if obs is not None else None) or "chen") if enabled else "none"
            if not enabled:
                obs = None  # a table switched off by its own enabled = false
        else:
            comp = DEFAULT_COMPENSATION[controller]
            if legacy_keys:
                raise ConfigError(
                    f"observer.{legacy_keys[0]}",
                    f"does not apply to kind = {controller!r}; choose the compensation "
                    "with [controller] compensation",
                )
        # The tables of the pair; any other given table is an error.
        if applies("observer", controller, comp):
            obs = obs if obs is not None else ObserverConfig()
            if (obs.enabled, obs.kind) != (None, None):  # 0.1 keys, now resolved
                obs = replace(obs, enabled=None, kind=None)
            if comp == "momentum" and obs.discretization != "implicit":
                raise ConfigError(
                    "observer.discretization",
                    "the momentum observer has only the semi-implicit form; remove the key "
                    "or set it to 'implicit'",
                )
        elif obs is not None:
            self._not_applicable("observer", controller, comp)
        ism = self.ism
        if applies("ism", controller, comp):
            ism = ism if ism is not None else ISMConfig()
            if comp == "ism" and ism.boundary_layer is not None:
                raise ConfigError(
                    "ism.boundary_layer",
                    "applies only to compensation 'ism-bl' (the pure sign law has none)",
                )
        elif ism is not None:
            self._not_applicable("ism", controller, comp)
        ct = self.computed_torque
        if applies("computed_torque", controller, comp):
            ct = ct if ct is not None else ComputedTorqueConfig()
            if controller == "computed-torque" and ct.ki is not None:
                raise ConfigError(
                    "computed_torque.ki", "applies only to kind = 'computed-torque-pid'"
                )
            for name in HMPC_ONLY:
                if getattr(self, name) is not None and not applies(name, controller, comp):
                    self._not_applicable(name, controller, comp)
        else:
            if ct is not None:
                self._not_applicable("computed_torque", controller, comp)
            if self.constraints is None:
                _set(self, "constraints", ConstraintConfig())
            eps = 1e-9 if self.eps_abs is None else self.eps_abs
            _set(self, "eps_abs", _float("eps_abs", eps, positive=True))
            cap = 1000 if self.max_iter is None else self.max_iter
            _set(self, "max_iter", _int("max_iter", cap, minimum=1))
            layout = "auto" if self.qp_layout is None else self.qp_layout
            _set(self, "qp_layout", _choice("qp_layout", layout, ("auto", "block", "joint")))
            backend = "auto" if self.backend is None else self.backend
            _set(self, "backend", _choice("backend", backend, BACKENDS))
        _set(self, "kind", controller)
        _set(self, "compensation", comp)
        _set(self, "observer", obs)
        _set(self, "ism", ism)
        _set(self, "computed_torque", ct)

    def controller_parts(self, robot) -> tuple:
        """The constructor arguments after ``robot`` of this controller's class (the
        deprecated 0.1 call ``HierarchicalMPC(robot, ControllerConfig)`` asks for them;
        :func:`hmpc_pin.experiment.controllers.controller_parts`)."""
        from .controllers import controller_parts

        return controller_parts(robot, self)

    @staticmethod
    def _not_applicable(name: str, controller: str, comp: str) -> None:
        raise ConfigError(
            name,
            f"does not apply to {controller} × {comp}; remove it, or choose a controller "
            "and compensation it applies to (README, Controllers)",
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


@dataclass(frozen=True, eq=False)
class RobotConfig:
    """The controller's robot model.

    Attributes:
        urdf: URDF path (relative paths are relative to the config file).
        model: Instead of ``urdf``, a robot name: ``"planar3"`` (shipped in the package)
            or an ``example-robot-data`` name (``"ur5"``, ``"panda"``, ``"z1"``, ...);
            give at most one of the two (neither: ``"planar3"``).
        gravity: Gravity magnitude [m/s²] along −z (paper: 9.8).
        locked_joints: Joints not controlled, by URDF name → locked position [rad or m]
            (e.g. Panda's fingers); removed with ``pin.buildReducedModel``.
    """

    urdf: Path | None = None
    model: str | None = None
    gravity: float = 9.8
    locked_joints: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.urdf is not None and self.model is not None:
            raise ConfigError("model", "give either robot.urdf or robot.model, not both")
        if self.urdf is not None:
            if not isinstance(self.urdf, (str, Path)):
                raise ConfigError("urdf", f"expected a path string, got {self.urdf!r}")
            _set(self, "urdf", Path(self.urdf))
        if self.model is not None and not isinstance(self.model, str):
            raise ConfigError("model", f"expected a robot name string, got {self.model!r}")
        _set(self, "gravity", _float("gravity", self.gravity, nonneg=True))
        if not isinstance(self.locked_joints, dict):
            raise ConfigError(
                "locked_joints", f"expected a table name = position, got {self.locked_joints!r}"
            )
        _set(
            self,
            "locked_joints",
            {str(k): _float(f"locked_joints.{k}", v) for k, v in self.locked_joints.items()},
        )

    @property
    def source(self) -> Path | str:
        """The URDF path or the robot name, as :func:`~hmpc_pin.model.robot.load_robot`
        takes it (neither given: ``"planar3"``, the paper's arm shipped in the package)."""
        if self.urdf is not None:
            return self.urdf
        return self.model if self.model is not None else "planar3"


#: Physics engines of the plant (``[plant] engine``).
ENGINES = ("pinocchio", "mujoco")
#: Integrators of the Pinocchio plant (``[plant] integrator``): the plants of
#: :data:`~hmpc_pin.sim.plants.PLANTS` that integrate Pinocchio's ABA.
PINOCCHIO_INTEGRATORS = tuple(
    name for name, cls in PLANTS.items() if getattr(cls, "engine", "pinocchio") == "pinocchio"
)


@dataclass(frozen=True, eq=False)
class ObstacleConfig:
    """A box fixed in the world that the MuJoCo arm can touch (a wall, a table).

    Attributes:
        position: Centre [x, y, z] in the world frame [m].
        size: Half-lengths [x, y, z] [m] (MuJoCo's box ``size``).
        friction: Sliding friction coefficient of the contact [-] (default 0.5).
        solref: Softness of the surface, MuJoCo's contact ``solref`` [time constant [s],
            damping ratio] (default MuJoCo's [0.02, 1]; larger time constant: softer).
    """

    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    size: np.ndarray = field(default_factory=lambda: np.full(3, 0.1))
    friction: float = 0.5
    solref: np.ndarray = field(default_factory=lambda: np.array([0.02, 1.0]))

    def __post_init__(self):
        for name in ("position", "size"):
            arr = _array(name, getattr(self, name), positive=name == "size")
            if arr.shape != (3,):
                raise ConfigError(name, f"expected [x, y, z], got {arr.tolist()}")
            _set(self, name, arr)
        _set(self, "friction", _float("friction", self.friction, nonneg=True))
        solref = _array("solref", self.solref, positive=True)
        if solref.shape != (2,):
            raise ConfigError("solref", f"expected [time constant, damping ratio], got {solref!r}")
        _set(self, "solref", solref)


@dataclass(frozen=True, eq=False)
class MuJoCoConfig:
    """The MuJoCo plant (``[plant] engine = "mujoco"``): the simulated arm's own joint
    friction, damping and armature, MuJoCo's integrator and the scene.

    Attributes:
        integrator: ``"implicitfast"`` (default), ``"euler"``, ``"rk4"`` or ``"implicit"``.
        timestep: MuJoCo's step [s]; must divide the control period (default 1 ms).
        frictionloss: Dry joint friction [N·m] (MuJoCo ``frictionloss``), per joint or one
            value (default 0).
        damping: Viscous joint damping [N·m·s/rad], per joint or one value (default 0).
        armature: Rotor inertia added to each joint [kg·m²] (default 0).
        import_urdf_dynamics: Also apply the URDF's ``<dynamics damping friction>``
            (added to the values above; default ``false``: the controller's Pinocchio
            model ignores them too).
        geometry: Collision geometry of the arm: ``"collision"`` (the URDF's, default),
            ``"visual"`` (its visual shapes, for an arm without collision tags) or
            ``"none"`` (dynamics only).
        obstacle: :class:`ObstacleConfig`, or ``None`` (no contacts).
    """

    integrator: str = "implicitfast"
    timestep: float = 0.001
    frictionloss: np.ndarray = 0.0
    damping: np.ndarray = 0.0
    armature: np.ndarray = 0.0
    import_urdf_dynamics: bool = False
    geometry: str = "collision"
    obstacle: ObstacleConfig | None = None

    def __post_init__(self):
        _set(self, "integrator", _choice("integrator", self.integrator, tuple(MUJOCO_INTEGRATORS)))
        _set(self, "timestep", _float("timestep", self.timestep, positive=True))
        for name in ("frictionloss", "damping", "armature"):
            _set(self, name, _array(name, getattr(self, name), nonneg=True))
        _set(self, "import_urdf_dynamics", _bool("import_urdf_dynamics", self.import_urdf_dynamics))
        _set(self, "geometry", _choice("geometry", self.geometry, GEOMETRY_SOURCES))
        if isinstance(self.obstacle, dict):
            _set(self, "obstacle", _section(ObstacleConfig, self.obstacle, "obstacle"))
        elif self.obstacle is not None and not isinstance(self.obstacle, ObstacleConfig):
            raise ConfigError("obstacle", f"expected a table, got {self.obstacle!r}")
        if self.obstacle is not None and self.geometry == "none":
            raise ConfigError(
                "geometry", "'none' leaves the arm without geometry to touch the obstacle; "
                "use 'collision' or 'visual'",
            )  # fmt: skip


@dataclass(frozen=True, eq=False)
class PlantConfig:
    """The simulated plant.

    Attributes:
        engine: ``"pinocchio"`` (default: Pinocchio's ABA on the plant model, integrated
            by ``integrator``) or ``"mujoco"`` (MuJoCo on the same URDF; then
            ``[plant.mujoco]`` holds its settings and ``dt``/``integrator`` do not apply).
        urdf: URDF of the plant; ``None`` uses the controller's model (no mismatch).
        gravity: Plant gravity [m/s²]; ``None`` uses the robot's.
        dt: Integration step [s], must divide the control period (default 1 ms).
        integrator: ``"rk4"`` (default) or ``"euler"`` (semi-implicit).
        saturate: Clip the applied torque to the effort limits (default ``True``).
        effort_limit: Effort limits [N·m] overriding the URDF's (per joint or one value);
            ``None`` keeps the URDF's (a URDF value <= 0 means no limit).
        mujoco: :class:`MuJoCoConfig` (``engine = "mujoco"`` only).
        backend: Deprecated since 0.3, without effect (``integrator = "rk4"`` only): the
            period is always the compiled one; ``"python"`` loads with a
            :class:`DeprecationWarning`.
    """

    urdf: Path | None = None
    gravity: float | None = None
    dt: float = 0.001
    integrator: str = "rk4"
    saturate: bool = True
    effort_limit: np.ndarray | None = None
    engine: str = "pinocchio"
    mujoco: MuJoCoConfig | None = None
    backend: str = "auto"

    def __post_init__(self):
        if self.urdf is not None:
            if not isinstance(self.urdf, (str, Path)):
                raise ConfigError("urdf", f"expected a path string, got {self.urdf!r}")
            _set(self, "urdf", Path(self.urdf))
        if self.gravity is not None:
            _set(self, "gravity", _float("gravity", self.gravity, nonneg=True))
        _set(self, "dt", _float("dt", self.dt, positive=True))
        _set(self, "integrator", _choice("integrator", self.integrator, PINOCCHIO_INTEGRATORS))
        _set(self, "saturate", _bool("saturate", self.saturate))
        if self.effort_limit is not None:
            _set(self, "effort_limit", _array("effort_limit", self.effort_limit, positive=True))
        _set(self, "engine", _choice("engine", self.engine, ENGINES))
        if isinstance(self.mujoco, dict):
            _set(self, "mujoco", _section(MuJoCoConfig, self.mujoco, "mujoco"))
        elif self.mujoco is not None and not isinstance(self.mujoco, MuJoCoConfig):
            raise ConfigError("mujoco", f"expected a table, got {self.mujoco!r}")
        _set(self, "backend", _choice("backend", self.backend, BACKENDS))
        if self.backend != "auto" and (self.engine != "pinocchio" or self.integrator != "rk4"):
            raise ConfigError(
                "backend", f"does not apply to engine = {self.engine!r}, integrator = "
                f"{self.integrator!r} (only the Pinocchio RK4 plant has a native path); "
                "remove it",
            )  # fmt: skip
        if self.engine == "pinocchio" and self.mujoco is not None:
            raise ConfigError("mujoco", "applies only to engine = 'mujoco'; remove the table "
                              "or set plant.engine = 'mujoco'")  # fmt: skip
        if self.engine == "mujoco":
            if self.mujoco is None:
                _set(self, "mujoco", MuJoCoConfig())
            for key, default, instead in (
                ("dt", 0.001, "timestep"),
                ("integrator", "rk4", "integrator"),
            ):
                if getattr(self, key) != default:
                    raise ConfigError(
                        key, f"does not apply to engine = 'mujoco'; set "
                        f"plant.mujoco.{instead} instead",
                    )  # fmt: skip


@dataclass(frozen=True, eq=False)
class CollisionConfig:
    """Collision detection on the disturbance estimate, and the reaction to it.

    A collision is flagged at the first control instant at which
    :math:`|\\hat d_i| > \\text{threshold}_i` for some joint i (the observer as a
    contact-torque estimator).

    Attributes:
        threshold: Estimate magnitude [N·m] that flags a collision, per joint or one value.
        reaction: ``"ignore"`` (keep compensating, the paper's behaviour: the arm keeps
            pushing) or ``"stop"`` (hold the position reached, the estimate no longer
            fed back).
    """

    threshold: np.ndarray = 1.0
    reaction: str = "ignore"

    def __post_init__(self):
        _set(self, "threshold", _array("threshold", self.threshold, positive=True))
        _set(self, "reaction", _choice("reaction", self.reaction, ("ignore", "stop")))


@dataclass(frozen=True, eq=False)
class CartesianConfig:
    """Point-to-point tool motion of Section 5.4, in the arm's x–z plane.

    Both poses are solved by inverse kinematics on the branch inside the joint
    limits (the goal's branch closest to the start), and joined by a joint-space
    quintic with zero velocity and acceleration at both ends.

    Attributes:
        start_position: Tool (x, z) at the start [m] (paper: 1.2, 0.5).
        start_angle: Angle of link 3 to the x axis at the start [deg] (paper: −90).
        goal_position: Tool (x, z) at the goal [m] (paper: 2.423, 2.234).
        goal_angle: Angle of link 3 at the goal [deg] (paper: 0, parallel to x).
        t_start: Time the motion starts [s] (not in the paper; 0).
        move_time: Duration of the motion [s] (not in the paper; 5).
    """

    start_position: np.ndarray = field(default_factory=lambda: np.array([1.2, 0.5]))
    start_angle: float = -90.0
    goal_position: np.ndarray = field(default_factory=lambda: np.array([2.423, 2.234]))
    goal_angle: float = 0.0
    t_start: float = 0.0
    move_time: float = 5.0

    def __post_init__(self):
        for name in ("start_position", "goal_position"):
            arr = _array(name, getattr(self, name))
            if arr.shape != (2,):
                raise ConfigError(name, f"expected [x, z], got {arr.tolist()}")
            _set(self, name, arr)
        _set(self, "start_angle", _float("start_angle", self.start_angle))
        _set(self, "goal_angle", _float("goal_angle", self.goal_angle))
        _set(self, "t_start", _float("t_start", self.t_start, nonneg=True))
        _set(self, "move_time", _float("move_time", self.move_time, positive=True))


@dataclass(frozen=True, eq=False)
class TrajectoryConfig:
    """A joint trajectory from a file (``[reference.trajectory]``, ``kind = "trajectory"``).

    Attributes:
        file: A ``.csv`` (header ``t``, then one column per controlled joint, optionally
            ``dq_<joint>`` for every joint) or ``.npz`` (arrays ``t``, ``q``, optionally
            ``dq``, ``joint_names``) [s, rad, rad/s]; relative to the config file
            (:func:`~hmpc_pin.tasks.trajectory.load_trajectory`).
    """

    file: Path | None = None

    def __post_init__(self):
        if not isinstance(self.file, (str, Path)):
            raise ConfigError("file", f"expected the path of a .csv or .npz file, got "
                              f"{self.file!r}")  # fmt: skip
        _set(self, "file", Path(self.file))


@dataclass(frozen=True, eq=False)
class WaypointsConfig:
    """Joint waypoints retimed by TOPP-RA (``[reference.waypoints]``, ``kind = "waypoints"``).

    Attributes:
        points: The waypoints [rad], a list of P >= 2 joint vectors.
        acceleration_limit: :math:`\\ddot q_{max}` [rad/s²], one value or per joint.
        velocity_limit: :math:`\\dot q_{max}` [rad/s] overriding the URDF's (one value or
            per joint); ``None`` keeps the URDF's velocity limits.
        t_start: Time the motion starts [s]; the first waypoint is held before.
    """

    points: list | None = None
    acceleration_limit: np.ndarray = 2.0
    velocity_limit: np.ndarray | None = None
    t_start: float = 0.0

    def __post_init__(self):
        pts = self.points
        if not isinstance(pts, (list, tuple)) or len(pts) < 2:
            raise ConfigError("points", f"expected a list of >= 2 joint vectors, got {pts!r}")
        rows = [_array(f"points[{i}]", p) for i, p in enumerate(pts)]
        if any(r.ndim != 1 or r.shape != rows[0].shape for r in rows):
            raise ConfigError("points", "expected joint vectors of one length, got "
                              f"{[r.tolist() for r in rows]}")  # fmt: skip
        _set(self, "points", np.array(rows))
        _set(self, "acceleration_limit",
             _array("acceleration_limit", self.acceleration_limit, positive=True))  # fmt: skip
        if self.velocity_limit is not None:
            _set(self, "velocity_limit",
                 _array("velocity_limit", self.velocity_limit, positive=True))  # fmt: skip
        _set(self, "t_start", _float("t_start", self.t_start, nonneg=True))


#: End-effector paths (``[reference.pose] path``) and the keys each one takes.
POSE_PATHS = {
    "circle": ("center", "radius", "frequency", "plane", "ramp"),
    "line": ("start", "end", "t_start", "duration"),
    "waypoints": ("times", "positions", "orientations"),
}


def _point(key: str, value) -> np.ndarray:
    arr = _array(key, value)
    if arr.shape != (3,):
        raise ConfigError(key, f"expected [x, y, z] [m], got {arr.tolist()}")
    return arr


def _quaternion(key: str, value) -> np.ndarray:
    arr = _array(key, value)
    if arr.shape != (4,) or np.linalg.norm(arr) < 1e-9:
        raise ConfigError(key, f"expected a quaternion [x, y, z, w] (scalar last), got "
                          f"{arr.tolist()}")  # fmt: skip
    return arr / np.linalg.norm(arr)


@dataclass(frozen=True, eq=False)
class PoseConfig:
    """An end-effector task (``[reference.pose]``, ``kind = "pose"``), solved by pink's
    differential IK before the run (:mod:`hmpc_pin.tasks.pose`).

    Positions are in the world frame [m]; orientations quaternions ``[x, y, z, w]``.

    Attributes:
        frame: The frame that follows the path (default: the model's last frame, the tool).
        path: ``"circle"``, ``"line"`` or ``"waypoints"`` (:data:`POSE_PATHS`: only the
            path's own keys may be given).
        q_init: Joint vector the IK starts from and whose posture it keeps [rad] (default
            ``simulation.q0``, else the middle of the joint limits).
        orientation: Orientation held by ``circle`` and ``line`` (default: the frame's at
            ``q_init``).
        center: Circle centre [m] (default: so that the circle starts at the frame's
            position at ``q_init``). radius: [m]. frequency: [Hz]. plane: ``"xy"``,
            ``"xz"``, ``"yz"`` or a normal ``[nx, ny, nz]`` (default ``"yz"``). ramp: time
            [s] over which the circle's angular speed rises from rest (minimum-jerk
            profile; default 0: the circle starts at full speed).
        start: Line start [m] (default: the frame's position at ``q_init``). end: [m].
        t_start: Line start time [s]. duration: Line duration [s] (minimum-jerk timing).
        times: Waypoint times [s], strictly increasing. positions: Waypoint positions [m].
        orientations: Waypoint quaternions (default: the frame's at ``q_init`` for all).
        dt: Period of the IK samples [s].
        posture_cost: Weight of the posture term relative to the frame task.
    """

    path: str | None = None
    frame: str | None = None
    q_init: np.ndarray | None = None
    orientation: np.ndarray | None = None
    center: np.ndarray | None = None
    radius: float | None = None
    frequency: float | None = None
    plane: object = None
    ramp: float | None = None
    start: np.ndarray | None = None
    end: np.ndarray | None = None
    t_start: float | None = None
    duration: float | None = None
    times: np.ndarray | None = None
    positions: np.ndarray | None = None
    orientations: np.ndarray | None = None
    dt: float = 0.01
    posture_cost: float = 1e-3

    def __post_init__(self):
        _set(self, "path", _choice("path", self.path, tuple(POSE_PATHS)))
        own = POSE_PATHS[self.path]
        for other in {k for keys in POSE_PATHS.values() for k in keys} - set(own):
            if getattr(self, other) is not None:
                raise ConfigError(other, f"does not apply to path = {self.path!r} (its keys: "
                                  f"{', '.join(own)})")  # fmt: skip
        if self.frame is not None and not isinstance(self.frame, str):
            raise ConfigError("frame", f"expected a frame name, got {self.frame!r}")
        if self.q_init is not None:
            _set(self, "q_init", _array("q_init", self.q_init))
        if self.orientation is not None:
            if self.path == "waypoints":
                raise ConfigError("orientation", "does not apply to path = 'waypoints' (give "
                                  "orientations, one per waypoint)")  # fmt: skip
            _set(self, "orientation", _quaternion("orientation", self.orientation))
        for name in ("center", "start", "end"):
            if getattr(self, name) is not None:
                _set(self, name, _point(name, getattr(self, name)))
        if self.path == "circle":
            for name in ("radius", "frequency"):
                if getattr(self, name) is None:
                    raise ConfigError(name, "path = 'circle' needs radius and frequency")
                _set(self, name, _float(name, getattr(self, name), positive=True))
            plane = "yz" if self.plane is None else self.plane
            if not isinstance(plane, str):
                plane = _point("plane", plane)
            elif plane not in ("xy", "xz", "yz"):
                raise ConfigError("plane", f"expected 'xy', 'xz', 'yz' or a normal [nx, ny, "
                                  f"nz], got {plane!r}")  # fmt: skip
            _set(self, "plane", plane)
            _set(self, "ramp", _float("ramp", 0.0 if self.ramp is None else self.ramp,
                                      nonneg=True))  # fmt: skip
        elif self.path == "line":
            if self.end is None or self.duration is None:
                raise ConfigError("end", "path = 'line' needs end and duration")
            _set(self, "duration", _float("duration", self.duration, positive=True))
            _set(self, "t_start", _float("t_start", self.t_start or 0.0, nonneg=True))
        else:
            if self.times is None or self.positions is None:
                raise ConfigError("times", "path = 'waypoints' needs times and positions")
            times = _array("times", self.times)
            if times.ndim != 1 or times.size < 2 or np.any(np.diff(times) <= 0):
                raise ConfigError("times", f"expected >= 2 strictly increasing times [s], got "
                                  f"{times.tolist()}")  # fmt: skip
            _set(self, "times", times)
            pos = self.positions
            if not isinstance(pos, (list, tuple)) or len(pos) != times.size:
                raise ConfigError("positions", f"expected {times.size} points [x, y, z], one "
                                  f"per time, got {pos!r}")  # fmt: skip
            _set(self, "positions", np.array([_point(f"positions[{i}]", p)
                                              for i, p in enumerate(pos)]))  # fmt: skip
            if self.orientations is not None:
                quats = self.orientations
                if not isinstance(quats, (list, tuple)) or len(quats) != times.size:
                    raise ConfigError("orientations", f"expected {times.size} quaternions "
                                      f"[x, y, z, w], got {quats!r}")  # fmt: skip
                _set(self, "orientations", np.array(
                    [_quaternion(f"orientations[{i}]", q) for i, q in enumerate(quats)]))
        _set(self, "dt", _float("dt", self.dt, positive=True))
        _set(self, "posture_cost", _float("posture_cost", self.posture_cost, positive=True))


SINE_KEYS = ("amplitude", "frequency", "offset", "phase")
SINE_DEFAULTS = {"amplitude": 1.0, "frequency": 0.1, "offset": 0.0, "phase": 0.0}
#: Reference kinds (``[reference] kind``) and the table each one needs (``None``: the sine
#: keys of ``[reference]`` itself).
REFERENCE_TABLES = {
    "sine": (None, None),
    "cartesian": ("cartesian", CartesianConfig),
    "trajectory": ("trajectory", TrajectoryConfig),
    "waypoints": ("waypoints", WaypointsConfig),
    "pose": ("pose", PoseConfig),
}


@dataclass(frozen=True, eq=False)
class ReferenceConfig:
    """Joint reference: the sine of Eq (31), the Cartesian motion of Section 5.4, a
    trajectory file, joint waypoints or an end-effector task (README, "Tasks").

    ``kind = "sine"``: :math:`r_i = o_i + a_i \\sin(2\\pi f_i t + \\phi_i)`. Every other
    kind needs its own table (``[reference.cartesian]``, ``[reference.trajectory]``,
    ``[reference.waypoints]``, ``[reference.pose]``) and takes no sine key.

    Attributes:
        kind: One of :data:`REFERENCE_TABLES`.
        amplitude: a [rad] (paper: 1), scalar or per joint.
        frequency: f [Hz] (paper: 0.1, i.e. 0.2π rad/s).
        offset: o [rad] (paper: 0).
        phase: φ [rad] (paper: 0).
        cartesian: :class:`CartesianConfig` for ``kind = "cartesian"``.
        trajectory: :class:`TrajectoryConfig` for ``kind = "trajectory"``.
        waypoints: :class:`WaypointsConfig` for ``kind = "waypoints"``.
        pose: :class:`PoseConfig` for ``kind = "pose"``.
    """

    kind: str = "sine"
    amplitude: np.ndarray | None = None
    frequency: np.ndarray | None = None
    offset: np.ndarray | None = None
    phase: np.ndarray | None = None
    cartesian: CartesianConfig | None = None
    trajectory: TrajectoryConfig | None = None
    waypoints: WaypointsConfig | None = None
    pose: PoseConfig | None = None

    def __post_init__(self):
        _set(self, "kind", _choice("kind", self.kind, tuple(REFERENCE_TABLES)))
        own, cls = REFERENCE_TABLES[self.kind]
        for name, _ in REFERENCE_TABLES.values():
            if name is not None and name != own and getattr(self, name) is not None:
                raise ConfigError(name, f"applies only to kind = {name!r}")
        if own is not None:
            given = [k for k in SINE_KEYS if getattr(self, k) is not None]
            if given:
                raise ConfigError(
                    given[0], f"applies only to kind = 'sine'; remove it for kind = {own!r}"
                )
            value = getattr(self, own)
            if isinstance(value, dict):
                _set(self, own, _section(cls, value, own))
            elif value is None:
                raise ConfigError(own, f"kind = {own!r} needs a [reference.{own}] table")
            elif not isinstance(value, cls):
                raise ConfigError(own, f"expected a table, got {value!r}")
            return
        for key in SINE_KEYS:
            value = getattr(self, key)
            _set(self, key, _array(key, SINE_DEFAULTS[key] if value is None else value))
        if np.any(self.frequency < 0):
            raise ConfigError("frequency", f"expected values >= 0, got {self.frequency.tolist()}")


@dataclass(frozen=True, eq=False)
class FrictionConfig:
    """Coulomb–viscous friction, Eq (32) (SPEC §3).

    Attributes:
        viscous: a [N·m·s/rad] (paper: 10, 8, 5).
        coulomb: b [N·m] (paper: 3.0, 2.4, 1.8).
        sign: ``"opposing"`` (default, physical): :math:`d = -(a\\dot q + b\\,\\mathrm{sgn}\\,
            \\dot q)`; ``"literal"``: the paper's Eq 32 as printed, :math:`d = +F`, friction
            feeding energy in (the second reading of the paper, README "Friction sign").
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


@dataclass(frozen=True, eq=False)
class SimulationConfig:
    """Closed-loop run settings.

    Attributes:
        duration: Simulated time [s] (paper: 10).
        q0: Initial joint angles [rad] (paper: 1, 1, 1); ``None`` starts on the
            reference, r(0) (for a Cartesian motion: the start pose's IK solution).
        dq0: Initial joint velocities [rad/s] (paper: 0).
        state_bound: The run stops as diverged (``complete = False``, CLI exit 1) at the
            first control period after which any |q| [rad] or |q̇| [rad/s] of the plant
            exceeds it (default 1e3).
    """

    duration: float = 10.0
    q0: np.ndarray | None = None
    dq0: np.ndarray = 0.0
    state_bound: float = 1e3

    def __post_init__(self):
        _set(self, "duration", _float("duration", self.duration, positive=True))
        if self.q0 is not None:
            _set(self, "q0", _array("q0", self.q0))
        _set(self, "dq0", _array("dq0", self.dq0))
        _set(self, "state_bound", _float("state_bound", self.state_bound, positive=True))


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
        q_noise: Standard deviation of the white noise added to each measured joint
            angle [rad] (issue 7: 1e-3).
        dq_noise: Standard deviation of the noise on each measured joint velocity [rad/s]
            (SPEC §4's prototype: 1e-2; 0 for none).
        delay: Measurement delay in control periods (the controller at t_k sees the
            state measured at t_{k-delay}; 0 for none).
        after: Metrics (RMS, max error) are taken over t >= after [s].
        error_bound: A run counts as *bounded* when it completes (no divergence, no
            non-finite value, no solver failure) and its max |q − r| after ``after``
            stays <= error_bound [rad].
        rms_target: The pass mark on the worst joint's RMS error after ``after`` [rad]
            reported in the summary (issue 7: 1e-2).
        variants: Controllers run on every sample, each a controller × compensation
            pair (:func:`parse_combination`: ``"hmpc+momentum"``, a 0.1 name such as
            ``"hmpc-ism"``, a bare controller for its default compensation), or
            ``"ndo"`` (the config's pair; its compensation must be an observer) and
            ``"no-ndo"`` (the config's controller without compensation). Two variants
            that are the same pair are an error. Default: the config's pair and, when it
            has a compensation, the same controller without.
    """

    mass: np.ndarray = field(default_factory=lambda: np.array([0.8, 1.2]))
    friction: np.ndarray = field(default_factory=lambda: np.array([0.5, 2.0]))
    disturbance: np.ndarray = field(default_factory=lambda: np.array([0.5, 2.0]))
    q_noise: float = 1e-3
    dq_noise: float = 1e-2
    delay: int = 1
    after: float = 1.0
    error_bound: float = 1.0
    rms_target: float = 1e-2
    variants: tuple[str, ...] | None = None

    def __post_init__(self):
        for name in ("mass", "friction", "disturbance"):
            _set(self, name, _range(name, getattr(self, name)))
        _set(self, "q_noise", _float("q_noise", self.q_noise, nonneg=True))
        _set(self, "dq_noise", _float("dq_noise", self.dq_noise, nonneg=True))
        _set(self, "delay", _int("delay", self.delay, minimum=0))
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


@dataclass(frozen=True, eq=False)
class RealtimeConfig:
    """The real-time loop of ``hmpc-pin realtime`` (:mod:`hmpc_pin.realtime`).

    Attributes:
        rate: Interface rate [Hz]; ``1/rate`` must divide ``controller.Ts`` and be a whole
            number of ``plant.dt`` (the arm process integrates its plant at that period).
        gc: Garbage-collection handling (freeze after start-up, collect in the slack).
        gc_slack: Minimum slack [s] before the next deadline for a collection.
        damping: Joint damping of the safe torque [N·m·s/rad], one value or per joint.
        gravity: Gravity compensation in the safe torque.
        max_misses: Consecutive missed deadlines that stop the loop (k).
        watchdog: A state stamp that does not advance for this long [s] stops the loop.
        hold: How long the safe torque is refreshed after a stop [s].
        limits: Stop when the measured state leaves the URDF limits widened by
            ``position_margin`` and ``velocity_scale``.
        position_margin: Margin [rad] outside the URDF position limits (with ``limits``).
        velocity_scale: Factor on the URDF velocity limits (with ``limits``).
        priority: ``SCHED_FIFO`` priority (1–99) of the loop and the arm process; 0
            (default) keeps normal scheduling.
        spin: Busy-wait this long [s] before each deadline instead of sleeping (the loop
            is awake at the deadline: no wake-up latency), below ``1/rate``; 0 (default)
            sleeps.
    """

    rate: float = 1000.0
    gc: bool = True
    gc_slack: float = 3e-4
    damping: np.ndarray = 2.0
    gravity: bool = True
    max_misses: int = 10
    watchdog: float = 0.02
    hold: float = 0.1
    limits: bool = True
    position_margin: float | None = None
    velocity_scale: float | None = None
    priority: int = 0
    spin: float = 0.0

    def __post_init__(self):
        _set(self, "rate", _float("rate", self.rate, positive=True))
        _set(self, "spin", _float("spin", self.spin, nonneg=True))
        if self.spin >= 1.0 / self.rate:
            raise ConfigError(
                "spin", f"expected a time [s] below the period 1/rate = {1.0 / self.rate:g} s, "
                f"got {self.spin:g}"
            )
        _set(self, "priority", _int("priority", self.priority, minimum=0))
        if self.priority > 99:
            raise ConfigError("priority", f"expected 0 (off) or 1..99, got {self.priority}")
        _set(self, "gc", _bool("gc", self.gc))
        _set(self, "gc_slack", _float("gc_slack", self.gc_slack, positive=True))
        _set(self, "damping", _array("damping", self.damping, nonneg=True))
        _set(self, "gravity", _bool("gravity", self.gravity))
        _set(self, "max_misses", _int("max_misses", self.max_misses, minimum=1))
        _set(self, "watchdog", _float("watchdog", self.watchdog, positive=True))
        _set(self, "hold", _float("hold", self.hold, nonneg=True))
        _set(self, "limits", _bool("limits", self.limits))
        for name in ("position_margin", "velocity_scale"):
            value = getattr(self, name)
            if value is None:
                continue
            if not self.limits:
                raise ConfigError(name, "does not apply with limits = false; drop it or set "
                                  "limits = true")  # fmt: skip
            _set(self, name, _float(name, value, nonneg=name == "position_margin",
                                    positive=name == "velocity_scale"))  # fmt: skip

    @property
    def margin(self) -> float:
        """``position_margin`` [rad] (default 0.05)."""
        return 0.05 if self.position_margin is None else self.position_margin

    @property
    def scale(self) -> float:
        """``velocity_scale`` (default 1.5)."""
        return 1.5 if self.velocity_scale is None else self.velocity_scale


@dataclass(frozen=True, eq=False)
class ExperimentConfig:
    """A whole experiment: robot, controller, plant, reference, disturbance, run.

    Attributes:
        name: Short name (defaults to the file stem).
        description: Free text, e.g. the paper section reproduced.
        source: The TOML file it was loaded from, if any.
    """

    name: str = "experiment"
    description: str = ""
    robot: RobotConfig = field(default_factory=RobotConfig)
    controller: ControllerConfig = field(default_factory=ControllerConfig)
    plant: PlantConfig = field(default_factory=PlantConfig)
    reference: ReferenceConfig = field(default_factory=ReferenceConfig)
    disturbance: DisturbanceConfig = field(default_factory=DisturbanceConfig)
    simulation: SimulationConfig = field(default_factory=SimulationConfig)
    sweep: SweepConfig = field(default_factory=SweepConfig)
    realtime: RealtimeConfig = field(default_factory=RealtimeConfig)
    source: Path | None = None
    collision: CollisionConfig | None = None

    def __post_init__(self):
        for name in ("name", "description"):
            if not isinstance(getattr(self, name), str):
                raise ConfigError(name, f"expected a string, got {getattr(self, name)!r}")

    def vector(self, key: str, n: int) -> np.ndarray:
        """The dotted ``key`` (e.g. ``"simulation.q0"``) broadcast to ``n`` joints.

        Raises:
            ConfigError: The value is a vector whose length is not ``n``.
        """
        value = self
        for part in key.split("."):
            value = getattr(value, part)
        if value.ndim == 1 and value.shape != (n,):
            raise ConfigError(
                key,
                f"has {value.shape[0]} entries but the robot has {n} joints; "
                f"give {n} values or one value for all joints",
                source=str(self.source) if self.source else None,
            )
        return np.broadcast_to(value, (n,)).astype(float)

    def check_dimensions(self, n: int) -> None:
        """Raise :class:`ConfigError` if any per-joint vector does not have ``n`` entries."""
        keys = ["simulation.dq0", "realtime.damping"]
        if self.simulation.q0 is not None:
            keys.append("simulation.q0")
        if self.reference.kind == "sine":
            keys += [f"reference.{k}" for k in SINE_KEYS]
        wc = self.reference.waypoints
        if self.reference.kind == "waypoints":
            keys.append("reference.waypoints.acceleration_limit")
            if wc.velocity_limit is not None:
                keys.append("reference.waypoints.velocity_limit")
            if wc.points.shape[1] != n:
                raise ConfigError(
                    "reference.waypoints.points", f"has joint vectors of {wc.points.shape[1]} "
                    f"entries but the robot has {n} joints",
                    source=str(self.source) if self.source else None,
                )  # fmt: skip
        if self.reference.kind == "pose" and self.reference.pose.q_init is not None:
            keys.append("reference.pose.q_init")
        if self.disturbance.friction is not None:
            keys += ["disturbance.friction.viscous", "disturbance.friction.coulomb"]
        if self.plant.mujoco is not None:
            keys += [f"plant.mujoco.{k}" for k in ("frictionloss", "damping", "armature")]
        if self.collision is not None:
            keys.append("collision.threshold")
        if self.disturbance.pulse is not None:
            keys += [
                "disturbance.pulse.amplitude",
                "disturbance.pulse.center",
                "disturbance.pulse.sigma",
            ]
        for key in keys:
            self.vector(key, n)
        try:
            self.controller.bounds(n)
        except ConfigError as exc:
            raise ConfigError(
                exc.key, exc.message, source=str(self.source) if self.source else None
            ) from None


# ---------------------------------------------------------------------- loader
def _section(cls, data, prefix: str):
    """Build dataclass ``cls`` from a TOML table, naming keys with ``prefix``."""
    if not isinstance(data, dict):
        raise ConfigError(prefix, f"expected a table, got {type(data).__name__} {data!r}")
    allowed = {f.name for f in fields(cls)} - {"source"}
    unknown = sorted(set(data) - allowed)
    if unknown:
        raise ConfigError(
            f"{prefix}.{unknown[0]}",
            f"unknown key; allowed keys in [{prefix}] are {sorted(allowed)}",
        )
    try:
        return cls(**data)
    except ConfigError as exc:
        key = exc.key if exc.key.startswith(prefix + ".") else f"{prefix}.{exc.key}"
        msg = exc.message
        raise ConfigError(key, msg) from None


def load_config(path: str | Path) -> ExperimentConfig:
    """Load and validate an experiment TOML file.

    Relative URDF paths are resolved against the config file's directory. Only the TOML
    file is read: the robot, and every check that needs it (vector lengths, limits),
    come with :meth:`~hmpc_pin.experiment.build.Experiment.from_config`.

    Raises:
        ConfigError: Missing or unreadable file, invalid TOML, unknown key, wrong
            type or value; the message names the file and the key.
    """
    path = Path(path)
    if not path.is_file() and config_path(str(path)) is not None:
        path = config_path(str(path))  # a packaged config by name, e.g. "paper_combined"
    src = str(path)
    if not path.is_file():
        raise ConfigError(
            "<file>",
            "config file not found; pass a .toml file path or the name of a packaged config "
            f"{config_names()}",
            source=src,
        )
    try:
        raw = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError("<file>", f"cannot be read ({exc})", source=src) from exc
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError("<file>", f"not valid TOML: {exc}", source=src) from exc

    sections = {
        "robot": RobotConfig,
        "controller": ControllerConfig,
        "plant": PlantConfig,
        "reference": ReferenceConfig,
        "disturbance": DisturbanceConfig,
        "simulation": SimulationConfig,
        "sweep": SweepConfig,
        "collision": CollisionConfig,
        "realtime": RealtimeConfig,
    }
    top_allowed = set(sections) | {"name", "description"}
    unknown = sorted(set(raw) - top_allowed)
    if unknown:
        raise ConfigError(
            unknown[0], f"unknown key; allowed top-level keys are {sorted(top_allowed)}", source=src
        )
    kwargs: dict = {"name": raw.get("name", path.stem), "description": raw.get("description", "")}
    try:
        for name, cls in sections.items():
            if name in raw:
                kwargs[name] = _section(cls, raw[name], name)
        base = path.parent
        robot = kwargs.get("robot", RobotConfig())
        if robot.urdf is not None and not robot.urdf.is_absolute():
            robot = replace(robot, urdf=(base / robot.urdf).resolve())
        kwargs["robot"] = robot
        plant = kwargs.get("plant", PlantConfig())
        given = [k for k in ("dt", "integrator") if k in raw.get("plant", {})]
        if plant.engine == "mujoco" and given:
            raise ConfigError(
                f"plant.{given[0]}", "does not apply to engine = 'mujoco'; set "
                f"plant.mujoco.{'timestep' if given[0] == 'dt' else 'integrator'} instead",
            )  # fmt: skip
        if plant.urdf is not None and not plant.urdf.is_absolute():
            plant = replace(plant, urdf=(base / plant.urdf).resolve())
        kwargs["plant"] = plant
        if (
            "collision" in kwargs
            and kwargs.get("controller", ControllerConfig()).compensation not in OBSERVERS
        ):
            raise ConfigError(
                "collision", "needs a disturbance observer (controller.compensation one of "
                f"{OBSERVERS}): the collision is flagged on its estimate",
            )  # fmt: skip
        ref = kwargs.get("reference")
        if ref is not None and ref.trajectory is not None and not ref.trajectory.file.is_absolute():
            traj = replace(ref.trajectory, file=(base / ref.trajectory.file).resolve())
            kwargs["reference"] = replace(ref, trajectory=traj)
        config = ExperimentConfig(**kwargs, source=path)
    except ConfigError as exc:
        raise ConfigError(exc.key, exc.message, source=src) from None

    return config
