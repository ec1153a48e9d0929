"""The arm's workspace: its collision geometry above the mounting plane and free of
self-collision, at a posture or along a joint trajectory.

The geometry is the URDF's ``<collision>`` elements, loaded by Pinocchio
(``pin.buildGeomFromUrdf`` with ``pin.COLLISION``: meshes as coal BVH models, primitives as
coal shapes) on the arm's *whole* kinematic tree: the controlled joints, the locked ones at
their positions, mimic followers at :math:`m\\,q_l + o`.

* **The mounting plane** is :math:`\\{x : n^T x = h\\}` in the URDF's root frame, ``normal``
  n (made unit) and ``height`` h [m]; the arm stands on the side n points to. A geometry's
  *clearance* is the distance of its lowest point above the plane,
  :math:`\\min_{x \\in \\text{geometry}} n^T x - h`, computed exactly from the shape's
  support function: the vertices of a mesh (its convex hull's, the same minimum), the
  corners of a box, a sphere's centre less its radius, a capsule's or a cylinder's axis
  and rim. The geometry fixed to the base (the root link and what is welded to it) stands
  on the plane and is not checked, nor is a geometry whose clearance no joint changes
  (a link turning about the plane's normal only, such as a first link above a vertical
  axis: where it is mounted is not a motion; :data:`INVARIANT_TOL`). Every other geometry
  must keep a clearance of at least ``margin``.
* **Self-collision** is Pinocchio's ``computeCollisions`` (coal's exact test on the
  meshes) over every pair of geometries on different links, less the pairs that may
  touch: adjacent links (a link and its parent in the kinematic tree, which meet at their
  joint), with an SRDF its ``<disable_collisions>`` pairs (``pin.removeCollisionPairs``),
  and the pairs the caller allows. Geometries welded to one another (by a fixed or a
  locked joint) are one rigid body, never a pair.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..exceptions import ConfigError, URDFError

__all__ = [
    "INVARIANT_TOL",
    "MARGIN",
    "PlaneViolation",
    "SelfCollision",
    "Workspace",
    "WorkspaceScan",
    "find_srdf",
]

#: The clearance [m] a moving link keeps above the mounting plane by default: a table's
#: thickness of error in where the arm is mounted, and a link's mesh that is a few
#: millimetres short of the real cover.
MARGIN = 0.02

#: A geometry whose clearance varies less than this [m] over seeded postures is where it
#: is mounted, not moved (so101's shoulder: 2e-7 m, its pan axis a rounding off vertical;
#: the links that move vary by centimetres).
INVARIANT_TOL = 1e-4


def find_srdf(path: str | Path, name: str | None = None) -> Path | None:
    """The SRDF of the arm: example-robot-data's for the model ``name``, else where a ROS
    description package keeps it beside the URDF ``path`` (``arm.srdf`` next to it, or
    ``../srdf/arm.srdf``); ``None`` when there is none."""
    from .catalogue import example_robot_srdf

    if name:
        srdf, _ = example_robot_srdf(name)
        if srdf is not None:
            return srdf
    path = Path(path)
    for candidate in (path.with_suffix(".srdf"), path.parent.parent / "srdf" / f"{path.stem}.srdf"):
        if candidate.is_file():
            return candidate
    return None


@dataclass(frozen=True)
class PlaneViolation:
    """A link below the mounting plane plus the margin.

    Attributes:
        link: The URDF link whose collision geometry goes too low.
        first: The first time it does [s] (or sample index, without times).
        lowest: Its lowest clearance along the trajectory [m] (negative: below the plane).
        at: The time of the lowest clearance [s].
    """

    link: str
    first: float
    lowest: float
    at: float

    def describe(self, margin: float) -> str:
        """One sentence naming the link and the times."""
        where = (
            f"{-self.lowest:.3g} m below the mounting plane"
            if self.lowest < 0
            else f"{self.lowest:.3g} m above the mounting plane (margin {margin:g} m)"
        )
        return (
            f"link {self.link!r} leaves the workspace at t = {self.first:.3g} s: its collision "
            f"geometry reaches {where} at t = {self.at:.3g} s"
        )


@dataclass(frozen=True)
class SelfCollision:
    """Two links whose collision geometries intersect.

    Attributes:
        links: The two URDF links.
        first: The first time they collide [s].
        last: The last time they do [s].
    """

    links: tuple[str, str]
    first: float
    last: float

    def describe(self) -> str:
        """One sentence naming the links and the times."""
        span = (
            f"at t = {self.first:.3g} s"
            if self.last == self.first
            else f"from t = {self.first:.3g} s (until {self.last:.3g} s)"
        )
        return f"links {self.links[0]!r} and {self.links[1]!r} collide {span}"


@dataclass
class WorkspaceScan:
    """What :meth:`Workspace.scan` found along a trajectory.

    Attributes:
        clearance: Per checked link, its lowest clearance above the plane [m] along the
            trajectory.
        below: The links below the plane plus the margin.
        collisions: The colliding pairs.
        margin: The margin it was checked with [m].
    """

    clearance: dict[str, float]
    below: list[PlaneViolation] = field(default_factory=list)
    collisions: list[SelfCollision] = field(default_factory=list)
    margin: float = MARGIN

    @property
    def ok(self) -> bool:
        """No link below the plane plus the margin and no collision."""
        return not self.below and not self.collisions

    def lines(self) -> list[str]:
        """One sentence per finding."""
        return [v.describe(self.margin) for v in self.below] + [
            c.describe() for c in self.collisions
        ]


class _Support:
    """The lowest point of one geometry along a direction, in its own frame."""

    def __init__(self, geometry):
        import coal

        self.points: np.ndarray | None = None
        self.radius = 0.0
        self.kind = "points"
        if isinstance(geometry, coal.Sphere):
            self.points, self.radius = np.zeros((1, 3)), float(geometry.radius)
        elif isinstance(geometry, coal.Capsule):
            h = float(geometry.halfLength)
            self.points, self.radius = np.array([[0, 0, -h], [0, 0, h]]), float(geometry.radius)
        elif isinstance(geometry, coal.Box):
            half = np.asarray(geometry.halfSide, dtype=float)
            signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
            self.points = signs * half
        elif isinstance(geometry, coal.Cylinder):
            self.kind = "cylinder"
            self.r, self.h = float(geometry.radius), float(geometry.halfLength)
        elif isinstance(geometry, coal.Cone):
            self.kind = "cone"
            self.r, self.h = float(geometry.radius), float(geometry.halfLength)
        elif isinstance(geometry, coal.Ellipsoid):
            self.kind = "ellipsoid"
            self.radii = np.asarray(geometry.radii, dtype=float)
        elif hasattr(geometry, "vertices") and geometry.num_vertices > 0:
            self.points = _hull(np.asarray(geometry.vertices(), dtype=float))
        elif hasattr(geometry, "points"):  # a convex polytope
            self.points = _hull(np.asarray(geometry.points(), dtype=float))
        else:  # any other shape: its local bounding box (lower, never higher)
            geometry.computeLocalAABB()
            box = geometry.aabb_local
            lo, hi = np.asarray(box.min_, dtype=float), np.asarray(box.max_, dtype=float)
            self.points = np.array(
                [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
            )

    def lowest(self, d: np.ndarray) -> np.ndarray:
        """:math:`\\min_x d^T x` over the geometry for each unit direction row of ``d``
        (shape (T, 3), in the geometry's frame)."""
        if self.kind == "cylinder":
            dz = np.clip(np.abs(d[:, 2]), 0.0, 1.0)
            return -self.h * dz - self.r * np.sqrt(1.0 - dz**2)
        if self.kind == "cone":  # apex at +h on z, base disc of radius r at -h
            dz = np.clip(d[:, 2], -1.0, 1.0)
            return np.minimum(self.h * dz, -self.h * dz - self.r * np.sqrt(1.0 - dz**2))
        if self.kind == "ellipsoid":
            return -np.sqrt(((d * self.radii) ** 2).sum(axis=1))
        assert self.points is not None
        return (d @ self.points.T).min(axis=1) - self.radius


def _hull(points: np.ndarray) -> np.ndarray:
    """The vertices of the convex hull of ``points`` (all of them if qhull refuses)."""
    if len(points) <= 8:
        return points
    from scipy.spatial import ConvexHull, QhullError

    try:
        return points[ConvexHull(points).vertices]
    except (QhullError, ValueError):
        return points


class Workspace:
    """The collision geometry of an arm, for the mounting-plane and self-collision checks
    (module docstring).

    Args:
        robot: The controlled :class:`~hmpc_pin.model.robot.Robot` (its URDF, locked and
            mimic joints).
        height: Height h of the mounting plane along ``normal`` [m].
        normal: The plane's normal n, pointing to the arm's side (made unit) [-].
        margin: The clearance every moving link keeps above the plane [m].
        srdf: The arm's SRDF, whose ``<disable_collisions>`` pairs are not checked
            (adjacent links never are).
        self_collision: Check the pairs of links (``False``: the plane only).
        allowed: Pairs of links not checked either, by URDF name (links that touch by
            design).

    Attributes:
        links: Per geometry, its URDF link.
        checked: Per geometry, whether its clearance is checked (a moving link).
        pairs: The pairs of links checked for self-collision.

    Raises:
        URDFError: Pinocchio cannot load the collision geometry (a mesh missing).
        ConfigError: ``normal`` is not 3 finite numbers, or all 0.
    """

    def __init__(
        self,
        robot,
        *,
        height: float = 0.0,
        normal: Sequence[float] = (0.0, 0.0, 1.0),
        margin: float = MARGIN,
        srdf: str | Path | None = None,
        self_collision: bool = True,
        allowed: Sequence[Sequence[str]] = (),
    ):
        from .robot import without_continuous

        path = Path(robot.source)
        n = np.asarray(normal, dtype=float)
        if n.shape != (3,) or not np.all(np.isfinite(n)) or np.linalg.norm(n) == 0:
            raise ConfigError("normal", f"expected 3 finite numbers, not all 0, got {normal!r}")
        self.normal = n / np.linalg.norm(n)
        self.height, self.margin = float(height), float(margin)
        self.srdf = Path(srdf) if srdf is not None else None
        try:  # the robot was loaded from it: checked already
            root = ET.parse(path).getroot()
        except (OSError, ET.ParseError) as exc:
            raise URDFError(
                path, f"cannot be read again for its collision geometry: {exc}"
            ) from exc
        xml, _ = without_continuous(root)
        self.model = pin.buildModelFromXML(xml)
        try:
            self.geometry = pin.buildGeomFromUrdf(
                self.model,
                str(path),
                pin.COLLISION,
                package_dirs=[str(p) for p in path.resolve().parents],
            )
        except (ValueError, RuntimeError) as exc:
            raise URDFError(path, f"Pinocchio cannot load its collision geometry: {exc}") from exc
        self.data = self.model.createData()
        self.gdata = pin.GeometryData(self.geometry)
        objects = list(self.geometry.geometryObjects)
        self.links = tuple(self.model.frames[g.parentFrame].name for g in objects)
        self._supports = [_Support(g.geometry) for g in objects]
        self._map = self._coordinates(robot)
        self._pairs(self_collision, allowed)
        self.checked = self._moving(robot)

    # -- the whole tree's configuration -------------------------------------------------

    def _coordinates(self, robot):
        """Per coordinate of the whole model: (index of the controlled coordinate it follows
        or ``None``, multiplier, offset): q_full = offset + multiplier q[index]."""
        names = list(robot.joint_names)
        out = []
        for j in range(1, self.model.njoints):
            name = self.model.names[j]
            if name in names:
                out.append((names.index(name), 1.0, 0.0))
            elif name in robot.locked_joints:
                out.append((None, 0.0, float(robot.locked_joints[name])))
            elif name in robot.mimic_joints:
                leader, mult, offset = robot.mimic_joints[name]
                out.append((names.index(leader), float(mult), float(offset)))
            else:  # a joint Pinocchio reduced away differently: at 0
                out.append((None, 0.0, 0.0))
        return out

    def full(self, q: np.ndarray) -> np.ndarray:
        """The whole tree's configurations (T, nq_full) for controlled ones ``q`` (T, n)."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        out = np.empty((q.shape[0], self.model.nq))
        for k, (i, mult, offset) in enumerate(self._map):
            out[:, k] = offset + (mult * q[:, i] if i is not None else 0.0)
        return out

    # -- pairs and moving links -----------------------------------------------------------

    def _pairs(self, self_collision: bool, allowed) -> None:
        gm, model = self.geometry, self.model
        if self_collision:
            gm.addAllCollisionPairs()
        if self.srdf is not None and self_collision:
            pin.removeCollisionPairs(model, gm, str(self.srdf), False)
        # a locked joint does not move: what it carries is one rigid body with its parent
        moves = [False] + [i is not None for i, _, _ in self._map]
        body = list(range(model.njoints))
        for j in range(1, model.njoints):  # parents come first in Pinocchio's order
            body[j] = j if moves[j] else body[model.parents[j]]

        def parent_body(j: int) -> int:
            return body[model.parents[j]] if j else -1

        allowed = {frozenset(p) for p in allowed}
        objects = list(gm.geometryObjects)
        for k in reversed(range(len(gm.collisionPairs))):
            pair = gm.collisionPairs[k]
            a = body[objects[pair.first].parentJoint]
            b = body[objects[pair.second].parentJoint]
            adjacent = parent_body(a) == b or parent_body(b) == a
            names = frozenset((self.links[pair.first], self.links[pair.second]))
            if a == b or adjacent or names in allowed:
                gm.removeCollisionPair(pair)
        self.gdata = pin.GeometryData(gm)
        self.pairs = tuple((self.links[p.first], self.links[p.second]) for p in gm.collisionPairs)

    def _moving(self, robot) -> np.ndarray:
        """Whether each geometry's clearance changes with the joints (12 seeded postures)."""
        rng = np.random.default_rng(0)
        lo = np.where(np.isfinite(robot.lower), robot.lower, -math.pi)
        hi = np.where(np.isfinite(robot.upper), robot.upper, math.pi)
        c = self.clearance(rng.uniform(lo, hi, size=(12, robot.nq)))
        base = np.array([g.parentJoint == 0 for g in self.geometry.geometryObjects], dtype=bool)
        return ~base & (np.ptp(c, axis=0) > INVARIANT_TOL)

    # -- the checks -----------------------------------------------------------------------

    def clearance(self, q: np.ndarray) -> np.ndarray:
        """Each geometry's clearance above the plane [m] at the postures ``q`` (T, n):
        shape (T, ngeoms), negative below it."""
        Q = self.full(q)
        G = len(self._supports)
        up = np.empty((Q.shape[0], G, 3))  # the normal in each geometry's frame
        at = np.empty((Q.shape[0], G))  # the normal's component of each geometry's origin
        model, data, gm, gdata = self.model, self.data, self.geometry, self.gdata
        for t, qf in enumerate(Q):
            pin.framesForwardKinematics(model, data, qf)
            pin.updateGeometryPlacements(model, data, gm, gdata)
            for g in range(G):
                M = gdata.oMg[g]
                up[t, g] = M.rotation.T @ self.normal
                at[t, g] = self.normal @ M.translation
        out = np.empty((Q.shape[0], G))
        for g, support in enumerate(self._supports):
            out[:, g] = at[:, g] + support.lowest(up[:, g])
        return out - self.height

    def collides(self, q: np.ndarray) -> bool:
        """Whether any pair of :attr:`pairs` intersects at posture ``q`` (the test stops
        at the first)."""
        if not self.pairs:
            return False
        qf = self.full(q)[0]
        return bool(
            pin.computeCollisions(self.model, self.data, self.geometry, self.gdata, qf, True)
        )

    def colliding(self, q: np.ndarray) -> list[tuple[str, str]]:
        """The pairs of links (:attr:`pairs`) whose geometries intersect at posture ``q``."""
        qf = self.full(q)[0]
        pin.computeCollisions(self.model, self.data, self.geometry, self.gdata, qf, False)
        out = []
        for k, result in enumerate(self.gdata.collisionResults):
            if result.isCollision():
                pair = self.geometry.collisionPairs[k]
                out.append((self.links[pair.first], self.links[pair.second]))
        return out

    def scan(self, q: np.ndarray, t: np.ndarray | None = None) -> WorkspaceScan:
        """The clearance of every checked link and the self-collisions along the
        trajectory ``q`` (T, n) sampled at times ``t`` [s] (default: the sample index)."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        t = np.arange(len(q), dtype=float) if t is None else np.asarray(t, dtype=float)
        c = self.clearance(q)
        out = WorkspaceScan({}, margin=self.margin)
        per_link: dict[str, np.ndarray] = {}
        for g in np.flatnonzero(self.checked):
            link = self.links[g]
            prev = per_link.get(link)
            per_link[link] = c[:, g] if prev is None else np.minimum(prev, c[:, g])
        for link, values in per_link.items():
            out.clearance[link] = float(values.min())
            low = np.flatnonzero(values < self.margin)
            if low.size:
                k = int(np.argmin(values))
                out.below.append(
                    PlaneViolation(link, float(t[low[0]]), float(values[k]), float(t[k]))
                )
        times: dict[tuple[str, str], list[float]] = {}
        for k in range(len(q)):
            for pair in self.colliding(q[k]):
                times.setdefault(pair, []).append(float(t[k]))
        out.collisions = [SelfCollision(p, ts[0], ts[-1]) for p, ts in times.items()]
        out.below.sort(key=lambda v: v.first)
        out.collisions.sort(key=lambda c: c.first)
        return out

    def score(self, q: np.ndarray) -> float:
        """The smallest clearance above the plane plus the margin of the checked links
        along ``q`` (T, n) [m], or -1 when two links collide (a posture search's
        objective: >= 0 is inside the workspace)."""
        c = self.clearance(q)[:, self.checked]
        low = float(c.min()) - self.margin if c.size else math.inf
        if any(self.collides(qk) for qk in np.atleast_2d(q)):
            return min(low, -1.0)
        return low
