"""The ROS arm interface (joint states in, efforts out) with a real rclpy node: its cases
(tests/ros_interface_cases.py) run by pytest inside a private network namespace, since
rclpy may start DDS only there."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from .test_ros import _netns_reason

ROOT = Path(__file__).resolve().parents[1]
CASES = Path(__file__).with_name("ros_interface_cases.py")


def test_the_interfaces_cases_pass_inside_a_private_network_namespace():
    reason = _netns_reason()
    if reason:
        pytest.skip(reason)
    env = dict(os.environ, HMPC_PIN_IN_NETNS="1", ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    pytest_cmd = f"{sys.executable} -m pytest -q -p no:cacheprovider -p no:randomly {CASES}"
    proc = subprocess.run(
        ["unshare", "-n", "bash", "-c", f"ip link set lo up && exec {pytest_cmd}"],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=ROOT,
        env=env,
    )
    assert proc.returncode == 0, proc.stdout[-6000:] + proc.stderr[-2000:]
    assert " passed" in proc.stdout and "skipped" not in proc.stdout, proc.stdout
