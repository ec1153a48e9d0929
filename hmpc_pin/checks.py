"""Checks of values given to the package, one place for the config loader and the library.

Each converter checks one value's type and range and names it (``key``) in the
:class:`~hmpc_pin.exceptions.ConfigError` it raises; :func:`mpc_fields` checks the per-joint
MPC's settings together. The TOML loader (:mod:`hmpc_pin.experiment.config`) and the
library's settings classes (:class:`~hmpc_pin.controllers.MPCSettings`) both call these,
so a value refused in a config file is refused, with the same error, when given in code.
"""

from __future__ import annotations

import math

import numpy as np

from .exceptions import ConfigError

__all__ = [
    "MAX_LATENCY",
    "as_array",
    "as_bool",
    "as_choice",
    "as_float",
    "as_int",
    "as_latency",
    "as_weight",
    "available_memory",
    "mpc_fields",
    "run_memory",
]

#: The longest measurement latency a controller accepts [s]. Arms' interfaces deliver
#: their state within milliseconds (one 1 kHz cycle for libfranka, 2 ms for UR's RTDE);
#: a second is a unit error, and the controller keeps one torque per period of it.
MAX_LATENCY = 1.0

#: A run's arrays may take at most this share of the memory available when it starts (the
#: rest: the saved copies of the arrays, the figures, the other processes).
MEMORY_SHARE = 0.5


def available_memory() -> float:
    """The memory available to a new allocation [bytes]: ``MemAvailable`` of
    ``/proc/meminfo`` (Linux), else the physical memory; ``inf`` when neither is known."""
    import os

    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    try:
        return float(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return math.inf


def run_memory(key: str, duration: float, Ts: float, n: int, arrays: int = 9) -> float:
    """Check, before anything is allocated, that a run of ``duration`` [s] sampled every
    ``Ts`` [s] on ``n`` joints fits in memory: its ``arrays`` per-joint arrays (a
    :class:`~hmpc_pin.sim.result.Result` holds nine) and the time and step-time columns,
    8 bytes a number, within :data:`MEMORY_SHARE` of :func:`available_memory`.

    Returns:
        The bytes the arrays take.

    Raises:
        ConfigError: Naming ``key``, the memory needed and available, and the longest
            duration that fits.
    """
    per_sample = 8.0 * (arrays * n + 2)
    samples = duration / Ts + 1.0
    need, free = samples * per_sample, MEMORY_SHARE * available_memory()
    if need > free:
        longest = (free / per_sample - 1.0) * Ts
        raise ConfigError(
            key,
            f"{duration:g} s at Ts = {Ts:g} s is {samples:.3g} samples of {n} joints, whose "
            f"arrays would take {need / 1e9:.3g} GB: more than half of the "
            f"{2 * free / 1e9:.3g} GB of memory available here; expected at most "
            f"{longest:.3g} s (or shorter runs one after another)",
        )
    return need


def as_float(key: str, value, *, positive: bool = False, nonneg: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ConfigError(key, f"expected a number, got {type(value).__name__} {value!r}")
    x = float(value)
    if not math.isfinite(x):
        raise ConfigError(key, f"expected a finite number, got {x!r}")
    if positive and x <= 0:
        raise ConfigError(key, f"expected a number > 0, got {x!r}")
    if nonneg and x < 0:
        raise ConfigError(key, f"expected a number >= 0, got {x!r}")
    return x


def as_latency(key: str, value) -> float:
    """A measurement latency [s]: a finite number in ``[0, MAX_LATENCY]``."""
    x = as_float(key, value, nonneg=True)
    if x > MAX_LATENCY:
        raise ConfigError(
            key,
            f"expected a latency in [0, {MAX_LATENCY:g}] s (the age of the measurements, "
            f"milliseconds on an arm's interface), got {x!r} s",
        )
    return x


def as_int(key: str, value, *, minimum: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ConfigError(key, f"expected an integer, got {type(value).__name__} {value!r}")
    if minimum is not None and value < minimum:
        raise ConfigError(key, f"expected an integer >= {minimum}, got {value!r}")
    return int(value)


def as_bool(key: str, value) -> bool:
    if not isinstance(value, bool):
        raise ConfigError(key, f"expected true or false, got {type(value).__name__} {value!r}")
    return value


def as_choice(key: str, value, choices: tuple[str, ...]) -> str:
    if value not in choices:
        raise ConfigError(key, f"expected one of {choices}, got {value!r}")
    return value


def as_array(key: str, value, *, nonneg: bool = False, positive: bool = False) -> np.ndarray:
    """A finite float scalar or 1-D vector (length checked later against the robot)."""
    items = value.tolist() if isinstance(value, np.ndarray) else value
    if isinstance(items, (list, tuple)):
        if len(items) == 0:
            raise ConfigError(key, "expected a number or a non-empty list of numbers, got []")
        arr = np.array([as_float(f"{key}[{i}]", v) for i, v in enumerate(items)], dtype=float)
    else:
        arr = np.array(as_float(key, items), dtype=float)
    if positive and np.any(arr <= 0):
        raise ConfigError(key, f"expected values > 0, got {arr.tolist()}")
    if nonneg and np.any(arr < 0):
        raise ConfigError(key, f"expected values >= 0, got {arr.tolist()}")
    return arr


def as_weight(key: str, value) -> np.ndarray:
    """A 2×2 PSD weight given as a diagonal [a, b] or a full [[..],[..]] matrix."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ConfigError(key, f"expected [a, b] or a 2x2 matrix, got {value!r}") from exc
    if arr.shape == (2,):
        arr = np.diag(arr)
    if arr.shape != (2, 2):
        raise ConfigError(key, f"expected a diagonal [a, b] or a 2x2 matrix, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ConfigError(key, f"expected finite numbers, got {arr.tolist()}")
    if not np.allclose(arr, arr.T):
        raise ConfigError(key, f"expected a symmetric matrix, got {arr.tolist()}")
    eig = np.linalg.eigvalsh(arr)
    if eig.min() < 0 or eig.max() <= 0:
        raise ConfigError(
            key,
            f"expected a positive semi-definite, non-zero weight, got eigenvalues {eig.tolist()}",
        )
    return arr


def mpc_fields(
    Ts, N, Nc, Q, R, P, v_min, v_max, prefix: str = ""
) -> dict[str, float | int | np.ndarray]:
    """The per-joint MPC's settings checked together (Section 4): ``Ts > 0`` [s],
    ``1 <= Nc <= N`` [steps], ``Q``, ``P`` 2×2 positive semi-definite and non-zero,
    ``R > 0``, ``v_min < v_max`` [rad/s²] (scalars or per joint, same length).

    Args:
        prefix: Put before every key in the errors (``"MPCSettings."``).

    Returns:
        The values converted (floats, ints, arrays), keyed by name.

    Raises:
        ConfigError: The first value that is wrong, naming ``prefix + name``.
    """
    out: dict[str, float | int | np.ndarray] = {
        "Ts": as_float(prefix + "Ts", Ts, positive=True),
        "N": as_int(prefix + "N", N, minimum=1),
        "Nc": as_int(prefix + "Nc", Nc, minimum=1),
    }
    if out["Nc"] > out["N"]:
        raise ConfigError(prefix + "Nc", f"Nc={out['Nc']} but N={out['N']}; expected 1 <= Nc <= N")
    out["Q"] = as_weight(prefix + "Q", Q)
    out["P"] = as_weight(prefix + "P", P)
    out["R"] = as_float(prefix + "R", R, positive=True)
    lo = out["v_min"] = as_array(prefix + "v_min", v_min)
    hi = out["v_max"] = as_array(prefix + "v_max", v_max)
    if lo.shape != hi.shape and lo.ndim and hi.ndim:
        raise ConfigError(
            prefix + "v_max",
            f"v_min has shape {lo.shape} but v_max {hi.shape}; give both per joint",
        )
    if np.any(lo >= hi):
        raise ConfigError(
            prefix + "v_min",
            f"v_min={lo.tolist()} must be < v_max={hi.tolist()} on every joint",
        )
    return out
