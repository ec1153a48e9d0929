"""``[reference]`` and its tables: the sine, the Cartesian move, trajectory files,
waypoints and end-effector paths."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...exceptions import ConfigError
from ._fields import _array, _choice, _float, _section, _set


@dataclass(frozen=True, eq=False)
class CartesianConfig:
    """Point-to-point tool motion of Section 5.4, in the arm's x–z plane.

    Both poses are solved by inverse kinematics on the branch inside the joint
    limits (the goal's branch closest to the start), and joined by a joint-space
    quintic with zero velocity and acceleration at both ends.

    Attributes:
        start_position: Tool (x, z) at the start [m] (paper: 1.2, 0.5).
        start_angle: Angle of link 3 to the x axis at the start [deg] (paper: −90).
        goal_position: Tool (x, z) at the goal [m] (paper: 2.423, 2.234).
        goal_angle: Angle of link 3 at the goal [deg] (paper: 0, parallel to x).
        t_start: Time the motion starts [s] (not in the paper; 0).
        move_time: Duration of the motion [s] (not in the paper; 5).
    """

    start_position: np.ndarray = field(default_factory=lambda: np.array([1.2, 0.5]))
    start_angle: float = -90.0
    goal_position: np.ndarray = field(default_factory=lambda: np.array([2.423, 2.234]))
    goal_angle: float = 0.0
    t_start: float = 0.0
    move_time: float = 5.0

    def __post_init__(self):
        for name in ("start_position", "goal_position"):
            arr = _array(name, getattr(self, name))
            if arr.shape != (2,):
                raise ConfigError(name, f"expected [x, z], got {arr.tolist()}")
            _set(self, name, arr)
        _set(self, "start_angle", _float("start_angle", self.start_angle))
        _set(self, "goal_angle", _float("goal_angle", self.goal_angle))
        _set(self, "t_start", _float("t_start", self.t_start, nonneg=True))
        _set(self, "move_time", _float("move_time", self.move_time, positive=True))


@dataclass(frozen=True, eq=False)
class TrajectoryConfig:
    """A joint trajectory from a file (``[reference.trajectory]``, ``kind = "trajectory"``).

    Attributes:
        file: A ``.csv`` (header ``t``, then one column per controlled joint, optionally
            ``dq_<joint>`` for every joint) or ``.npz`` (arrays ``t``, ``q``, optionally
            ``dq``, ``joint_names``) [s, rad, rad/s]; relative to the config file
            (:func:`~hmpc_pin.tasks.trajectory.load_trajectory`).
    """

    file: Path | None = None

    def __post_init__(self):
        if not isinstance(self.file, (str, Path)):
            raise ConfigError(
                "file", f"expected the path of a .csv or .npz file, got {self.file!r}"
            )
        _set(self, "file", Path(self.file))


@dataclass(frozen=True, eq=False)
class WaypointsConfig:
    """Joint waypoints retimed by TOPP-RA (``[reference.waypoints]``, ``kind = "waypoints"``).

    Attributes:
        points: The waypoints [rad], a list of P >= 2 joint vectors.
        acceleration_limit: :math:`\\ddot q_{max}` [rad/s²], one value or per joint.
        velocity_limit: :math:`\\dot q_{max}` [rad/s] overriding the URDF's (one value or
            per joint); ``None`` keeps the URDF's velocity limits.
        t_start: Time the motion starts [s]; the first waypoint is held before.
    """

    points: list | None = None
    acceleration_limit: np.ndarray = 2.0
    velocity_limit: np.ndarray | None = None
    t_start: float = 0.0

    def __post_init__(self):
        pts = self.points
        if not isinstance(pts, (list, tuple)) or len(pts) < 2:
            raise ConfigError("points", f"expected a list of >= 2 joint vectors, got {pts!r}")
        rows = [_array(f"points[{i}]", p) for i, p in enumerate(pts)]
        if any(r.ndim != 1 or r.shape != rows[0].shape for r in rows):
            raise ConfigError(
                "points", f"expected joint vectors of one length, got {[r.tolist() for r in rows]}"
            )
        _set(self, "points", np.array(rows))
        _set(
            self,
            "acceleration_limit",
            _array("acceleration_limit", self.acceleration_limit, positive=True),
        )
        if self.velocity_limit is not None:
            _set(
                self, "velocity_limit", _array("velocity_limit", self.velocity_limit, positive=True)
            )
        _set(self, "t_start", _float("t_start", self.t_start, nonneg=True))


#: End-effector paths (``[reference.pose] path``) and the keys each one takes.
POSE_PATHS = {
    "circle": ("center", "radius", "frequency", "plane", "ramp"),
    "line": ("start", "end", "t_start", "duration"),
    "waypoints": ("times", "positions", "orientations"),
}


def _point(key: str, value) -> np.ndarray:
    arr = _array(key, value)
    if arr.shape != (3,):
        raise ConfigError(key, f"expected [x, y, z] [m], got {arr.tolist()}")
    return arr


def _quaternion(key: str, value) -> np.ndarray:
    arr = _array(key, value)
    if arr.shape != (4,) or np.linalg.norm(arr) < 1e-9:
        raise ConfigError(
            key, f"expected a quaternion [x, y, z, w] (scalar last), got {arr.tolist()}"
        )
    return arr / np.linalg.norm(arr)


@dataclass(frozen=True, eq=False)
class PoseConfig:
    """An end-effector task (``[reference.pose]``, ``kind = "pose"``), solved by pink's
    differential IK before the run (:mod:`hmpc_pin.tasks.pose`).

    Positions are in the world frame [m]; orientations quaternions ``[x, y, z, w]``.

    Attributes:
        frame: The frame that follows the path (default: the model's last frame, the tool).
        path: ``"circle"``, ``"line"`` or ``"waypoints"`` (:data:`POSE_PATHS`: only the
            path's own keys may be given).
        q_init: Joint vector the IK starts from and whose posture it keeps [rad] (default
            ``simulation.q0``, else the middle of the joint limits).
        orientation: Orientation held by ``circle`` and ``line`` (default: the frame's at
            ``q_init``).
        center: Circle centre [m] (default: so that the circle starts at the frame's
            position at ``q_init``).
        radius: Circle radius [m].
        frequency: Circle frequency [Hz].
        plane: Circle plane: ``"xy"``, ``"xz"``, ``"yz"`` or a normal ``[nx, ny, nz]``
            (default ``"yz"``).
        ramp: Time [s] over which the circle's angular speed rises from rest (minimum-jerk
            profile; default 0: the circle starts at full speed).
        start: Line start [m] (default: the frame's position at ``q_init``).
        end: Line end [m].
        t_start: Line start time [s].
        duration: Line duration [s] (minimum-jerk timing).
        times: Waypoint times [s], strictly increasing.
        positions: Waypoint positions [m].
        orientations: Waypoint quaternions (default: the frame's at ``q_init`` for all).
        dt: Period of the IK samples [s].
        posture_cost: Weight of the posture term relative to the frame task.
    """

    path: str | None = None
    frame: str | None = None
    q_init: np.ndarray | None = None
    orientation: np.ndarray | None = None
    center: np.ndarray | None = None
    radius: float | None = None
    frequency: float | None = None
    plane: object = None
    ramp: float | None = None
    start: np.ndarray | None = None
    end: np.ndarray | None = None
    t_start: float | None = None
    duration: float | None = None
    times: np.ndarray | None = None
    positions: np.ndarray | None = None
    orientations: np.ndarray | None = None
    dt: float = 0.01
    posture_cost: float = 1e-3

    def __post_init__(self):
        _set(self, "path", _choice("path", self.path, tuple(POSE_PATHS)))
        own = POSE_PATHS[self.path]
        for other in {k for keys in POSE_PATHS.values() for k in keys} - set(own):
            if getattr(self, other) is not None:
                raise ConfigError(
                    other, f"does not apply to path = {self.path!r} (its keys: {', '.join(own)})"
                )
        if self.frame is not None and not isinstance(self.frame, str):
            raise ConfigError("frame", f"expected a frame name, got {self.frame!r}")
        if self.q_init is not None:
            _set(self, "q_init", _array("q_init", self.q_init))
        if self.orientation is not None:
            if self.path == "waypoints":
                raise ConfigError(
                    "orientation",
                    "does not apply to path = 'waypoints' (give orientations, one per waypoint)",
                )
            _set(self, "orientation", _quaternion("orientation", self.orientation))
        for name in ("center", "start", "end"):
            if getattr(self, name) is not None:
                _set(self, name, _point(name, getattr(self, name)))
        if self.path == "circle":
            for name in ("radius", "frequency"):
                if getattr(self, name) is None:
                    raise ConfigError(name, "path = 'circle' needs radius and frequency")
                _set(self, name, _float(name, getattr(self, name), positive=True))
            plane = "yz" if self.plane is None else self.plane
            if not isinstance(plane, str):
                plane = _point("plane", plane)
            elif plane not in ("xy", "xz", "yz"):
                raise ConfigError(
                    "plane", f"expected 'xy', 'xz', 'yz' or a normal [nx, ny, nz], got {plane!r}"
                )
            _set(self, "plane", plane)
            _set(self, "ramp", _float("ramp", 0.0 if self.ramp is None else self.ramp, nonneg=True))
        elif self.path == "line":
            if self.end is None or self.duration is None:
                raise ConfigError("end", "path = 'line' needs end and duration")
            _set(self, "duration", _float("duration", self.duration, positive=True))
            _set(self, "t_start", _float("t_start", self.t_start or 0.0, nonneg=True))
        else:
            if self.times is None or self.positions is None:
                raise ConfigError("times", "path = 'waypoints' needs times and positions")
            times = _array("times", self.times)
            if times.ndim != 1 or times.size < 2 or np.any(np.diff(times) <= 0):
                raise ConfigError(
                    "times", f"expected >= 2 strictly increasing times [s], got {times.tolist()}"
                )
            _set(self, "times", times)
            pos = self.positions
            if not isinstance(pos, (list, tuple)) or len(pos) != times.size:
                raise ConfigError(
                    "positions",
                    f"expected {times.size} points [x, y, z], one per time, got {pos!r}",
                )
            _set(
                self,
                "positions",
                np.array([_point(f"positions[{i}]", p) for i, p in enumerate(pos)]),
            )
            if self.orientations is not None:
                quats = self.orientations
                if not isinstance(quats, (list, tuple)) or len(quats) != times.size:
                    raise ConfigError(
                        "orientations",
                        f"expected {times.size} quaternions [x, y, z, w], got {quats!r}",
                    )
                _set(
                    self,
                    "orientations",
                    np.array([_quaternion(f"orientations[{i}]", q) for i, q in enumerate(quats)]),
                )
        _set(self, "dt", _float("dt", self.dt, positive=True))
        _set(self, "posture_cost", _float("posture_cost", self.posture_cost, positive=True))


SINE_KEYS = ("amplitude", "frequency", "offset", "phase")
SINE_DEFAULTS = {"amplitude": 1.0, "frequency": 0.1, "offset": 0.0, "phase": 0.0}
#: Reference kinds (``[reference] kind``) and the table each one needs (``None``: the sine
#: keys of ``[reference]`` itself).
REFERENCE_TABLES = {
    "sine": (None, None),
    "cartesian": ("cartesian", CartesianConfig),
    "trajectory": ("trajectory", TrajectoryConfig),
    "waypoints": ("waypoints", WaypointsConfig),
    "pose": ("pose", PoseConfig),
}


@dataclass(frozen=True, eq=False)
class ReferenceConfig:
    """Joint reference: the sine of Eq (31), the Cartesian motion of Section 5.4, a
    trajectory file, joint waypoints or an end-effector task (docs, "Tutorials").

    ``kind = "sine"``: :math:`r_i = o_i + a_i \\sin(2\\pi f_i t + \\phi_i)`. Every other
    kind needs its own table (``[reference.cartesian]``, ``[reference.trajectory]``,
    ``[reference.waypoints]``, ``[reference.pose]``) and takes no sine key.

    Attributes:
        kind: One of :data:`REFERENCE_TABLES`.
        amplitude: a [rad] (paper: 1), scalar or per joint.
        frequency: f [Hz] (paper: 0.1, i.e. 0.2π rad/s).
        offset: o [rad] (paper: 0).
        phase: φ [rad] (paper: 0).
        cartesian: :class:`CartesianConfig` for ``kind = "cartesian"``.
        trajectory: :class:`TrajectoryConfig` for ``kind = "trajectory"``.
        waypoints: :class:`WaypointsConfig` for ``kind = "waypoints"``.
        pose: :class:`PoseConfig` for ``kind = "pose"``.
    """

    kind: str = "sine"
    amplitude: np.ndarray | None = None
    frequency: np.ndarray | None = None
    offset: np.ndarray | None = None
    phase: np.ndarray | None = None
    cartesian: CartesianConfig | None = None
    trajectory: TrajectoryConfig | None = None
    waypoints: WaypointsConfig | None = None
    pose: PoseConfig | None = None

    def __post_init__(self):
        _set(self, "kind", _choice("kind", self.kind, tuple(REFERENCE_TABLES)))
        own, cls = REFERENCE_TABLES[self.kind]
        for name, _ in REFERENCE_TABLES.values():
            if name is not None and name != own and getattr(self, name) is not None:
                raise ConfigError(name, f"applies only to kind = {name!r}")
        if own is not None:
            given = [k for k in SINE_KEYS if getattr(self, k) is not None]
            if given:
                raise ConfigError(
                    given[0], f"applies only to kind = 'sine'; remove it for kind = {own!r}"
                )
            value = getattr(self, own)
            if isinstance(value, dict):
                _set(self, own, _section(cls, value, own))
            elif value is None:
                raise ConfigError(own, f"kind = {own!r} needs a [reference.{own}] table")
            elif not isinstance(value, cls):
                raise ConfigError(own, f"expected a table, got {value!r}")
            return
        for key in SINE_KEYS:
            value = getattr(self, key)
            _set(self, key, _array(key, SINE_DEFAULTS[key] if value is None else value))
        if np.any(self.frequency < 0):
            raise ConfigError("frequency", f"expected values >= 0, got {self.frequency.tolist()}")
