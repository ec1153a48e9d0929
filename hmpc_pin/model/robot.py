"""Robot model: a URDF loaded into Pinocchio, with the dynamics terms of Eq (1).

.. math::  M(q)\\,\\ddot q + C(q,\\dot q)\\,\\dot q + G(q) = \\tau + d   \\qquad (1)

Every dynamics quantity comes from Pinocchio: ``crba`` for :math:`M`,
``nonLinearEffects`` for :math:`C\\dot q + G`, ``computeGeneralizedGravity`` for
:math:`G`, ``aba`` for the forward dynamics and ``rnea`` for the inverse dynamics.
No dynamics is written by hand.

Before Pinocchio sees a file, the file is checked with the standard library's XML
parser (:mod:`hmpc_pin.model.urdf_checks`): well-formedness (with line and column), the
structure and completeness the URDF specification requires (names, joint types, parent
and child links, limits, numbers, geometry), so that a bad file gets a message naming
the file and the problem instead of urdfdom's terse output. An arm is named by its URDF
file or by its name in ``example-robot-data`` (:mod:`hmpc_pin.model.catalogue`).

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

import xml.etree.ElementTree as ET
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..data import robot_path
from ..exceptions import DimensionError, NonFiniteError, URDFError
from .catalogue import MOUNTED_ARMS, example_robot_names, example_robot_srdf, example_robot_urdf
from .urdf_checks import SUPPORTED_JOINT_TYPES, URDF_JOINT_TYPES, check_inertias, check_urdf

# the URDF checks (.urdf_checks) and the catalogue (.catalogue) are re-exported here
__all__ = [
    "MOUNTED_ARMS",
    "SUPPORTED_JOINT_TYPES",
    "URDF_JOINT_TYPES",
    "Robot",
    "check_inertias",
    "check_urdf",
    "damping_time_constants",
    "example_robot_names",
    "example_robot_srdf",
    "example_robot_urdf",
    "load_robot",
    "urdf_mimics",
    "without_continuous",
]


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


def without_continuous(root: ET.Element) -> tuple[str, tuple[str, ...]]:
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
    xml, continuous = without_continuous(root)
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
