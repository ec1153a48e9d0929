"""Data shipped in the wheel: the paper's arm (``robots/planar3.urdf``) and the configs.

The repository's top-level ``robots/`` and ``configs/`` are links to these folders: one
copy, found by users where they look, and installed with the package.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["DATA", "config_names", "config_path", "robot_names", "robot_path"]

#: The folder of the packaged data.
DATA = Path(__file__).resolve().parent


def robot_names() -> tuple[str, ...]:
    """Names of the packaged URDF robots (e.g. ``"planar3"``)."""
    return tuple(sorted(p.stem for p in (DATA / "robots").glob("*.urdf")))


def robot_path(name: str) -> Path | None:
    """Path of the packaged URDF ``name`` (``"planar3"``), or ``None``."""
    path = DATA / "robots" / f"{name}.urdf"
    return path if path.is_file() else None


def config_names() -> tuple[str, ...]:
    """Names of the packaged configs (e.g. ``"paper_combined"``)."""
    return tuple(sorted(p.stem for p in (DATA / "configs").glob("*.toml")))


def config_path(name: str) -> Path | None:
    """Path of the packaged config ``name`` (with or without ``.toml``), or ``None``."""
    stem = name[:-5] if name.endswith(".toml") else name
    path = DATA / "configs" / f"{stem}.toml"
    return path if path.is_file() and "/" not in name else None
