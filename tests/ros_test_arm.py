"""An arm node the tests write themselves (plain rclpy, Pinocchio's ABA), run against
``hmpc-pin ros`` by tests/test_ros_boundary.py inside a private network namespace
(``unshare -n``; never outside one: DDS discovery multicasts).

The arm publishes ``sensor_msgs/JointState`` on ``/joint_states`` every period (stamped
with the period's instant on the system clock), applies the newest
``std_msgs/Float64MultiArray`` on ``/effort_controller/commands`` from the next period
on, and holds it (as ros2_control's effort controller: no timeout). Its physics is the
controller's URDF integrated by Pinocchio's ABA (semi-implicit Euler, 1 ms substeps, joint
friction); before the first command it holds still (brakes). Each scenario perturbs what
the controller sees (module ``SCENARIOS``). When the controller has exited, the arm
integrates 2 s of holding the last command it received, in simulated time, from its state
when that command was applied: the drift is what the motors would do with the last thing
sent. The physics has joint friction (``COULOMB``, ``VISCOUS``): a real arm's.

    python tests/ros_test_arm.py SCENARIO CONFIG OUT DURATION

Writes ``OUT/arm.json``: the controller's exit code and stderr, every command's arrival
time and values (non-finite ones counted), the states published, and the drift.
"""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

SCENARIOS = ("traffic", "nan", "silent", "stall", "delay", "trajectory", "interrupt",
             "deactivate", "remap", "gravity_arm", "inactive", "sim_time",
             "shutdown_inactive")  # fmt: skip
#: "sim_time": a simulator's arm (Gazebo-like) at a real-time factor of 0.5: states stamped
#: on its simulated clock (from SIM0, one period per period), /clock published, the
#: controller run with use_sim_time.
SIM0, SIM_WALL = 100.0, 2.0  # [s] the simulated clock's start; wall seconds per simulated one
#: "remap": the arm's topics under /arm, the controller told so by --ros-args remaps.
REMAP = ["-r", "joint_states:=/arm/joint_states", "-r", "effort_controller/commands:=/arm/effort",
         "-p", "use_sim_time:=false"]  # fmt: skip
GRIPPER = ["panda_finger_joint1", "panda_finger_joint2"]
#: [s] The transport delay of "delay": each state is sent this long after its stamp — 1.5
#: interface periods at the tests' 500 Hz (the 1.5 ms of a 1 kHz arm): were the deadline the
#: stamp, every cycle would miss.
DELAY = 3e-3
#: "stall": (run time [s], length [s]) of each stall of the arm's stream (its states then
#: come in a burst): four below the tests' 0.5 s watchdog (the longest 150 ms: 350 ms left
#: for a loaded machine's scheduler, which held processes up to 200 ms at a load of 12;
#: 15 and 30 ms are bursts the subscription's queue of 10 takes), one of 1 s above it.
STALLS = [(0.8, 0.005), (1.2, 0.015), (1.6, 0.030), (2.0, 0.150), (2.45, 1.0)]


#: The arm's joint friction: Coulomb [N·m] (with stiction: a joint at rest stays until the
#: other torques exceed it) and viscous [N·m·s/rad]. The Panda's identified Coulomb
#: friction is 0.3–1.3 N·m per joint (Gaz et al., RA-L 2019); 0.3 is below all of them.
#: Without friction no constant command holds a Panda still: balanced by G(q) above its
#: joints, the posture is an unstable equilibrium (1 mrad/s grows to radians in 2 s).
COULOMB, VISCOUS = 0.3, 0.1


class Arm:
    """The physics and the command held (module doc)."""

    def __init__(self, model, q0, period: float):
        import pinocchio as pin

        self.pin, self.model, self.data = pin, model, model.createData()
        self.q, self.dq = np.array(q0, dtype=float), np.zeros(model.nv)
        self.period = period
        self.sub = max(1, round(period / 1e-3))
        self.tau: np.ndarray | None = None  # None: on its brakes
        self.applied: tuple | None = None  # (q, dq, tau) when the last command was applied
        self.adds_gravity = False

    def _advance(self, q, dq, tau, h):
        """One semi-implicit Euler step of h [s] with friction: ABA with the viscous term,
        then the Coulomb impulse h·fc/M_ii against each joint's motion, never reversing it
        (a joint it brings to rest sticks)."""
        pin = self.pin
        if self.adds_gravity:  # the arm's own gravity compensation, at the current q
            tau = tau + pin.computeGeneralizedGravity(self.model, self.data, q)
        ddq = pin.aba(self.model, self.data, q, dq, tau - VISCOUS * dq)
        dq = dq + h * ddq
        M = pin.crba(self.model, self.data, q)
        slow = h * COULOMB / np.diag(M)
        dq = np.sign(dq) * np.maximum(0.0, np.abs(dq) - slow)
        return q + h * dq, dq

    def apply(self, tau) -> None:
        """Hold ``tau`` from now on (and remember the state it started from)."""
        self.tau = tau
        self.applied = (self.q.copy(), self.dq.copy(), tau.copy())

    def step(self) -> None:
        """One period with the held command."""
        if self.tau is None:
            return
        h = self.period / self.sub
        for _ in range(self.sub):
            self.q, self.dq = self._advance(self.q, self.dq, self.tau, h)

    def drift(self, seconds: float = 2.0) -> float:
        """Largest |q(t) − q(0)| [rad] over ``seconds`` of holding the last command from
        the state it was applied at (simulated time, the same physics)."""
        if self.applied is None:
            return 0.0
        q, dq, tau = (x.copy() for x in self.applied)
        q0 = q.copy()
        worst = 0.0
        for _ in range(round(seconds / 1e-3)):
            q, dq = self._advance(q, dq, tau, 1e-3)
            worst = max(worst, float(np.abs(q - q0).max()))
        return worst


def main(scenario: str, config_path: str, out: str, duration: float) -> None:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions
    from ros_scenario import trajectory_message  # run as a script: tests/ is on sys.path
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64MultiArray
    from trajectory_msgs.msg import JointTrajectory

    from hmpc_pin.experiment.build import Experiment
    from hmpc_pin.experiment.config import load_config

    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    config = load_config(config_path)
    experiment = Experiment.from_config(config)
    robot = experiment.robot
    names = list(robot.joint_names)
    P = config.ros.period
    arm = Arm(robot.model, experiment.q0, P)
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("test_arm")
    prefix = "/arm" if scenario == "remap" else ""
    pub = node.create_publisher(JointState, prefix + "/joint_states", 10)
    lock = threading.Lock()
    commands: list[tuple[float, list[float]]] = []
    report: dict = {"scenario": scenario, "nonfinite_commands": 0, "events": {}}

    def on_command(msg):
        tau = np.asarray(msg.data, dtype=float)
        with lock:
            commands.append((time.time(), tau.tolist()))
            if not np.isfinite(tau).all():
                report["nonfinite_commands"] += 1
                return  # (an effort controller would apply it; counted, never expected)
            arm.pending = tau

    arm.pending = None
    node.create_subscription(Float64MultiArray,
                             "/arm/effort" if prefix else "/effort_controller/commands",
                             on_command, 10)  # fmt: skip
    traj_pub = node.create_publisher(JointTrajectory, "/hmpc_pin_controller/joint_trajectory",
                                     10)  # fmt: skip
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    threading.Thread(target=executor.spin, daemon=True).start()

    def state_msg(stamp: float, which=None, order=None, nan=False):
        msg = JointState()
        idx = list(range(len(names))) if which is None else list(which)
        if order == "reversed":
            idx = idx[::-1]
        msg.name = [names[i] for i in idx]
        ns = round(stamp * 1e9)
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 1_000_000_000)
        q = arm.q.copy()
        if nan:
            q[2] = math.nan
        msg.position = [float(q[i]) for i in idx]
        msg.velocity = [float(arm.dq[i]) for i in idx]
        msg.effort = [0.0] * len(idx)
        return msg

    delayed: list = []  # (due [s], message): "delay" publishes each state DELAY late
    delay_cv = threading.Condition()

    def delayed_publisher():
        while True:
            with delay_cv:
                while not delayed:
                    delay_cv.wait()
                due, msg = delayed[0]
            wait = due - time.time()
            if wait > 0:
                time.sleep(wait)
            with delay_cv:
                delayed.pop(0)
            pub.publish(msg)

    if scenario == "delay":
        threading.Thread(target=delayed_publisher, daemon=True).start()

    def gripper_msg(stamp: float):
        msg = JointState()
        msg.name = list(GRIPPER)
        ns = round(stamp * 1e9)
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 1_000_000_000)
        msg.position, msg.velocity, msg.effort = [0.02, 0.02], [0.0, 0.0], [0.0, 0.0]
        return msg

    extra = None
    if scenario == "traffic":  # one more node in the graph: gripper states and chatter
        from std_msgs.msg import String

        heard = threading.Event()
        node.create_subscription(String, "/chatter", lambda _msg: heard.set(), 10)
        extra = subprocess.Popen([sys.executable, __file__, "--extra-node"])
        # the controller starts once the node is up: its start-up (imports, discovery) is
        # a burst of CPU that, on two loaded cores, could hold the arm's loop past the
        # watchdog; what is tested is the traffic, not that burst
        if not heard.wait(60.0):
            raise RuntimeError("the extra node published nothing within 60 s")
    exe = [sys.executable, "-m", "hmpc_pin"]
    ctrl_cmd = [*exe, "ros", config_path, "--duration", str(duration), "--out", out]
    if scenario == "remap":
        ctrl_cmd += ["--ros-args", *REMAP]
    wall = SIM_WALL if scenario == "sim_time" else 1.0
    if scenario == "sim_time":
        from rosgraph_msgs.msg import Clock

        ctrl_cmd += ["--ros-args", "-p", "use_sim_time:=true"]
        clock_pub = node.create_publisher(Clock, "/clock", 10)
        clock_msg = Clock()
    arm.adds_gravity = scenario == "gravity_arm"  # as Franka's FCI: the arm adds G(q)
    t0 = time.time()
    published = 0
    # (the tests' watchdog is 0.5 s: the first four stalls far below it, whatever a loaded
    # machine adds to them, the last twice it, at the sine's turning point: the arm nearly
    # at rest)
    stalls = {"stall": STALLS}.get(scenario, [])
    report["stalls"] = stalls
    if scenario == "traffic":  # gripper-only states before the controller starts
        for _ in range(20):
            pub.publish(gripper_msg(time.time()))
            time.sleep(0.005)
    ctrl = subprocess.Popen(ctrl_cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    k = 0
    first_cmd_at = None
    backlog: list = []
    stall_end = -1.0
    acted = set()
    deactivating = None  # the orchestrator's deactivate call (scenario "deactivate")
    clients = _orchestrator_clients(node) if scenario == "deactivate" else None
    t0 = time.time()
    while ctrl.poll() is None:
        k += 1
        deadline = t0 + k * P * wall
        now = time.time()
        if deadline > now:
            time.sleep(deadline - now)
        with lock:
            if arm.pending is not None:
                arm.apply(arm.pending)
                arm.pending = None
                if first_cmd_at is None:
                    first_cmd_at = deadline
        arm.step()
        stamp = t0 + k * P * wall
        run_t = None if first_cmd_at is None else stamp - first_cmd_at
        if scenario == "silent":  # one state once the controller listens, then silence
            if published >= 1 or pub.get_subscription_count() == 0:
                continue
            if "matched" not in acted:
                acted.add("matched")
                time.sleep(0.5)  # discovery completes both ways
                continue
        if run_t is not None:
            for at, length in stalls:
                if (at, length) not in acted and run_t >= at:
                    acted.add((at, length))
                    stall_end = stamp + length
                    report["events"].setdefault("stall_started", []).append(run_t)
                    report["events"].setdefault("stall_stamps", []).append([stamp, length])
        if stamp < stall_end:
            backlog.append(state_msg(stamp))
            continue  # stalled: the states of these periods come in a burst after it
        for msg in backlog:  # the burst: every missed period's state (a driver's queue)
            pub.publish(msg)
        published += len(backlog)
        backlog.clear()
        if scenario == "nan" and run_t is not None and 1.0 <= run_t < 1.05:
            # NaN states for 50 ms, then finite ones: one of them is the newest the
            # controller takes even if it takes several states at once
            report["events"].setdefault("nan_at", run_t)
            pub.publish(state_msg(stamp, nan=True))
        elif scenario == "traffic":  # the arm's joints in two messages, any order
            pub.publish(state_msg(stamp, which=range(4), order="reversed"))
            pub.publish(state_msg(stamp, which=range(4, len(names))))
            if k % 5 == 0:
                pub.publish(gripper_msg(stamp))
        elif scenario == "delay":
            with delay_cv:
                delayed.append((stamp + DELAY, state_msg(stamp)))
                delay_cv.notify()
        elif scenario == "sim_time":  # the simulator's clock first, then the state
            ns = round((SIM0 + k * P) * 1e9)
            clock_msg.clock.sec, clock_msg.clock.nanosec = divmod(ns, 1_000_000_000)
            clock_pub.publish(clock_msg)
            pub.publish(state_msg(SIM0 + k * P))
        else:
            pub.publish(state_msg(stamp))
        published += 1
        if scenario in ("inactive", "shutdown_inactive") and "activate" not in acted:
            acted.add("activate")  # an orchestrator: configure, wait, then activate (or shut down)
            threading.Thread(target=_activate, args=(node, report, commands, lock,
                             scenario == "shutdown_inactive"), daemon=True).start()  # fmt: skip
        if run_t is None:
            continue
        matched = scenario == "trajectory" and traj_pub.get_subscription_count() > 0
        if matched and "good" not in acted and run_t >= 1.0:  # (once discovered: not lost)
            acted.add("good")
            target = [float(x) + 0.1 for x in experiment.reference.sample(0.0)[0]]
            report["events"]["target"] = target
            report["events"]["good_at"] = run_t
            traj_pub.publish(trajectory_message(names, target))
        good_at = report["events"].get("good_at")
        if matched and "bad" not in acted and good_at is not None and run_t >= good_at + 0.5:
            acted.add("bad")
            bad = [float(x) + 0.1 for x in experiment.reference.sample(0.0)[0]]
            bad[3] = 1.0  # above the Panda's joint 4 range (< 0)
            traj_pub.publish(trajectory_message(names, bad))
        if matched and "future" not in acted and good_at is not None and run_t >= good_at + 1.6:
            # one stamped 1 s ahead (pending), then one stamped now: the second supersedes
            # the first, which never runs (its target is elsewhere)
            acted.add("future")
            elsewhere = [float(x) + 0.2 for x in experiment.reference.sample(0.0)[0]]
            msg = trajectory_message(names, elsewhere)
            ns = round((time.time() + 1.0) * 1e9)
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 1_000_000_000)
            traj_pub.publish(msg)
            report["events"]["elsewhere"] = elsewhere
        if matched and "now" not in acted and "future" in acted and run_t >= good_at + 1.8:
            acted.add("now")
            traj_pub.publish(trajectory_message(names, report["events"]["target"]))
        if (scenario in ("interrupt", "gravity_arm") and "sigint" not in acted
                and run_t >= 1.5):  # fmt: skip
            acted.add("sigint")
            ctrl.send_signal(signal.SIGINT)
        if scenario == "deactivate" and "deactivate" not in acted and run_t >= 1.5:
            acted.add("deactivate")
            deactivating = threading.Thread(target=_deactivate, args=(node, report, clients),
                                            daemon=True)  # fmt: skip
            deactivating.start()
    c_out, c_err = ctrl.communicate()
    report["controller"] = {"exit": ctrl.returncode, "stdout": c_out, "stderr": c_err}
    if deactivating is not None:  # its answer may be on its way still (a loaded machine)
        deactivating.join(timeout=10.0)
    _quiet(commands, lock)  # the commands in flight, on a loaded machine too
    with lock:
        if arm.pending is not None:
            arm.apply(arm.pending)
        report["commands"] = commands
        report["published"] = published
        report["q_end"], report["dq_end"] = arm.q.tolist(), arm.dq.tolist()
        report["held"] = None if arm.tau is None else arm.tau.tolist()
        report["drift"] = arm.drift(2.0)
    if extra is not None:
        extra.send_signal(signal.SIGINT)
        extra.wait(timeout=10)
    (Path(out) / "arm.json").write_text(json.dumps(report))
    sys.stdout.flush()
    os._exit(0)


def _quiet(commands: list, lock, still: float = 0.5, at_most: float = 10.0) -> None:
    """Wait until no command has arrived for ``still`` [s] (at most ``at_most`` [s]): the
    last ones sent before the controller exited are taken, however long a loaded machine
    keeps this process's spinning thread from running (a fixed 0.1 s once left the arm on
    a brake command instead of the G(q) sent after it)."""
    end = time.monotonic() + at_most
    with lock:
        seen, since = len(commands), time.monotonic()
    while time.monotonic() < end:
        time.sleep(0.05)
        with lock:
            if len(commands) != seen:
                seen, since = len(commands), time.monotonic()
            elif time.monotonic() - since >= still:
                return


def _orchestrator_clients(node):
    """The clients of an orchestrator (a lifecycle manager holds them from its start: a
    client made just before its call can lose the answer while DDS still matches the
    service's response writer to it, the known service-discovery race of ROS 2)."""
    from lifecycle_msgs.srv import ChangeState
    from rcl_interfaces.srv import ListParameters

    return (node.create_client(ListParameters, "/hmpc_pin_controller/list_parameters"),
            node.create_client(ChangeState, "/hmpc_pin_controller/change_state"))  # fmt: skip


def _deactivate(node, report, clients) -> None:
    """``ros2 lifecycle set /hmpc_pin_controller deactivate`` and ``ros2 param list``, as
    rclpy service calls."""
    from lifecycle_msgs.msg import Transition
    from lifecycle_msgs.srv import ChangeState
    from rcl_interfaces.srv import ListParameters

    params, client = clients
    if params.wait_for_service(timeout_sec=10.0):
        res = params.call(ListParameters.Request(), timeout_sec=10.0)
        report["events"]["parameters"] = [] if res is None else list(res.result.names)
    if client.wait_for_service(timeout_sec=10.0):
        req = ChangeState.Request()
        req.transition.id = Transition.TRANSITION_DEACTIVATE
        report["events"]["deactivate_sent"] = time.time()
        try:  # (rclpy raises TimeoutError where older versions returned None)
            res = client.call(req, timeout_sec=10.0)
        except TimeoutError:
            res = None
        report["events"]["deactivated"] = None if res is None else bool(res.success)
        report["events"]["deactivate_answered"] = time.time()


def _activate(node, report, commands, lock, shutdown: bool = False) -> None:
    """An orchestrator (``ros2 lifecycle set ... configure``, then ``activate``) for a
    controller started with ``[ros] autostart = false``: the commands received before
    the activation are counted (there must be none)."""
    from lifecycle_msgs.msg import Transition
    from lifecycle_msgs.srv import ChangeState, GetState

    state = node.create_client(GetState, "/hmpc_pin_controller/get_state")
    client = node.create_client(ChangeState, "/hmpc_pin_controller/change_state")
    if not (state.wait_for_service(timeout_sec=60.0) and client.wait_for_service(60.0)):
        return
    res = state.call(GetState.Request(), timeout_sec=10.0)
    report["events"]["state_at_start"] = None if res is None else res.current_state.label
    time.sleep(0.5)  # states stream meanwhile; an inactive controller answers none
    for name in ("unconfigured_shutdown",) if shutdown else ("configure", "activate"):
        req = ChangeState.Request()
        req.transition.id = getattr(Transition, f"TRANSITION_{name.upper()}")
        if name in ("activate", "unconfigured_shutdown"):
            time.sleep(0.3)
            with lock:
                report["events"]["commands_before_activate"] = len(commands)
        res = client.call(req, timeout_sec=10.0)
        report["events"][name] = None if res is None else bool(res.success)


def extra_node() -> None:
    """One more node in the graph: a gripper's joint states and chatter at 100 Hz until
    SIGINT."""
    import rclpy
    from rclpy.signals import SignalHandlerOptions
    from sensor_msgs.msg import JointState
    from std_msgs.msg import String

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("gripper_driver")
    js = node.create_publisher(JointState, "/joint_states", 10)
    chat = node.create_publisher(String, "/chatter", 10)
    stop = []
    signal.signal(signal.SIGINT, lambda *_: stop.append(1))
    k = 0
    while not stop:
        k += 1
        if k % 2 == 0:
            msg = JointState()
            msg.name = list(GRIPPER)
            msg.position, msg.velocity = [0.03, 0.03], [0.0, 0.0]
            js.publish(msg)
        s = String()
        s.data = "x" * 200
        chat.publish(s)
        time.sleep(0.01)
    os._exit(0)


if __name__ == "__main__":
    if sys.argv[1] == "--extra-node":
        extra_node()
    main(sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4]))
