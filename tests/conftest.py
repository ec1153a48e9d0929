"""Shared fixtures: paths of the repository's robot and configs, and small factories."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
PLANAR3 = ROOT / "robots" / "planar3.urdf"
CONFIGS = ROOT / "configs"


@pytest.fixture(scope="session")
def planar3():
    """The paper's 3-link arm (a fresh model per test session)."""
    import hmpc_pin

    return hmpc_pin.load_robot(PLANAR3)


@pytest.fixture
def write_config(tmp_path):
    """Factory: write a TOML text (with the robot path filled in) and return its path."""

    def _write(text: str, name: str = "cfg.toml") -> Path:
        path = tmp_path / name
        path.write_text(text.replace("@URDF@", PLANAR3.as_posix()), encoding="utf-8")
        return path

    return _write


@pytest.fixture
def make_rng():
    """Factory of seeded generators, so each test draws a reproducible sequence."""

    def _make(seed: int = 0) -> np.random.Generator:
        return np.random.default_rng(seed)

    return _make


@pytest.fixture
def write_urdf(tmp_path):
    """Factory writing ``text`` to ``tmp_path / name`` and returning the path."""

    def _write(text: str, name: str = "robot.urdf") -> Path:
        path = tmp_path / name
        path.write_text(text, encoding="utf-8")
        return path

    return _write
