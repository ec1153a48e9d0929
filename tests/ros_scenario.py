"""One ROS 2 scenario with real processes, run by tests/test_ros.py inside a private
network namespace (``unshare -n``; never outside one: DDS discovery multicasts).

Starts ``hmpc-pin ros-arm CONFIG`` and ``hmpc-pin ros CONFIG --duration D --out OUT``,
watches the topics with its own rclpy node, acts on the run (a trajectory message, the
arm stopped, Ctrl-C), and writes ``OUT/scenario.json``: exit codes, the controller's
stderr, every effort command and disturbance estimate received.

    python tests/ros_scenario.py SCENARIO CONFIG OUT DURATION
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

SCENARIOS = ("track", "trajectory", "watchdog", "interrupt", "interface")
#: The history depth of this node's subscriptions: more than a run's messages (500 Hz ×
#: 12 s), so that none is dropped while a loaded machine keeps this node from taking them.
DEPTH = 10000


def trajectory_message(names, target, seconds: float = 1.0):
    """A one-point ``trajectory_msgs/JointTrajectory``: ``target`` [rad] reached ``seconds``
    after the message's start (shared with the tests' arm node, ``ros_test_arm.py``)."""
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

    msg = JointTrajectory()
    msg.joint_names = list(names)
    point = JointTrajectoryPoint()
    point.positions = [float(x) for x in target]
    point.time_from_start.sec = int(seconds)
    point.time_from_start.nanosec = round((seconds % 1) * 1e9)
    msg.points = [point]
    return msg


def probe_interface(config: str, out: Path) -> None:
    """The ``interface`` scenario: the arm node only, and this process as the controller
    side through :class:`~hmpc_pin.ros.interface.RosArmInterface`."""
    import numpy as np

    from hmpc_pin.experiment.build import Experiment
    from hmpc_pin.experiment.config import load_config
    from hmpc_pin.realtime.interface import PacedInterface
    from hmpc_pin.ros.interface import RosArmInterface
    from hmpc_pin.ros.node import RosNode

    exe = [sys.executable, "-m", "hmpc_pin"]
    arm = subprocess.Popen([*exe, "ros-arm", config], stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, text=True)  # fmt: skip
    experiment = Experiment.from_config(load_config(config))
    robot, P = experiment.robot, experiment.config.ros.period
    ros = RosNode("probe", "", "LOCALHOST", "the probe")
    iface = RosArmInterface(ros, robot.joint_names, P, "/joint_states",
                            "/effort_controller/commands", start_timeout=120.0)  # fmt: skip
    report: dict = {"paced": isinstance(iface, PacedInterface), "period": P}
    iface.start()
    stamp0, q, dq = iface.read()
    report["first"] = [stamp0, q.tolist(), dq.tolist(), iface.clock() - stamp0]
    steps = []
    for _ in range(100):
        count = iface.wait(1.0)
        stamp, q, _ = iface.read()
        steps.append([count, stamp, q.tolist()])
    report["steps"] = steps
    q0 = np.array(report["first"][1])
    iface.write(robot.gravity_torque(q0))  # held by the arm until the next write
    end = time.monotonic() + 0.2
    while time.monotonic() < end:
        iface.wait(0.1)
    stamp, q, dq = iface.read()
    report["held"] = [q.tolist(), dq.tolist()]
    iface.write(np.zeros(robot.nq))
    end = time.monotonic() + 0.05
    while time.monotonic() < end:
        iface.wait(0.1)
    report["fell"] = iface.read()[1].tolist()
    report["timeout"] = [iface.wait(0.0)]
    iface.close()
    iface.close()
    report["closed_twice"] = True
    arm.send_signal(signal.SIGINT)
    _a_out, a_err = arm.communicate(timeout=30)
    report["arm"] = {"exit": arm.returncode, "stderr": a_err}
    (out / "scenario.json").write_text(json.dumps(report))
    sys.stdout.flush()
    os._exit(0)


def main(scenario: str, config: str, out: str, duration: float, extra=()) -> None:
    from ros_test_arm import _quiet  # run as a script: tests/ is on sys.path

    if scenario == "interface":
        probe_interface(config, Path(out))
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Bool, Float64MultiArray
    from trajectory_msgs.msg import JointTrajectory

    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    outdir = Path(out)
    exe = [sys.executable, "-m", "hmpc_pin"]
    arm = subprocess.Popen([*exe, "ros-arm", config], stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, text=True)  # fmt: skip
    ctrl = subprocess.Popen([*exe, "ros", config, "--duration", str(duration), "--out", out,
                             *extra],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("scenario")
    lock = threading.Lock()
    commands: list[tuple[float, list[float]]] = []
    torques: list[list[float]] = []

    def on_command(msg):
        with lock:
            commands.append((time.monotonic(), list(msg.data)))

    # (a reader history holding every message of a run: with 100, a loaded machine that
    # kept this node's Python thread from taking them for 0.2 s lost the oldest, once the
    # very safe torque the Ctrl-C test looks for: 356 of some 900 commands arrived)
    node.create_subscription(Float64MultiArray, "/effort_controller/commands", on_command,
                             DEPTH)  # fmt: skip
    names_seen: list[list[str]] = []

    def on_torque(m):  # sensor_msgs/JointState: names, stamp, d̂ in effort
        torques.append(list(m.effort))
        names_seen.append([*m.name, m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec])

    node.create_subscription(JointState, "/hmpc_pin_controller/external_torque", on_torque,
                             DEPTH)  # fmt: skip
    flags: list[bool] = []
    node.create_subscription(Bool, "/hmpc_pin_controller/collision",
                             lambda m: flags.append(bool(m.data)), DEPTH)  # fmt: skip
    pub = node.create_publisher(JointTrajectory, "/hmpc_pin_controller/joint_trajectory", 10)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    events: dict = {}

    def running_for(seconds: float, timeout: float = 120.0) -> bool:
        """Wait until commands have flowed for ``seconds`` (False if the controller quit)."""
        end = time.monotonic() + timeout
        while time.monotonic() < end and ctrl.poll() is None:
            with lock:
                # (every topic discovered: DDS matches endpoints one by one)
                heard = commands and torques and (flags or scenario != "watchdog")
                if heard and time.monotonic() - commands[0][0] >= seconds:
                    return True
            time.sleep(0.01)
        return False

    if scenario == "trajectory" and running_for(1.0):
        from hmpc_pin.experiment.build import Experiment
        from hmpc_pin.experiment.config import load_config

        experiment = Experiment.from_config(load_config(config))
        names = list(experiment.robot.joint_names)
        # every joint 0.1 rad above the sine's centre, sent in reversed joint order
        # (matched by name)
        target = [float(p) + 0.1 for p in experiment.reference.sample(0.0)[0]]
        events["target"] = dict(zip(names, target, strict=True))
        # (once the controller's subscription is matched: a message sent before is lost,
        # and on a loaded machine discovery of this one topic can come seconds later)
        end = time.monotonic() + 60.0
        while pub.get_subscription_count() == 0 and time.monotonic() < end:
            time.sleep(0.01)
        pub.publish(trajectory_message(names[::-1], target[::-1], 1.0))
        events["accepted_sent"] = time.monotonic()
        time.sleep(0.5)
        bad = list(target)
        bad[names.index("panda_joint4")] = 1.0  # above the Panda's joint 4 range (< 0)
        pub.publish(trajectory_message(names, bad, 1.0))
        events["refused_sent"] = time.monotonic()
    elif scenario == "watchdog" and running_for(1.0):
        arm.send_signal(signal.SIGSTOP)
        events["arm_stopped"] = time.monotonic()
        ctrl.wait(timeout=60)
        arm.send_signal(signal.SIGCONT)
    elif scenario == "interrupt" and running_for(1.5):
        ctrl.send_signal(signal.SIGINT)
        events["sigint"] = time.monotonic()
    try:
        c_out, c_err = ctrl.communicate(timeout=120)
    finally:
        if ctrl.poll() is None:
            ctrl.kill()
    _quiet(commands, lock)  # the last commands in flight, on a loaded machine too
    arm.send_signal(signal.SIGINT)
    try:
        a_out, a_err = arm.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        arm.kill()
        a_out, a_err = arm.communicate()
    with lock:
        report = {
            "scenario": scenario,
            "controller": {"exit": ctrl.returncode, "stdout": c_out, "stderr": c_err},
            "arm": {"exit": arm.returncode, "stdout": a_out, "stderr": a_err},
            "commands": commands,
            "external_torque": torques,
            "external_torque_header": names_seen,
            "collision": flags,
            "events": events,
        }
    (outdir / "scenario.json").write_text(json.dumps(report))
    # (no rclpy teardown: the spinning thread would race it; the namespace ends with us)
    sys.stdout.flush()
    os._exit(0)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4]), sys.argv[5:])
