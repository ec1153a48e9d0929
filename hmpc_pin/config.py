"""Typed, validated configuration: frozen dataclasses loaded from TOML.

Every controller setting defaults to the paper's value (Section 4), so
``ControllerConfig()`` is the paper's controller. An experiment file
(``configs/*.toml``) has the sections ``[robot]``, ``[controller]``,
``[controller.observer]``, ``[plant]``, ``[reference]``, ``[disturbance]``
(with optional ``[disturbance.friction]`` and ``[disturbance.pulse]``),
``[simulation]`` and ``[sweep]``; see ``configs/paper_combined.toml`` for every key.

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

from .exceptions import ConfigError

__all__ = [
    "CONTROLLER_KINDS",
    "CartesianConfig",
    "ComputedTorqueConfig",
    "ConstraintConfig",
    "ControllerConfig",
    "DisturbanceConfig",
    "ExperimentConfig",
    "FrictionConfig",
    "ISMConfig",
    "ObserverConfig",
    "PlantConfig",
    "PulseConfig",
    "ReferenceConfig",
    "RobotConfig",
    "SimulationConfig",
    "SweepConfig",
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


#: Controller names accepted by ``[controller] kind`` (README, "Controllers").
CONTROLLER_KINDS = (
    "hmpc",
    "hmpc-none",
    "hmpc-momentum",
    "hmpc-ism",
    "hmpc-ism-bl",
    "computed-torque",
    "computed-torque-pid",
)


# -------------------------------------------------------------------- sections
@dataclass(frozen=True, eq=False)
class ObserverConfig:
    """Disturbance observer settings (Section 3.2, Eq 28–30).

    Attributes:
        enabled: Use the observer; ``False`` gives the baseline without NDO (d̂ = 0).
        kind: ``"chen"`` (Y lower-triangular ones, the paper's Eq 28, planar arms),
            ``"general"`` (Y = I, p = c·q̇, any arm for c above
            :func:`~hmpc_pin.observers.general_gain_bound`) or ``"momentum"``
            (generalized-momentum observer, gain K_O [1/s], any arm, any gain > 0).
        gain: Observer gain c (the paper does not give it; 100 is this project's choice, README).
        discretization: ``"implicit"`` (backward Euler, stable for any c) or ``"explicit"``
            (not for ``"momentum"``, which is always semi-implicit).
    """

    enabled: bool = True
    kind: str = "chen"
    gain: float = 100.0
    discretization: str = "implicit"

    def __post_init__(self):
        _set(self, "enabled", _bool("enabled", self.enabled))
        _set(self, "kind", _choice("kind", self.kind, ("chen", "general", "momentum")))
        _set(self, "gain", _float("gain", self.gain, positive=True))
        _set(
            self,
            "discretization",
            _choice("discretization", self.discretization, ("implicit", "explicit")),
        )
        if self.kind == "momentum" and self.discretization != "implicit":
            raise ConfigError(
                "discretization",
                "the momentum observer has only the semi-implicit form; remove the key or "
                "set it to 'implicit'",
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

    def limits(self, robot) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """``(lower, upper, velocity)`` for ``robot``, overrides applied; ``None`` if disabled.

        Disabled parts are ±inf. Raises :class:`ConfigError` if an override has the
        wrong length or ``lower >= upper`` on a joint.
        """
        if not self.enabled:
            return None
        n = robot.nq
        inf = np.full(n, np.inf)

        def pick(name, default):
            value = getattr(self, name)
            if value is None:
                return np.array(default, dtype=float)
            if value.ndim == 1 and value.shape != (n,):
                raise ConfigError(
                    f"controller.constraints.{name}",
                    f"has {value.shape[0]} entries but the robot has {n} joints "
                    f"{robot.joint_names}",
                )
            return np.broadcast_to(value, (n,)).astype(float)

        lower, upper = pick("lower", robot.lower), pick("upper", robot.upper)
        vel = pick("velocity_limit", np.where(robot.velocity_limit > 0, robot.velocity_limit, inf))
        bad = np.flatnonzero(lower >= upper)
        if bad.size:
            i = int(bad[0])
            raise ConfigError(
                "controller.constraints.lower",
                f"joint {robot.joint_names[i]!r}: lower={lower[i]:g} >= upper={upper[i]:g}; "
                "expected lower < upper",
            )
        if not self.position:
            lower, upper = -inf, inf.copy()
        if not self.velocity:
            vel = inf.copy()
        return lower, upper, vel


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
    """Hierarchical MPC settings; every default is the paper's value (Section 4).

    Attributes:
        kind: The controller, one of :data:`CONTROLLER_KINDS` (default ``"hmpc"``, the
            paper's scheme; README "Controllers"). ``"hmpc-none"`` ignores ``observer``,
            ``"hmpc-momentum"`` uses ``observer.gain`` as the momentum observer's K_O,
            the ``hmpc-ism*`` kinds use ``ism`` and no observer, the
            ``computed-torque*`` kinds use ``computed_torque``, the MPC's weights (for
            their default gains) and ``v_min``/``v_max``, and no observer.
        Ts: Control period [s] (paper: 0.01).
        N: Prediction horizon [steps] (paper: 10).
        Nc: Control horizon [steps], 1 <= Nc <= N (paper: 1).
        Q: State weight on [q − r, q̇ − ṙ], diagonal or 2×2 (paper: diag(50, 0)).
        R: Input weight, > 0 (paper: 1e-6).
        P: Terminal weight (paper: 2Q = diag(100, 0)).
        v_min, v_max: Bounds of the commanded acceleration v [rad/s²], scalar or per joint
            (paper: −100, 100).
        observer: :class:`ObserverConfig`.
        constraints: :class:`ConstraintConfig` (joint limits as soft state constraints).
        eps_abs: ProxSuite absolute tolerance.
        max_iter: ProxSuite iteration cap per solve.
        ism: :class:`ISMConfig`.
        computed_torque: :class:`ComputedTorqueConfig`.
        qp_layout: ``"block"`` (the n joint QPs as one block-diagonal ProxSuite QP, one
            solve per step; default, fastest) or ``"joint"`` (one QP per joint). Same
            solution to solver tolerance (tested); ``BENCHMARKS.md`` has the timings.
    """

    kind: str = "hmpc"
    Ts: float = 0.01
    N: int = 10
    Nc: int = 1
    Q: np.ndarray = field(default_factory=lambda: np.diag([50.0, 0.0]))
    R: float = 1e-6
    P: np.ndarray = field(default_factory=lambda: np.diag([100.0, 0.0]))
    v_min: np.ndarray = -100.0
    v_max: np.ndarray = 100.0
    observer: ObserverConfig = field(default_factory=ObserverConfig)
    constraints: ConstraintConfig = field(default_factory=ConstraintConfig)
    eps_abs: float = 1e-9
    max_iter: int = 1000
    qp_layout: str = "block"
    ism: ISMConfig = field(default_factory=ISMConfig)
    computed_torque: ComputedTorqueConfig = field(default_factory=ComputedTorqueConfig)

    def __post_init__(self):
        _set(self, "kind", _choice("kind", self.kind, CONTROLLER_KINDS))
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
        if isinstance(self.observer, dict):
            _set(self, "observer", _section(ObserverConfig, self.observer, "observer"))
        elif not isinstance(self.observer, ObserverConfig):
            raise ConfigError("observer", f"expected a table, got {self.observer!r}")
        for name, cls in (
            ("constraints", ConstraintConfig),
            ("ism", ISMConfig),
            ("computed_torque", ComputedTorqueConfig),
        ):
            value = getattr(self, name)
            if isinstance(value, dict):
                _set(self, name, _section(cls, value, name))
            elif not isinstance(value, cls):
                raise ConfigError(name, f"expected a table, got {value!r}")
        _set(self, "eps_abs", _float("eps_abs", self.eps_abs, positive=True))
        _set(self, "max_iter", _int("max_iter", self.max_iter, minimum=1))
        _set(self, "qp_layout", _choice("qp_layout", self.qp_layout, ("block", "joint")))

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
        model: Instead of ``urdf``, an ``example-robot-data`` name (``"ur5"``, ``"panda"``,
            ``"z1"``, ...); give exactly one of the two.
        gravity: Gravity magnitude [m/s²] along −z (paper: 9.8).
        locked_joints: Joints not controlled, by URDF name → locked position [rad or m]
            (e.g. Panda's fingers); removed with ``pin.buildReducedModel``.
    """

    urdf: Path | None = None
    model: str | None = None
    gravity: float = 9.8
    locked_joints: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.urdf is None and self.model is None:
            _set(self, "urdf", Path("robots/planar3.urdf"))
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
        """The URDF path or the example-robot-data name, as :func:`load_robot` takes it."""
        return self.urdf if self.urdf is not None else self.model

    def load(self, gravity: float | None = None):
        """Load the robot (:func:`~hmpc_pin.robot.load_robot`), optionally with another gravity."""
        from .robot import load_robot

        g = self.gravity if gravity is None else gravity
        return load_robot(self.source, gravity=g, locked_joints=self.locked_joints)


@dataclass(frozen=True, eq=False)
class PlantConfig:
    """The simulated plant.

    Attributes:
        urdf: URDF of the plant; ``None`` uses the controller's model (no mismatch).
        gravity: Plant gravity [m/s²]; ``None`` uses the robot's.
        dt: Integration step [s], must divide the control period (default 1 ms).
        integrator: ``"rk4"`` (default) or ``"euler"`` (semi-implicit).
        saturate: Clip the applied torque to the effort limits (default ``True``).
        effort_limit: Effort limits [N·m] overriding the URDF's (per joint or one value);
            ``None`` keeps the URDF's (a URDF value <= 0 means no limit).
    """

    urdf: Path | None = None
    gravity: float | None = None
    dt: float = 0.001
    integrator: str = "rk4"
    saturate: bool = True
    effort_limit: np.ndarray | None = None

    def __post_init__(self):
        if self.urdf is not None:
            if not isinstance(self.urdf, (str, Path)):
                raise ConfigError("urdf", f"expected a path string, got {self.urdf!r}")
            _set(self, "urdf", Path(self.urdf))
        if self.gravity is not None:
            _set(self, "gravity", _float("gravity", self.gravity, nonneg=True))
        _set(self, "dt", _float("dt", self.dt, positive=True))
        _set(self, "integrator", _choice("integrator", self.integrator, ("rk4", "euler")))
        _set(self, "saturate", _bool("saturate", self.saturate))
        if self.effort_limit is not None:
            _set(self, "effort_limit", _array("effort_limit", self.effort_limit, positive=True))


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


SINE_KEYS = ("amplitude", "frequency", "offset", "phase")
SINE_DEFAULTS = {"amplitude": 1.0, "frequency": 0.1, "offset": 0.0, "phase": 0.0}


@dataclass(frozen=True, eq=False)
class ReferenceConfig:
    """Joint reference: the sine of Eq (31) or the Cartesian motion of Section 5.4.

    ``kind = "sine"``: :math:`r_i = o_i + a_i \\sin(2\\pi f_i t + \\phi_i)`.

    Attributes:
        kind: ``"sine"`` or ``"cartesian"`` (then the ``cartesian`` table is required
            and the sine keys must not be given).
        amplitude: a [rad] (paper: 1), scalar or per joint.
        frequency: f [Hz] (paper: 0.1, i.e. 0.2π rad/s).
        offset: o [rad] (paper: 0).
        phase: φ [rad] (paper: 0).
        cartesian: :class:`CartesianConfig` for ``kind = "cartesian"``.
    """

    kind: str = "sine"
    amplitude: np.ndarray | None = None
    frequency: np.ndarray | None = None
    offset: np.ndarray | None = None
    phase: np.ndarray | None = None
    cartesian: CartesianConfig | None = None

    def __post_init__(self):
        _set(self, "kind", _choice("kind", self.kind, ("sine", "cartesian")))
        if self.kind == "cartesian":
            given = [k for k in SINE_KEYS if getattr(self, k) is not None]
            if given:
                raise ConfigError(
                    given[0], "applies only to kind = 'sine'; remove it for kind = 'cartesian'"
                )
            if isinstance(self.cartesian, dict):
                _set(self, "cartesian", _section(CartesianConfig, self.cartesian, "cartesian"))
            elif self.cartesian is None:
                raise ConfigError(
                    "cartesian", "kind = 'cartesian' needs a [reference.cartesian] table"
                )
            return
        if self.cartesian is not None:
            raise ConfigError("cartesian", "applies only to kind = 'cartesian'")
        for key in SINE_KEYS:
            value = getattr(self, key)
            _set(self, key, _array(key, SINE_DEFAULTS[key] if value is None else value))
        if np.any(self.frequency < 0):
            raise ConfigError("frequency", f"expected values >= 0, got {self.frequency.tolist()}")


@dataclass(frozen=True, eq=False)
class FrictionConfig:
    """Coulomb–viscous friction, Eq (32), opposing motion (SPEC §3).

    Attributes:
        viscous: a [N·m·s/rad] (paper: 10, 8, 5).
        coulomb: b [N·m] (paper: 3.0, 2.4, 1.8).
    """

    viscous: np.ndarray = field(default_factory=lambda: np.array([10.0, 8.0, 5.0]))
    coulomb: np.ndarray = field(default_factory=lambda: np.array([3.0, 2.4, 1.8]))

    def __post_init__(self):
        _set(self, "viscous", _array("viscous", self.viscous, nonneg=True))
        _set(self, "coulomb", _array("coulomb", self.coulomb, nonneg=True))


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
        friction: Factor range per joint on the viscous and Coulomb coefficients
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
        variants: Controller variants run on every sample: ``"ndo"``, ``"no-ndo"`` (the
            config's controller with its observer on/off) or any controller name of
            :data:`CONTROLLER_KINDS` (see :data:`hmpc_pin.sweep.VARIANTS`).
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
    variants: tuple[str, ...] = ("ndo", "no-ndo")

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
    source: Path | None = None

    def __post_init__(self):
        for name in ("name", "description"):
            if not isinstance(getattr(self, name), str):
                raise ConfigError(name, f"expected a string, got {getattr(self, name)!r}")
        Ts, dt = self.controller.Ts, self.plant.dt
        substeps = round(Ts / dt)
        if substeps < 1 or abs(substeps * dt - Ts) > 1e-9 * Ts:
            raise ConfigError(
                "plant.dt",
                f"dt={dt:g} does not divide the control period controller.Ts={Ts:g}; "
                "expected Ts / dt to be a whole number >= 1",
            )

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
        keys = ["simulation.dq0"]
        if self.simulation.q0 is not None:
            keys.append("simulation.q0")
        if self.reference.kind == "sine":
            keys += [f"reference.{k}" for k in SINE_KEYS]
        if self.disturbance.friction is not None:
            keys += ["disturbance.friction.viscous", "disturbance.friction.coulomb"]
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

    Relative URDF paths are resolved against the config file's directory. The
    controller's robot is loaded once to check every per-joint vector's length.

    Raises:
        ConfigError: Missing or unreadable file, invalid TOML, unknown key, wrong
            type or value; the message names the file and the key.
        URDFError: The robot's URDF is invalid.
    """
    path = Path(path)
    src = str(path)
    if not path.is_file():
        raise ConfigError("<file>", "config file not found; pass a .toml file path", source=src)
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
        if plant.urdf is not None and not plant.urdf.is_absolute():
            plant = replace(plant, urdf=(base / plant.urdf).resolve())
        kwargs["plant"] = plant
        config = ExperimentConfig(**kwargs, source=path)
    except ConfigError as exc:
        raise ConfigError(exc.key, exc.message, source=src) from None

    try:
        robot = config.robot.load()
        config.check_dimensions(robot.nq)
        config.controller.constraints.limits(robot)
        if config.plant.effort_limit is not None:
            config.vector("plant.effort_limit", robot.nq)
    except ConfigError as exc:
        raise ConfigError(exc.key, exc.message, source=src) from None
    return config
