"""Draw a circle with any arm's tool, from the library: pink IK, then the hierarchical MPC.

Loads an example-robot-data arm, solves a circle of the tool frame (centre so that it
starts at the tool's position at the given joint vector, orientation held) by pink's
differential IK within the joint position and velocity limits, tracks the resulting joint
trajectory with the paper's controller (observer ``general``), and prints the task-space
position and orientation RMS after 1 s, from Pinocchio's forward kinematics of the run.
Needs the extra ``hmpc_pin[tasks]``.

Example: python examples/tool_circle.py --robot ur5 --radius 0.1 --frequency 0.2
"""

from __future__ import annotations

import argparse

import numpy as np

import hmpc_pin
from hmpc_pin.experiment.build import task_space
from hmpc_pin.tasks.pose import CirclePath, PoseReference, frame_pose, plane_axes

HOMES = {
    "ur5": [0.0, -1.2, 1.4, -1.0, -1.57, 0.0],
    "panda": [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785],
}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--robot", choices=sorted(HOMES), default="ur5")
    parser.add_argument("--radius", type=float, default=0.1, help="[m]")
    parser.add_argument("--frequency", type=float, default=0.2, help="[Hz]")
    parser.add_argument("--plane", default="yz", help="xy, xz or yz")
    parser.add_argument("--duration", type=float, default=6.0, help="[s]")
    args = parser.parse_args(argv)

    locked = {"panda_finger_joint1": 0.02, "panda_finger_joint2": 0.02}
    robot = hmpc_pin.load_robot(
        args.robot, gravity=9.81, locked_joints=locked if args.robot == "panda" else None
    )
    q_init = np.array(HOMES[args.robot])
    frame = robot.tool_frame
    p0, R0 = frame_pose(robot, frame, q_init)
    u, v = plane_axes(args.plane)
    path = CirclePath(p0[0] - args.radius * u, args.radius, args.frequency, u, v, R0[0])
    reference = PoseReference.solve(robot, frame, path, args.duration + 0.2, q_init)
    controller = hmpc_pin.make_controller(
        robot, hmpc_pin.ControllerConfig(observer=hmpc_pin.ObserverConfig(kind="general"))
    )
    q0, _ = reference.sample(0.0)
    result = hmpc_pin.simulate(robot, controller, reference, duration=args.duration, q0=q0)
    task = hmpc_pin.compute_metrics(task_space(reference, robot, result)).task
    print(f"{args.robot}, frame {frame}: circle r = {args.radius} m at {args.frequency} Hz")
    print(f"position RMS after 1 s    {task.position_rms:.3e} m (max {task.position_max:.3e})")
    print(f"orientation RMS after 1 s {task.orientation_rms:.3e} rad "
          f"(max {task.orientation_max:.3e})")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
