"""Joint waypoints time-parametrised under velocity and acceleration limits (TOPP-RA).

The waypoints :math:`q^{(0)}, \\dots, q^{(P-1)}` are joined by a geometric path
:math:`q(s)`, the cubic spline through them in the path parameter :math:`s` (the
cumulative joint-space distance, normalised to [0, 1]); TOPP-RA (Pham & Pham 2018,
``toppra``) then finds the fastest :math:`s(t)` with, at every point of its grid,

.. math::

    |q'(s)\\,\\dot s| \\le \\alpha\\,\\dot q_{max}, \\qquad
    |q'(s)\\,\\ddot s + q''(s)\\,\\dot s^2| \\le \\alpha\\,\\ddot q_{max},

starting and ending at rest. The result is sampled every ``dt`` and interpolated by a
:class:`~hmpc_pin.tasks.trajectory.JointTrajectory` through positions and velocities;
:math:`\\alpha < 1` (``margin``) keeps the interpolant within the limits between TOPP-RA's
grid points, and where the interpolant still exceeds :math:`\\alpha` times a limit
between its samples, time is stretched uniformly (:math:`t \\to \\lambda t`,
:math:`\\lambda \\ge 1`: same path, velocity / :math:`\\lambda`, acceleration /
:math:`\\lambda^2`). Why TOPP-RA rather than Ruckig: docs, "Tutorials".

``toppra`` is in the extra ``hmpc_pin[tasks]``; without it :func:`retime_waypoints`
raises :class:`~hmpc_pin.exceptions.ExtraError` naming the extra.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..exceptions import DimensionError, ExtraError, TrajectoryError
from .trajectory import JointTrajectory

__all__ = ["retime_waypoints"]


def _toppra():
    try:
        import toppra
        import toppra.algorithm
        import toppra.constraint
    except ImportError as exc:
        raise ExtraError("tasks", "joint waypoints retimed by TOPP-RA (toppra)") from exc
    toppra.setup_logging("WARNING")
    return toppra


def _peak_acceleration(trajectory: JointTrajectory) -> np.ndarray:
    """The exact largest |q̈| per joint [rad/s²] of a quintic Hermite trajectory: on each
    segment q̈(τ) = 2c₂ + 6c₃τ + 12c₄τ² + 20c₅τ³ is a cubic, so its extrema are at the
    segment's ends and at the real roots of the jerk 6c₃ + 24c₄τ + 60c₅τ² inside it."""
    c = trajectory._c  # (K-1, 6, n), local time τ in [0, h]
    h = np.diff(trajectory.times)[:, None]

    def acc(tau):
        return 2 * c[:, 2] + 6 * c[:, 3] * tau + 12 * c[:, 4] * tau**2 + 20 * c[:, 5] * tau**3

    peak = np.maximum(np.abs(acc(0.0 * h)), np.abs(acc(h))).max(axis=0)
    a2, a1, a0 = 60 * c[:, 5], 24 * c[:, 4], 6 * c[:, 3]
    disc = a1**2 - 4 * a2 * a0
    with np.errstate(divide="ignore", invalid="ignore"):
        root = np.sqrt(np.where(disc >= 0, disc, np.nan))
        cands = [(-a1 + root) / (2 * a2), (-a1 - root) / (2 * a2), -a0 / a1]
    for tau in cands:
        ok = np.isfinite(tau) & (tau > 0) & (tau < h)
        val = np.where(ok, np.abs(acc(np.where(ok, tau, 0.0))), 0.0)
        peak = np.maximum(peak, val.max(axis=0))
    return peak


def retime_waypoints(
    waypoints,
    velocity_limit,
    acceleration_limit,
    *,
    t_start: float = 0.0,
    dt: float = 0.01,
    margin: float = 0.97,
    joint_names: Sequence[str] = (),
) -> JointTrajectory:
    """The time-optimal trajectory through ``waypoints`` under the limits (module doc).

    Args:
        waypoints: Joint positions [rad], shape (P, n), P >= 2, consecutive ones distinct.
        velocity_limit: :math:`\\dot q_{max}` [rad/s], shape (n,) or scalar, > 0.
        acceleration_limit: :math:`\\ddot q_{max}` [rad/s²], shape (n,) or scalar, > 0.
        t_start: Time the motion starts [s]; the first waypoint is held before.
        dt: Sampling period of the retimed trajectory [s].
        margin: :math:`\\alpha`, the share of each limit given to TOPP-RA.
        joint_names: For messages.

    Returns:
        The trajectory; its ``duration`` is the motion's duration [s].

    Raises:
        TrajectoryError: Fewer than 2 waypoints, a non-finite value, two equal consecutive
            waypoints, a limit <= 0, TOPP-RA failing.
        ExtraError: toppra is not installed (extra ``tasks``).
    """
    way = np.asarray(waypoints, dtype=float)
    where = "reference.waypoints.points"
    if way.ndim != 2 or way.shape[0] < 2:
        raise TrajectoryError(where, f"shape {way.shape}", "at least 2 joint vectors")
    n = way.shape[1]
    if not np.all(np.isfinite(way)):
        raise TrajectoryError(where, f"{way.tolist()}", "finite numbers")
    vmax = np.broadcast_to(np.asarray(velocity_limit, dtype=float), (n,))
    amax = np.broadcast_to(np.asarray(acceleration_limit, dtype=float), (n,))
    for name, lim in (("velocity limit", vmax), ("acceleration limit", amax)):
        if not np.all(np.isfinite(lim) & (lim > 0)):
            raise TrajectoryError(
                where,
                f"{name} {lim.tolist()}",
                f"a finite {name} > 0 "
                "for every joint (a URDF velocity of 0 means none: give "
                "reference.waypoints.velocity_limit)",
            )
    step = np.linalg.norm(np.diff(way, axis=0), axis=1)
    if np.any(step <= 0):
        k = int(np.flatnonzero(step <= 0)[0]) + 1
        raise TrajectoryError(
            where,
            f"waypoint {k} equals waypoint {k - 1} (0-based)",
            "distinct consecutive waypoints",
        )
    ta = _toppra()
    ss = np.concatenate([[0.0], np.cumsum(step)])
    ss /= ss[-1]
    path = ta.SplineInterpolator(ss, way)
    vlim = np.column_stack([-margin * vmax, margin * vmax])
    alim = np.column_stack([-margin * amax, margin * amax])
    instance = ta.algorithm.TOPPRA(
        [
            ta.constraint.JointVelocityConstraint(vlim),
            ta.constraint.JointAccelerationConstraint(alim),
        ],
        path,
        gridpoints=np.linspace(0.0, 1.0, max(200, 40 * way.shape[0])),
        parametrizer="ParametrizeConstAccel",
    )
    traj = instance.compute_trajectory(0.0, 0.0)
    if traj is None:
        raise TrajectoryError(
            where,
            "TOPP-RA found no time parametrisation",
            "waypoints the arm can follow within its limits",
        )
    duration = float(traj.duration)
    k = max(2, int(np.ceil(duration / dt)) + 1)
    ts = np.linspace(0.0, duration, k)
    q, dq, ddq = (np.asarray(traj(ts, order), dtype=float) for order in (0, 1, 2))
    if q.shape != (k, n):
        raise DimensionError(f"toppra returned shape {q.shape}, expected {(k, n)}")
    # At rest at both ends (q̇ = 0); the acceleration is TOPP-RA's, which jumps at the start
    # and end (bang-bang): forcing it to 0 there made the first and last interpolant
    # overshoot by a third and stretched the whole motion ~17 % (one segment's optimum).
    q[0], q[-1], dq[0], dq[-1] = way[0], way[-1], 0.0, 0.0
    trajectory = JointTrajectory(ts, q, dq, joint_names, source=where, ddq=ddq)
    # The interpolant may exceed a limit between TOPP-RA's grid points (its acceleration
    # is piecewise constant): check it on a grid 20x finer than the samples and stretch
    # time by lam >= 1 where needed (velocity / lam, acceleration / lam², same path).
    fine = np.linspace(0.0, duration, 20 * (k - 1) + 1)
    v_ratio = np.max(np.abs(trajectory.sample_many(fine)[1]) / vmax)
    a_ratio = np.max(_peak_acceleration(trajectory) / amax)
    lam = max(1.0, v_ratio / margin, np.sqrt(a_ratio / margin))
    return JointTrajectory(
        ts * lam + t_start, q, dq / lam, joint_names, source=where, ddq=ddq / lam**2
    )
