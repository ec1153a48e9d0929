"""Data shipped in the wheel: the paper's arm (``robots/planar3.urdf``), the configs and
the example scripts (``hmpc_pin/examples``, scripts to copy and run, not modules).

The repository's top-level ``robots/``, ``configs/`` and ``examples/`` are links to these
folders: one copy, found by users where they look, and installed with the package
(``hmpc-pin configs`` and ``hmpc-pin examples`` list them and write editable copies).
"""

from __future__ import annotations

from pathlib import Path

__all__ = [
    "DATA",
    "EXAMPLES",
    "config_names",
    "config_path",
    "example_names",
    "example_path",
    "robot_names",
    "robot_path",
]

#: The folder of the packaged data.
DATA = Path(__file__).resolve().parent
#: The folder of the example scripts shipped with the package.
EXAMPLES = DATA.parent / "examples"


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


def example_names() -> tuple[str, ...]:
    """Names of the packaged example scripts (e.g. ``"track_sine"``)."""
    return tuple(sorted(p.stem for p in EXAMPLES.glob("*.py")))


def example_path(name: str) -> Path | None:
    """Path of the packaged example ``name`` (with or without ``.py``), or ``None``."""
    stem = name[:-3] if name.endswith(".py") else name
    path = EXAMPLES / f"{stem}.py"
    return path if path.is_file() and "/" not in name else None
