"""The Panda under ros2_control with `hmpc-pin ros` as its torque controller.

    ros2 launch panda_hardware.launch.py urdf:=/path/to/panda.urdf \
        config:=panda_sine [hardware:=mock_components/GenericSystem]

Starts ros2_control_node with the URDF plus a <ros2_control> block (effort command
interfaces; position, velocity and effort states) for the hardware plugin ``hardware``
(default: ros2_control's mock components, a dry run that checks the wiring: topics,
joint order, lifecycle; a mock arm does not move under effort commands), the controllers
of panda_effort_controllers.yaml (joint_state_broadcaster, a JointGroupEffortController
in the node's joint order), then `hmpc-pin ros CONFIG` once the effort controller is
active. For a real Panda use its vendor's hardware plugin and description (franka_ros2)
and check `[ros] gravity` ("arm" for Franka: the robot adds its own G(q)).

Needs a sourced ROS 2 with ros2_control, ros2_controllers and launch_ros installed.
"""

from pathlib import Path

from launch import LaunchDescription
from launch.actions import (
    DeclareLaunchArgument,
    ExecuteProcess,
    OpaqueFunction,
    RegisterEventHandler,
)
from launch.event_handlers import OnProcessExit
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

HERE = Path(__file__).resolve().parent
JOINTS = [f"panda_joint{i}" for i in range(1, 8)]  # the node's joint order


def ros2_control_block(plugin: str) -> str:
    """The <ros2_control> element: effort commands, position/velocity/effort states."""
    joints = "".join(
        f'<joint name="{j}"><command_interface name="effort"/>'
        '<state_interface name="position"/><state_interface name="velocity"/>'
        '<state_interface name="effort"/></joint>'
        for j in JOINTS
    )
    return (
        f'<ros2_control name="panda" type="system"><hardware><plugin>{plugin}'
        f"</plugin></hardware>{joints}</ros2_control>"
    )


def setup(context):
    urdf = Path(LaunchConfiguration("urdf").perform(context)).read_text()
    plugin = LaunchConfiguration("hardware").perform(context)
    config = LaunchConfiguration("config").perform(context)
    description = urdf.replace("</robot>", ros2_control_block(plugin) + "</robot>")
    control = Node(
        package="controller_manager",
        executable="ros2_control_node",
        parameters=[
            {"robot_description": description},
            str(HERE / "panda_effort_controllers.yaml"),
        ],
        output="screen",
    )
    states = Node(
        package="controller_manager", executable="spawner", arguments=["joint_state_broadcaster"]
    )
    effort = Node(
        package="controller_manager", executable="spawner", arguments=["effort_controller"]
    )
    hmpc = ExecuteProcess(cmd=["hmpc-pin", "ros", config, "--out", "out"], output="screen")
    return [
        control,
        states,
        effort,
        # the torque controller starts once the effort controller is active
        RegisterEventHandler(OnProcessExit(target_action=effort, on_exit=[hmpc])),
    ]


def generate_launch_description():
    return LaunchDescription(
        [
            DeclareLaunchArgument("urdf", description="the arm's URDF file"),
            DeclareLaunchArgument(
                "config", default_value="panda_sine", description="the experiment of hmpc-pin ros"
            ),
            DeclareLaunchArgument(
                "hardware",
                default_value="mock_components/GenericSystem",
                description="the ros2_control hardware plugin",
            ),
            OpaqueFunction(function=setup),
        ]
    )
