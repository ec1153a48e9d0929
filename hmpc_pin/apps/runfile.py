"""A run saved by ``hmpc-pin run``, ``realtime`` or ``ros`` read back for the commands
that work on one (``identify``, ``replay``): a bad file is one
:class:`~hmpc_pin.exceptions.ConfigError` naming the file and what was expected, and
nothing is ever unpickled."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..exceptions import ConfigError
from ..sim.result import Result

__all__ = ["load_run", "run_robot"]


def load_run(path: Path, key: str = "RUN") -> Result:
    """The run saved at ``path``, or one :class:`~hmpc_pin.exceptions.ConfigError`
    (named ``key``) saying what the file is instead: missing, empty, not a ``.npz``,
    truncated, another program's ``.npz``, or arrays of the wrong shapes. Nothing is
    ever unpickled."""
    import zipfile

    what = "pass a .npz written by `hmpc-pin run`, `realtime` or `ros`"
    if not path.is_file():
        raise ConfigError(key, f"{str(path)!r} not found; {what}")
    try:
        with path.open("rb") as f:
            head = f.read(4)
    except OSError as exc:
        raise ConfigError(key, f"{str(path)!r} cannot be read ({exc.strerror or exc})") from None
    if not head:
        raise ConfigError(key, f"{str(path)!r} is empty (0 bytes); {what}")
    if head != b"PK\x03\x04":
        raise ConfigError(
            key, f"{str(path)!r} is not a .npz archive (a result is a zip of arrays); {what}"
        )
    try:
        result = Result.load(path)
    except (zipfile.BadZipFile, EOFError) as exc:
        raise ConfigError(
            key,
            f"{str(path)!r} is truncated or corrupt ({str(exc) or 'the data end early'}); "
            "write it again, or pass another run",
        ) from None
    except KeyError as exc:
        missing = str(exc.args[0] if exc.args else exc).split(" is not a file")[0]
        raise ConfigError(
            key,
            f"{str(path)!r} is a .npz but not a hmpc_pin result (it "
            f"has no {missing!r} array); {what}",
        ) from None
    except (OSError, ValueError, TypeError) as exc:
        why = (
            "it holds object arrays, which a result never does"
            if "pickle" in str(exc)
            else str(exc)
        )
        raise ConfigError(key, f"{str(path)!r} is not a hmpc_pin result ({why}); {what}") from None
    _check_shapes(result, path, key)
    return result


def _check_shapes(result: Result, path: Path, key: str) -> None:
    """The arrays of a result agree: ``t`` (K+1,), the others (K+1, n), K >= 1."""
    if not isinstance(result.meta, dict):
        raise ConfigError(key, f"{str(path)!r}: its metadata is not a table; is it a result?")
    t = np.asarray(result.t)
    if t.ndim != 1 or len(t) < 2:
        raise ConfigError(
            key,
            f"{str(path)!r}: the time array has shape {t.shape}, expected "
            "(K+1,) with at least 2 samples",
        )
    numeric = np.issubdtype(t.dtype, np.number)
    if not (numeric and np.all(np.isfinite(t)) and np.all(np.diff(t) > 0)):
        raise ConfigError(
            key, f"{str(path)!r}: the time array is not finite and increasing; is it a result?"
        )
    n = np.asarray(result.q).shape[-1] if np.ndim(result.q) == 2 else None
    for name in ("q", "dq", "tau", "d_hat", "tau_applied"):
        arr = getattr(result, name)
        shape = np.shape(arr)
        if n is None or shape != (len(t), n):
            raise ConfigError(
                key,
                f"{str(path)!r}: the array {name!r} has shape {shape}, "
                f"expected ({len(t)}, n) like q",
            )
        if not np.issubdtype(np.asarray(arr).dtype, np.number):
            raise ConfigError(key, f"{str(path)!r}: the array {name!r} is not numeric")


def run_robot(result: Result, urdf: str | None, key: str = "RUN"):
    """The arm of ``result``: the URDF it names (or ``urdf``, from ``--urdf``), reduced as
    it ran, with as many joints of the same names as the run (else a
    :class:`~hmpc_pin.exceptions.ConfigError`)."""
    from ..model.robot import load_robot

    source = urdf or result.meta.get("urdf")
    if not source:
        raise ConfigError("--urdf", "the run does not name its URDF; pass --urdf PATH")
    robot = load_robot(
        source,
        gravity=result.meta.get("gravity", 9.81),
        locked_joints=result.meta.get("locked_joints") if not urdf else None,
    )
    n = np.shape(result.q)[1]
    names = tuple(result.joint_names)
    if robot.nq != n or (names and tuple(robot.joint_names) != names):
        ran = f"{n} joints {names}" if names else f"{n} joints"
        raise ConfigError(
            "--urdf" if urdf else key,
            f"the URDF {str(source)!r} has "
            f"{robot.nq} joints {tuple(robot.joint_names)} but the run has "
            f"{ran}; pass the URDF of the arm that ran" + ("" if urdf else " with --urdf"),
        )
    return robot
