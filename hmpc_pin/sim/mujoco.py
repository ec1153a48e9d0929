"""MuJoCo as the plant: a second physics engine on the same URDF as the controller's model.

The plant of :mod:`~hmpc_pin.sim.plants` integrates the controller's own Pinocchio model (ABA), with
friction an added formula. :class:`MuJoCoPlant` instead compiles the arm's URDF with
MuJoCo (``MjSpec``) and steps it with MuJoCo's integrator, so that the arm's joint
friction (``frictionloss``, a dry-friction constraint), viscous damping, rotor armature,
joint-limit constraints and contacts with an obstacle are properties of the simulated
arm, computed by another engine than the controller's model. Per MuJoCo step of
``h = dt`` with the torque :math:`\\tau` held over the control period:

.. math::

    M(q)\\ddot q + C(q,\\dot q)\\dot q + G(q) = \\tau + d(t, q, \\dot q)
        + \\tau_\\mathrm{passive} + J_c^T f_c + \\tau_\\mathrm{friction}
        + \\tau_\\mathrm{limit}, \\qquad (1)

where :math:`d` is the config's ``[disturbance]`` (applied as the generalized force
``qfrc_applied``), :math:`\\tau_\\mathrm{passive} = -D\\dot q` the joint damping and the
three constraint terms (contacts, dry joint friction, joint limits) MuJoCo's soft
constraint solver. Everything beyond :math:`\\tau + d` is what the controller's model
does not know: :meth:`MuJoCoPlant.disturbance_now` reports it with :math:`d`, the
total the disturbance observer estimates, and :attr:`MuJoCoPlant.contact_force`
the contact part :math:`J_c^T f_c` alone.

The URDF is made consistent with the controller's model before MuJoCo sees it:

* ``package://`` and relative mesh paths are resolved to files (MuJoCo's URDF reader
  does not know ROS packages), or meshes left out (``geometry = "none"``);
* locked joints (``[robot] locked_joints``) become fixed joints at their locked
  position, as ``pin.buildReducedModel`` does;
* ``<mimic>``: a follower the controller's model makes Pinocchio's mimic joint of its
  leader (:attr:`~hmpc_pin.model.robot.Robot.mimic_joints`) keeps the tag, which MuJoCo
  turns into a joint equality constraint :math:`q_f = m q_l + o`, made stiff (see
  :func:`mujoco_model`); a follower the controller controls as an independent coordinate
  loses it; a locked follower is fixed with its leader;
* ``<dynamics damping friction>``: imported as ``dof_damping`` and ``dof_frictionloss``
  of the joint's dof (matched by name) unless ``import_urdf_dynamics = False``, as the
  Pinocchio plants apply them (:attr:`~hmpc_pin.model.robot.Robot.joint_damping`);
* the joints are matched to the controller's by name, not by order.

``mujoco`` is an optional dependency (extra ``mujoco``); it is imported when a plant is
built.
"""

from __future__ import annotations

import copy
import functools
import math
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..exceptions import ConfigError, DimensionError, ExtraError, URDFError
from ..model.robot import Robot
from .disturbances import ZeroDisturbance
from .plants import PLANTS, _substeps, held_torque, split_disturbance

__all__ = [
    "MUJOCO_INTEGRATORS",
    "MuJoCoPlant",
    "MuJoCoSettings",
    "Obstacle",
    "import_mujoco",
    "mujoco_model",
    "mujoco_version",
    "urdf_for_mujoco",
]

FloatArray = NDArray[np.float64]

#: ``[plant.mujoco] integrator`` names → MuJoCo's ``mjtIntegrator`` member names.
MUJOCO_INTEGRATORS = {
    "euler": "mjINT_EULER",
    "rk4": "mjINT_RK4",
    "implicit": "mjINT_IMPLICIT",
    "implicitfast": "mjINT_IMPLICITFAST",
}
#: ``[plant.mujoco] geometry``: which URDF geometry becomes MuJoCo's collision geometry.
GEOMETRY_SOURCES = ("collision", "visual", "none")
#: Mesh formats MuJoCo reads.
MESH_SUFFIXES = (".stl", ".obj", ".msh")
#: MuJoCo's ``solref``/``solimp`` of a mimic equality: the stiffest MuJoCo's soft
#: constraints allow (time constant 2 ms, impedance 0.9999: the constrained acceleration
#: is met to a relative 1e-4), closest to Pinocchio's exact mimic joint.
MIMIC_TIMECONST = 0.002
MIMIC_SOLIMP = (0.9999, 0.9999, 0.001, 0.5, 2.0)
#: Collision bits: arm geoms collide with the obstacle only, never with each other.
ARM_CONTYPE, ARM_CONAFFINITY = 1, 0
OBSTACLE_CONTYPE, OBSTACLE_CONAFFINITY = 0, 1


def import_mujoco():
    """The ``mujoco`` module, or :class:`~hmpc_pin.exceptions.ExtraError` naming the extra."""
    try:
        import mujoco
    except ImportError as exc:
        raise ExtraError("mujoco", "the MuJoCo plant (plant.engine = 'mujoco')") from exc
    return mujoco


def mujoco_version() -> str:
    """The installed MuJoCo version (for the result's metadata)."""
    return str(import_mujoco().__version__)


@dataclass(frozen=True)
class Obstacle:
    """A fixed box in the world the arm can touch (a wall or a table).

    Attributes:
        position: Centre of the box in the world frame [m], (3,).
        size: Half-lengths of the box along the world x, y, z axes [m], (3,) (MuJoCo's
            box ``size``).
        friction: Sliding friction coefficient of the contact [-].
        solref: MuJoCo's contact ``solref`` (time constant [s], damping ratio [-]): the
            softness of the surface (MuJoCo's default 0.02, 1; larger is softer, e.g. a
            padded surface). The obstacle's values are the contact's (geom priority).
    """

    position: tuple[float, float, float]
    size: tuple[float, float, float]
    friction: float = 0.5
    solref: tuple[float, float] = (0.02, 1.0)

    def __post_init__(self):
        for name in ("position", "size"):
            value = np.asarray(getattr(self, name), dtype=float)
            if value.shape != (3,) or not np.all(np.isfinite(value)):
                raise ConfigError(name, f"expected 3 finite numbers [x, y, z], got {value!r}")
            if name == "size" and np.any(value <= 0):
                raise ConfigError(name, f"expected half-lengths > 0, got {value.tolist()}")
            object.__setattr__(self, name, tuple(float(x) for x in value))
        if not (math.isfinite(self.friction) and self.friction >= 0):
            raise ConfigError("friction", f"expected a number >= 0, got {self.friction!r}")
        sr = np.asarray(self.solref, dtype=float)
        if sr.shape != (2,) or not np.all(np.isfinite(sr)) or np.any(sr <= 0):
            raise ConfigError(
                "solref", f"expected [time constant > 0, damping ratio > 0], got {sr!r}"
            )
        object.__setattr__(self, "solref", (float(sr[0]), float(sr[1])))


@dataclass(frozen=True)
class MuJoCoSettings:
    """What the MuJoCo plant adds to the URDF (everything defaults to the bare arm).

    Attributes:
        integrator: One of :data:`MUJOCO_INTEGRATORS` (default ``"implicitfast"``).
        frictionloss: Dry joint friction [N·m], one value or one per joint (controller
            order), MuJoCo's ``dof_frictionloss``.
        damping: Viscous joint damping [N·m·s/rad], ``dof_damping``.
        armature: Rotor inertia added to the joint [kg·m²], ``dof_armature``.
        friction_timeconst: Time constant [s] of the joints' dry-friction constraint (the
            controlled dofs' ``dof_solref``, damping ratio 1); ``None`` (default) keeps
            MuJoCo's 0.02 s. MuJoCo's ``frictionloss`` is a soft constraint: on a joint of
            small inertia or fast damping its force stays far below ``f`` at the speeds of a
            run unless this is short (2 timesteps is MuJoCo's shortest advisable value).
        import_urdf_dynamics: Keep the URDF's ``<dynamics damping friction>`` (added to
            the values above; default ``True``, as the Pinocchio plants apply them);
            ``False`` drops them.
        geometry: ``"collision"`` (the URDF's collision geometry, default), ``"visual"``
            (its visual geometry used for collisions, e.g. for an arm without collision
            tags) or ``"none"`` (no geometry: dynamics only).
        obstacle: An :class:`Obstacle`, or ``None`` (then contacts are switched off).
        package_dirs: Extra directories searched for ``package://`` names.
    """

    integrator: str = "implicitfast"
    frictionloss: float | tuple[float, ...] = 0.0
    damping: float | tuple[float, ...] = 0.0
    armature: float | tuple[float, ...] = 0.0
    friction_timeconst: float | None = None
    import_urdf_dynamics: bool = True
    geometry: str = "collision"
    obstacle: Obstacle | None = None
    package_dirs: tuple[str, ...] = field(default_factory=tuple)

    def __post_init__(self):
        if self.integrator not in MUJOCO_INTEGRATORS:
            raise ConfigError(
                "integrator",
                f"expected one of {tuple(MUJOCO_INTEGRATORS)}, got {self.integrator!r}",
            )
        if self.geometry not in GEOMETRY_SOURCES:
            raise ConfigError(
                "geometry", f"expected one of {GEOMETRY_SOURCES}, got {self.geometry!r}"
            )
        if self.obstacle is not None and self.geometry == "none":
            raise ConfigError(
                "geometry",
                "'none' leaves the arm without geometry, so it cannot touch the obstacle; "
                "use 'collision' or 'visual'",
            )
        tc = self.friction_timeconst
        if tc is not None and not (isinstance(tc, (int, float)) and math.isfinite(tc) and tc > 0):
            raise ConfigError("friction_timeconst", f"expected a time [s] > 0, got {tc!r}")
        for name in ("frictionloss", "damping", "armature"):
            value = np.asarray(getattr(self, name), dtype=float)
            if value.ndim > 1 or not np.all(np.isfinite(value)) or np.any(value < 0):
                raise ConfigError(
                    name, f"expected numbers >= 0 (one or one per joint), got {value!r}"
                )

    def per_joint(self, name: str, n: int) -> np.ndarray:
        """``frictionloss``, ``damping`` or ``armature`` broadcast to ``n`` joints."""
        value = np.asarray(getattr(self, name), dtype=float)
        if value.ndim == 1 and value.shape != (n,):
            raise ConfigError(
                name,
                f"has {value.shape[0]} entries but the robot has {n} joints; give {n} "
                "values or one value for all joints",
            )
        return np.broadcast_to(value, (n,)).astype(float)


# ------------------------------------------------------------------------- URDF
def _package_roots(urdf: Path, package: str, extra: tuple[str, ...]) -> list[Path]:
    """Directories that may hold ``package://<package>/...``: the URDF's ancestors named
    ``package`` or holding it, ``extra`` and ``ROS_PACKAGE_PATH`` entries."""
    found = []
    for parent in urdf.resolve().parents:
        if parent.name == package:
            found.append(parent)
        if (parent / package).is_dir():
            found.append(parent / package)
    dirs = [*extra, *os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep)]
    for d in filter(None, dirs):
        base = Path(d)
        found += [p for p in (base / package, base) if p.is_dir() and (p.name == package)]
    return found


def resolve_mesh_path(filename: str, urdf: Path, package_dirs: tuple[str, ...] = ()) -> Path:
    """The file a URDF mesh ``filename`` names (``package://``, ``file://`` or relative).

    Raises:
        URDFError: No such file, naming the mesh and the URDF.
    """
    if filename.startswith("package://"):
        package, _, rel = filename[len("package://") :].partition("/")
        for root in _package_roots(urdf, package, package_dirs):
            if (root / rel).is_file():
                return (root / rel).resolve()
        raise URDFError(
            urdf,
            f"mesh {filename!r} not found: no directory of package {package!r} holding "
            f"{rel!r} above the URDF or in ROS_PACKAGE_PATH; add its parent directory to "
            "ROS_PACKAGE_PATH or use [plant.mujoco] geometry = 'none'",
        )
    path = Path(filename[len("file://") :] if filename.startswith("file://") else filename)
    path = path if path.is_absolute() else urdf.parent / path
    if not path.is_file():
        raise URDFError(
            urdf,
            f"mesh {filename!r} not found (looked for {path}); fix the path or use "
            "[plant.mujoco] geometry = 'none'",
        )
    return path.resolve()


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation matrix about the unit ``axis`` by ``angle`` [rad] (Rodrigues)."""
    a = axis / np.linalg.norm(axis)
    K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * K @ K


def _rpy_matrix(rpy) -> np.ndarray:
    r, p, y = rpy
    return (
        _rotation(np.array([0, 0, 1.0]), y)
        @ _rotation(np.array([0, 1.0, 0]), p)
        @ _rotation(np.array([1.0, 0, 0]), r)
    )


def _matrix_rpy(R: np.ndarray) -> tuple[float, float, float]:
    """URDF roll-pitch-yaw of ``R`` = Rz(y) Ry(p) Rx(r)."""
    p = math.atan2(-R[2, 0], math.hypot(R[0, 0], R[1, 0]))
    if abs(math.cos(p)) < 1e-12:  # gimbal lock: put everything in yaw
        return 0.0, p, math.atan2(-R[0, 1], R[1, 1])
    return math.atan2(R[2, 1], R[2, 2]), p, math.atan2(R[1, 0], R[0, 0])


def _lock(joint: ET.Element, value: float) -> None:
    """Make ``joint`` fixed at ``value`` [rad or m]: its origin absorbs the joint motion."""
    origin = joint.find("origin")
    if origin is None:
        origin = ET.SubElement(joint, "origin")
    xyz = np.array([float(x) for x in origin.get("xyz", "0 0 0").split()])
    R = _rpy_matrix([float(x) for x in origin.get("rpy", "0 0 0").split()])
    ax = joint.find("axis")
    axis = np.array(
        [float(x) for x in (ax.get("xyz", "1 0 0") if ax is not None else "1 0 0").split()]
    )
    if joint.get("type") == "prismatic":
        xyz = xyz + R @ (value * axis / np.linalg.norm(axis))
    else:  # revolute, continuous
        R = R @ _rotation(axis, value)
    origin.set("xyz", " ".join(repr(float(x)) for x in xyz))
    origin.set("rpy", " ".join(repr(float(x)) for x in _matrix_rpy(R)))
    joint.set("type", "fixed")
    for tag in ("axis", "limit", "dynamics", "mimic", "safety_controller", "calibration"):
        for child in joint.findall(tag):
            joint.remove(child)


def urdf_for_mujoco(
    path: str | Path,
    controlled: tuple[str, ...],
    locked: dict[str, float] | None = None,
    settings: MuJoCoSettings | None = None,
    mimics: dict | None = None,
) -> str:
    """The URDF text MuJoCo compiles: consistent with the controller's Pinocchio model.

    Args:
        path: The URDF file.
        controlled: Names of the joints the controller controls (its coordinates).
        locked: Locked joints and their positions [rad or m] (made fixed).
        settings: What to keep (geometry, URDF dynamics).
        mimics: Followers that are mimic joints of the controller's model (their
            ``<mimic>`` is kept: an equality constraint in MuJoCo).

    Raises:
        URDFError: A mesh file that does not exist, or a mimic joint that the controller
            neither controls nor locks.
    """
    path = Path(path)
    s = settings if settings is not None else MuJoCoSettings()
    locked = dict(locked or {})
    root = ET.fromstring(path.read_text(encoding="utf-8"))
    for tag in ("gazebo", "transmission", "mujoco", "ros2_control"):
        for el in root.findall(tag):
            root.remove(el)
    for joint in root.findall("joint"):
        name = joint.get("name", "")
        if name in locked:
            _lock(joint, locked[name])
            continue
        for mimic in joint.findall("mimic"):
            if name in (mimics or {}):
                continue  # a mimic joint in the controller's model too: MuJoCo's equality
            if name not in controlled:
                raise URDFError(
                    path,
                    f"joint {name!r} mimics {mimic.get('joint')!r} but is neither "
                    "controlled, nor a mimic joint of the controller's model, nor locked",
                )
            joint.remove(mimic)  # an independent coordinate of the controller's model
        if not s.import_urdf_dynamics:
            for dyn in joint.findall("dynamics"):
                joint.remove(dyn)
    for link in root.findall("link"):
        if s.geometry == "visual":
            for col in link.findall("collision"):
                link.remove(col)
            for vis in link.findall("visual"):
                vis.tag = "collision"
                for mat in vis.findall("material"):
                    vis.remove(mat)
        else:
            for vis in link.findall("visual"):
                link.remove(vis)
        for col in link.findall("collision"):
            if s.geometry == "none":
                link.remove(col)
                continue
            mesh = col.find("geometry/mesh")
            if mesh is None:
                continue
            file = resolve_mesh_path(mesh.get("filename", ""), path, s.package_dirs)
            if file.suffix.lower() not in MESH_SUFFIXES:
                raise URDFError(
                    path,
                    f"mesh {file.name!r} of link {link.get('name')!r}: MuJoCo reads "
                    f"{MESH_SUFFIXES} meshes only; use [plant.mujoco] geometry = 'collision' "
                    "(if the collision meshes are STL/OBJ) or 'none'",
                )
            mesh.set("filename", str(file))
    mj = ET.Element("mujoco")
    # Inertias from the URDF only (as Pinocchio): a link without <inertial> is massless.
    ET.SubElement(
        mj, "compiler", {"strippath": "false", "discardvisual": "true", "inertiafromgeom": "false"}
    )
    root.insert(0, mj)
    return ET.tostring(root, encoding="unicode")


@functools.lru_cache(maxsize=16)
def _compile(xml: str, source: str, obstacle: Obstacle | None):
    """Compile the URDF text (cached: a sweep builds many plants of one arm)."""
    mujoco = import_mujoco()
    try:
        spec = mujoco.MjSpec.from_string(xml)
        for geom in spec.geoms:
            geom.contype, geom.conaffinity = ARM_CONTYPE, ARM_CONAFFINITY
        if obstacle is not None:
            spec.worldbody.add_geom(
                name="obstacle",
                type=mujoco.mjtGeom.mjGEOM_BOX,
                pos=list(obstacle.position),
                size=list(obstacle.size),
                contype=OBSTACLE_CONTYPE,
                conaffinity=OBSTACLE_CONAFFINITY,
                friction=[obstacle.friction, 0.005, 0.0001],
                solref=list(obstacle.solref),
                priority=1,
                rgba=[0.6, 0.6, 0.6, 0.5],
            )
        return spec.compile()
    except ValueError as exc:  # MuJoCo's compiler and parser errors
        raise URDFError(source, f"MuJoCo cannot compile this URDF: {exc}") from exc


def mujoco_model(robot: Robot, settings: MuJoCoSettings | None = None):
    """A fresh ``mujoco.MjModel`` of ``robot``'s URDF (its locked joints fixed), with the
    friction, damping, armature, integrator and gravity of ``settings``/``robot``.

    Raises:
        URDFError: MuJoCo cannot compile the file (MuJoCo's message and the file), a
            mesh is missing, or the joints do not match the controller's by name.
        ExtraError: ``mujoco`` is not installed.
    """
    mujoco = import_mujoco()
    s = settings if settings is not None else MuJoCoSettings()
    source = Path(robot.source)
    mimics = dict(getattr(robot, "mimic_joints", {}) or {})
    xml = urdf_for_mujoco(source, robot.joint_names, robot.locked_joints, s, mimics)
    model = copy.deepcopy(_compile(xml, str(source), s.obstacle))
    names = [model.joint(i).name for i in range(model.njnt)]
    if sorted(names) != sorted([*robot.joint_names, *mimics]):
        raise URDFError(
            source,
            f"MuJoCo's model has the joints {names} but the controller's "
            f"{list(robot.joint_names)} (mimic joints {list(mimics)}); they must be the same",
        )
    if model.neq:  # the mimic equalities: as stiff as MuJoCo's soft constraints allow
        model.eq_solref[:] = (MIMIC_TIMECONST, 1.0)
        model.eq_solimp[:] = MIMIC_SOLIMP
    if s.obstacle is not None and model.ngeom < 2:  # the obstacle is the only geom
        raise URDFError(
            source,
            f"the arm has no {s.geometry} geometry, so it can never touch the obstacle; "
            "use [plant.mujoco] geometry = 'visual' (its visual shapes) or add <collision> tags",
        )
    dofs = np.array([model.joint(name).dofadr[0] for name in robot.joint_names])
    n = robot.nq
    for name in ("frictionloss", "damping", "armature"):
        base = getattr(model, f"dof_{name}")[dofs] if s.import_urdf_dynamics else 0.0
        getattr(model, f"dof_{name}")[dofs] = base + s.per_joint(name, n)
    if s.friction_timeconst is not None:
        model.dof_solref[dofs] = (s.friction_timeconst, 1.0)
    model.opt.integrator = getattr(mujoco.mjtIntegrator, MUJOCO_INTEGRATORS[s.integrator])
    model.opt.gravity[:] = robot.model.gravity.linear
    if s.obstacle is None:
        model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    return model


def _joint_bodies(model, joint_names) -> list[list[int]]:
    """For each joint, the MuJoCo bodies it moves rigidly (its body and the fixed bodies
    below it): the links Pinocchio merges into that joint's body."""
    owner = {}
    for b in range(1, model.nbody):
        k = b
        while k > 0 and model.body_jntnum[k] == 0:
            k = model.body_parentid[k]
        owner[b] = model.body_jntadr[k] if k > 0 else -1
    groups = []
    for name in joint_names:
        j = model.joint(name).id
        groups.append([b for b, o in owner.items() if o == j])
    return groups


def _inertia_factors(robot: Robot) -> np.ndarray | None:
    """Per-joint factors by which ``robot``'s link inertias are its URDF's scaled
    (:meth:`~hmpc_pin.model.robot.Robot.with_scaled_inertias`), or ``None`` if unscaled.

    Raises:
        URDFError: The inertias differ otherwise than by one factor per link.
    """
    from ..model.robot import load_robot

    nominal = load_robot(robot.source, robot.gravity, robot.locked_joints)
    factors = []
    for i in range(1, robot.model.njoints):
        a, b = robot.model.inertias[i], nominal.model.inertias[i]
        k = a.mass / b.mass if b.mass > 0 else 1.0
        if not (
            np.allclose(a.lever, b.lever, atol=1e-12)
            and np.allclose(a.inertia, k * b.inertia, rtol=1e-9, atol=1e-15)
        ):
            raise URDFError(
                robot.source,
                f"the plant model's link {i} differs from its URDF other than "
                "by a factor on mass and inertia; the MuJoCo plant can only scale a link",
            )
        factors.append(k)
    k = np.array(factors)
    return None if np.allclose(k, 1.0, rtol=1e-12) else k


class MuJoCoPlant:
    """The arm simulated by MuJoCo, advanced one control period at a time.

    Args:
        robot: The plant's :class:`~hmpc_pin.model.robot.Robot`: its URDF, locked joints,
            gravity and link inertias (a :meth:`~hmpc_pin.model.robot.Robot.with_scaled_inertias`
            copy scales MuJoCo's links the same way) define MuJoCo's model.
        disturbance: Callable ``d(t, q, dq) -> (n,)`` [N·m] applied as generalized force
            at every MuJoCo step; ``None`` for none.
        Ts: Control period [s] (the torque is held over it).
        dt: MuJoCo's time step ``opt.timestep`` [s]; must divide ``Ts``.
        settings: :class:`MuJoCoSettings` (friction, damping, armature, integrator,
            geometry, obstacle).

    Attributes:
        model, data: MuJoCo's ``MjModel``/``MjData``.
        contact_force: Generalized contact force :math:`J_c^T f_c` [N·m] on each joint,
            of MuJoCo's last step of the last period (zeros after :meth:`reset`).
        engine_force: Everything MuJoCo adds beyond :math:`\\tau + d` (damping, dry
            friction, limits, contacts) [N·m], of the last step of the last period.
        history: With an obstacle, ``contact_force`` at every control instant since
            :meth:`reset` (a list of arrays); empty without (contacts are off).
    """

    name = "mujoco"
    _was_reset = False
    engine = "mujoco"

    def __init__(
        self,
        robot: Robot,
        disturbance=None,
        Ts: float = 0.01,
        dt: float = 0.001,
        settings: MuJoCoSettings | None = None,
    ):
        mujoco = import_mujoco()
        self._mj = mujoco
        self.settings = settings if settings is not None else MuJoCoSettings()
        n = robot.nq
        self.nq = self.n = n
        self.robot = robot
        self.Ts = float(Ts)
        self.substeps = _substeps(Ts, dt)
        self.h = self.Ts / self.substeps
        self.model = model = mujoco_model(robot, self.settings)
        model.opt.timestep = self.h
        factors = _inertia_factors(robot)
        if factors is not None:  # one factor per joint of the Pinocchio model (mimic too)
            names = list(robot.model.names)[1:]
            for k, bodies in zip(factors, _joint_bodies(model, names), strict=True):
                model.body_mass[bodies] *= k
                model.body_inertia[bodies] *= k
        self.data = mujoco.MjData(model)
        self.qadr = np.array([model.joint(j).qposadr[0] for j in robot.joint_names])
        self.vadr = np.array([model.joint(j).dofadr[0] for j in robot.joint_names])
        # MuJoCo's velocities from the controller's, q̇_mj = E q̇ (mimic followers:
        # m·q̇_leader); generalized forces back to the controller's coordinates by Eᵀ.
        index = {name: i for i, name in enumerate(robot.joint_names)}
        self._mimics = []
        E = np.zeros((model.nv, n))
        E[self.vadr, np.arange(n)] = 1.0
        for follower, (leader, mult, offset) in dict(getattr(robot, "mimic_joints", {})).items():
            j = model.joint(follower)
            self._mimics.append((j.qposadr[0], j.dofadr[0], index[leader], mult, offset))
            E[j.dofadr[0], index[leader]] = mult
        self._E = E
        self._ident = bool(
            np.array_equal(self.qadr, np.arange(n))
            and np.array_equal(self.vadr, np.arange(n))
            and model.nq == n
            and model.nv == n
        )
        self.disturbance = disturbance if disturbance is not None else ZeroDisturbance(n)
        split = split_disturbance(self.disturbance, n)
        # Time-only terms tabulated per period (none: the torque alone); ``None``: the
        # disturbance is called at every step.
        self._pulses = split[0] if split is not None and split[1] is None else None
        self._offsets = self.h * np.arange(self.substeps)
        self._contact_rows = tuple(
            int(getattr(mujoco.mjtConstraint, name))
            for name in (
                "mjCNSTR_CONTACT_FRICTIONLESS",
                "mjCNSTR_CONTACT_PYRAMIDAL",
                "mjCNSTR_CONTACT_ELLIPTIC",
            )
        )
        self._qfrc = np.zeros(model.nv)
        self._zero = np.zeros(n)
        self._contacts = self.settings.obstacle is not None
        self.t0, self.k, self.t = 0.0, 0, 0.0
        self.q, self.dq = np.zeros(n), np.zeros(n)
        self.contact_force = np.zeros(n)
        self.engine_force = np.zeros(n)
        self.history: list[np.ndarray] = []

    @property
    def version(self) -> str:
        """MuJoCo's version."""
        return str(self._mj.__version__)

    def __getstate__(self) -> dict:
        """Picklable (e.g. to run the plant in another process): all but the module."""
        state = self.__dict__.copy()
        del state["_mj"]
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._mj = import_mujoco()

    def reset(self, q0: FloatArray, dq0: FloatArray, t0: float = 0.0) -> None:
        """Start at ``(q0, dq0)`` [rad, rad/s] at time ``t0`` [s]."""
        q = np.array(q0, dtype=float)
        dq = np.array(dq0, dtype=float)
        if q.shape != (self.n,) or dq.shape != (self.n,):
            raise DimensionError(
                f"plant state of shapes {q.shape}, {dq.shape}; expected ({self.n},)"
            )
        m, d = self.model, self.data
        self._mj.mj_resetData(m, d)
        d.qpos[self.qadr] = q
        d.qvel[self.vadr] = dq
        for qa, va, leader, mult, offset in self._mimics:  # on their constraint
            d.qpos[qa] = mult * q[leader] + offset
            d.qvel[va] = mult * dq[leader]
        d.time = float(t0)
        self._mj.mj_forward(m, d)
        self.q, self.dq = q, dq
        self.t0, self.k, self.t = float(t0), 0, float(t0)
        self.contact_force = np.zeros(self.n)
        self.engine_force = np.zeros(self.n)
        self.history = [self.contact_force] if self._contacts else []
        self._was_reset = True

    def disturbance_now(self) -> FloatArray:
        """What the controller's model does not know [N·m]: the config's
        :math:`d(t, q, \\dot q)` now plus MuJoCo's damping, dry friction, limit and contact
        forces (of the last step of the period that ended now: they depend on the torque
        held)."""
        return np.asarray(self.disturbance(self.t, self.q, self.dq)) + self.engine_force

    def generalized_contact_force(self) -> FloatArray:
        """:math:`J_c^T f_c` [N·m] of the contacts of MuJoCo's last step, per controlled joint:
        the constraint forces of the contact rows mapped by the constraint Jacobian (and
        a mimic follower's share onto its leader)."""
        m, d = self.model, self.data
        if d.ncon == 0:
            return np.zeros(self.n)
        rows = np.isin(d.efc_type, self._contact_rows)
        force = np.where(rows, d.efc_force, 0.0)
        self._mj.mj_mulJacTVec(m, d, self._qfrc, force)
        return self._qfrc[self.vadr].copy() if self._ident else self._E.T @ self._qfrc

    def advance(self, tau: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Step MuJoCo over one period with ``tau`` held; return new ``(q, dq)`` at ``t + Ts``.

        The applied generalized force of step s is :math:`\\tau + d(t_s, q_s, \\dot q_s)`.
        Time-only terms (the pulses) are tabulated for the whole period in one call each
        and the steps run in a tight loop (one ``mj_step`` per step); without any
        disturbance the period is one ``mj_step(model, data, nstep)`` call; any other
        disturbance is called at every step with the state MuJoCo has reached.
        """
        tau = held_torque(self, tau)
        m, d, step = self.model, self.data, self._mj.mj_step
        S, v = self.substeps, self.vadr
        qfrc = d.qfrc_applied
        pulses = self._pulses
        if pulses is not None and not pulses:  # torque only: one call for the period
            if self._ident:
                qfrc[:] = tau
            else:
                qfrc[v] = tau
            step(m, d, S)
        elif pulses is not None:
            times = self.t + self._offsets
            applied = np.add(tau, pulses[0].sample_times(times))
            for term in pulses[1:]:
                applied += term.sample_times(times)
            if self._ident:
                for row in applied:
                    qfrc[:] = row
                    step(m, d)
            else:
                for row in applied:
                    qfrc[v] = row
                    step(m, d)
        else:
            dist, qadr, h, t = self.disturbance, self.qadr, self.h, self.t
            for s in range(S):
                qfrc[v] = tau + dist(t + s * h, d.qpos[qadr], d.qvel[v])
                step(m, d)
        self.k += 1
        self.t = self.t0 + self.Ts * self.k
        self.q, self.dq = d.qpos[self.qadr], d.qvel[v]  # fancy indexing: new arrays
        if self._ident:
            self.engine_force = d.qfrc_constraint + d.qfrc_passive
        else:  # (a mimic equality's forces cancel in Eᵀ)
            self.engine_force = self._E.T @ (d.qfrc_constraint + d.qfrc_passive)
        self.contact_force = self.generalized_contact_force() if d.ncon else self._zero
        if self._contacts:
            self.history.append(self.contact_force)
        return self.q, self.dq


PLANTS[MuJoCoPlant.name] = MuJoCoPlant
