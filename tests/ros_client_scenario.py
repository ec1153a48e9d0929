"""The pip-only commands against a running controller, run by tests/test_ros_client.py inside
a private network namespace (``unshare -n``; never outside one: DDS discovery multicasts).

    python tests/ros_client_scenario.py SCENARIO CONFIG OUT DURATION

Starts ``hmpc-pin ros-arm CONFIG``, a fourth participant (a gripper driver's joint states
and chatter: tests/ros_test_arm.py --extra-node), and ``hmpc-pin ros CONFIG --duration D``;
once the controller runs, ``hmpc-pin ros-params``, ``ros-lifecycle get``,
``ros-trajectory --to ...`` and ``ros-lifecycle deactivate``, each a process of its own
(as a user types them). Writes ``OUT/client.json``: every command's exit code and output.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path


def main(scenario: str, config: str, out: str, duration: str) -> None:
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    exe = [sys.executable, "-m", "hmpc_pin"]
    here = Path(__file__).with_name("ros_test_arm.py")
    arm = subprocess.Popen([*exe, "ros-arm", config], stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, text=True)  # fmt: skip
    extra = subprocess.Popen([sys.executable, str(here), "--extra-node"])
    ctrl = subprocess.Popen([*exe, "ros", config, "--duration", duration, "--out", out],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
    report: dict = {"scenario": scenario, "commands": {}}

    def run(name, *args):
        t = time.monotonic()
        p = subprocess.run([*exe, *args], capture_output=True, text=True, timeout=120)
        seconds = time.monotonic() - t
        report["commands"][name] = {"exit": p.returncode, "stdout": p.stdout,
                                    "stderr": p.stderr, "seconds": seconds}  # fmt: skip
        return p

    # the controller runs once its node answers `get` with "active"
    end = time.monotonic() + 120
    while time.monotonic() < end and ctrl.poll() is None:
        p = run("get_before", "ros-lifecycle", "get", "--timeout", "5")
        if p.returncode == 0 and p.stdout.strip() == "active":
            break
        time.sleep(0.5)
    run("params", "ros-params")
    run("param_rate", "ros-params", "ros.rate", "realtime.watchdog")
    run("param_unknown", "ros-params", "ros.nosuch")
    run("get", "ros-lifecycle", "get")
    time.sleep(1.0)
    run("trajectory", "ros-trajectory", config, "--to",
        "0.1,-0.685,0.1,-2.256,0.1,1.671,0.885", "--in", "1")  # fmt: skip
    time.sleep(2.0)  # the trajectory taken over
    run("deactivate", "ros-lifecycle", "deactivate")
    try:
        c_out, c_err = ctrl.communicate(timeout=120)
    finally:
        if ctrl.poll() is None:
            ctrl.kill()
    report["controller"] = {"exit": ctrl.returncode, "stdout": c_out, "stderr": c_err}
    run("get_after", "ros-lifecycle", "get", "--timeout", "3")
    for p in (arm, extra):
        p.send_signal(signal.SIGINT)
    for p in (arm, extra):
        try:
            p.wait(timeout=30)
        except subprocess.TimeoutExpired:
            p.kill()
    (Path(out) / "client.json").write_text(json.dumps(report))
    sys.stdout.flush()
    os._exit(0)


if __name__ == "__main__":
    main(*sys.argv[1:5])
