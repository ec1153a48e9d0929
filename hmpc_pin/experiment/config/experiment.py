"""The whole experiment (:class:`ExperimentConfig`) and :func:`load_config`, which reads
a TOML file table by table."""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ...data import config_names, config_path
from ...exceptions import ConfigError
from ...sim.engines import engine_spec
from ..combos import OBSERVERS
from ._fields import _section
from .collision import CollisionConfig
from .controller import ControllerConfig
from .disturbance import DisturbanceConfig
from .plant import PlantConfig
from .realtime import RealtimeConfig
from .reference import SINE_KEYS, ReferenceConfig
from .robot import RobotConfig
from .ros import RosConfig
from .simulation import SimulationConfig
from .sweep import SweepConfig
from .workspace import WorkspaceConfig


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
    ros: RosConfig = field(default_factory=RosConfig)
    workspace: WorkspaceConfig | None = None

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
        keys = ["simulation.dq0"]
        if self.realtime.damping is not None:
            keys.append("realtime.damping")
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
                    "reference.waypoints.points",
                    f"has joint vectors of {wc.points.shape[1]} "
                    f"entries but the robot has {n} joints",
                    source=str(self.source) if self.source else None,
                )
        if self.reference.kind == "pose" and self.reference.pose.q_init is not None:
            keys.append("reference.pose.q_init")
        if self.disturbance.friction is not None:
            keys += ["disturbance.friction.viscous", "disturbance.friction.coulomb"]
        if self.plant.mujoco is not None:
            keys += [f"plant.mujoco.{k}" for k in ("frictionloss", "damping", "armature")]
        if self.collision is not None:
            keys.append("collision.threshold")
        if self.controller.friction is not None:
            keys += ["controller.friction.viscous", "controller.friction.coulomb"]
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


def _urdf_path(key: str, given: Path, base: Path) -> Path:
    """The URDF ``given`` under ``key``, resolved against the config's folder ``base``
    (an absolute path is kept); a file that is not there is a :class:`ConfigError`
    naming the key, the path tried and what to write instead (a config moved without its
    URDF, or copied out of the repository)."""
    resolved = given if given.is_absolute() else (base / given).resolve()
    if resolved.is_file():
        return resolved
    if resolved.exists():
        raise ConfigError(
            key,
            f"{str(given)!r} is not a file ({resolved} is a directory); "
            "give the path of a .urdf file",
        )
    hints = []
    beside = base / given.name
    if beside.is_file() and beside.resolve() != resolved:
        hints.append(
            f'{given.name} is next to the config: write {key.split(".")[1]} = "{given.name}"'
        )
    cwd = Path.cwd() / given
    if not given.is_absolute() and cwd.is_file():
        hints.append(
            f"it exists relative to the current directory ({cwd}), but a relative "
            "path is relative to the config file's folder"
        )
    if _shipped_robot(given.stem):
        hints.append(
            f'for the robot shipped with hmpc_pin write model = "{given.stem}" instead of urdf'
        )
    else:
        hints.append(
            "give an existing .urdf (absolute, or relative to the config file), or "
            'model = "planar3" (or an example-robot-data name) for a shipped '
            "robot"
        )
    raise ConfigError(
        key,
        f"{str(given)!r} not found: tried {resolved} (relative paths are relative to the "
        f"config file's folder, {base.resolve()}); " + "; ".join(hints),
    )


def _shipped_robot(name: str) -> bool:
    """Whether ``name`` is a robot ``model =`` loads (shipped, or example-robot-data)."""
    from ...data import robot_path

    if robot_path(name) is not None:
        return True
    try:
        from ...model.robot import example_robot_names

        return name in example_robot_names()
    except ImportError:  # pragma: no cover - a dependency of the package
        return False


def _not_text(path: Path) -> str:
    """What a config path that is not UTF-8 text is instead (a saved run, another binary)."""
    try:
        with path.open("rb") as f:
            head = f.read(4)
    except OSError:
        head = b""
    if head == b"PK\x03\x04" or path.suffix.lower() == ".npz":
        return (
            "is an .npz archive (a saved run or trajectory), not an experiment config; pass "
            "the .toml file the run was made from, or a packaged config's name "
            "(`hmpc-pin configs`)"
        )
    return (
        "is not a text file (not UTF-8); expected an experiment config in TOML "
        "(`hmpc-pin init ROBOT` writes one, `hmpc-pin configs` lists the packaged ones)"
    )


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
            "",
            "config file not found; pass a .toml file path or the name of a packaged config "
            f"{config_names()}",
            source=src,
        )
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise ConfigError("", _not_text(path), source=src) from None
    except OSError as exc:
        raise ConfigError("", f"cannot be read ({exc})", source=src) from exc
    if text.startswith("PK\x03\x04"):  # a zip (.npz) that happens to decode
        raise ConfigError("", _not_text(path), source=src)
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        if path.suffix.lower() in (".urdf", ".xml") or text.lstrip().startswith("<"):
            raise ConfigError(
                "",
                "is a robot description (URDF/XML), not an experiment config; "
                f"write a config for this arm with `hmpc-pin init {path}` and pass the "
                ".toml file it writes",
                source=src,
            ) from exc
        raise ConfigError("", f"not valid TOML: {exc}", source=src) from exc

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
        "ros": RosConfig,
        "workspace": WorkspaceConfig,
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
        if robot.urdf is not None:
            robot = replace(robot, urdf=_urdf_path("robot.urdf", robot.urdf, base))
        kwargs["robot"] = robot
        plant = kwargs.get("plant", PlantConfig())
        engine = engine_spec(plant.engine)
        given = [k for k in engine.replaces if k in raw.get("plant", {})]
        if given:
            raise ConfigError(
                f"plant.{given[0]}",
                f"does not apply to engine = {engine.name!r}; set "
                f"plant.{engine.table}.{engine.replaces[given[0]]} instead",
            )
        if plant.urdf is not None:
            plant = replace(plant, urdf=_urdf_path("plant.urdf", plant.urdf, base))
        kwargs["plant"] = plant
        if (
            "collision" in kwargs
            and kwargs.get("controller", ControllerConfig()).compensation not in OBSERVERS
        ):
            raise ConfigError(
                "collision",
                "needs a disturbance observer (controller.compensation one of "
                f"{OBSERVERS}): the collision is flagged on its estimate",
            )
        ref = kwargs.get("reference")
        if ref is not None and ref.trajectory is not None and not ref.trajectory.file.is_absolute():
            traj = replace(ref.trajectory, file=(base / ref.trajectory.file).resolve())
            kwargs["reference"] = replace(ref, trajectory=traj)
        config = ExperimentConfig(**kwargs, source=path)
    except ConfigError as exc:
        raise ConfigError(exc.key, exc.message, source=src) from None

    return config
