"""Robot model: a URDF loaded into Pinocchio, with the dynamics terms of Eq (1).

.. math::  M(q)\\,\\ddot q + C(q,\\dot q)\\,\\dot q + G(q) = \\tau + d   \\qquad (1)

Every dynamics quantity comes from Pinocchio: ``crba`` for :math:`M`,
``nonLinearEffects`` for :math:`C\\dot q + G`, ``computeGeneralizedGravity`` for
:math:`G`, ``aba`` for the forward dynamics and ``rnea`` for the inverse dynamics.
No dynamics is written by hand.

Before Pinocchio sees a file, the file is checked with the standard library's XML
parser: well-formedness (with line and column), the structure and completeness the URDF
specification requires (names, joint types, parent and child links, limits, numbers,
geometry), so that a bad file gets a message naming the file and the problem instead of
urdfdom's terse output.

Joint types (docs, "Your own arm"):

* ``revolute`` and ``prismatic`` joints are one coordinate each [rad or m];
* a ``continuous`` joint is loaded as a revolute joint without position limits (limits
  ±inf): Pinocchio's own continuous joint has the two coordinates (cos θ, sin θ), whereas
  the controller needs one angle per joint (nq = nv); the angle does not wrap;
* a ``mimic`` joint (``<mimic joint= multiplier= offset=>``) follows its leader,
  :math:`q_f = m\\,q_l + o`, through Pinocchio's mimic joint: it has no coordinate of its
  own, so it is never controlled on its own; its mass and inertia load the leader. Pinocchio
  has no ABA for mimic joints, so :meth:`Robot.forward_dynamics` (and the plants, through
  :attr:`Robot.aba`) solve :math:`M\\ddot q = \\tau - h` with CRBA instead;
* the base is fixed unless the URDF itself has a ``floating`` (or ``planar``) joint, which
  is refused: the URDF decides, not the flag of the package that ships it.
"""

from __future__ import annotations

import difflib
import math
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..data import robot_path
from ..exceptions import DimensionError, NonFiniteError, URDFError, ValidityWarning

__all__ = [
    "Robot",
    "check_urdf",
    "damping_time_constants",
    "example_robot_names",
    "example_robot_srdf",
    "example_robot_urdf",
    "load_robot",
    "urdf_mimics",
]

#: URDF joint types the controller supports (one coordinate each, nq == nv; a continuous
#: joint becomes a revolute joint without position limits).
SUPPORTED_JOINT_TYPES = ("revolute", "prismatic", "continuous")


#: Arms example-robot-data mounts on a floating base although their URDF is a fixed-base
#: arm (the loader's ``free_flyer`` says how it mounts a model, not what the URDF is).
MOUNTED_ARMS = ("so100", "so101")


def example_robot_names() -> tuple[str, ...]:
    """Names accepted by :func:`load_robot` from ``example-robot-data`` (fixed-base URDF arms
    and all other fixed-base URDF models the loader package lists, and the arms of
    :data:`MOUNTED_ARMS`)."""
    from example_robot_data import robots_loader

    return tuple(
        sorted(
            name
            for name, loader in robots_loader.ROBOTS.items()
            if loader.urdf_filename and (not loader.free_flyer or name in MOUNTED_ARMS)
        )
    )


def example_robot_urdf(name: str) -> Path:
    """Path of the URDF of the ``example-robot-data`` model ``name`` (e.g. ``"panda"``).

    Raises:
        URDFError: Unknown name (the message lists the closest known names), a
            floating-base model, or a model shipped only as SDF.
    """
    from os.path import join

    from example_robot_data import robots_loader

    loader = robots_loader.ROBOTS.get(name)
    if loader is None:
        arms = ["planar3", *example_robot_names()]  # suggest arms only (not drones, legs)
        close = difflib.get_close_matches(name, arms, n=5, cutoff=0.5)
        hint = f"did you mean {', '.join(map(repr, close))}? " if close else ""
        raise URDFError(
            name,
            "is neither a URDF file nor an example-robot-data model name; "
            f"{hint}known arms include 'ur5', 'ur10', 'panda', 'z1' "
            "(`hmpc-pin init --list` or hmpc_pin.model.robot.example_robot_names() lists all)",
        )
    # The loader's free_flyer flag is not read: it says how example-robot-data mounts the
    # model, not what the URDF is (so100/so101 are flagged but are fixed-base arms). A
    # floating joint in the URDF itself is refused by load_robot.
    if not loader.urdf_filename:
        raise URDFError(name, "is shipped as SDF only; hmpc_pin loads URDF models")
    rel = join(loader.path, loader.urdf_subpath, loader.urdf_filename)
    model_path = loader.model_path or robots_loader.getModelPath(rel)
    return Path(model_path, rel).resolve()


def example_robot_srdf(name: str) -> tuple[Path | None, str | None]:
    """The SRDF of the ``example-robot-data`` model ``name`` and the name of its reference
    posture (``"default"``, ``"half_sitting"``, ``"ready"``, ...), or ``None`` for what the
    package does not ship."""
    from os.path import join

    from example_robot_data import robots_loader

    loader = robots_loader.ROBOTS.get(name)
    if loader is None or not loader.srdf_filename:
        return None, None
    rel = join(loader.path, loader.srdf_subpath, loader.srdf_filename)
    model_path = loader.model_path or robots_loader.getModelPath(rel)
    path = Path(model_path, rel).resolve()
    return (path if path.is_file() else None), (loader.ref_posture or None)


def check_urdf(path: Path, locked: tuple[str, ...] = ()) -> ET.Element:
    """Reject a missing, unreadable, malformed or incomplete URDF with a clear message;
    return its parsed ``<robot>`` element.

    Joints named in ``locked`` are exempt from the joint-type check (they are
    removed from the model before control)."""
    if not path.exists():
        raise URDFError(path, "file not found; pass the path of a .urdf file")
    if not path.is_file():
        raise URDFError(path, "is not a file; pass the path of a .urdf file")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise URDFError(path, f"cannot be read ({exc})") from exc
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        line, col = exc.position
        raise URDFError(path, f"malformed XML at line {line}, column {col}: {exc.msg}") from exc
    if root.tag != "robot":
        raise URDFError(path, f"root element is <{root.tag}>, expected <robot>")
    check_inertias(root, path, locked)
    for joint in root.findall("joint"):  # named, with the fix (before the general check)
        limit = joint.find("limit")
        if joint.get("type") in ("revolute", "prismatic", "continuous") and limit is not None:
            missing = [a for a in ("effort", "velocity") if limit.get(a) is None]
            if missing:
                raise URDFError(
                    path,
                    f"joint {joint.get('name')!r}: <limit> has no {' and no '.join(missing)} "
                    "attribute; the URDF requires both on a movable joint's <limit> (write "
                    '0 where the arm has none: effort="0" is no torque limit, velocity="0" '
                    "no velocity limit)",
                )

    _check_structure(root, path)
    problems = "; ".join(_completeness_problems(root))
    if problems:
        raise URDFError(path, f"incomplete or invalid URDF: {problems}")

    joints = [(j.get("name", ""), j) for j in root.findall("joint")]
    joint_names = {name for name, _ in joints}
    names = [name for name, j in joints if j.get("type") != "fixed"]
    unknown = [name for name in locked if name not in names]
    if unknown:
        raise URDFError(
            path,
            f"locked joint(s) {unknown} not found; the movable joints are {names}",
        )
    floating = [
        f"{name!r} ({j.get('type')})"
        for name, j in joints
        if j.get("type") in ("floating", "planar") and name not in locked
    ]
    if floating:
        raise URDFError(
            path,
            "has a floating base: joint(s) " + ", ".join(floating) + " give the base "
            "more than one coordinate per joint; hmpc_pin controls fixed-base arms. Remove "
            "the joint (the base is then fixed to the world) or lock it ([robot] locked_joints)",
        )
    unsupported = [
        f"{name!r} ({j.get('type')})"
        for name, j in joints
        if j.get("type") not in (*SUPPORTED_JOINT_TYPES, "fixed") and name not in locked
    ]
    if unsupported:
        raise URDFError(
            path,
            "unsupported joint type(s): "
            + ", ".join(unsupported)
            + f"; hmpc_pin controls {', '.join(SUPPORTED_JOINT_TYPES)} joints of a "
            "fixed-base arm (one coordinate per joint); lock them ([robot] locked_joints)",
        )
    for name, j in joints:
        mimic = j.find("mimic")
        if mimic is not None and mimic.get("joint") not in joint_names:
            raise URDFError(
                path,
                f"joint {name!r} mimics {mimic.get('joint')!r}, which is not a joint of the URDF",
            )
    actuated = [
        name
        for name, j in joints
        if j.get("type") in SUPPORTED_JOINT_TYPES and name not in locked and j.find("mimic") is None
    ]
    if not actuated:
        raise URDFError(
            path,
            "has no actuated joint (revolute, prismatic or continuous, not locked, not a "
            "mimic); there is nothing to control",
        )
    return root


#: The classes of yourdfpy's ``URDF.validate`` errors, which name each problem (the
#: messages of earlier versions, which checked the file with yourdfpy, are kept word for word).
_INCOMPLETE, _BAD_VALUE = "URDFIncompleteError", "URDFAttributeValueError"
#: The joint types a URDF may name (the URDF specification).
URDF_JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")


def _required(value: str | None, message: str, allowed: tuple[str, ...] = ()) -> list[str]:
    """The problems of a required attribute ``value``: missing or empty, or not one of
    ``allowed``."""
    out = []
    if value is None or value == "":
        out.append(f"{_INCOMPLETE}: {message}")
    if allowed and value is not None and value not in allowed:
        out.append(f"{_BAD_VALUE}: {message}")
    return out


def _completeness_problems(root: ET.Element) -> list[str]:
    """Every required piece the URDF lacks, each in the words of yourdfpy's
    ``URDF.validate`` (``"URDFIncompleteError: ..."``): the names of the robot, links and
    joints, each joint's type, parent and child links, and the ``<limit>`` of a revolute or
    prismatic joint with its bounds, effort and velocity. The elements themselves exist
    (:func:`_check_structure` ran first)."""
    out = _required(root.get("name"), "The <robot> tag misses a 'name' attribute.")
    for link in root.findall("link"):
        out += _required(link.get("name"), "The <link> tag misses a 'name' attribute.")
    bad_type = (
        "The <joint> tag misses a 'type' attribute or value is not part of allowed values "
        f"[{', '.join(URDF_JOINT_TYPES)}]."
    )
    missing = f"{_INCOMPLETE}: Tag <limit> of joint is missing attribute"
    for joint in root.findall("joint"):
        kind = joint.get("type")
        out += _required(joint.get("name"), "The <joint> tag misses a 'name' attribute.")
        out += _required(kind, bad_type, URDF_JOINT_TYPES)
        for end in ("parent", "child"):
            element = joint.find(end)
            link = element.get("link") if element is not None else None
            out += _required(link, f"The <{end}> of a <joint> is missing.")
        limit = joint.find("limit")
        if limit is None:
            if kind in ("revolute", "prismatic"):
                out.append(
                    f"{_INCOMPLETE}: The <limit> of a (prismatic, revolute) joint is missing."
                )
            continue
        needed = ("upper", "lower") if kind in ("revolute", "prismatic") else ()
        out += [
            f"{missing} '{a}'." for a in (*needed, "effort", "velocity") if limit.get(a) is None
        ]
    return out


#: How many numbers an attribute holds: one, any number (a vector read as given), a
#: position (three, or one for all three) or three angles (the first three are read).
_ONE, _ANY, _XYZ, _RPY = "a number", "numbers", "3 numbers", "3 angles"
#: The numeric attributes of a ``<link>``, ``<joint>`` and ``<material>``: the path of the
#: element below it -> {attribute: how many numbers}.
_NUMBERS: dict[str, dict[str, dict[str, str]]] = {
    "link": {
        "inertial/origin": {"xyz": _XYZ, "rpy": _RPY},
        "inertial/mass": {"value": _ONE},
        "inertial/inertia": dict.fromkeys(("ixx", "ixy", "ixz", "iyy", "iyz", "izz"), _ONE),
        "visual/origin": {"xyz": _XYZ, "rpy": _RPY},
        "visual/material/color": {"rgba": _ANY},
        "collision/origin": {"xyz": _XYZ, "rpy": _RPY},
    },
    "joint": {
        "origin": {"xyz": _XYZ, "rpy": _RPY},
        "axis": {"xyz": _ANY},
        "limit": dict.fromkeys(("effort", "velocity", "lower", "upper"), _ONE),
        "mimic": {"multiplier": _ONE, "offset": _ONE},
        "calibration": {"rising": _ONE, "falling": _ONE},
        "safety_controller": dict.fromkeys(
            ("soft_lower_limit", "soft_upper_limit", "k_position", "k_velocity"), _ONE
        ),
    },
    "material": {"color": {"rgba": _ANY}},
}
#: The shapes a ``<geometry>`` holds besides ``<mesh>``, with their required dimensions.
_SHAPES = {
    "box": {"size": _ANY},
    "cylinder": {"radius": _ONE, "length": _ONE},
    "sphere": {"radius": _ONE},
}


def _is_numbers(text: str, count: str, commas: bool = False) -> bool:
    """Whether ``text`` is ``count`` numbers (:data:`_ONE`, ...) separated by spaces (or
    commas)."""
    try:
        n = len([float(v) for v in (text.replace(",", " ") if commas else text).split()])
    except ValueError:
        return False
    return {_ONE: n == 1, _ANY: True, _XYZ: n == 1 or n >= 3, _RPY: n >= 3}[count]


def _check_numbers(path: Path, owner: str, element: ET.Element, attributes: dict[str, str]):
    """Each of ``attributes`` that ``element`` has holds the numbers it must."""
    commas = element.tag in ("box", "mesh")
    for attribute, count in attributes.items():
        text = element.get(attribute)
        if text is not None and not _is_numbers(text, count, commas):
            raise URDFError(
                path, f"{owner}: <{element.tag} {attribute}={text!r}>: expected {count}"
            )


def _check_structure(root: ET.Element, path: Path) -> None:
    """Refuse a URDF whose structure the URDF specification does not allow, naming the
    element: a ``<robot>``, ``<link>`` or ``<joint>`` without ``name``, a joint without
    ``<parent>`` or ``<child>``, a ``<visual>`` or ``<collision>`` without a box, cylinder,
    sphere or mesh (with its dimensions), and a numeric attribute that is not the numbers
    it must be."""
    if root.get("name") is None:
        raise URDFError(path, "the <robot> tag has no 'name' attribute; give the robot a name")
    for kind in ("link", "joint", "material"):
        for element in root.findall(kind):
            name = element.get("name")
            owner = f"<{kind}> {name!r}" if name is not None else f"a <{kind}>"
            if kind != "material" and name is None:
                raise URDFError(path, f"{owner} has no 'name' attribute; name each <{kind}>")
            for end in ("parent", "child") if kind == "joint" else ():
                if element.find(end) is None:
                    raise URDFError(
                        path,
                        f"{owner} has no <{end}>; a joint names its parent "
                        "and child links (<parent link=...>, <child link=...>)",
                    )
            for sub, attributes in _NUMBERS[kind].items():
                for child in element.findall(sub):
                    _check_numbers(path, owner, child, attributes)
            for shape in element.findall("visual") + element.findall("collision"):
                _check_geometry(shape, owner, path)


def _check_geometry(shape: ET.Element, owner: str, path: Path) -> None:
    """The ``<visual>`` or ``<collision>`` ``shape`` holds a ``<geometry>`` whose first
    element is a mesh or a shape of :data:`_SHAPES` with its dimensions."""
    shapes = ", ".join(f"<{s}>" for s in (*_SHAPES, "mesh"))
    geometry = shape.find("geometry")
    first = geometry[0] if geometry is not None and len(geometry) else None
    if first is None or first.tag not in (*_SHAPES, "mesh"):
        found = f"<{first.tag}>" if first is not None else "nothing"
        raise URDFError(
            path,
            f"{owner}: the <geometry> of a <{shape.tag}> holds {found}; expected one of {shapes}",
        )
    for attribute in _SHAPES.get(first.tag, {}):
        if first.get(attribute) is None:
            raise URDFError(path, f"{owner}: <{first.tag}> has no {attribute!r} attribute")
    _check_numbers(path, owner, first, _SHAPES.get(first.tag, {}))
    if first.tag == "mesh":
        _check_numbers(path, owner, first, {"scale": _ANY})


def _moving_links(root: ET.Element, locked: tuple[str, ...]) -> set[str]:
    """The links that move when the controlled joints move: those with a movable joint
    (not fixed, not locked) on their path from the root."""
    parent = {}
    for joint in root.findall("joint"):
        child, par = joint.find("child"), joint.find("parent")
        if child is not None and par is not None:
            movable = joint.get("type") != "fixed" and joint.get("name") not in locked
            parent[child.get("link", "")] = (par.get("link", ""), movable)
    moving: dict[str, bool] = {}

    def moves(link: str, depth: int = 0) -> bool:
        if link not in moving:
            if link not in parent or depth > len(parent):  # the root (or a cycle)
                moving[link] = False
            else:
                par, movable = parent[link]
                moving[link] = movable or moves(par, depth + 1)
        return moving[link]

    return {link.get("name", "") for link in root.findall("link") if moves(link.get("name", ""))}


def check_inertias(root: ET.Element, path: Path, locked: tuple[str, ...] = ()) -> None:
    r"""Check the ``<inertial>`` of every link that moves, before any model is built.

    A rigid body has a mass :math:`m \ge 0` and a rotational inertia :math:`I` that is
    symmetric (the URDF gives its six entries) and positive semi-definite, with principal
    moments satisfying the triangle inequalities :math:`I_1 + I_2 \ge I_3` (for each
    order). Zero moments (a point mass, a thin rod) are valid; a singular :math:`M(q)`
    they may cause is refused later, naming the joint
    (:meth:`Robot.check_mass_matrix`). Links fixed to the world are not checked (their
    inertia acts on nothing). Tolerances: :math:`10^{-9}` of the largest moment for the
    sign, :math:`10^{-6}` of the trace for the triangle (values rounded in the file).

    A negative mass or a moment below zero makes :math:`M(q)` indefinite: refused. A
    violated triangle inequality leaves :math:`M(q)` positive definite and is common in
    published URDFs exported from CAD (the Allegro hand, PR2, Romeo): a
    :class:`~hmpc_pin.exceptions.ValidityWarning` naming the link, the arm still loads.

    Raises:
        URDFError: Naming the link, the offending values and what is expected.
    """
    moving = _moving_links(root, locked)
    for link in root.findall("link"):
        name = link.get("name", "")
        inertial = link.find("inertial")
        if inertial is None or name not in moving:
            continue
        mass_el = inertial.find("mass")
        try:
            mass = float(mass_el.get("value", "nan")) if mass_el is not None else 0.0
        except ValueError:
            mass = math.nan
        if not (math.isfinite(mass) and mass >= 0):
            text = mass_el.get("value") if mass_el is not None else None
            raise URDFError(
                path, f"link {name!r}: <mass value> = {text!r}; expected a finite mass >= 0 [kg]"
            )
        inertia = inertial.find("inertia")
        if inertia is None:
            continue
        keys = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
        try:
            v = {k: float(inertia.get(k, "0")) for k in keys}
        except ValueError as exc:
            raise URDFError(path, f"link {name!r}: <inertia> {exc}; expected numbers") from None
        if not all(math.isfinite(x) for x in v.values()):
            raise URDFError(path, f"link {name!r}: <inertia> {v}; expected finite numbers")
        matrix = np.array(
            [
                [v["ixx"], v["ixy"], v["ixz"]],
                [v["ixy"], v["iyy"], v["iyz"]],
                [v["ixz"], v["iyz"], v["izz"]],
            ]
        )
        moments = np.linalg.eigvalsh(matrix)
        scale = float(np.abs(moments).max())
        given = ", ".join(f"{k}={inertia.get(k, '0')}" for k in keys)
        if moments[0] < -1e-9 * scale:
            raise URDFError(
                path,
                f"link {name!r}: the inertia ({given}) is not positive semi-definite: its "
                f"principal moments are {np.round(moments, 12).tolist()} kg·m²; a rigid "
                "body's are all >= 0. Correct the link's <inertia> (e.g. from its CAD model)",
            )
        if moments[0] + moments[1] < moments[2] - 1e-6 * float(moments.sum()):
            warnings.warn(
                f"{path}: link {name!r}: the principal moments of inertia "
                f"{np.round(moments, 12).tolist()} kg·m² ({given}) violate the triangle "
                f"inequality I1 + I2 >= I3 ({moments[0] + moments[1]:.4g} < {moments[2]:.4g}): "
                "no rigid body has them. The Pinocchio plant runs on them as given (M(q) "
                "stays positive definite), MuJoCo refuses them; correct the link's <inertia> "
                "(e.g. from its CAD model)",
                ValidityWarning,
                stacklevel=4,
            )


def urdf_mimics(root: ET.Element) -> dict[str, tuple[str, float, float]]:
    """URDF mimic joints: follower name -> (leader name, multiplier, offset)."""
    out = {}
    for joint in root.findall("joint"):
        mimic = joint.find("mimic")
        if mimic is not None and joint.get("type") != "fixed":
            out[joint.get("name", "")] = (
                mimic.get("joint", ""),
                float(mimic.get("multiplier", 1.0)),
                float(mimic.get("offset", 0.0)),
            )
    return out


def _without_continuous(root: ET.Element) -> tuple[str, tuple[str, ...]]:
    """The URDF text with every ``continuous`` joint made ``revolute`` (its ``<limit>``
    effort and velocity kept, a placeholder position range the loader then replaces by
    ±inf) and without mimic tags; and the names of the changed joints."""
    changed = []
    for joint in root.findall("joint"):
        mimic = joint.find("mimic")
        if mimic is not None:
            joint.remove(mimic)  # mimic joints are made by _apply_mimics after locking
        if joint.get("type") != "continuous":
            continue
        joint.set("type", "revolute")
        limit = joint.find("limit")
        if limit is None:
            limit = ET.SubElement(joint, "limit", {"effort": "0", "velocity": "0"})
        limit.set("lower", "-1")
        limit.set("upper", "1")
        changed.append(joint.get("name", ""))
    return ET.tostring(root, encoding="unicode"), tuple(changed)


def _link_inertials(root: ET.Element) -> dict[str, float | None]:
    """URDF link name -> its ``<inertial><mass value>`` (``None``: no ``<inertial>``)."""
    out: dict[str, float | None] = {}
    for link in root.findall("link"):
        inertial = link.find("inertial")
        mass = inertial.find("mass") if inertial is not None else None
        out[link.get("name", "")] = (
            (float(mass.get("value", 0.0)) if mass is not None else None)
            if inertial is not None
            else None
        )
    return out


class Robot:
    """A fixed-base serial arm as a Pinocchio model with its own data.

    Attributes:
        model: The ``pin.Model`` (gravity set from the ``gravity`` argument).
        data: The ``pin.Data`` this object owns; do not share it across threads.
        name: Robot name (URDF ``<robot name>``).
        source: Path of the URDF it was loaded from.
        locked_joints: Joints of the URDF removed from the model, with the
            positions they are locked at [rad or m].
        joint_names: Names of the controlled joints, in coordinate order.
        lower, upper: Joint position limits [rad or m], shape (n,).
        velocity_limit: Joint velocity limits [rad/s or m/s], shape (n,).
        effort_limit: Joint effort limits [N·m or N], shape (n,).
        joint_damping, joint_friction: The URDF's ``<dynamics damping friction>`` per
            coordinate [N·m·s/rad, N·m], shape (n,): the joint torque
            :math:`-b\\dot q - f\\,\\mathrm{sgn}\\,\\dot q` the plants apply and the inverse
            dynamics compensates.
    """

    def __init__(
        self,
        model: pin.Model,
        source: str | Path = "<model>",
        locked_joints: Mapping[str, float] | None = None,
        mimic_joints: Mapping[str, tuple[str, float, float]] | None = None,
        continuous_joints: tuple[str, ...] = (),
        base_model: pin.Model | None = None,
    ):
        if model.nq != model.nv:
            raise URDFError(
                source,
                f"{model.nq=} but {model.nv=}; only joints with one coordinate "
                "(revolute, prismatic, continuous loaded as revolute) are supported",
            )
        if model.nq == 0:
            raise URDFError(source, "has no actuated joint; there is nothing to control")
        self.model = model
        self.data = model.createData()
        self.source = str(source)
        self.locked_joints: dict[str, float] = dict(locked_joints or {})
        #: Mimic joints: follower -> (leader, multiplier, offset); not coordinates.
        self.mimic_joints: dict[str, tuple[str, float, float]] = dict(mimic_joints or {})
        #: Joints that are ``continuous`` in the URDF (here revolute, limits ±inf).
        self.continuous_joints: tuple[str, ...] = tuple(continuous_joints)
        # With mimic joints: the model before they were made mimic joints. Pinocchio 4.1
        # pickles a mimic joint badly (CRBA on the copy crashes), so a Robot is pickled
        # through this model and rebuilt (__getstate__ / __setstate__).
        self._base_model = base_model if self.mimic_joints else None
        self.name = model.name
        coordinates = sorted(
            (model.joints[i].idx_v, model.names[i])
            for i in range(1, model.njoints)
            if model.joints[i].nv > 0
        )
        self.joint_names: tuple[str, ...] = tuple(name for _, name in coordinates)
        #: Per coordinate: ``"prismatic"`` [m, m/s, N] or ``"revolute"`` [rad, rad/s, N·m].
        self.joint_kinds: tuple[str, ...] = tuple(
            "prismatic"
            if model.joints[model.getJointId(name)].shortname()[10:].startswith("P")
            else "revolute"
            for name in self.joint_names
        )
        self.lower = np.array(model.lowerPositionLimit, dtype=float)
        self.upper = np.array(model.upperPositionLimit, dtype=float)
        self.velocity_limit = np.array(model.velocityLimit, dtype=float)
        self.effort_limit = np.array(model.effortLimit, dtype=float)
        #: Viscous joint damping b [N·m·s/rad or N·s/m] per coordinate, the URDF's
        #: ``<dynamics damping>`` (Pinocchio's ``model.damping``; 0 where not declared).
        self.joint_damping = np.array(model.damping, dtype=float)
        #: Coulomb joint friction f [N·m or N] per coordinate, the URDF's ``<dynamics
        #: friction>`` (Pinocchio's ``model.friction``; 0 where not declared).
        self.joint_friction = np.array(model.friction, dtype=float)
        # Pinocchio's C++ CRBA fills only the upper triangle; some bindings
        # symmetrise. Detect once, at a generic configuration (where M has
        # non-zero off-diagonal terms), so the hot path does no needless work.
        q = np.clip(
            0.3 + 0.1 * np.arange(model.nq), model.lowerPositionLimit, model.upperPositionLimit
        )
        m = pin.crba(model, self.data, q)
        self._symmetrize = not np.allclose(m, m.T)
        #: Whether ``pin.crba`` already returns the full symmetric M (then
        #: :meth:`mass_matrix` is ``pin.crba`` itself, and a hot loop may call it directly).
        self.crba_is_symmetric = not self._symmetrize
        self.check_mass_matrix(q)

    def check_mass_matrix(self, q: np.ndarray) -> None:
        """Raise :class:`~hmpc_pin.exceptions.URDFError` naming the joint and its links
        when :math:`M(q)` is not positive definite (a joint that moves no mass or inertia
        about its axis: a zero ``<mass>`` or no ``<inertial>`` at the end of the chain).

        The test is the pivot :math:`d_j` of the :math:`LDL^T` factorisation of
        :math:`M(q)` (in joint order): joint j fails when
        :math:`d_j \\le 10^{-14} \\max_i M_{ii}` (a 10 g fingertip has
        :math:`d_j/M_{11} \approx 10^{-8}` on a 50 kg arm, far above it).
        """
        m = self.mass_matrix(np.asarray(q, dtype=float))
        scale = max(float(np.max(np.diag(m))), 0.0)
        tol = 1e-14 * scale if scale > 0 else 0.0
        work = m.copy()
        n = len(work)
        for j in range(n):
            pivot = work[j, j]
            if not np.isfinite(pivot) or pivot <= tol:
                self._raise_singular(j, q, float(pivot))
            col = work[j + 1 :, j] / pivot
            work[j + 1 :, j + 1 :] -= np.outer(col, work[j, j + 1 :])

    def _raise_singular(self, j: int, q, pivot: float) -> None:
        model = self.model
        name = self.joint_names[j]
        jid = model.getJointId(name)
        subtree = set(model.subtrees[jid])
        links = [
            f.name
            for f in model.frames
            if f.type == pin.FrameType.BODY and f.parentJoint in subtree
        ]
        inertials = (
            _link_inertials(ET.parse(self.source).getroot()) if Path(self.source).is_file() else {}
        )
        why = []
        for link in links:
            if link in inertials:
                mass = inertials[link]
                why.append(
                    f"{link!r} (" + ("no <inertial>" if mass is None else f"mass {mass:g} kg") + ")"
                )
            else:
                why.append(repr(link))
        raise URDFError(
            self.source,
            f"M(q) is not positive definite at q={np.round(np.asarray(q), 4).tolist()}: "
            f"joint {name!r} meets no inertia about its axis (pivot {pivot:.3g}): the "
            f"link(s) it moves, {', '.join(why)}, are massless, have no <inertial>, or are "
            "point masses on its axis. Give the link at the end of the chain a mass and an "
            "inertia about the joint's axis (<inertial>), or lock the joint "
            "([robot] locked_joints)",
        )

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        if self._base_model is not None:
            state["model"] = state["data"] = None
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        if self.model is None:
            self.model = _apply_mimics(self._base_model, self.mimic_joints)
            self.data = self.model.createData()

    @property
    def aba(self):
        """Forward dynamics ``aba(model, data, q, dq, tau) -> ddq`` with Pinocchio's
        signature: ``pin.aba``, or for a model with mimic joints (which Pinocchio's ABA does
        not support) the solve of :math:`M\\ddot q = \\tau - h` by CRBA. (A property, so
        that a :class:`Robot` stays picklable.)"""
        return _crba_forward_dynamics if self.mimic_joints else pin.aba

    @property
    def nq(self) -> int:
        """Number of joint coordinates n."""
        return self.model.nq

    @property
    def gravity(self) -> float:
        """Magnitude of gravity [m/s²] (acting along −z)."""
        return float(-self.model.gravity.linear[2])

    def copy(self) -> Robot:
        """Return a robot with a copy of the model and its own fresh data."""
        base = self._base_model.copy() if self._base_model is not None else None
        return Robot(
            self.model.copy(),
            self.source,
            self.locked_joints,
            self.mimic_joints,
            self.continuous_joints,
            base_model=base,
        )

    def with_scaled_inertias(self, factors) -> Robot:
        """A copy whose link ``i`` has its mass and rotational inertia multiplied by
        ``factors[i]`` (centre of mass unchanged), for plant/model mismatch.

        ``factors`` has one entry per joint's body, in coordinate order (``model.inertias[1:]``,
        each the body moved by that joint with any fixed or locked links merged into it).
        """
        model = self.model.copy()
        k = np.asarray(factors, dtype=float)
        if k.shape != (model.njoints - 1,) or not np.all(np.isfinite(k)) or np.any(k <= 0):
            raise DimensionError(
                f"inertia factors must be {model.njoints - 1} finite numbers > 0, got {k!r}"
            )
        base = self._base_model.copy() if self._base_model is not None else None
        for m in (model, base) if base is not None else (model,):
            for i, ki in enumerate(k, start=1):  # the same joint (body) indices in both
                old = m.inertias[i]
                m.inertias[i] = pin.Inertia(ki * old.mass, old.lever.copy(), ki * old.inertia)
        return Robot(
            model,
            self.source,
            self.locked_joints,
            self.mimic_joints,
            self.continuous_joints,
            base_model=base,
        )

    def is_planar_chain(self, tol: float = 1e-9) -> bool:
        """Whether the arm is a planar serial chain: each joint hangs from the previous one,
        every revolute axis is parallel to the first and every prismatic axis
        perpendicular to it (world axes at the neutral configuration). Chen's observer
        (``compensation = "chen"``) is proven for such arms only."""
        model, data = self.model, self.model.createData()
        if self.mimic_joints or any(model.parents[i] != i - 1 for i in range(1, model.njoints)):
            return False
        pin.computeJointJacobians(model, data, pin.neutral(model))
        J = pin.getJointJacobian(model, data, model.njoints - 1, pin.ReferenceFrame.WORLD)
        J = np.asarray(J).reshape(6, model.nv)  # a 6×1 Jacobian comes back as a vector
        axes = [
            (kind, J[3:, j] if kind == "revolute" else J[:3, j])
            for j, kind in enumerate(self.joint_kinds)
        ]
        normal = next((a for k, a in axes if k == "revolute"), None)
        if normal is None:
            return True
        normal = normal / np.linalg.norm(normal)
        for kind, axis in axes:
            if kind == "revolute" and np.linalg.norm(np.cross(axis, normal)) > tol:
                return False
            if kind == "prismatic" and abs(float(axis @ normal)) > tol:
                return False
        return True

    # ------------------------------------------------------------------ checks
    def check_vector(self, name: str, value, *, finite: bool = True) -> np.ndarray:
        """Convert ``value`` to a float array of shape (n,), or raise a clear error."""
        arr = np.asarray(value, dtype=float)
        if arr.shape != (self.nq,):
            raise DimensionError(
                f"{name} has shape {arr.shape} but the robot {self.name!r} has "
                f"{self.nq} joints {self.joint_names}; pass a vector of shape ({self.nq},)"
            )
        if finite and not np.all(np.isfinite(arr)):
            raise NonFiniteError(name, arr)
        return arr

    # ---------------------------------------------------------------- dynamics
    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """Joint-space inertia matrix :math:`M(q)` (n×n, symmetric), Eq (1)."""
        m = pin.crba(self.model, self.data, q)
        if self._symmetrize:
            m = np.triu(m) + np.triu(m, 1).T
        return m  # pin.crba returns a new array (not a view of data.M)

    def nonlinear_effects(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """Coriolis, centrifugal and gravity torques :math:`C(q,\\dot q)\\dot q + G(q)` [N·m]."""
        return pin.nonLinearEffects(self.model, self.data, q, dq)  # a new array

    def coriolis_matrix(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """Coriolis matrix :math:`C(q,\\dot q)` (n×n) with :math:`\\dot M = C + C^T`."""
        return pin.computeCoriolisMatrix(self.model, self.data, q, dq).copy()

    def gravity_torque(self, q: np.ndarray) -> np.ndarray:
        """Gravity torques :math:`G(q)` [N·m]."""
        return pin.computeGeneralizedGravity(self.model, self.data, q).copy()

    def forward_dynamics(self, q: np.ndarray, dq: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """Joint accelerations :math:`\\ddot q = M^{-1}(\\tau - C\\dot q - G)` by ABA [rad/s²]."""
        return np.array(self.aba(self.model, self.data, q, dq, tau), dtype=float)

    def inverse_dynamics(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray) -> np.ndarray:
        """Torques :math:`M\\ddot q + C\\dot q + G` by RNEA [N·m]."""
        return pin.rnea(self.model, self.data, q, dq, ddq).copy()

    # -------------------------------------------------------------- kinematics
    @property
    def tool_frame(self) -> str:
        """Name of the last frame of the kinematic tree (the tool point)."""
        return self.model.frames[len(self.model.frames) - 1].name

    def frame_placement(self, q: np.ndarray, frame: str | None = None) -> pin.SE3:
        """World placement of ``frame`` (default: :attr:`tool_frame`) at ``q``."""
        name = frame or self.tool_frame
        if not self.model.existFrame(name):
            raise DimensionError(
                f"frame {name!r} is not in robot {self.name!r}; known frames: "
                f"{[f.name for f in self.model.frames]}"
            )
        fid = self.model.getFrameId(name)
        pin.framesForwardKinematics(self.model, self.data, q)
        return pin.SE3(self.data.oMf[fid])

    def __repr__(self) -> str:
        return (
            f"Robot({self.name!r}, n={self.nq}, joints={self.joint_names}, source={self.source!r})"
        )


def damping_time_constants(robot, q: np.ndarray) -> np.ndarray:
    """Per joint the time constant [s] of the URDF's joint damping at posture ``q``:

    .. math:: T_j = \\frac{m_j}{b_j}, \\qquad m_j = \\frac{1}{(M(q)^{-1})_{jj}}

    (``inf`` for an undamped joint). The one definition every part uses: the controller's
    warning, ``hmpc-pin check``, ``init`` and the plant's step check.

    The mass is joint j's effective inertia with the other joints free,
    :math:`1/(M^{-1})_{jj}`, not :math:`M_{jj}` (the inertia with the others locked):
    a torque on joint j accelerates it by :math:`(M^{-1})_{jj}` per N·m while the others
    move, so joint j's velocity relaxes at the rate :math:`\\lambda_j = b_j
    (M^{-1})_{jj}`. That is the rate an explicit integrator must resolve and the one the
    zero-order-hold gain of the compiled step uses. Since :math:`1/(M^{-1})_{jj} \\le
    M_{jj}`, :math:`M_{jj}/b_j` would overstate the time constant (Z1's wrist: 0.76 ms
    either way at its sine's posture, but on coupled joints up to several times).

    Args:
        robot: Any model with ``mass_matrix(q)`` and ``joint_damping`` [N·m·s/rad]
            (a model without ``joint_damping`` has no damping).
        q: Posture [rad or m].
    """
    M = np.asarray(robot.mass_matrix(np.asarray(q, dtype=float)), dtype=float)
    n = M.shape[0]
    b = np.asarray(getattr(robot, "joint_damping", np.zeros(n)), dtype=float)
    out = np.full(n, np.inf)
    if not b.any():
        return out
    m = 1.0 / np.diag(np.linalg.inv(M))
    on = b > 0
    out[on] = m[on] / b[on]
    return out


def load_robot(
    source: str | Path,
    gravity: float = 9.8,
    locked_joints: Mapping[str, float] | None = None,
) -> Robot:
    """Load a fixed-base arm from a URDF file or an ``example-robot-data`` name.

    The file is validated first (existence, XML, URDF completeness, joint types)
    so that a bad file raises :class:`~hmpc_pin.exceptions.URDFError` naming the
    file and the problem.

    Args:
        source: Path of a ``.urdf`` file, or a robot name: ``"planar3"`` (the paper's
            arm, shipped in the package) or an ``example-robot-data`` model (``"ur5"``,
            ``"ur10"``, ``"panda"``, ``"z1"``, ...). A string is
            taken as a name when no file of that name exists and it has no suffix.
        gravity: Magnitude of gravity [m/s²], acting along the world −z axis.
            The paper uses 9.8 (Table 1), not Pinocchio's default 9.81.
        locked_joints: Joints not to control, by URDF name, with the position
            [rad or m] each is locked at (e.g. Panda's fingers). They are removed with
            ``pin.buildReducedModel``; their mass still loads the arm.

    Returns:
        The :class:`Robot`.
    """
    path = Path(source)
    if not path.exists() and not path.suffix and len(path.parts) == 1:
        packaged = robot_path(str(source))
        path = packaged if packaged is not None else example_robot_urdf(str(source))
    if not np.isfinite(gravity) or gravity < 0:
        raise URDFError(path, f"gravity={gravity!r}; expected a finite value >= 0")
    locked = {str(k): float(v) for k, v in (locked_joints or {}).items()}
    root = check_urdf(path, tuple(locked))
    mimics = urdf_mimics(root)
    for follower, (leader, _, _) in mimics.items():
        if follower in locked and leader not in locked:
            raise URDFError(
                path,
                f"locked joint {follower!r} mimics {leader!r}, which is not locked; lock "
                f"{leader!r} (the follower is then locked with it) or neither",
            )
    changed = True
    while changed:  # followers of locked leaders (and their followers) are locked too
        changed = False
        for follower, (leader, mult, offset) in mimics.items():
            if leader in locked and follower not in locked:
                locked[follower] = mult * locked[leader] + offset
                changed = True
    xml, continuous = _without_continuous(root)
    try:
        model = pin.buildModelFromXML(xml)
    except (ValueError, RuntimeError) as exc:
        raise URDFError(path, f"Pinocchio could not build a model: {exc}") from exc
    model.name = root.get("name", model.name)
    for name in continuous:  # revolute without position limits
        idx = model.joints[model.getJointId(name)].idx_q
        model.lowerPositionLimit[idx] = -np.inf
        model.upperPositionLimit[idx] = np.inf
    if locked:
        model = _reduce(model, path, locked)
    active = {f: v for f, v in mimics.items() if f not in locked}
    model.gravity.linear = np.array([0.0, 0.0, -float(gravity)])
    base = model if active else None
    model = _apply_mimics(model, active)
    return Robot(
        model,
        path,
        locked,
        active,
        tuple(c for c in continuous if c not in locked),
        base_model=base,
    )


def _apply_mimics(model: pin.Model, mimics: Mapping[str, tuple[str, float, float]]) -> pin.Model:
    """``model`` with each follower of ``mimics`` made Pinocchio's mimic joint of its leader
    (a new model; ``model`` itself is unchanged)."""
    for follower, (leader, mult, offset) in mimics.items():
        model = pin.transformJointIntoMimic(
            model, model.getJointId(leader), model.getJointId(follower), mult, offset
        )
    return model


def _crba_forward_dynamics(model: pin.Model, data: pin.Data, q, dq, tau) -> np.ndarray:
    """:math:`\\ddot q = M(q)^{-1}(\\tau - h(q, \\dot q))` by CRBA and a Cholesky solve:
    the forward dynamics of a model with mimic joints, which ``pin.aba`` refuses."""
    m = pin.crba(model, data, q)
    m = np.triu(m) + np.triu(m, 1).T
    h = pin.nonLinearEffects(model, data, q, dq)
    return np.linalg.solve(m, tau - h)


def _reduce(model: pin.Model, path: Path, locked: dict[str, float]) -> pin.Model:
    """Remove the ``locked`` joints at their given positions (``pin.buildReducedModel``)."""
    q_ref = pin.neutral(model)
    ids = []
    for name, value in locked.items():
        jid = model.getJointId(name)
        joint = model.joints[jid]
        if not np.isfinite(value):
            raise URDFError(path, f"locked joint {name!r} at {value!r}; expected a finite value")
        if joint.nq == 2:  # continuous joint: (cos, sin) of the locked angle
            q_ref[joint.idx_q : joint.idx_q + 2] = (np.cos(value), np.sin(value))
        else:
            lo = model.lowerPositionLimit[joint.idx_q]
            hi = model.upperPositionLimit[joint.idx_q]
            if not lo <= value <= hi:
                raise URDFError(
                    path,
                    f"locked joint {name!r} at {value!r} is outside its limits [{lo:g}, {hi:g}]",
                )
            q_ref[joint.idx_q] = value
        ids.append(jid)
    try:
        return pin.buildReducedModel(model, ids, q_ref)
    except (ValueError, RuntimeError) as exc:  # e.g. a joint and a link of the same name
        raise URDFError(
            path,
            f"Pinocchio cannot lock {sorted(locked)}: {exc}; a joint that shares its name "
            "with a link cannot be locked (rename one of them in the URDF)",
        ) from exc
