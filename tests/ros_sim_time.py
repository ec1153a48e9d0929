"""The package's own simulator on simulated time, run by tests/test_ros_sim_time.py inside a
private network namespace (``unshare -n``; never outside one: DDS discovery multicasts).

    python tests/ros_sim_time.py SCENARIO CONFIG OUT FACTOR

``track``: ``hmpc-pin ros-arm CONFIG --real-time-factor FACTOR`` and ``hmpc-pin ros CONFIG
--duration 2 --ros-args -p use_sim_time:=true``; this node records ``/clock`` and the
states' stamps. ``stops``: ``ros-arm`` alone, fed a zero effort command by this node (the
arm falls under gravity onto its joint stops) until 3 simulated seconds of states have
been received, then stopped by SIGINT; every state recorded. Writes ``OUT/sim.json``.
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


def main(scenario: str, config: str, out: str, factor: str) -> None:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rclpy.signals import SignalHandlerOptions
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64MultiArray

    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    exe = [sys.executable, "-m", "hmpc_pin"]
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("sim_probe")
    lock = threading.Lock()
    clocks: list[float] = []
    states: list[list] = []
    qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)

    def on_clock(msg):
        with lock:
            clocks.append(msg.clock.sec + 1e-9 * msg.clock.nanosec)

    def on_state(msg):
        st = msg.header.stamp
        with lock:
            states.append([st.sec + 1e-9 * st.nanosec, list(msg.position), list(msg.velocity)])

    node.create_subscription(Clock, "/clock", on_clock, qos)
    node.create_subscription(JointState, "/joint_states", on_state, qos)
    pub = node.create_publisher(Float64MultiArray, "/effort_controller/commands", 10)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    threading.Thread(target=executor.spin, daemon=True).start()
    report: dict = {"scenario": scenario, "factor": float(factor)}
    if scenario == "stops":
        arm = subprocess.Popen([*exe, "ros-arm", config, "--real-time-factor", factor],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True)  # fmt: skip
        zero = Float64MultiArray()
        zero.data = [0.0] * 7
        end = time.monotonic() + 180.0
        # a zero torque held, until 3 simulated seconds of states have been received (the
        # discovery on a loaded machine may take seconds: the arm runs until then)
        while arm.poll() is None and time.monotonic() < end:
            pub.publish(zero)
            with lock:
                span = states[-1][0] - states[0][0] if states else 0.0
            if span >= 3.0:
                break
            time.sleep(0.01)
        arm.send_signal(signal.SIGINT)
        a_out, a_err = arm.communicate(timeout=60)
        report["arm"] = {"exit": arm.returncode, "stdout": a_out, "stderr": a_err}
    else:
        arm = subprocess.Popen([*exe, "ros-arm", config, "--real-time-factor", factor],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True)  # fmt: skip
        ctrl = subprocess.run([*exe, "ros", config, "--duration", "2", "--out", out,
                               "--ros-args", "-p", "use_sim_time:=true"],
                              capture_output=True, text=True, timeout=300)  # fmt: skip
        report["controller"] = {"exit": ctrl.returncode, "stdout": ctrl.stdout,
                                "stderr": ctrl.stderr}  # fmt: skip
        arm.send_signal(signal.SIGINT)
        a_out, a_err = arm.communicate(timeout=60)
        report["arm"] = {"exit": arm.returncode, "stdout": a_out, "stderr": a_err}
    time.sleep(0.2)
    with lock:
        report["clock"] = list(clocks)
        report["states"] = list(states)
    (Path(out) / "sim.json").write_text(json.dumps(report))
    sys.stdout.flush()
    os._exit(0)


if __name__ == "__main__":
    main(*sys.argv[1:5])
