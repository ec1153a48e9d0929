"""The ros2_control files shipped with the ROS guide (docs/guide/ros2_control/): they cannot
run here (no ros2_control), so what is checked is what would break them silently: the
YAML parses, names the two controllers ros2_control needs, and lists the effort
controller's joints in the order the controller node publishes its torques (the Panda's
joint order, read from the model); the launch file's ros2_control block declares the
same joints in the same order.
"""

from __future__ import annotations

import ast
from pathlib import Path

import yaml

from hmpc_pin.experiment.build import load_robot_config
from hmpc_pin.experiment.config import load_config

DIR = Path(__file__).resolve().parents[1] / "docs" / "guide" / "ros2_control"


def _panda_joints() -> list[str]:
    return list(load_robot_config(load_config("panda_sine").robot).joint_names)


def test_the_yaml_parses_and_its_effort_joints_are_the_nodes_order():
    doc = yaml.safe_load((DIR / "panda_effort_controllers.yaml").read_text())
    manager = doc["controller_manager"]["ros__parameters"]
    assert manager["joint_state_broadcaster"]["type"] == (
        "joint_state_broadcaster/JointStateBroadcaster"
    )
    assert manager["effort_controller"]["type"] == "effort_controllers/JointGroupEffortController"
    assert manager["update_rate"] == 1000
    assert doc["effort_controller"]["ros__parameters"]["joints"] == _panda_joints()


def test_the_launch_file_declares_the_same_joints_and_parses():
    tree = ast.parse((DIR / "panda_hardware.launch.py").read_text())
    joints = None
    for node in ast.walk(tree):
        if isinstance(node, ast.Assign) and getattr(node.targets[0], "id", "") == "JOINTS":
            # the expression as written (the file imports `launch`, absent here)
            code = compile(ast.Expression(node.value), "JOINTS", "eval")
            joints = eval(code, {"range": range})  # (the repository's own file)
    assert joints == _panda_joints()
    source = (DIR / "panda_hardware.launch.py").read_text()
    assert "mock_components/GenericSystem" in source
    assert "panda_effort_controllers.yaml" in source
