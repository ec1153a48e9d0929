"""Converters of TOML values: each checks one key's type and range and names the key
in its :class:`~hmpc_pin.exceptions.ConfigError`."""

from __future__ import annotations

import math
from dataclasses import fields

import numpy as np

from ...exceptions import ConfigError


def _float(key: str, value, *, positive: bool = False, nonneg: bool = False) -> float:
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


def _int(key: str, value, *, minimum: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ConfigError(key, f"expected an integer, got {type(value).__name__} {value!r}")
    if minimum is not None and value < minimum:
        raise ConfigError(key, f"expected an integer >= {minimum}, got {value!r}")
    return int(value)


def _bool(key: str, value) -> bool:
    if not isinstance(value, bool):
        raise ConfigError(key, f"expected true or false, got {type(value).__name__} {value!r}")
    return value


def _choice(key: str, value, choices: tuple[str, ...]) -> str:
    if value not in choices:
        raise ConfigError(key, f"expected one of {choices}, got {value!r}")
    return value


def _array(key: str, value, *, nonneg: bool = False, positive: bool = False) -> np.ndarray:
    """A finite float scalar or 1-D vector (length checked later against the robot)."""
    items = value.tolist() if isinstance(value, np.ndarray) else value
    if isinstance(items, (list, tuple)):
        if len(items) == 0:
            raise ConfigError(key, "expected a number or a non-empty list of numbers, got []")
        arr = np.array([_float(f"{key}[{i}]", v) for i, v in enumerate(items)], dtype=float)
    else:
        arr = np.array(_float(key, items), dtype=float)
    if positive and np.any(arr <= 0):
        raise ConfigError(key, f"expected values > 0, got {arr.tolist()}")
    if nonneg and np.any(arr < 0):
        raise ConfigError(key, f"expected values >= 0, got {arr.tolist()}")
    return arr


def _weight(key: str, value) -> np.ndarray:
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


def _set(obj, name: str, value) -> None:
    object.__setattr__(obj, name, value)


def _section(cls, data, prefix: str):
    """Build dataclass ``cls`` from a TOML table, naming keys with ``prefix``."""
    if not isinstance(data, dict):
        raise ConfigError(prefix, f"expected a table, got {type(data).__name__} {data!r}")
    allowed = {f.name for f in fields(cls)} - {"source"}
    unknown = sorted(set(data) - allowed)
    if unknown:
        raise ConfigError(
            f"{prefix}.{unknown[0]}",
            f"unknown key; allowed keys in [{prefix}] are {sorted(allowed)}",
        )
    try:
        return cls(**data)
    except ConfigError as exc:
        key = exc.key if exc.key.startswith(prefix + ".") else f"{prefix}.{exc.key}"
        msg = exc.message
        raise ConfigError(key, msg) from None
