"""The numbers printed in the README and the guides are what the code prints now: every
generated passage (``docs/regenerate.py``) regenerated from runs and compared with the
text, each number within one unit of its last printed digit; timings left out. The
tuning passage (two Optuna studies, minutes) is marked ``slow``; the ROS guide's
(nodes in a private network namespace) is left out where rclpy or the namespace is not
available. The table of every example-robot-data arm shares its runs with the slow test of
``init`` (``benchmarks.studies.any_arm.rows``).

The comparison itself is checked to fail on a number off by more than its printed
precision, on changed text, and on a missing marker."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def _module():
    spec = importlib.util.spec_from_file_location(
        "docs_regenerate", ROOT / "docs" / "regenerate.py"
    )
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


regen = _module()


@pytest.mark.parametrize(
    "block",
    [pytest.param(b, id=b.name, marks=[pytest.mark.slow] if b.slow else []) for b in regen.BLOCKS],
)
def test_printed_numbers_are_what_the_code_prints(block):
    if block.needs_ros and (reason := regen.ros_reason()) is not None:
        pytest.skip(reason)
    text = (ROOT / block.file).read_text(encoding="utf-8")
    i, j = regen.passage(text, block.name)
    printed = text[i:j].strip("\n")
    diff = regen.agrees(printed, block.write().strip("\n"), block.volatile)
    if diff is not None and block.needs_ros:
        # three processes on a loaded machine: a run that a scheduling stall stopped
        # otherwise (a fault, a watchdog) is run once more; a real change differs twice
        diff = regen.agrees(printed, block.write().strip("\n"), block.volatile)
    assert diff is None, (
        f"{block.file} [{block.name}] is stale: {diff}; run `python docs/regenerate.py "
        f"--only {block.name}` and read the prose around it"
    )


def test_every_passage_is_marked_once():
    for block in regen.BLOCKS:
        text = (ROOT / block.file).read_text(encoding="utf-8")
        regen.passage(text, block.name)  # raises unless exactly one start and one end


def test_the_comparison_holds_the_printed_precision():
    agrees = regen.agrees
    assert agrees("a 8.264e-01 b", "a 8.2641e-01 b".replace("8.2641", "8.265")) is None
    assert agrees("a 8.264e-01 b", "a 8.266e-01 b") == "8.264e-01 is now 8.266e-01"
    assert agrees("0.86 → 0.15", "0.87 → 0.15") is None  # one unit of the last digit
    assert agrees("0.86 → 0.15", "0.88 → 0.15") is not None
    assert agrees("(−0.5 %)", "(−0.4 %)") is None
    assert agrees("(−0.5 %)", "(+0.5 %)") is not None  # the sign is read
    assert agrees("12 % bounded", "100 % bounded") is not None
    assert agrees("joint 3 falls", "joint 3 rises") is not None
    timing = (r"in \d+(?:\.\d+)? s;",)
    assert agrees("in 0.09 s; wrote", "in 0.35 s; wrote", timing) is None
    assert agrees("in 0.09 s; wrote", "in 0.35 s; wrote") is not None
    with pytest.raises(ValueError, match="expected one"):
        regen.passage("no markers here", "demo")
