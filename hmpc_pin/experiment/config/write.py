"""Writing a config back: a TOML file with some tables replaced (``identify``, ``tune``).

The source file is parsed with ``tomllib``, the tables are replaced, and the result is
written as TOML. Comments of the source are not kept; a header comment says where the file
came from.

A written config runs wherever it is copied (:func:`portable_paths`, the rule of every
config the package writes): the file paths (``robot.urdf``, ``plant.urdf``,
``reference.trajectory.file``) are written so that they do not depend on where the written
file is, nor on where the package is installed:

- a robot shipped with the package (``robots/planar3.urdf``) is named by
  ``model = "planar3"``, never by its path inside the installed package;
- any other file shipped with the package (the trajectory of ``panda_trajectory``, a
  packaged URDF given as ``plant.urdf``) is copied beside the written config and named by
  its file name;
- a user's file is named by its absolute path: the written config can be copied anywhere,
  the user's files stay where they are.
"""

from __future__ import annotations

import filecmp
import math
import os
import shutil
import tomllib
from pathlib import Path

from ...data import DATA
from ...exceptions import ConfigError, OutputError

__all__ = ["PATH_KEYS", "dump_toml", "portable_paths", "write_config"]

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


def _packaged(path: Path) -> bool:
    """Whether ``path`` is a file shipped inside the installed package's data."""
    try:
        path.resolve().relative_to(DATA)
    except ValueError:
        return False
    return True


def _beside(path: Path, dest: Path) -> str:
    """Copy the packaged file ``path`` into ``dest`` (unless the same file is there) and
    return its name; a different file of that name there is an :class:`OutputError`."""
    target = dest / path.name
    if target.exists() and not filecmp.cmp(path, target, shallow=False):
        raise OutputError(
            target,
            f"exists and differs from the packaged {path.name} the written config needs "
            "beside it; write the config to another folder, or move that file",
        )
    if not target.exists():
        try:
            dest.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(path, target)
        except OSError as exc:
            raise OutputError(dest, f"is not writable ({exc.strerror or exc})") from exc
    return path.name


def portable_paths(raw: dict, base: Path, dest: Path) -> dict:
    """Rewrite the file paths of the parsed config ``raw`` (read from the folder ``base``)
    for a config written into the folder ``dest``, so that it runs wherever it is copied
    (the module's rule: a packaged robot by ``model``, another packaged file copied beside,
    a user's file by its absolute path). ``raw`` is changed in place and returned.

    Raises:
        OutputError: A packaged side file cannot be copied into ``dest``.
    """
    for keys in PATH_KEYS:
        table = raw
        for k in keys[:-1]:
            table = table.get(k, {}) if isinstance(table, dict) else {}
        value = table.get(keys[-1]) if isinstance(table, dict) else None
        if not isinstance(value, str):
            continue
        path = (Path(value) if Path(value).is_absolute() else base / value).resolve()
        shipped_robot = path.parent == DATA / "robots" and path.suffix == ".urdf"
        if keys == ("robot", "urdf") and shipped_robot and "model" not in table:
            del table["urdf"]
            table["model"] = path.stem
        elif _packaged(path) and path.is_file():
            table[keys[-1]] = _beside(path, dest)
        else:
            table[keys[-1]] = str(path)
    return raw


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
    portable_paths(raw, Path(source).resolve().parent, Path(out).resolve().parent)
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
