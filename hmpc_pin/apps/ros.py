"""``hmpc-pin ros`` and ``hmpc-pin ros-arm``: the controller and the arm as ROS 2 nodes on
the topics ros2_control exposes (:mod:`hmpc_pin.ros`).

``ros`` runs the experiment's controller in the real-time loop of
:mod:`hmpc_pin.realtime` (same safe stops, latency statistics and saved run), paced by
the joint states, and writes ``<stem>_ros.npz`` (trajectories at the controller steps;
``meta["ros"]`` the topics, the trajectory messages accepted and refused, the message
counts; ``complete = False`` after a safe stop), ``<stem>_ros_timing.npz`` (every
cycle) and ``<stem>_ros.json`` (statistics and tracking metrics).
"""

from __future__ import annotations

import math
import signal
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..exceptions import ConfigError, NodeShutDown
from ..experiment.build import Experiment
from ..experiment.config import ExperimentConfig
from ..experiment.inner_law import close_law, inner_law_controller, inner_law_summary
from ..experiment.realtime import brake_settings, realtime_parts
from ..experiment.record import recorded_limits
from ..realtime.loop import RealtimeLoop, RealtimeRun, fifo_priority
from ..sim.engines import engine_spec
from .packaged import CONFIG_HELP
from .realtime import StatusLine, add_stop_options, priority_value, save_run
from .ros_trajectories import TrajectorySubscription

__all__ = [
    "format_ros",
    "ros_arguments",
    "ros_arm_arguments",
    "run_ros",
    "run_ros_arm",
    "with_namespace",
]


def with_namespace(config: ExperimentConfig, namespace: str | None) -> ExperimentConfig:
    """``config`` with ``[ros] namespace`` replaced (``--namespace``)."""
    if namespace is None:
        return config
    from ..experiment.config.ros import check_namespace

    ns = check_namespace("--namespace", namespace)
    return replace(config, ros=replace(config.ros, namespace=ns))


def ros_parts(experiment: Experiment, inner_law: str | None = None):
    """The loop settings, safety settings, safe torque and controller of ``hmpc-pin ros``:
    ``[realtime]``'s at ``[ros] rate`` (its errors named ``ros.rate``), the brake of
    ``[realtime] hold`` and ``brake_speed``, the controller run by the inner law of
    ``[realtime] inner_law`` (``inner_law``, ``--inner-law``, over it;
    :mod:`hmpc_pin.experiment.inner_law`; a threaded law's planner runs from here: close
    it with :func:`~hmpc_pin.experiment.inner_law.close_law`), and ``[ros] gravity``
    (``"arm"``: the controller's torque without G(q), no G(q) in the safe torques).

    Raises:
        ConfigError: ``[ros] rate`` does not divide the controller period; an inner law
            that does not apply.
    """
    from ..realtime.safety import GravityByArm, SafeTorque

    cfg = experiment.config
    rc = cfg.ros
    try:
        loop_settings, safety, safe = realtime_parts(experiment, rc.rate, plant=False)
    except ConfigError as exc:
        if exc.key != "realtime.rate":
            raise
        raise ConfigError("ros.rate", exc.message.replace("rate=", "ros.rate=")) from None
    check_gravity(cfg)
    ctrl = inner_law_controller(
        experiment, loop_settings.period, "ros", safe.effort_limit, choice=inner_law
    )
    if rc.gravity == "arm":
        safe = SafeTorque(
            experiment.robot,
            safe.damping,
            gravity=False,
            effort_limit=safe.effort_limit,
            brake_time=safe.brake_time,
        )
        ctrl = GravityByArm(ctrl, experiment.robot)
    return loop_settings, safety, safe, ctrl


def build_ros(config: ExperimentConfig, inner_law: str | None = None):
    """The experiment of ``hmpc-pin ros`` and its parts, built once: ``(experiment,
    ros_parts(experiment, inner_law))``; bad input (``[ros] rate``, the brake, ``[ros]
    gravity``, the inner law) raises here, before a node starts or a file is written. The
    caller closes the law (:func:`~hmpc_pin.experiment.inner_law.close_law` on the
    controller, ``parts[3]``; :func:`run_ros` does).

    Raises:
        ConfigError: As ``Experiment.from_config`` and :func:`ros_parts`.
    """
    experiment = Experiment.from_config(config)
    return experiment, ros_parts(experiment, inner_law)


def check_gravity(config: ExperimentConfig) -> None:
    """Who compensates gravity is one choice, ``[ros] gravity``, for both ROS nodes;
    ``[realtime] gravity``, if given, must agree with it.

    Raises:
        ConfigError: ``realtime.gravity`` contradicts ``ros.gravity``.
    """
    given, who = config.realtime.gravity, config.ros.gravity
    if given is None or given == (who == "controller"):
        return
    if who == "controller":
        raise ConfigError(
            "realtime.gravity",
            "is false, but [ros] gravity = 'controller' says the arm does not compensate "
            "gravity itself: the zero torque held after a stop would let it fall. Drop "
            "realtime.gravity (the ROS nodes follow [ros] gravity), or set [ros] gravity = "
            "'arm' if the arm adds G(q) itself",
        )
    raise ConfigError(
        "realtime.gravity",
        "is true, but [ros] gravity = 'arm' says the arm adds G(q) itself: G(q) in the safe "
        "torque would be counted twice. Drop realtime.gravity (the ROS nodes follow [ros] "
        "gravity), or set [ros] gravity = 'controller'",
    )


def run_ros(
    config: ExperimentConfig,
    out: Path,
    stem: str | None = None,
    ros_args: list[str] | None = None,
    built: tuple | None = None,
):
    """Run ``config``'s controller as a ROS 2 node until its duration or a safe stop.

    With ``[realtime] priority`` > 0 the whole node runs under ``SCHED_FIFO`` (the DDS
    threads rclpy starts inherit it: a state is delivered on time on a loaded machine).

    Args:
        config: The experiment.
        out: The output directory.
        stem: The files' stem (default: the config's name).
        ros_args: ROS arguments (those after ``--ros-args``: remaps, ``__ns``,
            ``use_sim_time`` ...), given to rclpy.
        built: ``build_ros(config)``, by a caller that checked the parts before writing
            anything (default: built here); the experiment is built once. Its inner law
            is closed here on every way out (a threaded law's planner thread joined).

    Returns:
        ``(run, files)``: the :class:`~hmpc_pin.realtime.loop.RealtimeRun` and the files.

    Raises:
        ArmError: No joint state within ``ros.start_timeout`` or one that lacks
            the robot's joints (nothing written).
    """
    built = built or build_ros(config)
    try:
        with fifo_priority(config.realtime.priority):
            return _run_ros(config, out, stem, ros_args, built)
    finally:
        close_law(built[1][3])  # the threaded law's planner joined on every way out


def _run_ros(
    config: ExperimentConfig,
    out: Path,
    stem: str | None,
    ros_args,
    built: tuple,
):
    from ..ros.interface import RosArmInterface
    from ..ros.node import RosNode, discovery_range

    rc = config.ros
    stem = (stem or config.name) + "_ros"
    experiment, (loop_settings, safety, safe, ctrl) = built
    ros = RosNode(
        rc.node,
        rc.namespace,
        discovery_range(rc.discovery),
        "hmpc-pin ros",
        ros_args=ros_args,
        parameters=config_parameters(config),
    )
    switch = sys.getswitchinterval()
    trajectories = None
    try:
        qos = ros.qos(rc.qos_depth, rc.qos_reliability == "reliable")
        iface = RosArmInterface(
            ros,
            experiment.robot.joint_names,
            rc.period,
            rc.joint_states,
            rc.commands,
            rc.start_timeout,
            qos=qos,
        )
        collision = config.collision is not None and hasattr(experiment.controller, "detected_at")
        on_step = _estimate_publisher(ros, rc, experiment, iface, qos, collision, ctrl)
        trajectories = TrajectorySubscription(ros, experiment, iface, rc.joint_trajectory, qos)
        trajectories.warm()
        _serve(ros, rc.autostart)
        loop = RealtimeLoop(
            iface,
            ctrl,
            experiment.reference,
            safe,
            loop_settings,
            safety,
            joint_names=tuple(experiment.robot.joint_names),
            meta=experiment.meta(),
            on_step=on_step,
        )
        trajectories.loop = loop
        # (deactivated before this: the loop is asked to stop now, before its first cycle)
        ros.on_deactivate(loop.request_stop_by, "deactivated")
        # a Python thread (the trajectory check) holds the GIL at most this long when the
        # control thread wants it back
        sys.setswitchinterval(min(switch, 1e-4))
        status = StatusLine(loop, loop_settings.duration)
        try:
            run = loop.run(start=True)  # set-up (heap frozen) before the first state
        finally:
            status.close()
        sys.setswitchinterval(switch)
        trajectories.close()
        run.result.meta["ros"] = _ros_meta(ros, rc, iface, trajectories, collision)
        run.stats["inner_law"] = inner_law_summary(ctrl, loop_settings.period)
        if collision:
            run.result.meta["collision"] = {"detected_at": experiment.controller.detected_at}
    finally:
        sys.setswitchinterval(switch)
        if trajectories is not None:
            trajectories.close()
        ros.close()
    return run, save_run(run, out, stem, "ros")


def _estimate_publisher(ros, rc, experiment: Experiment, iface, qos, collision: bool, ctrl):
    """The publishers of the disturbance estimate (``[ros] external_torque``) and, with a
    collision watch, its flag (``[ros] collision``).

    Args:
        ros: The node (:class:`~hmpc_pin.ros.node.RosNode`).
        rc: The ``[ros]`` table.
        experiment: The experiment (its controller's estimate is published).
        iface: The arm interface (its stamps).
        qos: The topics' quality of service.
        collision: Whether the controller watches for a collision (publish its flag).
        ctrl: The controller the loop runs (an inner law's estimate is its own observer's,
            every cycle).

    Returns:
        ``on_step(t)``, called by the loop after each controller step: publishes both.
    """
    std, sensor = ros.msgs["std_msgs"], ros.msgs["sensor_msgs"]
    inner = experiment.controller
    estimate = ctrl  # (the inner law's, else through the wrappers the controller's)
    names = list(experiment.robot.joint_names)
    if rc.external_torque_type == "joint_state":
        d_pub = ros.node.create_publisher(sensor.JointState, rc.external_torque, qos)
        d_msg = sensor.JointState()
        d_msg.name = names
    else:  # deprecated: no stamp, no names
        d_pub = ros.node.create_publisher(std.Float64MultiArray, rc.external_torque, qos)
        d_msg = std.Float64MultiArray()
    stamped = rc.external_torque_type == "joint_state"
    c_pub = ros.node.create_publisher(std.Bool, rc.collision, qos) if collision else None
    c_msg = std.Bool()

    def on_step(t: float) -> None:
        if stamped:
            ns = round(iface.stamp_time() * 1e9)
            d_msg.header.stamp.sec, d_msg.header.stamp.nanosec = divmod(ns, 1_000_000_000)
            d_msg.effort = estimate.disturbance_estimate.tolist()
        else:
            d_msg.data = estimate.disturbance_estimate.tolist()
        d_pub.publish(d_msg)
        if c_pub is not None:
            c_msg.data = inner.detected_at is not None
            c_pub.publish(c_msg)

    return on_step


def _serve(ros, autostart: bool) -> None:
    """Serve the node's parameters and lifecycle (in their own thread) and, without
    ``[ros] autostart``, wait for an orchestrator to activate it.

    Raises:
        NodeShutDown: The node was shut down before it was activated.
    """
    ros.serve(activate=autostart)  # parameters and lifecycle, in their own thread
    if not autostart:
        ros.node.get_logger().info(
            f"waiting for an orchestrator to configure and activate "
            f"{ros.node.get_fully_qualified_name()} ([ros] autostart = false)"
        )
        if not ros.wait_active():
            raise NodeShutDown(
                f"{ros.node.get_fully_qualified_name()} was shut down before it was "
                "activated: nothing was run, sent or written"
            )


def _ros_meta(ros, rc, iface, trajectories: TrajectorySubscription, collision: bool) -> dict:
    """The run record's ``meta["ros"]``: the node, its topics, the stamps and counts of
    the states and commands, and the trajectories accepted or refused."""
    return {
        "node": ros.node.get_fully_qualified_name(),
        "joint_states": iface.joint_states_topic,
        "commands": iface.commands_topic,
        "joint_trajectory": trajectories.topic,
        "external_torque": ros.topic(rc.external_torque),
        "collision": ros.topic(rc.collision) if collision else None,
        "stamps": iface.stamps,
        "stamp_origin": iface.origin,
        "states_received": iface.received,
        "states_ignored": iface.ignored,
        "commands_published": iface.published,
        "gravity": rc.gravity,
        "trajectories": list(trajectories.events),
    }


def config_parameters(config: ExperimentConfig) -> dict:
    """The ROS parameters the controller node declares (read-only, the config's values:
    ``ros2 param list`` shows them): every ``[ros]`` key as ``ros.<key>``, and the
    ``[realtime]`` keys of the loop and its stop as ``realtime.<key>`` (the brake and the
    gravity as the node runs them: ``realtime.brake_time`` or ``realtime.damping``,
    ``realtime.gravity``), plus ``controller.Ts``, ``simulation.duration`` and
    ``config.name``."""
    from dataclasses import fields

    out: dict = {
        "config.name": config.name,
        "controller.Ts": float(config.controller.Ts),
        "simulation.duration": float(config.simulation.duration),
    }
    for table in ("ros", "realtime"):
        section = getattr(config, table)
        for f in fields(section):
            value = getattr(section, f.name)
            if isinstance(value, np.ndarray):
                value = [float(x) for x in np.atleast_1d(value)]
            if value is None:
                continue
            if isinstance(value, (bool, int, float, str)) or (
                isinstance(value, list) and all(isinstance(x, float) for x in value)
            ):
                out[f"{table}.{f.name}"] = value
    # the brake and the gravity the node runs with (not only what the file gives)
    damping, brake = brake_settings(config, config.ros.period)
    out.pop("realtime.damping", None)
    if brake is not None:
        out["realtime.brake_time"] = brake
    else:
        out["realtime.damping"] = [float(x) for x in np.atleast_1d(damping)]
    out["realtime.gravity"] = config.ros.gravity == "controller"
    return out


def format_ros(run: RealtimeRun) -> str:
    """The message counts and the trajectory messages, a few lines."""
    r = run.result.meta["ros"]
    lines = [
        f"ros: {r['states_received']} joint states received on {r['joint_states']} "
        f"(stamps: {r['stamps']}), {r['commands_published']} commands published on "
        f"{r['commands']}"
    ]
    for ev in r["trajectories"]:
        what = f"accepted a trajectory of {ev['points']} points" if ev["accepted"] else ev["reason"]
        if "superseded_at" in ev:
            what += f", superseded at t={ev['superseded_at']:.3f} s before it started"
        lines.append(f"  t={ev['t']:.3f} s: {what}")
    return "\n".join(lines)


def check_run_length(duration: float, rate: float, key: str) -> None:
    """A ROS node's run of ``duration`` [s] spans at least one period :math:`1/r` of
    ``[ros] rate`` :math:`r` [Hz] (it runs :math:`\\mathrm{round}(d\\,r)` periods: a
    shorter run would step nothing and exit as if it had run).

    Raises:
        ConfigError: ``duration`` is shorter than one period (named ``key``).
    """
    period = 1.0 / rate
    if not duration >= period * (1.0 - 1e-9):
        raise ConfigError(
            key,
            f"expected at least one period of the node, 1/ros.rate = {period:g} s "
            f"([ros] rate = {rate:g} Hz), got {duration:g} s; lengthen it or raise [ros] rate",
        )


def _fixed_plant_step(config: ExperimentConfig) -> tuple[str, float] | None:
    """The key and value [s] of the plant's fixed step (``plant.dt``, MuJoCo's
    ``plant.mujoco.timestep``), or ``None`` when ``plant.tolerance`` chooses it per
    period (a whole fraction of that period, whatever it is)."""
    pc = config.plant
    engine = engine_spec(pc.engine)
    if "dt" in engine.replaces:  # the step is a key of the engine's table (MuJoCo's timestep)
        key = engine.replaces["dt"]
        return f"plant.{engine.table}.{key}", float(getattr(getattr(pc, engine.table), key))
    if pc.tolerance is None:
        return "plant.dt", float(pc.dt)
    return None


def check_arm_rate(config: ExperimentConfig) -> None:
    """``ros-arm`` advances its plant by one period :math:`P = 1/r` of ``[ros] rate`` per
    joint state: :math:`P` must be a whole number :math:`k \\ge 1` of the plant's fixed
    step :math:`h`, i.e. :math:`r = 1/(k h)`.

    Raises:
        ConfigError: ``ros.rate`` whose period is no whole number of steps, naming the
            rate, the step and the nearest rates that are.
    """
    fixed = _fixed_plant_step(config)
    if fixed is None:
        return
    key, h = fixed
    rate, P = config.ros.rate, config.ros.period
    k = round(P / h)
    if k >= 1 and abs(k * h - P) <= 1e-9 * P:
        return
    near = sorted({max(1, math.floor(P / h)), max(1, math.ceil(P / h))})
    rates = " or ".join(f"{1.0 / (m * h):g} Hz" for m in near)
    raise ConfigError(
        "ros.rate",
        f"{rate:g} Hz gives the arm node a period 1/rate = {P:g} s that is not a whole "
        f"number of the plant's steps ({key} = {h:g} s); expected a rate 1/(k {key}) "
        f"with k = 1, 2, ..., e.g. {rates}",
    )


def run_ros_arm(
    config: ExperimentConfig,
    duration: float | None = None,
    ros_args: list[str] | None = None,
    real_time_factor: float | None = None,
) -> dict:
    """Run ``config``'s plant as a ROS 2 node (:class:`~hmpc_pin.ros.arm.RosArmNode`)
    until ``duration`` [s] (``None``: until SIGINT or SIGTERM); under ``SCHED_FIFO``
    with ``[realtime] priority`` > 0.

    The node runs :math:`\\mathrm{round}(d\\,r)` periods of ``[ros] rate`` r for a
    ``duration`` d (simulated seconds with ``real_time_factor``: then it publishes
    ``/clock`` and stamps its states on it, :class:`~hmpc_pin.ros.arm.RosArmNode`). Its
    joints stop at the URDF's position limits.

    Returns:
        The node's counts (``steps``, ``late``, ``commands``, ``rejected``, ``stops``)
        and ``"interrupted"`` (stopped by SIGINT).

    Raises:
        ConfigError: Before rclpy starts: ``ros.rate`` whose period is no whole number of
            the plant's steps (:func:`check_arm_rate`), a ``duration`` shorter than one
            period (:func:`check_run_length`), ``realtime.gravity`` against ``ros.gravity``.
    """
    with fifo_priority(config.realtime.priority):
        return _run_ros_arm(config, duration, ros_args, real_time_factor)


def _run_ros_arm(
    config: ExperimentConfig, duration: float | None, ros_args=None, real_time_factor=None
) -> dict:
    from ..ros.arm import RosArmNode
    from ..ros.node import RosNode, discovery_range

    rc = config.ros
    check_gravity(config)
    check_arm_rate(config)
    if duration is not None:
        check_run_length(duration, rc.rate, "--duration")
    experiment = Experiment.from_config(config)
    plant = experiment.make_plant(rc.period)
    ros = RosNode(
        rc.arm_node,
        rc.namespace,
        discovery_range(rc.discovery),
        "hmpc-pin ros-arm",
        ros_args=ros_args,
    )
    stopped_by: list[int] = []
    try:
        gravity = experiment.plant.gravity_torque if rc.gravity == "arm" else None
        limits = recorded_limits(experiment.robot)  # the joint stops (±inf: none)
        arm = RosArmNode(
            ros,
            plant,
            experiment.robot.joint_names,
            experiment.q0,
            experiment.dq0,
            rc.period,
            rc.joint_states,
            rc.commands,
            experiment.effort_limit,
            gravity=gravity,
            lower=limits["lower"],
            upper=limits["upper"],
            real_time_factor=real_time_factor,
        )

        def on_signal(signum, frame) -> None:
            stopped_by.append(signum)
            arm.stop()

        old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
        simulated = (
            ""
            if real_time_factor is None
            else f" of simulated time at a real-time factor of {real_time_factor:g}, /clock "
            "published"
        )
        print(
            f"{config.name}: the arm's plant ({config.plant.engine}) as node "
            f"{ros.node.get_fully_qualified_name()}: {arm.joint_states_topic} at "
            f"{rc.rate:g} Hz{simulated}, efforts from {arm.commands_topic}",
            flush=True,
        )
        try:
            arm.run(duration)
        finally:
            for s, h in old.items():
                signal.signal(s, h)
        counts = {
            "steps": arm.steps,
            "late": arm.late,
            "commands": arm.commands,
            "rejected": arm.rejected,
            "stops": arm.stops,
        }
    finally:
        ros.close()
    counts["interrupted"] = signal.SIGINT in stopped_by
    print(
        f"arm stopped after {counts['steps']} steps: {counts['commands']} commands applied, "
        f"{counts['rejected']} ignored, {counts['late']} periods late, "
        f"{counts['stops']} on a joint stop",
        file=sys.stderr,
    )
    return counts


def ros_arguments(ros) -> None:
    """The ``ros`` subcommand's description and arguments (extra ``ros``; the command line
    sets its one-line help and its ``func``, which owns the exit codes and the output
    checks)."""
    ros.description = (
        "Run the experiment's controller as a ROS 2 node on the topics "
        "ros2_control exposes: sensor_msgs/JointState in ([ros] joint_states), "
        "std_msgs/Float64MultiArray efforts out ([ros] commands), paced by the arriving "
        "states; a new reference as trajectory_msgs/JointTrajectory on ~/joint_trajectory "
        "(checked against the limits first), the disturbance estimate on "
        "~/external_torque. Same safe stops, latency statistics and saved run as "
        "`realtime`: exit 130 on Ctrl-C, 1 on a fault or a watchdog stop."
    )
    ros.add_argument("config", type=Path, help=CONFIG_HELP)
    ros.add_argument(
        "--duration",
        type=float,
        help="run length [s] (overrides the config); at least one period 1/[ros] rate",
    )
    ros.add_argument("--out", type=Path, default=Path("out"), help="output directory [out]")
    add_stop_options(ros)
    _add_node_options(ros)


def ros_arm_arguments(arm) -> None:
    """The ``ros-arm`` subcommand's description and arguments (as :func:`ros_arguments`)."""
    arm.description = (
        "Run the experiment's plant (RK4 or MuJoCo) as a ROS 2 node that "
        "publishes sensor_msgs/JointState at [ros] rate and applies the latest "
        "std_msgs/Float64MultiArray effort command, as ros2_control's "
        "joint_state_broadcaster and JointGroupEffortController do. Runs until Ctrl-C "
        "(exit 130) or --duration."
    )
    arm.add_argument("config", type=Path, help=CONFIG_HELP)
    arm.add_argument(
        "--duration",
        type=float,
        help="stop after this long [s], rounded to whole periods 1/[ros] rate; shorter "
        "than one period is refused (exit 2) [until Ctrl-C]",
    )
    arm.add_argument(
        "--real-time-factor",
        type=_positive_factor,
        metavar="F",
        help="run on simulated time, F simulated seconds per wall second: publish /clock "
        "and stamp the states on it (run the controller with --ros-args -p "
        "use_sim_time:=true); --duration is then simulated time [system clock]",
    )
    _add_node_options(arm)


def _positive_factor(text: str) -> float:
    """``--real-time-factor``'s value: a finite number > 0 (argparse exits 2 otherwise)."""
    import argparse

    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and 0 < value <= 100):
        raise argparse.ArgumentTypeError(f"expected a factor > 0 and <= 100, got {text!r}")
    return value


def _add_node_options(parser) -> None:
    """``--namespace``, ``--priority`` and ``--ros-args``, the options of both ROS nodes."""
    import argparse

    parser.add_argument(
        "--ros-args",
        dest="ros_args",
        nargs=argparse.REMAINDER,
        default=None,
        metavar="ARG",
        help="ROS arguments, last on the line (remaps -r from:=to, -r __ns:=/ns, "
        "-r __node:=name, -p use_sim_time:=true), as every ROS 2 node takes them",
    )
    parser.add_argument("--namespace", metavar="NS", help="ROS namespace (overrides ros.namespace)")
    parser.add_argument(
        "--priority",
        type=priority_value,
        metavar="N",
        help="SCHED_FIFO priority 1-99 of the node; auto: 80 where permitted, else normal "
        "(overrides realtime.priority)",
    )
