"""Exceptions raised by hmpc_pin.

Every error the package raises derives from :class:`HmpcError`, so a caller can
catch the package's errors without catching programming errors. Errors about
bad input also derive from :class:`ValueError`; solver failures derive from
:class:`RuntimeError`. Messages name the offending value, what was expected and
what to do next.
"""

from __future__ import annotations

import os


class HmpcError(Exception):
    """Base class of every error raised by hmpc_pin."""


class ConfigError(HmpcError, ValueError):
    """A configuration value (TOML file, dataclass field) is invalid.

    The message is ``"<source>: <key>: <message>"``, each part left out when empty.

    Attributes:
        key: Dotted name of the offending key, e.g. ``"controller.N"``, or an option
            (``"--out"``); ``""`` when the file itself is wrong (missing, not TOML).
        source: The file the value came from, if any.
    """

    def __init__(self, key: str, message: str, source: str | None = None):
        self.key = key
        self.message = message
        self.source = source
        where = f"{source}: " if source else ""
        what = f"{key}: " if key else ""
        super().__init__(f"{where}{what}{message}")


class URDFError(HmpcError, ValueError):
    """A URDF file is missing, malformed, or describes an unsupported robot.

    Attributes:
        path: The URDF file (or robot name) that was rejected.
    """

    def __init__(self, path: str | os.PathLike[str], message: str):
        self.path = str(path)
        super().__init__(f"{path}: {message}")


class NonFiniteError(HmpcError, ValueError):
    """A state, time, reference or torque contains NaN or infinity.

    Attributes:
        name: What was non-finite (``"q"``, ``"dq"``, ``"t"``, ``"q_ref"``, ...).
        value: The offending value.
    """

    def __init__(self, name: str, value, context: str = ""):
        self.name = name
        self.value = value
        ctx = f" {context}" if context else ""
        super().__init__(
            f"{name} is not finite{ctx}: {name}={value!r}; "
            "the controller only accepts finite numbers (check the sensor "
            "values or the simulation for divergence)"
        )


class DimensionError(HmpcError, ValueError):
    """An array has the wrong shape for the robot it is used with."""


class LimitError(HmpcError, ValueError):
    """A reference or initial state leaves the joint limits.

    Attributes:
        joint: Name of the joint. time: Time [s] (``None`` for an initial state).
        value: The offending value. lower, upper: The limits.
        hint: What to do (default: change the reference or the limits).
    """

    def __init__(
        self,
        what: str,
        joint: str,
        time,
        value: float,
        lower: float,
        upper: float,
        hint: str | None = None,
    ):
        self.joint, self.time, self.value, self.lower, self.upper = joint, time, value, lower, upper
        when = f" at t={time:.6g} s" if time is not None else ""
        todo = hint or (
            "change the reference (amplitude, offset) or the limits "
            "(controller.constraints.lower/upper)"
        )
        super().__init__(
            f"{what} of joint {joint!r} is {value:.6g}{when}, outside its limits "
            f"[{lower:.6g}, {upper:.6g}]; {todo}"
        )


class SolverError(HmpcError, RuntimeError):
    """A joint QP did not report ``PROXQP_SOLVED``.

    Attributes:
        joint: Index of the joint whose QP failed (``None`` for the block QP of all
            joints; ``controller.qp_layout = "joint"`` names the joint).
        status: ProxSuite's status as a string.
    """

    def __init__(self, joint: int | None, joint_name: str, status: str, iterations: int):
        self.joint = joint
        self.status = status
        who = f"joint {joint} ({joint_name!r})" if joint is not None else f"the {joint_name}"
        super().__init__(
            f"{who} MPC QP was not solved: "
            f"status={status} after {iterations} iterations; no torque was "
            "returned. Check the MPC weights and bounds (controller.Q, R, P, "
            "v_min, v_max) or raise controller.max_iter"
        )


class SimulationError(HmpcError, RuntimeError):
    """A closed-loop run stopped early (non-finite state, divergence, solver failure).

    Attributes:
        result: The partial :class:`~hmpc_pin.sim.result.Result` up to the failing step,
            marked ``complete=False``.
    """

    def __init__(self, message: str, result=None):
        self.result = result
        super().__init__(message)


class OutputError(HmpcError, ValueError):
    """An output location (directory, file) cannot be written.

    Attributes:
        path: The location that was rejected.
        option: The command-line option that named it (``"--out"``, ``"--replay"``, ...),
            or ``None`` for a path given to a function.
        what: ``"output directory"`` or ``"output file"``.
    """

    def __init__(
        self, path, reason: str, option: str | None = "--out", what: str = "output directory"
    ):
        self.path = str(path)
        self.option = option
        self.what = what
        place = "a directory" if what == "output directory" else "a file in a directory"
        fix = f"pass {option} with {place}" if option else f"give {place}"
        where = f"{option}: " if option else ""
        super().__init__(f"{where}{what} {self.path!r} {reason}; {fix} you can write to")


class NodeShutDown(KeyboardInterrupt):
    """A ROS 2 lifecycle node waiting for its activation (``[ros] autostart = false``) was
    shut down by its orchestrator first: a stop from outside before anything ran, sent or
    was written (exit 130, as Ctrl-C). A :class:`KeyboardInterrupt`, as
    :class:`RunInterrupted`."""


class RunInterrupted(KeyboardInterrupt):
    """The user interrupted a run (Ctrl-C, SIGINT) and what it computed was kept.

    A :class:`KeyboardInterrupt` (not an :class:`HmpcError`), so that code catching the
    package's errors still stops on Ctrl-C.

    Attributes:
        where: Where the run stopped, in words (``"t=1.234 s of 60 s (step 1234)"``).
        result: The partial :class:`~hmpc_pin.sim.result.Result` (``complete=False``,
            the reason in ``message``), or ``None``.
        files: Files written with what was kept (filled in by the application).
    """

    def __init__(self, where: str, result=None, files=()):
        self.where = where
        self.result = result
        self.files = list(files)
        super().__init__(where)


class KinematicsError(HmpcError, ValueError):
    """A pose cannot be solved, or the arm is not a planar 3R arm.

    Attributes:
        value: The offending value (a pose ``(x, z, φ)``, a joint vector, an axis, ...).
        expected: What was expected instead, in words.
    """

    def __init__(self, message: str, *, value=None, expected: str | None = None):
        self.value = value
        self.expected = expected
        super().__init__(message)


class VizError(HmpcError, RuntimeError):
    """Meshcat is missing or its server cannot be started."""


class InterfaceError(HmpcError, TypeError):
    """An object passed where a protocol is expected lacks what the protocol needs.

    Raised once, at the boundary (e.g. a reference without ``sample_many``/``sample``
    that is not callable either), naming the object, the protocol and what is missing.

    Attributes:
        value: The offending object.
        expected: The protocol and the members it needs, in words.
    """

    def __init__(self, value, expected: str, hint: str = ""):
        self.value = value
        self.expected = expected
        text = f"{type(value).__name__} object {value!r:.80} is not {expected}"
        super().__init__(text + (f"; {hint}" if hint else ""))


class ArmError(HmpcError, RuntimeError):
    """The arm does not give the controller what it needs, before any torque is sent: no
    state within the start-up time (a ROS topic nobody publishes), a state without some of
    the robot's joints, or without positions and velocities. The message names the
    source (topic) and what to check."""


class ValidityWarning(UserWarning):
    """A design is used outside the conditions it is proven for (e.g. Chen's observer on a
    spatial arm); the run goes on. The message names the valid alternative."""


def install_command(extra: str) -> str:
    """The one ``pip`` command that adds the extra ``extra`` to this installation of
    hmpc_pin (every missing-extra message and the docs' "Extras" use this rule).

    hmpc_pin is installed from a clone or from a wheel, not from a package index, so a
    bare ``pip install "hmpc_pin[extra]"`` would not find it. pip records where the
    package came from (``direct_url.json``, PEP 610):

    * run from a clone (an editable install): ``pip install -e "<clone>[extra]"`` (from
      the clone's folder: ``pip install -e ".[extra]"``);
    * a wheel file: ``pip install "hmpc_pin[extra] @ file:///…/hmpc_pin-….whl"`` (the same
      wheel: pip then installs only the extra's packages);
    * anything else (an index, a wheel moved since): ``pip install "hmpc_pin[extra]"``
      with the source it came from, e.g. ``"hmpc_pin[extra] @ /path/to/the.whl"``.
    """
    import json
    from importlib import metadata
    from pathlib import Path
    from urllib.parse import unquote, urlparse

    clone = Path(__file__).resolve().parent.parent
    if (clone / "pyproject.toml").is_file() and (clone / "CMakeLists.txt").is_file():
        return f'pip install -e "{clone}[{extra}]"'  # run from a source tree (editable)
    try:
        record = json.loads(metadata.distribution("hmpc_pin").read_text("direct_url.json") or "")
    except (metadata.PackageNotFoundError, ValueError, OSError):
        record = {}
    url = record.get("url", "") if isinstance(record, dict) else ""
    wheel = url.startswith("file:") and "archive_info" in record
    if wheel and Path(unquote(urlparse(url).path)).is_file():  # the wheel it came from
        return f'pip install "hmpc_pin[{extra}] @ {url}"'
    return (
        f'pip install "hmpc_pin[{extra}] @ <the hmpc_pin wheel>" (or, in a clone, '
        f'pip install -e ".[{extra}]")'
    )


class ExtraError(HmpcError, ImportError):
    """An optional dependency of the package is not installed.

    Attributes:
        extra: The ``hmpc_pin`` extra that installs it (:func:`install_command`).
        needed_for: What needs it, in words.
    """

    def __init__(self, extra: str, needed_for: str):
        self.extra = extra
        self.needed_for = needed_for
        super().__init__(
            f"{needed_for} needs the optional package of the extra {extra!r} "
            f"(hmpc_pin[{extra}]), which is not installed; install it with: "
            f"{install_command(extra)}"
        )


class TrajectoryError(HmpcError, ValueError):
    """A trajectory (file or samples) or a task for one is unusable: file missing,
    a joint column missing, time not increasing, a non-finite value, a waypoint list
    too short...

    Attributes:
        source: The file (or ``"trajectory"``, a config key) it came from.
        value: What was found, in words.
        expected: What was expected instead.
    """

    def __init__(self, source: str, value: str, expected: str):
        self.source, self.value, self.expected = str(source), value, expected
        super().__init__(f"{source}: {value}; expected {expected}")


class NativeError(HmpcError, RuntimeError):
    """The compiled core (``hmpc_pin._core``) cannot be loaded here.

    Raised when a controller or an RK4 plant is built (they have no Python twin): the
    package was used from a source tree without ``pip install``, or the core was built
    against other Pinocchio/ProxSuite versions.

    Attributes:
        reason: What failed (the module is not installed, or was built against other
            Pinocchio/ProxSuite versions).
    """

    def __init__(self, reason: str):
        self.reason = reason
        super().__init__(
            f"the compiled core is not available: {reason}. `hmpc-pin native` reports what "
            "is installed"
        )


class PerformanceWarning(UserWarning):
    """A run takes a slower path than it could (e.g. the compiled core is unavailable)."""


class RealtimeWarning(UserWarning):
    """Something outside the run will delay a real-time loop (another process's
    real-time threads, :mod:`hmpc_pin.realtime.machine`); the run goes on. The message
    names it and what to do."""


class ExcitationError(HmpcError, ValueError):
    """A run does not excite a joint enough to identify it (``hmpc-pin identify``).

    Attributes:
        joint: The joint's name. reason: What was measured.
    """

    def __init__(self, joint: str, reason: str):
        self.joint = joint
        self.reason = reason
        super().__init__(
            f"joint {joint!r} is not excited enough to identify its friction: {reason}; "
            f"record a run in which {joint} moves both ways at speed, e.g. a sine reference "
            "on it with a peak velocity 2π·amplitude·frequency of 0.2 rad/s or more, over "
            "several periods"
        )
