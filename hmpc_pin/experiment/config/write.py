"""Writing a config back: a TOML file with some tables replaced (``identify``, ``tune``).

The source file is parsed with ``tomllib``, the tables are replaced, and the result is
written as TOML with the relative file paths (``robot.urdf``, ``plant.urdf``,
``reference.trajectory.file``) rewritten relative to the new file's folder, so that the
written config loads from wherever it is written. Comments of the source are not kept; a
header comment says where the file came from.
"""

from __future__ import annotations

import math
import os
import tomllib
from pathlib import Path

from ...exceptions import ConfigError, OutputError

__all__ = ["PATH_KEYS", "dump_toml", "write_config"]

#: Keys holding file paths relative to the config file.
PATH_KEYS = (("robot", "urdf"), ("plant", "urdf"), ("reference", "trajectory", "file"))


def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):  # an inline table (inside an array)
        return "{" + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + "}"
    if hasattr(v, "tolist"):  # a numpy array or scalar
        return _value(v.tolist())
    raise ConfigError(
        "<value>",
        f"cannot write {type(v).__name__} {v!r} as TOML; expected "
        "numbers, strings, booleans, lists or tables",
    )


def _key(k: str) -> str:
    return k if k.replace("_", "").replace("-", "").isalnum() else _value(k)


def dump_toml(data: dict, _prefix: str = "") -> str:
    """``data`` (nested dicts of numbers, strings, booleans and lists) as TOML text."""
    lines, tables = [], []
    for k, v in data.items():
        if isinstance(v, dict):
            tables.append((k, v))
        else:
            lines.append(f"{_key(k)} = {_value(v)}")
    out = "\n".join(lines) + ("\n" if lines else "")
    for k, v in tables:
        name = f"{_prefix}.{_key(k)}" if _prefix else _key(k)
        body = dump_toml(v, name)
        has_values = any(not isinstance(x, dict) for x in v.values())
        out += ("\n" if out else "") + (f"[{name}]\n" if has_values or not v else "") + body
    return out


def write_config(
    source: Path, tables: dict, out: Path, header: str = "", name: str | None = None
) -> Path:
    """Write ``source`` with ``tables`` set to ``out`` (written to ``out.part`` and renamed).

    Args:
        source: The config file.
        tables: Dotted table name → dict of keys (e.g. ``{"controller.friction": {...}}``);
            the table replaces the source's, if any.
        out: The file to write.
        header: Comment lines put first (each without ``#``).
        name: The written config's ``name`` (default: the source's).

    Raises:
        ConfigError: ``source`` cannot be read. OutputError: ``out`` cannot be written.
    """
    try:
        raw = tomllib.loads(Path(source).read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise ConfigError("", f"cannot be read ({exc})", source=str(source)) from exc
    base, dest = Path(source).resolve().parent, Path(out).resolve().parent
    for keys in PATH_KEYS:
        table = raw
        for k in keys[:-1]:
            table = table.get(k, {}) if isinstance(table, dict) else {}
        value = table.get(keys[-1]) if isinstance(table, dict) else None
        if isinstance(value, str) and not Path(value).is_absolute():
            table[keys[-1]] = os.path.relpath((base / value).resolve(), dest)
    for table_name, body in tables.items():
        *parents, last = table_name.split(".")
        table = raw
        for k in parents:
            table = table.setdefault(k, {})
        table[last] = dict(body)
    raw.setdefault("name", Path(source).stem)
    if name is not None:
        raw["name"] = name
    text = "".join(f"# {line}\n" for line in header.splitlines()) + dump_toml(raw)
    part = Path(out).with_name(Path(out).name + ".part")
    try:
        part.write_text(text, encoding="utf-8")
        os.replace(part, out)
    except OSError as exc:
        raise OutputError(
            Path(out).parent, f"is not writable ({exc.strerror or exc})", "--out"
        ) from exc
    finally:
        if part.exists():
            part.unlink()
    return Path(out)
