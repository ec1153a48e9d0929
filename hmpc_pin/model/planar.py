"""Closed-form kinematics of a planar three-revolute (3R) arm, checked against Pinocchio.

Section 5.4 of the paper moves the tool point of the three-link arm between two
Cartesian poses: from :math:`(1.2, 0.5)` with link 3 at :math:`-90°` to the
:math:`x` axis, to :math:`(2.423, 2.234)` with link 3 parallel to the :math:`x`
axis. The paper's planar coordinates :math:`(x, y)` are the URDF :math:`(x, z)`.

Geometry (read from the Pinocchio model, never typed in): with
:math:`e(\\theta) = (\\cos\\theta, \\sin\\theta)` in the :math:`x`–:math:`z` plane,
joint signs :math:`s_i = -a_{i,y} = \\pm 1` (:math:`a_i` the world joint axis, so
that :math:`s_i = +1` for the URDF axis :math:`(0, -1, 0)`: a positive angle lifts
the link), link lengths :math:`l_i`, link directions :math:`\\alpha_i` and tool
angle :math:`\\varphi_0` at :math:`q = 0`, and base point :math:`p_0`,

.. math::

    \\theta_j(q) = \\alpha_j + \\sum_{i \\le j} s_i q_i, \\qquad
    p(q) = p_0 + \\sum_{j=1}^{3} l_j\\, e(\\theta_j), \\qquad
    \\varphi(q) = \\varphi_0 + \\sum_{i=1}^{3} s_i q_i .

For ``robots/planar3.urdf`` :math:`s = (1, 1, 1)`, :math:`\\alpha = 0`,
:math:`\\varphi_0 = 0`, :math:`p_0 = 0`, :math:`l = (1.5, 1.2, 1.0)`, hence
:math:`\\varphi = q_1 + q_2 + q_3`.

Inverse kinematics (closed form): the wrist point is
:math:`w = p - l_3\\, e(\\theta_3) - p_0` with
:math:`\\theta_3 = \\alpha_3 + \\varphi - \\varphi_0`;
the two-link problem :math:`l_1 e(\\theta_1) + l_2 e(\\theta_2) = w` has

.. math::

    \\cos\\gamma = \\frac{|w|^2 - l_1^2 - l_2^2}{2 l_1 l_2}, \\quad
    \\theta_2 - \\theta_1 = \\gamma = \\pm\\arccos(\\cdot), \\quad
    \\theta_1 = \\operatorname{atan2}(w_z, w_x)
        - \\operatorname{atan2}(l_2 \\sin\\gamma,\\; l_1 + l_2 \\cos\\gamma),

two elbow branches, real when :math:`|l_1 - l_2| \\le |w| \\le l_1 + l_2`.
``"elbow_up"`` is :math:`\\gamma < 0`: the elbow lies counter-clockwise of the
line from joint 1 to the wrist (above it when the wrist is to the right of the
base). Each joint angle is then taken modulo :math:`2\\pi` into its limits
(Eq 27, :math:`lb_i \\le q_i \\le ub_i`) when possible, and every returned
solution is verified with Pinocchio's forward kinematics.

All lengths are in the model's length unit (the paper's dimensionless units for
planar3), all angles in radians unless a name or message says degrees.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import pinocchio as pin

from ..exceptions import KinematicsError
from .robot import Robot

__all__ = [
    "KinematicsError",
    "planar_chain",
    "planar_ik",
    "solve_pose",
    "tool_pose",
    "workspace_points",
]

Branch = Literal["elbow_up", "elbow_down"]
_BRANCHES: tuple[Branch, Branch] = ("elbow_up", "elbow_down")
#: Tolerance of the geometric checks (planarity, axis direction) [model units / rad].
_GEOM_TOL = 1e-9
#: Forward-kinematics tolerance of a returned IK solution, per unit of reach.
_FK_TOL = 1e-9


# --------------------------------------------------------------------------- chain
@dataclass(frozen=True)
class _Chain:
    """Planar geometry of a 3R arm at :math:`q = 0` (see the module docstring)."""

    frame: str
    frame_id: int
    lengths: np.ndarray  # (3,) l_1, l_2, l_3
    signs: np.ndarray  # (3,) s_i = ±1
    alphas: np.ndarray  # (3,) link directions at q = 0 [rad]
    phi0: float  # tool x-axis angle at q = 0 [rad]
    base: np.ndarray  # (2,) joint-1 origin (x, z)

    @property
    def reach(self) -> float:
        return float(self.lengths.sum())


def _xz(v: np.ndarray) -> np.ndarray:
    return np.array([v[0], v[2]], dtype=float)


def _angle(v: np.ndarray) -> float:
    """Angle of a 3-D vector's (x, z) projection with the x axis [rad]."""
    return math.atan2(float(v[2]), float(v[0]))


def _chain(robot: Robot, tool_frame: str | None = None) -> _Chain:
    """Read and check the planar 3R geometry of ``robot`` (see :func:`planar_chain`)."""
    model = robot.model
    name = tool_frame or robot.tool_frame
    why = "closed-form IK supports planar 3R arms only"
    if not model.existFrame(name):
        raise KinematicsError(
            f"frame {name!r} is not in robot {robot.name!r}; known frames: "
            f"{[f.name for f in model.frames]}",
            value=name,
            expected="the name of a frame of the robot",
        )
    if model.nq != 3 or model.njoints != 4:
        raise KinematicsError(
            f"robot {robot.name!r} has {model.nq} joint coordinates {robot.joint_names}; "
            f"{why} (three revolute joints)",
            value=model.nq,
            expected="3 revolute joints",
        )
    for j in range(1, 4):
        if model.parents[j] != j - 1:
            raise KinematicsError(
                f"robot {robot.name!r}: joint {model.names[j]!r} hangs from joint "
                f"{model.names[model.parents[j]]!r}; {why} forming a serial chain",
                value=int(model.parents[j]),
                expected=f"parent joint index {j - 1}",
            )
    fid = model.getFrameId(name)
    frame = model.frames[fid]
    if frame.parentJoint != 3:
        raise KinematicsError(
            f"robot {robot.name!r}: tool frame {name!r} is attached to joint "
            f"{model.names[frame.parentJoint]!r}, not to the last joint {model.names[3]!r}; "
            f"{why} with the tool on link 3",
            value=name,
            expected=f"a frame attached to joint {model.names[3]!r}",
        )

    data = model.createData()
    q0 = np.zeros(model.nq)
    pin.framesForwardKinematics(model, data, q0)
    signs = np.empty(3)
    for j in range(1, 4):
        jm = model.joints[j]
        jd = jm.createData()
        jm.calc(jd, q0)
        s = np.asarray(jd.S, dtype=float).reshape(6)
        if np.linalg.norm(s[:3]) > _GEOM_TOL or abs(np.linalg.norm(s[3:]) - 1.0) > _GEOM_TOL:
            raise KinematicsError(
                f"robot {robot.name!r}: joint {model.names[j]!r} ({jm.shortname()}) is not a "
                f"revolute joint (motion subspace {s.round(6).tolist()}); {why}",
                value=s,
                expected="a revolute joint",
            )
        axis = data.oMi[j].rotation @ s[3:]
        if abs(abs(axis[1]) - 1.0) > _GEOM_TOL:
            raise KinematicsError(
                f"robot {robot.name!r}: joint {model.names[j]!r} has world axis "
                f"{np.round(axis, 9).tolist()} at q = 0; {why} moving in the x–z plane, "
                "with every joint axis along ±y",
                value=axis,
                expected="a joint axis (0, ±1, 0)",
            )
        signs[j - 1] = -np.sign(axis[1])

    points = [data.oMi[j].translation for j in (1, 2, 3)] + [data.oMf[fid].translation]
    links = [points[k + 1] - points[k] for k in range(3)]
    # At q = 0 every joint motion is the identity, so links[k] is joint k's placement
    # translation rotated into the world: the norms are the model's own lengths.
    lengths = np.array(
        [
            np.linalg.norm(model.jointPlacements[2].translation),
            np.linalg.norm(model.jointPlacements[3].translation),
            np.linalg.norm(frame.placement.translation),
        ]
    )
    # Rotations about axes parallel to y keep every y coordinate, so a chain whose
    # axes are all ±y moves in planes y = const; the links and the tool x axis must
    # have no y component for the (x, z) geometry to be the whole geometry.
    for k, v in enumerate(links):
        if abs(v[1]) > _GEOM_TOL * max(1.0, lengths[k]):
            raise KinematicsError(
                f"robot {robot.name!r}: link {k + 1} has a y offset of {v[1]:.6g} at q = 0; "
                f"{why} whose links lie in the x–z plane",
                value=v,
                expected="a link vector (x, 0, z)",
            )
    for k in (0, 1):
        if lengths[k] <= _GEOM_TOL:
            raise KinematicsError(
                f"robot {robot.name!r}: link {k + 1} has length {lengths[k]:.6g}; "
                f"{why} with links 1 and 2 of positive length",
                value=float(lengths[k]),
                expected="a length > 0",
            )
    x_tool = data.oMf[fid].rotation[:, 0]
    if abs(x_tool[1]) > _GEOM_TOL:
        raise KinematicsError(
            f"robot {robot.name!r}: the x axis of tool frame {name!r} is "
            f"{np.round(x_tool, 9).tolist()} at q = 0; the tool angle φ is measured "
            "from a tool x axis lying in the x–z plane",
            value=x_tool,
            expected="a tool x axis (x, 0, z)",
        )
    phi0 = _angle(x_tool)
    # A zero-length link 3 has no direction of its own; the tool angle stands for it.
    alphas = np.array([_angle(v) for v in links[:2]] + [_angle(links[2]) if lengths[2] else phi0])
    return _Chain(
        frame=name,
        frame_id=int(fid),
        lengths=lengths,
        signs=signs,
        alphas=alphas,
        phi0=phi0,
        base=_xz(points[0]),
    )


def planar_chain(robot: Robot, tool_frame: str | None = None) -> np.ndarray:
    """Link lengths of a planar 3R arm, after checking that the arm is one.

    The lengths are the norms of ``robot.model.jointPlacements[j].translation`` for
    joints 2 and 3 and of the tool frame's placement relative to joint 3
    (``robot.model.frames[fid].placement``). The checks: three revolute joints in a
    serial chain, the tool frame on the last joint, every joint axis along world
    :math:`\\pm y` and every link (and the tool's :math:`x` axis) in the :math:`x`–:math:`z`
    plane at :math:`q = 0`, links 1 and 2 of positive length.

    Args:
        robot: The arm.
        tool_frame: Name of the tool frame (default: :attr:`Robot.tool_frame`).

    Returns:
        :math:`(l_1, l_2, l_3)`, shape (3,), in the model's length unit
        (``(1.5, 1.2, 1.0)`` for planar3).

    Raises:
        KinematicsError: If the arm is not a planar 3R arm in the :math:`x`–:math:`z`
            plane; the message names the joint, link or frame that breaks it.
    """
    return _chain(robot, tool_frame).lengths.copy()


# ---------------------------------------------------------------------- forward
def tool_pose(robot: Robot, q, tool_frame: str | None = None) -> tuple[float, float, float]:
    """Tool position and angle in the :math:`x`–:math:`z` plane by Pinocchio FK.

    Args:
        robot: The arm.
        q: Joint angles [rad], shape (n,).
        tool_frame: Name of the tool frame (default: :attr:`Robot.tool_frame`).

    Returns:
        :math:`(x, z, \\varphi)`: the tool frame's world :math:`x` and :math:`z` and
        :math:`\\varphi = \\operatorname{atan2}(R_{zx}, R_{xx}) \\in (-\\pi, \\pi]` [rad],
        the angle of the tool frame's :math:`x` axis with the world :math:`x` axis
        (counter-clockwise positive, :math:`x` to the right, :math:`z` up). For planar3
        this is the direction of link 3, :math:`\\varphi \\equiv q_1 + q_2 + q_3`.
    """
    q = robot.check_vector("q", q)
    m = robot.frame_placement(q, tool_frame)
    p, r = m.translation, m.rotation
    return float(p[0]), float(p[2]), math.atan2(float(r[2, 0]), float(r[0, 0]))


# ---------------------------------------------------------------------- inverse
@dataclass
class _Candidate:
    """One elbow branch before the limit check."""

    branch: Branch
    q: np.ndarray  # each angle on the 2π representative nearest to its range
    choices: list[list[float]]  # per joint, the representatives within the limits (± tol)


@dataclass
class _Analysis:
    chain: _Chain
    target: tuple[float, float, float]
    wrist: np.ndarray  # (2,) w + p_0, world (x, z)
    distance: float  # |w|
    reachable: bool
    boundary_slack: float  # how far |w| lies outside [|l1 - l2|, l1 + l2] (≤ tol)
    candidates: list[_Candidate]


def _wrap_into(value: float, lo: float, hi: float, tol: float) -> tuple[list[float], float]:
    """Representatives ``value + 2πk`` in ``[lo - tol, hi + tol]``, and the nearest one."""
    two_pi = 2.0 * math.pi
    k_lo = math.ceil((lo - tol - value) / two_pi)
    k_hi = math.floor((hi + tol - value) / two_pi)
    inside = [value + two_pi * k for k in range(k_lo, k_hi + 1)]
    if inside:
        return inside, inside[0]
    # None inside: the representative closest to the interval, for the error message.
    mid = 0.5 * (lo + hi)
    nearest = value + two_pi * round((mid - value) / two_pi)
    options = (nearest - two_pi, nearest, nearest + two_pi)
    best = min(options, key=lambda v: max(lo - v, v - hi, 0.0))
    return [], best


def _check_pose(position_xz, angle) -> tuple[float, float, float]:
    p = np.asarray(position_xz, dtype=float)
    if p.shape != (2,):
        raise KinematicsError(
            f"position_xz has shape {p.shape}: {position_xz!r}; pass the tool point (x, z)",
            value=position_xz,
            expected="a sequence of 2 numbers (x, z)",
        )
    a = float(angle)
    if not (np.all(np.isfinite(p)) and math.isfinite(a)):
        raise KinematicsError(
            f"tool pose (x, z) = {p.tolist()}, angle = {a!r} is not finite",
            value=(*p.tolist(), a),
            expected="finite numbers",
        )
    return float(p[0]), float(p[1]), a


def _analyse(robot: Robot, position_xz, angle, tol: float, tool_frame: str | None) -> _Analysis:
    if not (math.isfinite(tol) and tol >= 0):
        raise KinematicsError(f"tol={tol!r}", value=tol, expected="a finite tolerance >= 0")
    x, z, phi = _check_pose(position_xz, angle)
    ch = _chain(robot, tool_frame)
    l1, l2, l3 = ch.lengths
    sigma = phi - ch.phi0  # Σ s_i q_i
    theta3 = ch.alphas[2] + sigma
    w = np.array([x, z]) - l3 * np.array([math.cos(theta3), math.sin(theta3)]) - ch.base
    d = float(np.hypot(w[0], w[1]))
    d_min, d_max = abs(l1 - l2), l1 + l2
    slack = max(d - d_max, d_min - d, 0.0)
    analysis = _Analysis(ch, (x, z, phi), w + ch.base, d, slack <= tol, slack, [])
    if not analysis.reachable:
        return analysis
    c = min(1.0, max(-1.0, (d * d - l1 * l1 - l2 * l2) / (2.0 * l1 * l2)))
    s_abs = math.sqrt(max(0.0, (1.0 - c) * (1.0 + c)))
    atan_w = math.atan2(w[1], w[0])
    gammas = [-s_abs, s_abs] if s_abs > 0.0 else [0.0]
    for branch, sg in zip(_BRANCHES, gammas, strict=False):
        gamma = math.atan2(sg, c)
        theta1 = atan_w - math.atan2(l2 * math.sin(gamma), l1 + l2 * math.cos(gamma))
        theta2 = theta1 + gamma
        rel = (theta1 - ch.alphas[0], theta2 - ch.alphas[1], theta3 - ch.alphas[2])
        raw = ch.signs * np.array([rel[0], rel[1] - rel[0], rel[2] - rel[1]])
        choices, nearest = [], []
        for i in range(3):
            inside, best = _wrap_into(float(raw[i]), robot.lower[i], robot.upper[i], tol)
            choices.append(inside)
            nearest.append(best)
        analysis.candidates.append(_Candidate(branch, np.array(nearest), choices))
    return analysis


def _verify(robot: Robot, ch: _Chain, q: np.ndarray, target, tol_extra: float) -> None:
    """Check ``q`` against the target pose with Pinocchio FK, or raise (a bug if it fails)."""
    x, z, phi = tool_pose(robot, q, ch.frame)
    atol = _FK_TOL * max(1.0, ch.reach) + tol_extra
    dphi = math.remainder(phi - target[2], 2.0 * math.pi)
    if abs(x - target[0]) > atol or abs(z - target[1]) > atol or abs(dphi) > atol:
        raise KinematicsError(
            f"internal check failed: IK solution q = {q.tolist()} gives, by Pinocchio FK, "
            f"tool ({x:.12g}, {z:.12g}) at {math.degrees(phi):.12g}° instead of "
            f"({target[0]:.12g}, {target[1]:.12g}) at {math.degrees(target[2]):.12g}° "
            f"(tolerance {atol:.3g}); the model is not the planar chain that was inferred",
            value=q,
            expected=f"FK within {atol:.3g} of the target pose",
        )


def _solutions(robot: Robot, a: _Analysis, prefer: Branch | None) -> list[np.ndarray]:
    lo, hi = robot.lower, robot.upper
    out: list[np.ndarray] = []
    cands = list(a.candidates)
    if prefer is not None:
        cands.sort(key=lambda c: c.branch != prefer)
    for cand in cands:
        for combo in itertools.product(*cand.choices):
            raw = np.array(combo)
            q = np.clip(raw, lo, hi)  # values within tol outside a limit go onto it
            if any(np.allclose(q, other, rtol=0.0, atol=1e-12) for other in out):
                continue
            shift = float(np.abs(q - raw).sum())
            extra = a.boundary_slack + a.chain.reach * shift
            _verify(robot, a.chain, q, a.target, extra)
            out.append(q)
    return out


def _check_prefer(prefer) -> None:
    if prefer is not None and prefer not in _BRANCHES:
        raise KinematicsError(
            f"prefer={prefer!r}", value=prefer, expected=f"None or one of {_BRANCHES}"
        )


def planar_ik(
    robot: Robot,
    position_xz: Sequence[float] | np.ndarray,
    angle: float,
    *,
    prefer: Branch | None = None,
    tol: float = 1e-9,
    tool_frame: str | None = None,
) -> list[np.ndarray]:
    """Every joint solution of a planar 3R arm that puts the tool at a pose, within limits.

    Args:
        robot: A planar 3R arm (checked by :func:`planar_chain`).
        position_xz: Tool point :math:`(x, z)` in the world frame [model length unit].
        angle: Tool angle :math:`\\varphi` [rad] (for planar3, the angle of link 3 with
            the :math:`x` axis, :math:`q_1 + q_2 + q_3`).
        prefer: ``"elbow_up"`` or ``"elbow_down"`` to list that branch first
            (default: elbow-up first). ``"elbow_up"`` puts the elbow counter-clockwise
            of the line from joint 1 to the wrist.
        tol: Tolerance [rad] of the limit check, which is inclusive: a value up to
            ``tol`` outside a limit counts as on it and is moved onto it. The same
            ``tol`` [length unit] lets a wrist distance lie that far outside
            :math:`[|l_1 - l_2|, l_1 + l_2]`. The paper's start pose lies exactly on
            the limits of joints 1 and 2, hence a tolerance > 0 by default.
        tool_frame: Name of the tool frame (default: :attr:`Robot.tool_frame`).

    Returns:
        The solutions, each of shape (3,) [rad] inside ``[robot.lower, robot.upper]``:
        none (unreachable, or every branch outside the limits), one, two, or more
        when a joint's range exceeds :math:`2\\pi`. Each has been verified with
        Pinocchio FK to :math:`10^{-9}\\max(1, \\sum l_i)` (plus the effect of the
        moves allowed by ``tol``). :func:`solve_pose` explains an empty answer.

    Raises:
        KinematicsError: If the arm is not a planar 3R arm or an argument is invalid.
    """
    _check_prefer(prefer)
    a = _analyse(robot, position_xz, angle, tol, tool_frame)
    return _solutions(robot, a, prefer)


def _describe_pose(target) -> str:
    x, z, phi = target
    return f"tool ({x:.6g}, {z:.6g}) with link-3 angle {math.degrees(phi):.6g}°"


def _limit_violations(robot: Robot, cand: _Candidate) -> str:
    parts = []
    for i, value in enumerate(cand.q):
        if cand.choices[i]:
            continue
        lo, hi = robot.lower[i], robot.upper[i]
        side, limit = ("below its lower", lo) if value < lo else ("above its upper", hi)
        parts.append(
            f"{robot.joint_names[i]} = {value:.6g} rad ({math.degrees(value):.6g}°) is {side} "
            f"limit {limit:.6g} rad ({math.degrees(limit):.6g}°)"
        )
    q_txt = ", ".join(f"{v:.6g}" for v in cand.q)
    return f"{cand.branch} q = ({q_txt}) rad: " + "; ".join(parts)


def solve_pose(
    robot: Robot,
    position_xz: Sequence[float] | np.ndarray,
    angle: float,
    *,
    near=None,
    tol: float = 1e-9,
    tool_frame: str | None = None,
) -> np.ndarray:
    """The joint solution for a tool pose that lies within the limits and closest to ``near``.

    Args:
        robot: A planar 3R arm.
        position_xz: Tool point :math:`(x, z)` [model length unit].
        angle: Tool angle :math:`\\varphi` [rad].
        near: Joint angles [rad], shape (3,): return the valid solution with the
            smallest Euclidean joint distance :math:`\\|q - q_{near}\\|` to it. Default:
            the first solution of :func:`planar_ik` (elbow-up first).
        tol: As in :func:`planar_ik`.
        tool_frame: Name of the tool frame (default: :attr:`Robot.tool_frame`).

    Returns:
        Joint angles [rad], shape (3,), within the limits and verified by Pinocchio FK.

    Raises:
        KinematicsError: Naming the pose ("tool (x, z) with link-3 angle φ°") and why it
            has no solution: outside the workspace (the wrist distance vs the reach of
            links 1–2), or every elbow branch violates the joint limits (Eq 27), with
            each violating joint, its value and the limit.
    """
    ref = None if near is None else robot.check_vector("near", near)
    a = _analyse(robot, position_xz, angle, tol, tool_frame)
    pose = _describe_pose(a.target)
    if not a.reachable:
        l1, l2, l3 = a.chain.lengths
        wx, wz = a.wrist
        raise KinematicsError(
            f"cannot reach {pose}: outside the workspace: the wrist point ({wx:.6g}, {wz:.6g}) "
            f"= tool − l3·(cos φ, sin φ) with l3 = {l3:.6g} is at distance {a.distance:.6g} "
            f"from joint 1, but links 1 and 2 (l1 = {l1:.6g}, l2 = {l2:.6g}) reach distances "
            f"in [{abs(l1 - l2):.6g}, {l1 + l2:.6g}] only (total reach {a.chain.reach:.6g}); "
            "move the tool point or change the link-3 angle",
            value=a.target,
            expected=f"a wrist distance in [{abs(l1 - l2):.6g}, {l1 + l2:.6g}]",
        )
    sols = _solutions(robot, a, None)
    if not sols:
        why = " | ".join(_limit_violations(robot, c) for c in a.candidates)
        raise KinematicsError(
            f"cannot reach {pose} within the joint limits: every inverse-kinematics "
            f"branch violates the joint limits (Eq 27, lower {np.round(robot.lower, 6).tolist()}"
            f", upper {np.round(robot.upper, 6).tolist()} rad): {why}",
            value=a.target,
            expected="a pose reachable with every joint within its limits",
        )
    if ref is None:
        return sols[0]
    return min(sols, key=lambda q: float(np.linalg.norm(q - ref)))


# -------------------------------------------------------------------- workspace
def workspace_points(
    robot: Robot,
    samples: int = 8000,
    rng: np.random.Generator | int | None = None,
    tool_frame: str | None = None,
) -> np.ndarray:
    """Tool positions :math:`(x, z)` over the joint ranges, for a workspace figure.

    Args:
        robot: The arm (any arm; positions are projected on the :math:`x`–:math:`z` plane).
        samples: Number of points, at least 2. Without ``rng``: a regular grid of
            :math:`k = \\max(2, \\operatorname{round}(\\text{samples}^{1/n}))` values per
            joint, limits included (:math:`k^n` points). With ``rng``: exactly
            ``samples`` configurations drawn uniformly within the limits.
        rng: ``None`` for the grid, or a ``numpy.random.Generator`` or an integer seed
            for random sampling.
        tool_frame: Name of the tool frame (default: :attr:`Robot.tool_frame`).

    Returns:
        Array of shape (m, 2): world :math:`(x, z)` of the tool, by Pinocchio FK.
    """
    if isinstance(samples, bool) or not isinstance(samples, int | np.integer) or samples < 2:
        raise KinematicsError(
            f"samples={samples!r}", value=samples, expected="an integer number of points >= 2"
        )
    lo, hi = robot.lower, robot.upper
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
        raise KinematicsError(
            f"robot {robot.name!r} has unbounded joint limits {lo.tolist()}, {hi.tolist()}",
            value=(lo, hi),
            expected="finite joint limits to sample between",
        )
    n = robot.nq
    if rng is None:
        k = max(2, round(samples ** (1.0 / n)))
        axes = [np.linspace(lo[i], hi[i], k) for i in range(n)]
        qs = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, n)
    else:
        gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        qs = gen.uniform(lo, hi, size=(int(samples), n))
    model = robot.model
    data = model.createData()
    name = tool_frame or robot.tool_frame
    if not model.existFrame(name):
        raise KinematicsError(
            f"frame {name!r} is not in robot {robot.name!r}",
            value=name,
            expected="the name of a frame of the robot",
        )
    fid = model.getFrameId(name)
    out = np.empty((len(qs), 2))
    for row, q in enumerate(qs):
        pin.framesForwardKinematics(model, data, q)
        p = data.oMf[fid].translation
        out[row] = p[0], p[2]
    return out
