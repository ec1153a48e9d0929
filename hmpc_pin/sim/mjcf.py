"""The URDF → MuJoCo translation: the arm's URDF made consistent with the controller's
Pinocchio model, then compiled by MuJoCo (``MjSpec``) into the model the MuJoCo plant
steps (:mod:`hmpc_pin.sim.mujoco`).

* ``package://`` and relative mesh paths are resolved to files (MuJoCo's URDF reader
  does not know ROS packages), or meshes left out (``geometry = "none"``);
* locked joints become fixed joints at their locked position, as
  ``pin.buildReducedModel`` does;
* ``<mimic>``: a follower that is a mimic joint of the controller's model keeps the tag
  (MuJoCo's joint equality, made as stiff as its soft constraints allow); a follower the
  controller controls loses it;
* ``<dynamics damping friction>`` are kept or dropped (``import_urdf_dynamics``), then
  the settings' friction, damping and armature are added per joint, matched by name;
* an obstacle box is added to the world; the arm's geoms collide with it only.

``mujoco`` is an optional dependency (extra ``mujoco``); it is imported when a model is
compiled.
"""

from __future__ import annotations

import copy
import functools
import math
import os
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from ..exceptions import ExtraError, URDFError
from ..model.robot import Robot
from .mujoco_settings import MUJOCO_INTEGRATORS, MuJoCoSettings, Obstacle

__all__ = [
    "ARM_CONAFFINITY",
    "ARM_CONTYPE",
    "MESH_SUFFIXES",
    "MIMIC_SOLIMP",
    "MIMIC_TIMECONST",
    "OBSTACLE_CONAFFINITY",
    "OBSTACLE_CONTYPE",
    "import_mujoco",
    "mujoco_model",
    "resolve_mesh_path",
    "urdf_for_mujoco",
]

#: Collision bits: arm geoms collide with the obstacle only, never with each other.
ARM_CONTYPE, ARM_CONAFFINITY = 1, 0
OBSTACLE_CONTYPE, OBSTACLE_CONAFFINITY = 0, 1
#: Mesh formats MuJoCo reads.
MESH_SUFFIXES = (".stl", ".obj", ".msh")
#: MuJoCo's ``solref``/``solimp`` of a mimic equality: the stiffest MuJoCo's soft
#: constraints allow (time constant 2 ms, impedance 0.9999: the constrained acceleration
#: is met to a relative 1e-4), closest to Pinocchio's exact mimic joint.
MIMIC_TIMECONST = 0.002
MIMIC_SOLIMP = (0.9999, 0.9999, 0.001, 0.5, 2.0)


def import_mujoco():
    """The ``mujoco`` module, or :class:`~hmpc_pin.exceptions.ExtraError` naming the extra."""
    try:
        import mujoco
    except ImportError as exc:
        raise ExtraError("mujoco", "the MuJoCo plant (plant.engine = 'mujoco')") from exc
    return mujoco


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
