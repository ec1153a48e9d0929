"""``[plant]``, ``[plant.mujoco]`` and ``[plant.mujoco.obstacle]``: the simulated arm."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...exceptions import ConfigError
from ...native import BACKENDS
from ...sim.engines import DEFAULT_ENGINE, engine_spec
from ...sim.engines import ENGINES as ENGINE_REGISTRY
from ...sim.mujoco_settings import GEOMETRY_SOURCES, MUJOCO_INTEGRATORS
from ...sim.plants import COULOMB_LAWS, PLANTS
from ._fields import _array, _bool, _choice, _float, _section, _set

#: Physics engines of the plant (``[plant] engine``): the names of the engine registry
#: (:data:`~hmpc_pin.sim.engines.ENGINES`).
ENGINES = tuple(ENGINE_REGISTRY)
#: Integrators of the Pinocchio plant (``[plant] integrator``): the plants of
#: :data:`~hmpc_pin.sim.plants.PLANTS` that integrate Pinocchio's ABA.
PINOCCHIO_INTEGRATORS = tuple(
    name
    for name, cls in PLANTS.items()
    if engine_spec(getattr(cls, "engine", DEFAULT_ENGINE)).integrated
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
        friction_timeconst: Time constant [s] of MuJoCo's joint dry-friction constraint
            (``dof_solref``; default: MuJoCo's 0.02 s). Shorter is closer to Coulomb's
            :math:`-f\\,\\mathrm{sgn}\\,\\dot q`; at least twice ``timestep``.
        import_urdf_dynamics: Deprecated since 0.3: use ``[plant] joint_dynamics`` (the
            same switch for every engine). Loads with a :class:`DeprecationWarning` and
            sets ``plant.joint_dynamics``.
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
    friction_timeconst: float | None = None
    import_urdf_dynamics: bool | None = None
    geometry: str = "collision"
    obstacle: ObstacleConfig | None = None

    def __post_init__(self):
        _set(self, "integrator", _choice("integrator", self.integrator, tuple(MUJOCO_INTEGRATORS)))
        _set(self, "timestep", _float("timestep", self.timestep, positive=True))
        if self.friction_timeconst is not None:
            tc = _float("friction_timeconst", self.friction_timeconst, positive=True)
            if tc < 2 * self.timestep:
                raise ConfigError(
                    "friction_timeconst",
                    f"{tc:g} s is below 2 timesteps "
                    f"({2 * self.timestep:g} s), where MuJoCo's soft constraint is unstable; "
                    "expected at least twice plant.mujoco.timestep",
                )
            _set(self, "friction_timeconst", tc)
        for name in ("frictionloss", "damping", "armature"):
            _set(self, name, _array(name, getattr(self, name), nonneg=True))
        if self.import_urdf_dynamics is not None:
            _set(
                self,
                "import_urdf_dynamics",
                _bool("import_urdf_dynamics", self.import_urdf_dynamics),
            )
        _set(self, "geometry", _choice("geometry", self.geometry, GEOMETRY_SOURCES))
        if isinstance(self.obstacle, dict):
            _set(self, "obstacle", _section(ObstacleConfig, self.obstacle, "obstacle"))
        elif self.obstacle is not None and not isinstance(self.obstacle, ObstacleConfig):
            raise ConfigError("obstacle", f"expected a table, got {self.obstacle!r}")
        if self.obstacle is not None and self.geometry == "none":
            raise ConfigError(
                "geometry",
                "'none' leaves the arm without geometry to touch the obstacle; "
                "use 'collision' or 'visual'",
            )


@dataclass(frozen=True, eq=False)
class PlantConfig:
    """The simulated plant.

    Attributes:
        engine: ``"pinocchio"`` (default: Pinocchio's ABA on the plant model, integrated
            by ``integrator``) or ``"mujoco"`` (MuJoCo on the same URDF; then
            ``[plant.mujoco]`` holds its settings and ``dt``/``integrator`` do not apply).
        urdf: URDF of the plant; ``None`` uses the controller's model (no mismatch).
        gravity: Plant gravity [m/s²]; ``None`` uses the robot's.
        dt: Integration step [s], must divide the control period (default 1 ms; with
            ``tolerance``: ``None``, the step is chosen; give one or the other).
        tolerance: Choose the step by its error instead of ``dt`` [rad]: the largest
            step :math:`T_s/m` (m = 1, 2, ...) whose error over the run stays within it,
            the error of each period against the half step (step doubling) on
            :math:`\\max(|\\Delta q|, T_s |\\Delta\\dot q|)`, the worst one times the run's
            periods (:func:`~hmpc_pin.sim.plants.choose_step`), on a calibration along the
            reference made once, when the experiment's first plant is built: the step is then fixed,
            so a run is reproducible and pays nothing per period. For batch work (sweeps,
            tuning), where a coarser step that keeps the accuracy saves time. ``None``
            (default): the fixed ``dt``. Pinocchio plants only.
        integrator: ``"rk4"`` (default) or ``"euler"`` (semi-implicit).
        coulomb: How the RK4 plant integrates the Coulomb friction (the URDF's and the
            ``[disturbance.friction]`` term's): ``"stick-slip"`` (default: the velocity's
            sign changes located within a step, a joint at rest held while the torque on it
            is within the Coulomb level, so that RK4 keeps its fourth order) or ``"sign"``
            (:math:`\\mathrm{sgn}\\,\\dot q` per stage, first order at a sign change, as
            versions before 0.3). ``integrator = "rk4"`` only.
        saturate: Clip the applied torque to the effort limits (default ``True``).
        effort_limit: Effort limits [N·m] overriding the URDF's (per joint or one value);
            ``None`` keeps the URDF's (a URDF value <= 0 means no limit).
        mujoco: :class:`MuJoCoConfig` (``engine = "mujoco"`` only).
        joint_dynamics: Apply the URDF's ``<dynamics damping friction>`` of every joint:
            viscous damping :math:`-b\\dot q` [N·m·s/rad] and Coulomb friction
            :math:`-f\\,\\mathrm{sgn}\\,\\dot q` [N·m] (MuJoCo: ``dof_damping`` and the
            ``frictionloss`` constraint, added to ``[plant.mujoco]``'s own). Default
            ``true``; ``false`` simulates the arm without them.
        backend: Deprecated since 0.3, without effect (``integrator = "rk4"`` only): the
            period is always the compiled one; ``"python"`` loads with a
            :class:`DeprecationWarning`.
    """

    urdf: Path | None = None
    gravity: float | None = None
    dt: float | None = None
    integrator: str = "rk4"
    saturate: bool = True
    effort_limit: np.ndarray | None = None
    engine: str = DEFAULT_ENGINE
    mujoco: MuJoCoConfig | None = None
    backend: str = "auto"
    joint_dynamics: bool = True
    tolerance: float | None = None
    coulomb: str = "stick-slip"

    def __post_init__(self):
        if self.urdf is not None:
            if not isinstance(self.urdf, (str, Path)):
                raise ConfigError("urdf", f"expected a path string, got {self.urdf!r}")
            _set(self, "urdf", Path(self.urdf))
        if self.gravity is not None:
            _set(self, "gravity", _float("gravity", self.gravity, nonneg=True))
        if self.tolerance is not None:
            _set(self, "tolerance", _float("tolerance", self.tolerance, positive=True))
            if self.dt is not None:
                raise ConfigError(
                    "tolerance",
                    f"and plant.dt = {self.dt!r} are both given: the tolerance chooses the "
                    "step; expected one of them (remove plant.dt to choose by the error)",
                )
        else:  # (with a tolerance, dt stays None: the plant's step is chosen when built)
            _set(self, "dt", _float("dt", 0.001 if self.dt is None else self.dt, positive=True))
        _set(self, "integrator", _choice("integrator", self.integrator, PINOCCHIO_INTEGRATORS))
        _set(self, "coulomb", _choice("coulomb", self.coulomb, COULOMB_LAWS))
        _set(self, "saturate", _bool("saturate", self.saturate))
        if self.effort_limit is not None:
            _set(self, "effort_limit", _array("effort_limit", self.effort_limit, positive=True))
        _set(self, "engine", _choice("engine", self.engine, ENGINES))
        if isinstance(self.mujoco, dict):
            _set(self, "mujoco", _section(MuJoCoConfig, self.mujoco, "mujoco"))
        elif self.mujoco is not None and not isinstance(self.mujoco, MuJoCoConfig):
            raise ConfigError("mujoco", f"expected a table, got {self.mujoco!r}")
        _set(self, "backend", _choice("backend", self.backend, BACKENDS))
        _set(self, "joint_dynamics", _bool("joint_dynamics", self.joint_dynamics))
        old = self.mujoco.import_urdf_dynamics if isinstance(self.mujoco, MuJoCoConfig) else None
        if old is not None:
            if not self.joint_dynamics and old:
                raise ConfigError(
                    "mujoco.import_urdf_dynamics",
                    "is true but plant.joint_dynamics is false; "
                    "remove the deprecated key and keep plant.joint_dynamics",
                )
            warnings.warn(
                "plant.mujoco.import_urdf_dynamics is deprecated since 0.3; use "
                f"plant.joint_dynamics = {str(old).lower()} (one switch for every engine)",
                DeprecationWarning,
                stacklevel=2,
            )
            _set(self, "joint_dynamics", old)
        engine = engine_spec(self.engine)
        if self.backend != "auto" and (not engine.integrated or self.integrator != "rk4"):
            raise ConfigError(
                "backend",
                f"does not apply to engine = {self.engine!r}, integrator = "
                f"{self.integrator!r} (only the Pinocchio RK4 plant has a compiled path); "
                "remove it",
            )
        if engine.table != "mujoco" and self.mujoco is not None:
            raise ConfigError(
                "mujoco",
                "applies only to engine = 'mujoco'; remove the table "
                "or set plant.engine = 'mujoco'",
            )
        if self.tolerance is not None and not engine.integrated:
            raise ConfigError(
                "tolerance",
                f"does not apply to engine = {self.engine!r} (its step is fixed: "
                "plant.mujoco.timestep); expected engine = 'pinocchio', or remove it",
            )
        if self.coulomb != "stick-slip" and (not engine.integrated or self.integrator != "rk4"):
            raise ConfigError(
                "coulomb",
                f"does not apply to engine = {self.engine!r}, integrator = "
                f"{self.integrator!r} (only the Pinocchio RK4 plant has the choice); remove it",
            )
        if engine.table == "mujoco":
            if self.mujoco is None:
                _set(self, "mujoco", MuJoCoConfig())
            defaults = {"dt": 0.001, "integrator": "rk4"}
            for key, instead in engine.replaces.items():
                if getattr(self, key) != defaults[key]:
                    raise ConfigError(
                        key,
                        f"does not apply to engine = {engine.name!r}; set "
                        f"plant.{engine.table}.{instead} instead",
                    )
