"""A joint trajectory through timed samples: C²-smooth piecewise polynomials, last point held.

Given samples :math:`(t_k, q_k)`, :math:`k = 0..K-1` (and optionally :math:`\\dot q_k`):

* positions only: the **clamped cubic spline** through the :math:`q_k` — C² (continuous
  position, velocity and acceleration), zero velocity at both ends, so that holding the
  first point before :math:`t_0` and the last after :math:`t_{K-1}` keeps the velocity
  continuous;
* positions and velocities: the **quintic Hermite** interpolant that matches
  :math:`q_k` and :math:`\\dot q_k` at every sample, with the knot accelerations
  :math:`\\ddot q_k` taken from the cubic spline through the velocity samples — each knot's
  acceleration is shared by both segments, so the result is C² as well.

On segment :math:`k`, with :math:`s = t - t_k \\in [0, h_k]`,
:math:`q(t) = \\sum_{j=0}^{d} c_{kj} s^j` (:math:`d = 3` or :math:`5`); sampling is one
``searchsorted``, one gather of the coefficients and two small matrix products for the
whole horizon (the :class:`~hmpc_pin.tasks.base.Reference` protocol, vectorised over time).

Files (:func:`load_trajectory`): a CSV with the header ``t`` then one column per
controlled joint (its URDF name, or ``q_<name>``), and optionally ``dq_<name>`` velocity
columns for every joint; or an ``.npz`` with arrays ``t`` (K,), ``q`` (K, n), optionally
``dq`` (K, n) and ``joint_names`` (n,) — a run saved by the package (``run``, ``realtime``,
``ros``: its measured ``t``, ``q``, ``dq`` up to its last finite sample, the other arrays
left aside) is such a file. Checked on load: time strictly increasing, every
joint present, no unknown column, finite values (:class:`~hmpc_pin.exceptions.TrajectoryError`
naming the file, the row or column, and what was expected).
"""

from __future__ import annotations

import csv
import difflib
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..exceptions import DimensionError, TrajectoryError
from .base import CompiledSampling, FloatArray, PolynomialSampling

__all__ = ["JointTrajectory", "load_trajectory"]


def _check_samples(
    times, q, dq, where: str, names: Sequence[str] = ()
) -> tuple[FloatArray, FloatArray, FloatArray | None]:
    t = np.asarray(times, dtype=float)
    q = np.asarray(q, dtype=float)
    if t.ndim != 1 or t.size < 2:
        raise TrajectoryError(where, f"{t.size} time sample(s)", "at least 2 samples in time")
    if q.ndim == 1:
        q = q[:, None]
    if q.shape[0] != t.size or q.ndim != 2 or q.shape[1] == 0:
        raise DimensionError(
            f"{where}: q has shape {q.shape} but there are {t.size} times; "
            f"pass q of shape ({t.size}, n)"
        )
    if dq is not None:
        dq = np.asarray(dq, dtype=float).reshape(q.shape[0], -1)
        if dq.shape != q.shape:
            raise DimensionError(f"{where}: dq has shape {dq.shape}, expected {q.shape} like q")
    for name, arr in (("t", t), ("q", q), ("dq", dq)):
        if arr is not None and not np.all(np.isfinite(arr)):
            k = int(np.argwhere(~np.isfinite(arr.reshape(len(t), -1)))[0][0])
            raise TrajectoryError(
                where,
                f"{name} = {arr[k].tolist()} at sample {k} (0-based; t = {t[k]:g} s)",
                "finite numbers (no NaN or inf)",
            )
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        k = int(bad[0]) + 1
        raise TrajectoryError(
            where,
            f"time {t[k]:g} s at sample {k} (0-based) after {t[k - 1]:g} s",
            "time strictly increasing",
        )
    if dq is not None:
        names = tuple(names) or tuple(f"joint {i + 1}" for i in range(q.shape[1]))
        _check_velocities(t, q, dq, where, names)
    return t, q, dq


def _check_velocities(
    t: FloatArray, q: FloatArray, dq: FloatArray, where: str, names: Sequence[str]
) -> None:
    """Velocity columns must be the derivative of the positions (not another unit, not
    shifted): each segment's trapezoidal integral :math:`h(\\dot q_k + \\dot q_{k+1})/2` must
    match :math:`q_{k+1} - q_k` within 25 % of the joint's largest step plus 1e-6 rad (the
    trapezoid's own error is :math:`h^3 \\dddot q/12`, far below that for a smooth motion
    sampled finely enough to be tracked)."""
    h = np.diff(t)[:, None]
    step = np.diff(q, axis=0)
    integral = h * (dq[1:] + dq[:-1]) / 2.0
    gap = np.abs(step - integral)
    tol = 0.25 * np.abs(step).max(axis=0) + 1e-6
    bad = gap > tol
    if bad.any():
        k, i = np.argwhere(bad)[0]
        raise TrajectoryError(
            where,
            f"the velocities of {names[i]} between t = {t[k]:g} and {t[k + 1]:g} s "
            f"integrate to {float(integral[k, i]):.6g} rad but "
            f"the positions move {float(step[k, i]):.6g} rad",
            "velocity columns that are the derivative of the positions [rad/s], or none",
        )


def _cubic_coefficients(t: FloatArray, q: FloatArray, bc: str) -> FloatArray:
    """Power-basis coefficients (K-1, 4, n) of the cubic spline (``bc``: scipy's bc_type)."""
    from scipy.interpolate import CubicSpline

    if bc == "not-a-knot" and t.size < 4:  # scipy's not-a-knot needs 4 points; a parabola
        bc = "natural" if t.size < 3 else bc
    spline = CubicSpline(t, q, bc_type=bc, axis=0)
    return np.ascontiguousarray(spline.c[::-1].transpose(1, 0, 2))


def _quintic_coefficients(
    t: FloatArray, q: FloatArray, dq: FloatArray, ddq: FloatArray | None = None
) -> FloatArray:
    """Power-basis coefficients (K-1, 6, n) of the quintic Hermite interpolant.

    Knot accelerations ``ddq``, or from the not-a-knot cubic spline through the velocities.
    """
    from scipy.interpolate import CubicSpline

    if ddq is not None:
        pass
    elif t.size >= 3:
        ddq = CubicSpline(t, dq, axis=0, bc_type="not-a-knot" if t.size >= 4 else "natural")(t, 1)
    else:
        ddq = np.repeat((dq[1:] - dq[:1]) / (t[1] - t[0]), 2, axis=0)
    h = np.diff(t)[:, None]
    p0, p1, v0, v1, a0, a1 = q[:-1], q[1:], dq[:-1], dq[1:], ddq[:-1], ddq[1:]
    dp = p1 - p0
    c = np.empty((t.size - 1, 6, q.shape[1]))
    c[:, 0], c[:, 1], c[:, 2] = p0, v0, a0 / 2.0
    c[:, 3] = (20.0 * dp - (8.0 * v1 + 12.0 * v0) * h - (3.0 * a0 - a1) * h**2) / (2.0 * h**3)
    c[:, 4] = (-30.0 * dp + (14.0 * v1 + 16.0 * v0) * h + (3.0 * a0 - 2.0 * a1) * h**2) / (
        2.0 * h**4
    )
    c[:, 5] = (12.0 * dp - 6.0 * (v1 + v0) * h - (a0 - a1) * h**2) / (2.0 * h**5)
    return c


class JointTrajectory(CompiledSampling):
    """Joint reference through timed samples, C²-smooth, first/last point held (module doc).

    Args:
        times: Sample times :math:`t_k` [s], shape (K,), strictly increasing, K >= 2.
        q: Joint positions [rad], shape (K, n).
        dq: Optional joint velocities [rad/s], shape (K, n): quintic Hermite through
            positions and velocities; ``None``: cubic spline through the positions.
        joint_names: Names of the n joints (for messages).
        boundary: For ``dq = None``: ``"clamped"`` (zero velocity at both ends, the
            default: the held ends join smoothly) or ``"not-a-knot"`` (the ends' velocity
            follows the samples; used for paths sampled past the end of a run).
        source: Where the samples came from (file name), for messages.
        ddq: With ``dq``, the knot accelerations [rad/s²] (K, n) of the quintic Hermite
            (default: from the cubic spline through the velocities).

    Raises:
        TrajectoryError: Fewer than 2 samples, a non-finite value, time not strictly
            increasing, velocities that are not the derivative of the positions.
        DimensionError: ``q``/``dq`` shapes do not match ``times``.
    """

    def __init__(
        self,
        times,
        q,
        dq=None,
        joint_names: Sequence[str] = (),
        *,
        boundary: str = "clamped",
        source: str = "trajectory",
        ddq=None,
    ):
        t, q, dq = _check_samples(times, q, dq, source, joint_names)
        self.source = source
        self.times, self.q_samples = t, q
        self.dq_samples = dq
        self.n = q.shape[1]
        self.joint_names = tuple(joint_names) or tuple(f"joint{i + 1}" for i in range(self.n))
        if dq is None:
            self._c = _cubic_coefficients(t, q, boundary)
        else:
            acc = None if ddq is None else np.asarray(ddq, dtype=float).reshape(q.shape)
            self._c = _quintic_coefficients(t, q, dq, acc)
        deg = self._c.shape[1] - 1
        self.degree = deg
        self.t_start, self.t_end = float(t[0]), float(t[-1])
        # Segments: [hold q_0 | the K-1 polynomials | hold q_{K-1}], knots t_0 - 1, t_0..t_{K-1};
        # a time's segment is one searchsorted in t.
        n = self.n
        c = np.zeros((t.size + 1, deg + 1, n))
        c[1:-1] = self._c
        c[0, 0], c[-1, 0] = q[0], q[-1]
        j = np.arange(1, deg + 1, dtype=float)
        d = np.zeros((t.size + 1, deg, n))
        d[1:-1] = self._c[:, 1:] * j[None, :, None]
        self._dd = np.ascontiguousarray(d[:, 1:] * j[None, :-1, None])  # q̈ coefficients
        self._qd = np.concatenate([c, np.pad(d, ((0, 0), (0, 1), (0, 0)))], axis=2)  # [q | q̇]
        self._pow = np.arange(deg + 1, dtype=float)
        self._knots = np.concatenate([[t[0] - 1.0], t])

    @property
    def duration(self) -> float:
        """:math:`t_{K-1} - t_0` [s]."""
        return self.t_end - self.t_start

    def _locate(self, times: FloatArray) -> tuple[FloatArray, np.ndarray]:
        """Segment index and local time :math:`s = t - t_k` of each of ``times``.

        Index 0 is the hold before :math:`t_0`, K the hold after :math:`t_{K-1}`: constant
        segments, whose powers of s multiply zero coefficients (finite for any
        :math:`|s| < 10^{60}` s), so no clipping is needed.
        """
        idx = np.searchsorted(self.times, times, side="right")
        return times - self._knots.take(idx), idx

    def _form(self) -> PolynomialSampling:
        """The segments as a piecewise polynomial (breakpoints t_k, origins, [q | q̇]
        coefficients, degree) for the compiled sampler
        (:class:`~hmpc_pin.tasks.base.CompiledSampling`). Before
        :math:`t_0` and from :math:`t_{K-1}` on, the end point is held (velocity 0)."""
        coef = np.ascontiguousarray(self._qd.reshape(-1, 2 * self.n))
        return PolynomialSampling(self.times, self._knots, coef, self.degree)

    def acceleration_many(self, times: FloatArray) -> FloatArray:
        """Accelerations [rad/s²] at ``times`` (m,): shape (m, n); 0 outside the samples."""
        times = np.asarray(times, dtype=float).reshape(-1)
        s, idx = self._locate(times)
        powers = s[:, None] ** self._pow[:-2]
        return np.matmul(powers[:, None, :], self._dd.take(idx, axis=0))[:, 0]

    def acceleration(self, t: float) -> FloatArray:
        """Acceleration [rad/s²] at ``t`` [s], shape (n,) (for computed torque)."""
        return self.acceleration_many(np.array([t], dtype=float))[0]

    def __repr__(self) -> str:
        kind = "quintic Hermite" if self.dq_samples is not None else "cubic spline"
        return (
            f"JointTrajectory({self.source!r}, {self.times.size} samples, n={self.n}, "
            f"{kind}, t=[{self.t_start:g}, {self.t_end:g}] s)"
        )


def _read_csv(path: Path) -> tuple[list[str], FloatArray]:
    try:
        with open(path, newline="", encoding="utf-8") as f:
            rows = [row for row in csv.reader(f) if row and not row[0].lstrip().startswith("#")]
    except (OSError, UnicodeDecodeError) as exc:
        raise TrajectoryError(str(path), f"cannot be read ({exc})", "a readable CSV file") from exc
    if len(rows) < 3:
        raise TrajectoryError(
            str(path), f"{max(len(rows) - 1, 0)} data row(s)", "a header row and >= 2 data rows"
        )
    header = [h.strip() for h in rows[0]]
    data = np.empty((len(rows) - 1, len(header)))
    for r, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise TrajectoryError(
                str(path), f"line {r} has {len(row)} fields", f"{len(header)} like the header"
            )
        for c, cell in enumerate(row):
            try:
                data[r - 2, c] = float(cell)
            except ValueError:
                raise TrajectoryError(
                    str(path), f"line {r}, column {header[c]!r}: {cell.strip()!r}", "a number"
                ) from None
    return header, data


#: The arrays that mark an ``.npz`` as a run saved by the package
#: (:meth:`~hmpc_pin.sim.result.Result.save`: ``run``, ``realtime``, ``ros``).
RUN_MARKERS = ("complete", "meta")


def _is_run(arrays: dict) -> bool:
    return all(k in arrays for k in RUN_MARKERS)


def _run_samples(arrays: dict, where: str) -> dict:
    """The trajectory of a saved run: its measured ``t``, ``q``, ``dq`` and
    ``joint_names``, up to its last finite sample (a stopped run's tail is NaN)."""
    t, q = np.asarray(arrays["t"], float), np.atleast_2d(np.asarray(arrays["q"], float))
    dq = arrays.get("dq")
    finite = np.isfinite(t) & np.all(np.isfinite(q), axis=-1)
    if dq is not None:
        finite &= np.all(np.isfinite(np.atleast_2d(np.asarray(dq, float))), axis=-1)
    last = int(np.argmin(finite)) if not finite.all() else len(t)
    if last < 2:
        raise TrajectoryError(
            where, f"a saved run with {last} finite sample(s)", "a run of two samples or more"
        )
    out = {"t": t[:last], "q": q[:last]}
    if dq is not None:
        out["dq"] = np.atleast_2d(np.asarray(dq, float))[:last]
    if "joint_names" in arrays:
        out["joint_names"] = arrays["joint_names"]
    return out


def load_trajectory(path: str | Path, joint_names: Sequence[str]) -> JointTrajectory:
    """Read a trajectory file (module docstring) for the joints ``joint_names``.

    Columns are matched to the joints by name (any order); velocity columns must be
    given for every joint or none.

    Raises:
        TrajectoryError: Missing file, unknown extension, missing joint column, unknown
            column, non-numeric or non-finite value, time not strictly increasing.
    """
    path = Path(path)
    where = str(path)
    names = list(joint_names)
    if not path.is_file():
        raise TrajectoryError(where, "file not found", "a .csv or .npz trajectory file")
    if path.suffix.lower() == ".npz":
        try:
            with np.load(path, allow_pickle=False) as f:
                arrays = {k: f[k] for k in f.files}
        except (OSError, ValueError) as exc:
            raise TrajectoryError(where, f"cannot be read ({exc})", "an .npz file") from exc
        for key in ("t", "q"):
            if key not in arrays:
                raise TrajectoryError(
                    where, f"no array {key!r} (has {sorted(arrays)})", "arrays t, q [, dq]"
                )
        if _is_run(arrays):  # a recorded run: its measured t, q, dq, the rest left aside
            arrays = _run_samples(arrays, where)
        unknown = sorted(set(arrays) - {"t", "q", "dq", "joint_names"})
        if unknown:
            raise TrajectoryError(
                where, f"unknown array {unknown[0]!r}", "arrays t, q [, dq, joint_names]"
            )
        q, dq = np.atleast_2d(arrays["q"]), arrays.get("dq")
        if "joint_names" in arrays:
            given = [str(s) for s in arrays["joint_names"]]
            missing = [j for j in names if j not in given]
            if missing:
                raise TrajectoryError(
                    where,
                    f"no joint {missing[0]!r} in joint_names {given}",
                    f"the controlled joints {names}",
                )
            if len(given) != q.shape[-1]:
                raise TrajectoryError(
                    where,
                    f"{len(given)} joint_names for q of shape {q.shape}",
                    "one name per column of q",
                )
            order = [given.index(j) for j in names]
            q = q[:, order]
            dq = None if dq is None else np.atleast_2d(dq)[:, order]
        elif q.shape[-1] != len(names):
            raise TrajectoryError(
                where, f"q has {q.shape[-1]} columns", f"{len(names)}, one per joint {names}"
            )
        return JointTrajectory(arrays["t"], q, dq, names, source=where)
    if path.suffix.lower() != ".csv":
        raise TrajectoryError(where, f"extension {path.suffix!r}", "a .csv or .npz file")
    header, data = _read_csv(path)
    if header[0] != "t":
        raise TrajectoryError(where, f"first column {header[0]!r}", "'t' (time [s]) first")
    column = {}
    for c, h in enumerate(header[1:], start=1):
        key = h[2:] if h.startswith("q_") and h[2:] in names else h
        if key in column:
            raise TrajectoryError(where, f"column {h!r} given twice", "one column per joint")
        column[key] = c
    missing = [j for j in names if j not in column]
    allowed = set(names) | {f"dq_{j}" for j in names}
    if missing:
        extra = [h for h in column if h not in allowed]
        close = difflib.get_close_matches(missing[0], extra, n=1, cutoff=0.6)
        hint = (
            f" (column {close[0]!r} is not a joint: a typo of {missing[0]!r}?)"
            if close
            else f" (columns that are no joint: {extra})"
            if extra
            else ""
        )
        raise TrajectoryError(
            where,
            f"no column for joint {missing[0]!r}{hint}",
            f"a column per controlled joint: t, {', '.join(names)} [, dq_<joint>...]",
        )
    unknown = [h for h in column if h not in allowed]
    if unknown:
        raise TrajectoryError(
            where,
            f"unknown column {unknown[0]!r}",
            f"t, the controlled joints {names}, optionally dq_<joint> for every joint",
        )
    vel = [f"dq_{j}" for j in names]
    given = [v for v in vel if v in column]
    if given and len(given) != len(vel):
        missing_v = next(v for v in vel if v not in column)
        raise TrajectoryError(
            where,
            f"no column {missing_v!r} while {given[0]!r} is given",
            "velocity columns for every joint or none",
        )
    q = data[:, [column[j] for j in names]]
    dq = data[:, [column[v] for v in vel]] if given else None
    return JointTrajectory(data[:, 0], q, dq, names, source=where)
