"""Is a lifecycle ``deactivate`` answered on a loaded machine with a fourth participant on
the graph? Run inside a private network namespace (DDS discovery multicasts):

    unshare -n bash -c 'ip link set lo up; python benchmarks/studies/ros_deactivate_under_load.py \
        [--config panda_sine] [--tries 2] [--wait 12]'

Each try starts ``hmpc-pin ros-arm CONFIG``, a gripper driver publishing joint states and
chatter at 100 Hz (tests/ros_test_arm.py --extra-node, the fourth participant) and
``hmpc-pin ros CONFIG --duration 30``; ``--wait`` seconds later (the processes' start-up
included) a fresh rclpy client asks for ``deactivate`` and waits up to 20 s for the
answer. Prints, per try, whether it was answered, after how long, and how the
controller's run ended.
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def one_try(config: str, wait: float, options: tuple[str, ...] = ()) -> str:
    import rclpy
    from lifecycle_msgs.msg import Transition
    from lifecycle_msgs.srv import ChangeState
    from rclpy.signals import SignalHandlerOptions

    exe = [sys.executable, "-m", "hmpc_pin"]
    quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
    arm = subprocess.Popen([*exe, "ros-arm", config], **quiet)
    extra = subprocess.Popen([sys.executable, str(ROOT / "tests" / "ros_test_arm.py"),
                              "--extra-node"], **quiet)  # fmt: skip
    out = Path("out") / "deactivate_under_load"
    ctrl = subprocess.Popen([*exe, "ros", config, "--duration", "30", "--out", str(out), "--force",
                             *options],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
    time.sleep(wait)
    context = rclpy.context.Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("deactivate_probe", context=context)
    client = node.create_client(ChangeState, "/hmpc_pin_controller/change_state")
    found = client.wait_for_service(timeout_sec=20.0)
    req = ChangeState.Request()
    req.transition.id = Transition.TRANSITION_DEACTIVATE
    t = time.monotonic()
    future = client.call_async(req)
    from rclpy.executors import SingleThreadedExecutor

    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    executor.spin_until_future_complete(future, timeout_sec=20.0)
    answered = future.done() and future.result() is not None
    seconds = time.monotonic() - t
    _, err = ctrl.communicate(timeout=120)
    for p in (arm, extra):
        p.send_signal(signal.SIGINT)
        p.wait(timeout=30)
    executor.shutdown()
    node.destroy_node()
    context.try_shutdown()
    ends = [x for x in err.splitlines() if x.startswith(("error:", "deactivated", "interrupted"))]
    return (f"service found {found}, answered {answered} after {seconds:.2f} s; controller "
            f"exit {ctrl.returncode}: {ends[-1] if ends else '(no stop line)'}")  # fmt: skip


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="panda_sine")
    parser.add_argument("--tries", type=int, default=2)
    parser.add_argument("--wait", type=float, default=12.0)
    parser.add_argument(
        "--relax",
        action="store_true",
        help="run the controller with --max-misses 1000000 --watchdog 1 (a run that a loaded "
        "machine does not stop before the request)",
    )
    args = parser.parse_args(argv)
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    for k in range(args.tries):
        options = ("--max-misses", "1000000", "--watchdog", "1") if args.relax else ()
        print(f"try {k + 1}: {one_try(args.config, args.wait, options)}", flush=True)
    print(f"1-min load average {os.getloadavg()[0]:.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
