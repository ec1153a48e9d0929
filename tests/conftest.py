"""Shared fixtures: paths of the repository's robot and configs, and small factories; the
test tiers.

Every test is in one of two tiers, marked at collection (:func:`pytest_collection_modifyitems`),
so that no test is marked by hand:

- ``e2e``: the tests that go through a process boundary or a real clock: every test of the
  files of :data:`E2E_FILES` (the command line, the viewer, ROS 2, the real-time loop, the
  wheel, the interrupts), and any other test whose body starts a subprocess or a Meshcat
  viewer (:data:`E2E_SIGNS`);
- ``unit``: every other test (in-process, no subprocess).

``pytest`` runs both; ``pytest -m unit`` the fast tier, ``pytest -m e2e`` the other.
"""

from __future__ import annotations

import inspect
import signal
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
PLANAR3 = ROOT / "robots" / "planar3.urdf"
CONFIGS = ROOT / "configs"

#: Test files whose every test is end to end (CLI subprocesses, viewer, ROS, real time, wheel).
E2E_FILES = frozenset(
    {
        "test_cli.py",
        "test_cli_outputs.py",
        "test_cli_realtime.py",
        "test_franka.py",
        "test_imports.py",
        "test_interrupts.py",
        "test_realtime.py",
        "test_realtime_declared_latency.py",
        "test_ros.py",
        "test_ros_boundary.py",
        "test_viz.py",
        "test_wheel.py",
    }
)
#: What in a test's own source makes it end to end in any other file.
E2E_SIGNS = ("subprocess.", '"meshcat"', "run_in_netns(")


def _tier(item: pytest.Item) -> str:
    """``"e2e"`` or ``"unit"`` for a collected test (module docstring)."""
    if item.path.name in E2E_FILES:
        return "e2e"
    function = getattr(item, "function", None)
    try:
        source = inspect.getsource(function) if function is not None else ""
    except (OSError, TypeError):
        source = ""
    return "e2e" if any(sign in source for sign in E2E_SIGNS) else "unit"


def pytest_configure(config: pytest.Config) -> None:
    """Ctrl-C as a terminal delivers it: a suite started in the background by a shell
    without job control (``cmd &`` in a script, ``nohup``) inherits SIGINT ignored, and the
    tests of what a Ctrl-C does (here, and in the processes they start, which inherit an
    ignored signal) would fail for want of one. Python's own handler is installed where the
    signal was ignored."""
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark every collected test ``unit`` or ``e2e`` (module docstring)."""
    for item in items:
        item.add_marker(_tier(item))


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


@pytest.fixture(autouse=True)
def _scheduling_left_as_found():
    """Every test leaves the process's scheduling policy as it found it: a thread left at
    SCHED_FIFO (libfranka's Robot() sets 99) would make the later tests real-time. A change
    is put back and reported as a warning naming the policy."""
    import os
    import warnings

    try:
        before = (os.sched_getscheduler(0), os.sched_getparam(0).sched_priority)
    except (AttributeError, OSError):
        yield
        return
    yield
    after = (os.sched_getscheduler(0), os.sched_getparam(0).sched_priority)
    if after != before:
        os.sched_setscheduler(0, before[0], os.sched_param(before[1]))
        warnings.warn(f"the test left the scheduling policy at {after}, was {before}", stacklevel=1)
