"""A URDF checked before Pinocchio sees it: well-formedness (with line and column), the
structure and completeness the URDF specification requires (names, joint types, parent
and child links, limits, numbers, geometry), the joint types the controller supports and
physically valid link inertias, so that a bad file gets one message naming the file and
the problem instead of urdfdom's terse output (:func:`~hmpc_pin.model.urdf_checks.check_urdf`)."""

from __future__ import annotations

import math
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from ..exceptions import URDFError, ValidityWarning

__all__ = ["SUPPORTED_JOINT_TYPES", "URDF_JOINT_TYPES", "check_inertias", "check_urdf"]

#: The classes of yourdfpy's ``URDF.validate`` errors, which name each problem (the
#: messages of earlier versions, which checked the file with yourdfpy, are kept word for word).
_INCOMPLETE, _BAD_VALUE = "URDFIncompleteError", "URDFAttributeValueError"
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
#: URDF joint types the controller supports (one coordinate each, nq == nv; a continuous
#: joint becomes a revolute joint without position limits).
SUPPORTED_JOINT_TYPES = ("revolute", "prismatic", "continuous")


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
    (:meth:`~hmpc_pin.model.robot.Robot.check_mass_matrix`). Links fixed to the world are
    not checked (their inertia acts on nothing). Tolerances: :math:`10^{-9}` of the
    largest moment for the sign, :math:`10^{-6}` of the trace for the triangle (values
    rounded in the file).

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
