"""A sine reference's posture within the effort limits and inside the workspace
(``hmpc-pin init``).

``hold_gravity`` moves a posture toward hanging until gravity needs at most
:data:`HOLD` of every effort limit along the sine.

``init``'s sine moves every joint with one phase, :math:`r(t) = o + a\\sin(2\\pi f t)`, so
its path in joint space is the segment :math:`o + s\\,a`, :math:`s \\in [-1, 1]`.
:func:`place` finds an offset o whose whole segment keeps every moving link above the
mounting plane plus the margin and free of self-collision
(:class:`~hmpc_pin.model.workspace.Workspace`), with the arm's weight within its effort
limits, by a compass search (a pattern search on one joint at a time, the step halved when
no move improves) from the posture ``init`` would take otherwise: it ranks offsets by, in
order, the torque gravity needs beyond the effort limits, the number of colliding samples
and the lowest clearance, and stops at the first offset that keeps
:data:`SLACK` above the margin (the nearest such offset it finds, not the highest).
"""

from __future__ import annotations

import numpy as np

from ..exceptions import URDFError
from ..model.robot import Robot

__all__ = [
    "HOLD",
    "HOLD_STEPS",
    "PATH_SAMPLES",
    "SLACK",
    "gravity_along",
    "hold_gravity",
    "path",
    "place",
]

#: Gravity may need at most this share of a joint's effort limit along the sine.
HOLD = 0.8
#: Steps of at most 0.02 rad (or m) ``hold_gravity`` takes toward hanging.
HOLD_STEPS = 400

#: Samples of the segment per evaluation of the search (0.0625 a apart).
PATH_SAMPLES = 33
#: Clearance kept beyond the margin [m] at the samples by the offset the search stops at,
#: for the segment between them: there a link's lowest point dips below the samples' by
#: at most about r (0.0625 a)² / 8, 45 µm for a point r = 1 m from the joint at a = 0.3 rad.
SLACK = 1e-3
#: The compass search's first and smallest steps [rad or m].
FIRST_STEP, LAST_STEP = 0.4, 0.01
#: Largest number of moves of the search.
MAX_MOVES = 100


def path(offset: np.ndarray, amplitude: np.ndarray, samples: int = PATH_SAMPLES) -> np.ndarray:
    """The postures :math:`o + s\\,a` at ``samples`` values of s in [-1, 1], shape (samples, n)."""
    s = np.linspace(-1.0, 1.0, samples)[:, None]
    return offset[None, :] + s * amplitude[None, :]


def _rank(workspace, gravity_excess, offset, amplitude) -> tuple[float, int, float]:
    """(−gravity excess, −colliding samples, min(clearance − margin, SLACK)): larger is
    better; an offset is inside when the first two are 0 and the last is SLACK. The
    clearance at :data:`PATH_SAMPLES` samples, the collisions at every fourth (all of
    them, four times as many, once the search stops)."""
    Q = path(offset, amplitude)
    c = workspace.clearance(Q)[:, workspace.checked]
    low = float(c.min()) - workspace.margin if c.size else SLACK
    hits = sum(1 for q in Q[::4] if workspace.collides(q))
    return (-float(gravity_excess(offset)), -hits, min(low, SLACK))


def place(
    workspace,
    start: np.ndarray,
    amplitude: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    gravity_excess,
) -> tuple[np.ndarray, bool]:
    """An offset in [lo, hi] whose sine segment stays inside the workspace, searched from
    ``start`` (module docstring).

    Args:
        workspace: The arm's :class:`~hmpc_pin.model.workspace.Workspace`.
        start: Where the search starts [rad or m].
        amplitude: The sine's amplitude per joint [rad or m].
        lo, hi: Bounds of the offset [rad or m].
        gravity_excess: offset -> how far [-] the torque gravity needs along the segment
            exceeds what the effort limits allow (0: within them).

    Returns:
        The offset and whether it is inside (else the best one found).
    """
    best = np.clip(start, lo, hi)
    rank = _rank(workspace, gravity_excess, best, amplitude)
    goal = (0.0, 0, SLACK)
    step = FIRST_STEP
    for _ in range(MAX_MOVES):
        if rank >= goal:
            dense = path(best, amplitude, 4 * PATH_SAMPLES - 3)
            return best, not any(workspace.collides(q) for q in dense)
        moves = []
        for j in range(len(best)):
            for sign in (1.0, -1.0):
                q = best.copy()
                q[j] = np.clip(q[j] + sign * step, lo[j], hi[j])
                if q[j] != best[j]:
                    moves.append(q)
        scored = [(_rank(workspace, gravity_excess, q, amplitude), k) for k, q in enumerate(moves)]
        top = max(scored, default=None)
        if top is not None and top[0] > rank:
            rank, best = top[0], moves[top[1]]
        elif step > LAST_STEP:
            step /= 2
        else:
            break
    return best, rank >= goal


def gravity_along(robot: Robot, q: np.ndarray, amplitude: np.ndarray) -> np.ndarray:
    """Per joint, the largest |G| [N·m or N] along the sine's path
    :math:`q + s\\,a`, :math:`s \\in [-1, 1]` (every joint shares one phase, so the path
    is a segment; 9 points)."""
    return np.max(
        [np.abs(robot.gravity_torque(q + s * amplitude)) for s in np.linspace(-1, 1, 9)], axis=0
    )


def hold_gravity(
    robot: Robot, q: np.ndarray, amplitude: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> np.ndarray:
    """``q`` moved toward the hanging posture (steps of at most 0.02 rad or m against the
    gravity torque G, inside [lo, hi]) until gravity needs at most :data:`HOLD` × the
    effort limit on every joint with one, along the whole sine (``gravity_along``).

    Raises:
        URDFError: No such posture within :data:`HOLD_STEPS` steps (naming the joint and
            the torques): the URDF leaves out what holds the real arm.
    """
    effort = np.where(robot.effort_limit > 0, robot.effort_limit, np.inf)
    q = q.copy()
    for _ in range(HOLD_STEPS):
        if not np.any(gravity_along(robot, q, amplitude) > HOLD * effort):
            return q
        G = robot.gravity_torque(q)
        q_new = np.clip(q - 0.02 * G / max(np.abs(G).max(), 1e-12), lo, hi)
        if np.allclose(q_new, q):
            break
        q = q_new
    need = gravity_along(robot, q, amplitude)
    i = int(np.argmax(need / effort))
    raise URDFError(
        robot.source,
        f"out of scope: joint {robot.joint_names[i]!r} needs {need[i]:.3g} N·m to hold "
        f"the arm against gravity at best, above {HOLD:.0%} of its URDF effort limit "
        f"{effort[i]:.3g} N·m (the URDF leaves out what holds the real arm, e.g. springs or "
        "buoyancy); write a config by hand with [plant] saturate = false or a lower gravity",
    )
