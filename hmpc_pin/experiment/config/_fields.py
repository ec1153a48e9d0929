"""Converters of TOML values: each checks one key's type and range and names the key
in its :class:`~hmpc_pin.exceptions.ConfigError` (the converters live in
:mod:`hmpc_pin.checks`, shared with the library's settings classes)."""

from __future__ import annotations

from dataclasses import fields

from ...checks import as_array, as_bool, as_choice, as_float, as_int, as_weight
from ...exceptions import ConfigError

_float, _int, _bool = as_float, as_int, as_bool
_choice, _array, _weight = as_choice, as_array, as_weight


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
