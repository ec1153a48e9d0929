"""ROS 2: the controller and a simulated arm as nodes on the topics ros2_control exposes.

Layers: :mod:`.node` (rclpy brought up without its signal handler, discovery limited,
the executor in a thread) · :mod:`.interface` (the arm's joint states and effort topic
as a :class:`~hmpc_pin.realtime.interface.PacedInterface` for the real-time loop) ·
:mod:`.trajectory` (a ``trajectory_msgs/JointTrajectory`` message as a checked reference)
· :mod:`.arm` (an experiment's plant as the arm's node, on the system clock or simulated
time) · :mod:`.client` (the controller node driven from another process: a new
reference, lifecycle transitions, parameters, with rclpy alone). rclpy and the message
packages come with the extra ``hmpc_pin[ros]`` (or a sourced ROS 2 installation); they
are imported only when a node starts.
"""
