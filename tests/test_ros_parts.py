"""``hmpc-pin ros``'s parts without DDS: the experiment built once, the checks of the arm
node's rate and of a run's length at their boundaries with their one-line messages, the
parameters the node declares, the summary lines, ``--namespace``, and the joint-state
merge's handling of malformed arrays."""

from __future__ import annotations

import math
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

import hmpc_pin
from hmpc_pin.exceptions import ConfigError

from .conftest import CONFIGS


@pytest.fixture(scope="module")
def panda_sine():
    return hmpc_pin.load_config(CONFIGS / "panda_sine.toml")


def _with(config, ros=None, realtime=None, plant=None):
    return replace(
        config,
        ros=replace(config.ros, **(ros or {})),
        realtime=replace(config.realtime, **(realtime or {})),
        plant=replace(config.plant, **(plant or {})),
    )


# ------------------------------------------------------------------ built once
def test_the_ros_command_builds_the_experiment_once(tmp_path, monkeypatch, capsys):
    """``hmpc-pin ros`` checks the parts of the experiment before anything is written and
    runs that same experiment: one build. (The node is stopped at its creation, before
    rclpy starts: a Ctrl-C at start-up, exit 130, nothing run.)"""
    pytest.importorskip("rclpy", reason="extra hmpc_pin[ros] not installed")
    import hmpc_pin.ros.node
    from hmpc_pin.apps.cli import main
    from hmpc_pin.experiment.build import Experiment

    builds = []
    build = Experiment.from_config.__func__

    def counted(cls, *args, **kwargs):
        builds.append(args[0])
        return build(cls, *args, **kwargs)

    seen = []

    def no_node(*args, **kwargs):
        seen.append(args)
        raise KeyboardInterrupt("stopped before the node")

    monkeypatch.setattr(Experiment, "from_config", classmethod(counted))
    monkeypatch.setattr(hmpc_pin.ros.node, "RosNode", no_node)
    out = tmp_path / "out"
    code = main(["ros", str(CONFIGS / "panda_sine.toml"), "--duration", "0.1", "--out", str(out)])
    captured = capsys.readouterr()
    assert code == 130, captured.err
    assert seen, "the run did not reach the node"
    assert len(builds) == 1
    assert "stopped before the node" in captured.err
    assert not list(out.glob("*.npz"))  # nothing written


def test_build_ros_refuses_a_bad_rate_before_anything(panda_sine):
    from hmpc_pin.apps.ros import build_ros

    experiment, (loop, _safety, _safe, ctrl) = build_ros(panda_sine)
    assert loop.period == pytest.approx(1.0 / panda_sine.ros.rate)
    assert ctrl is experiment.controller  # [ros] gravity = "controller": not wrapped
    with pytest.raises(ConfigError) as info:
        build_ros(_with(panda_sine, ros={"rate": 150.0}))
    assert info.value.key == "ros.rate"


# -------------------------------------------------------------- rates and lengths
def test_the_arm_nodes_rate_names_the_nearest_whole_rates(panda_sine):
    from hmpc_pin.apps.ros import check_arm_rate

    assert panda_sine.plant.dt == 0.001
    with pytest.raises(ConfigError) as info:
        check_arm_rate(_with(panda_sine, ros={"rate": 300.0}))
    # P = 3.33 ms: k = 3 (333.333 Hz) or k = 4 (250 Hz)
    assert info.value.key == "ros.rate"
    assert str(info.value).endswith("e.g. 333.333 Hz or 250 Hz")
    assert "1/rate = 0.00333333 s" in str(info.value)
    # faster than the plant's step: k = 1 is the only whole rate
    with pytest.raises(ConfigError, match=r"e\.g\. 1000 Hz$"):
        check_arm_rate(_with(panda_sine, ros={"rate": 1500.0}))
    check_arm_rate(_with(panda_sine, ros={"rate": 1000.0}))
    # 10 ppm off a whole rate is no whole number of steps (a drift of 1 step per 100 s)
    with pytest.raises(ConfigError, match=r"e\.g\. 1000 Hz$"):
        check_arm_rate(_with(panda_sine, ros={"rate": 1000.0 * (1 + 1e-5)}))
    check_arm_rate(_with(panda_sine, ros={"rate": 125.0}))  # k = 8


def test_the_arm_nodes_rate_against_mujocos_step_or_none_with_a_tolerance(panda_sine):
    from hmpc_pin.apps.ros import _fixed_plant_step, check_arm_rate

    mujoco = _with(panda_sine, plant={"engine": "mujoco"})
    key, h = _fixed_plant_step(mujoco)
    assert key == "plant.mujoco.timestep" and h == mujoco.plant.mujoco.timestep
    rate = 1.0 / (1.5 * h)  # 1.5 steps per period
    with pytest.raises(ConfigError, match=r"plant\.mujoco\.timestep"):
        check_arm_rate(_with(mujoco, ros={"rate": rate}))
    assert _fixed_plant_step(panda_sine) == ("plant.dt", 0.001)
    adaptive = _with(panda_sine, plant={"tolerance": 1e-6, "dt": None})
    assert _fixed_plant_step(adaptive) is None
    check_arm_rate(_with(adaptive, ros={"rate": 300.0}))  # the step follows the period


def test_a_run_of_one_period_passes_and_a_shorter_or_nan_one_is_refused():
    from hmpc_pin.apps.ros import check_run_length

    check_run_length(0.25, 4.0, "--duration")
    check_run_length(0.25 * (1 - 1e-12), 4.0, "--duration")  # rounding
    for bad in (0.25 * (1 - 1e-6), 0.0, -1.0, math.nan):
        with pytest.raises(ConfigError) as info:
            check_run_length(bad, 4.0, "--duration")
        assert info.value.key == "--duration"
        assert f"got {bad:g} s" in str(info.value)
        assert "1/ros.rate = 0.25 s ([ros] rate = 4 Hz)" in str(info.value)


# --------------------------------------------------------------------- parameters
def test_the_declared_parameters_are_the_configs_values(panda_sine):
    from dataclasses import fields

    from hmpc_pin.apps.ros import config_parameters
    from hmpc_pin.experiment.build import minimum_brake_time

    config = _with(panda_sine, ros={"namespace": "/arm1", "discovery": None})
    p = config_parameters(config)
    assert p["config.name"] == config.name
    assert p["controller.Ts"] == config.controller.Ts
    assert p["simulation.duration"] == config.simulation.duration
    for f in fields(config.ros):
        value = getattr(config.ros, f.name)
        if value is None:
            assert f"ros.{f.name}" not in p
        else:
            assert p[f"ros.{f.name}"] == value, f.name
    assert p["ros.namespace"] == "/arm1" and p["ros.rate"] == config.ros.rate
    assert p["realtime.hold"] == config.realtime.hold
    assert p["realtime.watchdog"] == config.realtime.watchdog
    assert p["realtime.gravity"] is True
    # the default brake: the inertia brake of hold/6, no damping declared
    assert "realtime.damping" not in p
    assert p["realtime.brake_time"] == pytest.approx(config.realtime.hold / 6)
    # a short hold: the shortest brake at the ROS node's period (not [realtime] rate's)
    short = _with(config, ros={"rate": 1000.0}, realtime={"hold": 0.006, "rate": 250.0})
    p = config_parameters(short)
    assert p["realtime.brake_time"] == pytest.approx(minimum_brake_time(short, 1e-3))
    assert minimum_brake_time(short, 1e-3) != pytest.approx(minimum_brake_time(short, 4e-3))
    # a diagonal damping: declared per joint, no brake time; gravity by the arm: false
    damped = _with(config, ros={"gravity": "arm"}, realtime={"damping": 3.0})
    p = config_parameters(damped)
    assert p["realtime.damping"] == [3.0] * 7 or p["realtime.damping"] == [3.0]
    assert "realtime.brake_time" not in p
    assert p["realtime.gravity"] is False


# ------------------------------------------------------------------ the summary
def test_the_summary_counts_and_each_trajectory_message():
    from hmpc_pin.apps.ros import format_ros

    meta = {
        "states_received": 1200,
        "joint_states": "/arm1/joint_states",
        "stamps": "header",
        "commands_published": 1199,
        "commands": "/arm1/effort_controller/commands",
        "trajectories": [
            {"t": 0.5, "accepted": True, "points": 3, "t_end": 2.0},
            {"t": 0.75, "accepted": True, "points": 1, "t_end": 2.0, "superseded_at": 0.6},
            {"t": 1.25, "accepted": False, "reason": "refused the joint_trajectory message: x"},
        ],
    }
    run = SimpleNamespace(result=SimpleNamespace(meta={"ros": meta}))
    assert format_ros(run).splitlines() == [
        "ros: 1200 joint states received on /arm1/joint_states (stamps: header), 1199 "
        "commands published on /arm1/effort_controller/commands",
        "  t=0.500 s: accepted a trajectory of 3 points",
        "  t=0.750 s: accepted a trajectory of 1 points, superseded at t=0.600 s before it started",
        "  t=1.250 s: refused the joint_trajectory message: x",
    ]


def test_namespace_option(panda_sine):
    from hmpc_pin.apps.ros import with_namespace

    assert with_namespace(panda_sine, None) is panda_sine
    assert with_namespace(panda_sine, "arm1/").ros.namespace == "/arm1"
    assert with_namespace(panda_sine, "/").ros.namespace == ""
    named = with_namespace(panda_sine, "/arm1")
    assert with_namespace(named, "").ros.namespace == ""  # "" is the root, not "unchanged"
    with pytest.raises(ConfigError) as info:
        with_namespace(panda_sine, "/arm-1")
    assert info.value.key == "--namespace" and "'/arm-1'" in str(info.value)


# ----------------------------------------------------------------- the merge
def test_a_message_with_a_wrong_number_of_values_gives_nan_not_shifted_values():
    """Positions or velocities not one per name (a driver's bug): NaN for the joints it
    names (a fault downstream), never values taken from the wrong index; a later good
    message restores them."""
    from hmpc_pin.ros.interface import JointStateMerger

    merge = JointStateMerger(["a", "b"])
    assert merge.add(["b", "a"], [2.0, 1.0, 9.0], [0.2, 0.1])  # one position too many
    assert np.isnan(merge.q).all()
    np.testing.assert_array_equal(merge.dq, [0.1, 0.2])
    assert merge.add(["a", "b"], [1.0, 2.0], [0.1])  # one velocity too few
    np.testing.assert_array_equal(merge.q, [1.0, 2.0])
    assert np.isnan(merge.dq).all()
    assert merge.add(["x", "b", "a"], [0.0, 2.5, 1.5], [0.0, 0.25, 0.15])
    np.testing.assert_array_equal(merge.q, [1.5, 2.5])
    np.testing.assert_array_equal(merge.dq, [0.15, 0.25])
    # a message that names only other joints is counted and remembered, not merged
    assert not merge.add(["finger_1", "finger_2"], [0.0, 0.0], [0.0, 0.0])
    assert merge.ignored == 1 and merge.other_names == ["finger_1", "finger_2"]
    np.testing.assert_array_equal(merge.q, [1.5, 2.5])
    # a state is complete only when BOTH joints are new since the last one
    assert not merge.add(["a"], [3.0], [0.3])
    assert not merge.add(["a"], [3.5], [0.35])
    assert merge.add(["b"], [4.0], [0.4])
    np.testing.assert_array_equal(merge.q, [3.5, 4.0])
    assert merge.seen.all() and merge.missing == []


# ------------------------------------------------------- trajectory messages' worker
class _Log:
    def __init__(self):
        self.lines: list[tuple[str, str]] = []

    def info(self, line):
        self.lines.append(("info", line))

    def error(self, line):
        self.lines.append(("error", line))


def _worker(panda_experiment):
    """The check of ``~/joint_trajectory`` (the worker thread's function), on a real loop
    (not run: its time set by hand) and the real message type."""
    from hmpc_pin.apps.ros_trajectories import TrajectorySubscription, trajectory_limits
    from hmpc_pin.realtime import LoopSettings, PlantArm, RealtimeLoop, SafeTorque
    from hmpc_pin.realtime import SafetySettings as Safety

    ex = panda_experiment
    log = _Log()
    t = TrajectorySubscription.__new__(TrajectorySubscription)
    t.ros = SimpleNamespace(node=SimpleNamespace(get_logger=lambda: log))
    t.experiment, t.iface = ex, SimpleNamespace(origin=0.0)
    t.lower, t.upper = trajectory_limits(ex)
    t.loop, t.events, t._pending, t.topic = None, [], None, "/hmpc/joint_trajectory"
    arm = PlantArm(ex.make_plant(1e-3), ex.q0)
    loop = RealtimeLoop(arm, ex.controller, ex.reference, SafeTorque(ex.robot),
                        LoopSettings(1000.0, 1.0), Safety.unlimited(7))  # fmt: skip
    return t, loop, log


def _trajectory(names, q, t_from_start):
    msgs = pytest.importorskip("trajectory_msgs.msg")
    msg = msgs.JointTrajectory()
    msg.joint_names = list(names)
    p = msgs.JointTrajectoryPoint()
    p.positions = [float(x) for x in q]
    p.time_from_start.sec = int(t_from_start)
    p.time_from_start.nanosec = round((t_from_start % 1) * 1e9)
    msg.points.append(p)
    return msg


def test_the_trajectory_worker_accepts_refuses_and_marks_superseded(panda_sine):
    from hmpc_pin.experiment.build import Experiment

    ex = Experiment.from_config(panda_sine)
    t, loop, log = _worker(ex)
    names = list(ex.robot.joint_names)
    target = ex.reference.sample(2.0)[0] + 0.05
    msg = _trajectory(names, target, 1.0)
    t._check(msg)  # before the loop runs: refused, nothing recorded
    assert log.lines[-1][0] == "error" and "not running yet" in log.lines[-1][1]
    assert t.events == []
    t.loop = loop
    loop.time = 1.0
    Ts = ex.controller.Ts
    t._check(msg)
    first = t.events[-1]
    assert first["accepted"] and first["points"] == 1
    assert first["t"] == pytest.approx(1.0 + Ts)  # the step that takes it over
    assert first["t_end"] == pytest.approx(1.0 + Ts + 1.0)
    pending = loop.pending_reference
    assert pending is not None
    np.testing.assert_allclose(pending.sample(2.0 + Ts)[0], target, atol=1e-9)
    assert log.lines[-1][0] == "info"
    assert "accepted a joint_trajectory message of 1 points" in log.lines[-1][1]
    # a second one before the first started: the first is marked superseded
    loop.time = 1.002
    t._check(_trajectory(names, target, 0.5))
    assert first["superseded_at"] == pytest.approx(1.002 + Ts)
    assert t.events[-1]["accepted"] and loop.superseded is pending
    # one beyond the limits: refused, the pending one kept
    kept = loop.pending_reference
    beyond = target.copy()
    beyond[3] = t.upper[3] + 0.3
    t._check(_trajectory(names, beyond, 1.0))
    refused = t.events[-1]
    assert not refused["accepted"] and refused["t"] == pytest.approx(1.002 + Ts)
    assert refused["reason"].startswith("refused the joint_trajectory message: ")
    assert "panda_joint4" in refused["reason"]
    assert loop.pending_reference is kept


def test_messages_are_checked_against_the_mpcs_limits_else_the_urdfs(panda_sine):
    """[controller.constraints] upper narrower than the URDF's: the trajectory messages
    are checked against it; a controller without constraints: against the URDF's."""
    from hmpc_pin.apps.ros_trajectories import trajectory_limits
    from hmpc_pin.experiment.build import Experiment

    cc = panda_sine.controller
    urdf = Experiment.from_config(panda_sine).robot
    upper = urdf.upper - 0.01  # 10 mrad inside the URDF's, the start posture inside it
    narrow = replace(panda_sine, controller=replace(
        cc, constraints=replace(cc.constraints, upper=upper)))  # fmt: skip
    lo, hi = trajectory_limits(Experiment.from_config(narrow))
    np.testing.assert_array_equal(hi, upper)
    np.testing.assert_array_equal(lo, urdf.lower)
    off = replace(panda_sine, controller=replace(
        cc, constraints=replace(cc.constraints, enabled=False)))  # fmt: skip
    lo, hi = trajectory_limits(Experiment.from_config(off))
    np.testing.assert_array_equal(hi, urdf.upper)


def test_a_stamped_trajectory_waits_for_its_stamp_and_a_swapped_one_is_not_superseded(
    panda_sine,
):
    from hmpc_pin.experiment.build import Experiment

    ex = Experiment.from_config(panda_sine)
    t, loop, _ = _worker(ex)
    t.loop, loop.time = loop, 1.0
    names = list(ex.robot.joint_names)
    target = ex.reference.sample(3.0)[0] + 0.05
    stamped = _trajectory(names, target, 1.0)
    stamped.header.stamp.sec = 3  # the loop's clock has its origin at 0 here
    t._check(stamped)
    assert t.events[-1]["accepted"] and t.events[-1]["t"] == pytest.approx(3.0)
    old = loop.reference
    assert loop._swap_reference(2.5, old) is old  # not before its stamp
    new = loop._swap_reference(3.0, old)  # swapped in at its time
    assert new is not old and loop.pending_reference is None
    first = t.events[-1]
    loop.time = 3.5
    t._check(_trajectory(names, ex.reference.sample(4.0)[0], 1.0))
    assert t.events[-1]["accepted"]
    assert "superseded_at" not in first  # it ran: not superseded
