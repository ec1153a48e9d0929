"""Cases of :class:`hmpc_pin.ros.interface.RosArmInterface` with a real rclpy node, run by
pytest INSIDE a private network namespace (tests/test_ros_interface.py starts it; never
collected on its own: the file name does not start with ``test_``).

Most cases hand real ``sensor_msgs/JointState`` messages to the interface's state handler
with chosen stamps and reception times, so that the time base, the periods counted, the
overdue states and the start-up refusals are checked against the numbers the case wrote,
not against a clock; one case sends states through DDS to check the taking path.
"""

from __future__ import annotations

import os
import time
from types import SimpleNamespace

import numpy as np
import pytest

if os.environ.get("HMPC_PIN_IN_NETNS") != "1":  # pragma: no cover - a guard
    pytest.skip("runs only inside a private network namespace", allow_module_level=True)

# the user's publication mode, read before any node of this process sets a default
_USER_MODE = os.environ.get("RMW_FASTRTPS_PUBLICATION_MODE") or None

from sensor_msgs.msg import JointState  # noqa: E402

from hmpc_pin.exceptions import ArmError  # noqa: E402
from hmpc_pin.ros.interface import RosArmInterface  # noqa: E402
from hmpc_pin.ros.node import RosNode  # noqa: E402

P = 0.002  # the interface period [s]
NAMES = ["a", "b"]


@pytest.fixture(scope="module")
def ros():
    node = RosNode("iface_cases", "", "LOCALHOST", "test")
    yield node
    node.close()


_count = iter(range(1000))


@pytest.fixture
def iface(ros):
    # a topic of its own per case: no message of another case reaches it
    k = next(_count)
    out = RosArmInterface(ros, NAMES, P, f"states_{k}", f"commands_{k}", start_timeout=0.3)
    yield out


def _state(stamp: float, q, dq, names=NAMES) -> JointState:
    msg = JointState()
    msg.name = list(names)
    ns = round(stamp * 1e9)
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 1_000_000_000)
    msg.position = [float(x) for x in q]
    msg.velocity = [float(x) for x in dq]
    return msg


def test_header_stamps_are_the_time_and_periods_are_counted_from_them(iface):
    t0 = time.time()
    iface._on_state(_state(t0, [1.0, 2.0], [0.1, 0.2]), t0)
    assert iface.stamps == "header"
    origin = iface.origin
    assert origin == float(int(t0)) or origin == float(int(t0) + 1)
    assert iface.wait(0.0) == 1
    stamp, q, dq = iface.read()
    assert stamp == pytest.approx(t0 - origin, abs=1e-6)
    np.testing.assert_array_equal(q, [1.0, 2.0])
    np.testing.assert_array_equal(dq, [0.1, 0.2])
    assert iface.stamp_time() == pytest.approx(t0, abs=1e-6)
    # the next state one period later, then one three periods later (two not sent)
    iface._on_state(_state(t0 + P, [1.1, 2.1], [0.0, 0.0]), time.time())
    iface._on_state(_state(t0 + 4 * P, [1.4, 2.4], [0.4, 0.5]), time.time())
    assert iface.wait(0.0) == 4  # 1 + 3 periods by the stamps
    stamp, q, dq = iface.read()
    assert stamp == pytest.approx(t0 + 4 * P - origin, abs=1e-6)
    np.testing.assert_array_equal(q, [1.4, 2.4])  # the newest
    np.testing.assert_array_equal(dq, [0.4, 0.5])
    assert iface.stamp_time() == pytest.approx(t0 + 4 * P, abs=1e-6)
    # jitter: 1.4 periods is 1, 1.6 is 2; a repeated stamp still one (at least one)
    iface._on_state(_state(t0 + 5.4 * P, [0, 0], [0, 0]), time.time())
    assert iface.wait(0.0) == 1
    iface._on_state(_state(t0 + 7.0 * P, [0, 0], [0, 0]), time.time())
    assert iface.wait(0.0) == 2
    iface._on_state(_state(t0 + 7.0 * P, [0, 0], [0, 0]), time.time())
    assert iface.wait(0.0) == 1
    assert iface.received == 6
    # nothing new: no period, nothing overdue
    assert iface.wait(0.0) == 0 and iface.overdue == 0


def test_a_zero_stamp_or_another_clock_is_timed_by_arrival(ros):
    for k, stamp in enumerate((0.0, 5.0, time.time() - 30.0, time.time() + 2.0)):
        iface = RosArmInterface(ros, NAMES, P, f"arr_{k}", f"arr_cmd_{k}")
        received = time.time() - 0.05
        iface._on_state(_state(stamp, [0, 0], [0, 0]), received)
        assert iface.stamps == "arrival", stamp
        assert iface.wait(0.0) == 1
        origin = iface.origin
        assert iface.read()[0] == pytest.approx(received - origin, abs=1e-9)
        assert iface.arrival == pytest.approx(received - origin, abs=1e-9)
        # the stamp the node reports is the arrival on the system clock when it is zero,
        # the message's own stamp (simulated time) otherwise
        expected = received if stamp == 0.0 else stamp
        assert iface.stamp_time() == pytest.approx(expected, abs=1e-6)
    # a stamp 0.9 s from the wall is still the driver's clock
    iface = RosArmInterface(ros, NAMES, P, "near", "near_cmd")
    near = time.time() - 0.9
    iface._on_state(_state(near, [0, 0], [0, 0]), time.time())
    assert iface.stamps == "header"
    iface.wait(0.0)
    assert iface.read()[0] == pytest.approx(near - iface.origin, abs=1e-6)
    # a zero stamp later in a stamped stream: that state is timed by its arrival
    received = time.time()
    iface._on_state(_state(0.0, [0, 0], [0, 0]), received)
    iface.wait(0.0)
    assert iface.read()[0] == pytest.approx(received - iface.origin, abs=1e-9)
    assert iface.stamp_time() == pytest.approx(received, abs=1e-6)


def test_the_arrival_is_the_reception_time_unless_it_is_unknown_or_ahead(iface):
    now = time.time()
    iface._on_state(_state(now, [0, 0], [0, 0]), now - 0.25)
    iface.wait(0.0)
    assert iface.arrival == pytest.approx(now - 0.25 - iface.origin, abs=1e-9)
    for received in (0.0, time.time() + 1.0):  # unknown; a reception in the future
        before = time.time()
        iface._on_state(_state(time.time(), [0, 0], [0, 0]), received)
        after = time.time()
        iface.wait(0.0)
        assert before - iface.origin <= iface.arrival <= after - iface.origin


def test_states_that_arrived_more_than_a_period_ago_are_overdue_except_the_newest(iface):
    now = time.time()
    for k, age in enumerate((1.0, 0.9, 0.8)):
        iface._on_state(_state(now - age, [k, k], [0, 0]), now - age)
    assert iface.wait(0.0) >= 3
    assert iface.overdue == 2  # the newest is the one answered now
    # fresh states are not overdue, and a state half a period old is in time, three
    # periods old is not: judged at the instant the states were written for (the
    # interface's clock held there), not whenever a loaded machine lets this case reach
    # wait() — 2 ms later at a load of 10 would make every "fresh" state late
    now = time.time()
    iface._on_state(_state(now - 0.9 * P, [0, 0], [0, 0]), now - 0.9 * P)
    iface._on_state(_state(now, [0, 0], [0, 0]), now)
    iface.clock = lambda: now - iface.origin
    iface.wait(0.0)
    assert iface.overdue == 0  # 0.9 periods old
    now = time.time()
    iface._on_state(_state(now - 3 * P, [0, 0], [0, 0]), now - 3 * P)
    iface._on_state(_state(now - 0.5 * P, [0, 0], [0, 0]), now - 0.5 * P)
    iface._on_state(_state(now, [0, 0], [0, 0]), now)
    iface.wait(0.0)
    assert iface.overdue == 1
    # (a state judged 1.1 periods after its arrival is late: with 0.9 above, the rule's
    # one period bracketed)
    iface._on_state(_state(now, [0, 0], [0, 0]), now)
    iface._on_state(_state(now + 0.5 * P, [0, 0], [0, 0]), now)
    iface.clock = lambda: now + 1.1 * P - iface.origin
    iface.wait(0.0)
    assert iface.overdue == 1


def test_a_state_is_complete_only_when_every_joint_is_named(iface):
    now = time.time()
    iface._on_state(_state(now, [1.0], [0.1], names=["b"]), now)
    iface._on_state(_state(now, [9.0], [0.0], names=["gripper"]), now)
    assert iface.wait(0.0) == 0 and iface.received == 0 and iface.ignored == 1
    iface._on_state(_state(now, [0.5, 7.0], [0.05, 0.0], names=["a", "gripper"]), now)
    assert iface.wait(0.0) == 1
    np.testing.assert_array_equal(iface.read()[1], [0.5, 1.0])
    np.testing.assert_array_equal(iface.read()[2], [0.05, 0.1])


def test_start_refuses_what_is_not_a_complete_finite_state(ros):
    def fresh(k):
        return RosArmInterface(ros, NAMES, P, f"start_{k}", f"start_cmd_{k}", start_timeout=0.2)

    iface = fresh(0)
    with pytest.raises(ArmError, match=r"no sensor_msgs/JointState on /start_0 within 0\.2 s"):
        iface.start()
    iface = fresh(1)
    iface._on_state(_state(time.time(), [0.0], [0.0], names=["finger"]), 0.0)
    with pytest.raises(ArmError, match=r"the 1 joint states on /start_1 .* \['finger'\]"):
        iface.start()
    iface = fresh(2)
    iface._on_state(_state(time.time(), [0.0], [0.0], names=["a"]), 0.0)
    with pytest.raises(ArmError, match=r"named the robot's joints \['a'\] but never \['b'\]"):
        iface.start()
    iface = fresh(3)
    msg = _state(time.time(), [0.0, 0.0], [0.0, 0.0])
    msg.velocity = []
    iface._on_state(msg, 0.0)
    with pytest.raises(ArmError, match="no finite position and velocity"):
        iface.start()
    iface = fresh(4)
    iface._on_state(_state(time.time(), [0.3, 0.4], [0.0, 0.0]), 0.0)
    iface.start()
    np.testing.assert_array_equal(iface.read()[1], [0.3, 0.4])


def test_states_through_dds_are_taken_with_their_reception_time(ros, iface):
    """A real publisher on the states' topic: the interface takes the messages, merged, in
    order, with a reception time between the send and the take."""
    pub = ros.node.create_publisher(JointState, iface.joint_states_topic, ros.qos(10))
    try:
        deadline = time.monotonic() + 20.0
        while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
            time.sleep(0.01)
        sent = time.time()
        pub.publish(_state(sent, [0.25, 0.5], [1.0, 2.0]))
        count = 0
        while count == 0 and time.monotonic() < deadline:
            count = iface.wait(0.5)
        assert count == 1
        assert iface.stamps == "header"
        np.testing.assert_array_equal(iface.read()[1], [0.25, 0.5])
        np.testing.assert_array_equal(iface.read()[2], [1.0, 2.0])
        assert sent - 1e-3 <= iface.arrival + iface.origin <= time.time()
        assert iface._read_state.decoded_names == 1  # read from its bytes
    finally:
        ros.node.destroy_publisher(pub)


def _wait_for(find, timeout: float = 10.0):
    """``find()`` once it is truthy (the graph's cache fills asynchronously)."""
    deadline = time.monotonic() + timeout
    while not (got := find()) and time.monotonic() < deadline:
        time.sleep(0.02)
    return got


def test_the_topics_qos_as_the_middleware_reports_it(ros, iface):
    """States subscribed best effort and taken serialized; commands published reliable
    (what ros2_control's effort controller subscribes with), read back from the graph."""
    from rclpy.qos import ReliabilityPolicy

    subs = _wait_for(lambda: ros.node.get_subscriptions_info_by_topic(iface.joint_states_topic))
    pubs = _wait_for(lambda: ros.node.get_publishers_info_by_topic(iface.commands_topic))
    assert [s.qos_profile.reliability for s in subs] == [ReliabilityPolicy.BEST_EFFORT]
    assert [p.qos_profile.reliability for p in pubs] == [ReliabilityPolicy.RELIABLE]
    assert iface._sub.raw


def test_the_middleware_default_is_set_before_rclpy_unless_the_user_set_it(ros):
    key = "RMW_FASTRTPS_PUBLICATION_MODE"
    assert os.environ[key] == (_USER_MODE or "SYNCHRONOUS")
    assert ros.middleware == ({} if _USER_MODE else {key: "SYNCHRONOUS"})
    before = os.environ[key]
    os.environ[key] = "ASYNCHRONOUS"  # a user's value: kept by the next node
    try:
        other = RosNode("mode_cases", "", "LOCALHOST", "test")
        try:
            assert other.middleware == {} and os.environ[key] == "ASYNCHRONOUS"
        finally:
            other.close()
    finally:
        os.environ[key] = before


def test_write_publishes_the_torque_in_the_joint_order(iface):
    iface.write(np.array([1.5, -2.5]))
    iface.write([0.0, 3.0])
    assert iface.published == 2
    assert list(iface._cmd.data) == [0.0, 3.0]


# ------------------------------------------------------------ the arm node
@pytest.fixture(scope="module")
def panda():
    from dataclasses import replace

    from hmpc_pin.experiment.build import Experiment
    from hmpc_pin.experiment.config import load_config

    config = load_config("panda_sine")
    return Experiment.from_config(replace(config, ros=replace(config.ros, rate=1000.0)))


def _arm(ros, experiment, gravity=None, limit=None):
    from hmpc_pin.ros.arm import RosArmNode

    k = next(_count)
    return RosArmNode(
        ros,
        experiment.make_plant(1e-3),
        experiment.robot.joint_names,
        experiment.q0,
        experiment.dq0,
        1e-3,
        f"arm_states_{k}",
        f"arm_cmd_{k}",
        limit,
        gravity=gravity,
    )


def _command(values):
    from std_msgs.msg import Float64MultiArray

    msg = Float64MultiArray()
    msg.data = [float(x) for x in values]
    return msg


def _replay(experiment, taus):
    """The plant stepped by hand with the torques ``taus`` (the oracle of the node)."""
    plant = experiment.make_plant(1e-3)
    q, dq = np.array(experiment.q0, dtype=float), np.array(experiment.dq0, dtype=float)
    plant.reset(q, dq, 0.0)
    for tau in taus:
        q, dq = plant.advance(tau(q))
    return q, dq


def test_the_arm_holds_still_until_its_first_command_and_publishes_each_period(ros, panda):
    arm = _arm(ros, panda)
    before = time.time()
    arm.run(0.005)
    assert arm.steps == 5 and arm.commands == 0 and arm.rejected == 0
    np.testing.assert_array_equal(arm.q, panda.q0)  # on its brakes: not stepped
    msg = arm._msg
    stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
    assert before + 5e-3 - 1e-6 <= stamp <= time.time() + 1e-6  # t0 + 5 P
    assert list(msg.name) == list(panda.robot.joint_names)
    np.testing.assert_array_equal(msg.position, panda.q0)
    np.testing.assert_array_equal(msg.effort, np.zeros(7))


def test_the_arm_applies_the_held_command_clipped_and_ignores_malformed_ones(ros, panda):
    limit = np.full(7, 5.0)
    arm = _arm(ros, panda, limit=limit)
    cmd = np.array([9.0, -9.0, 1.0, -1.0, 0.5, 7.0, -0.25])
    arm._on_command(_command(cmd))
    for bad in (cmd[:6], [*cmd[:6], np.nan], [*cmd, 0.0]):
        arm._on_command(_command(bad))  # the last valid command stands
    assert arm.rejected == 3
    arm.run(0.004)
    assert arm.commands == 1 and arm.steps == 4
    applied = np.clip(cmd, -limit, limit)
    np.testing.assert_array_equal(arm.tau, applied)
    np.testing.assert_array_equal(arm._msg.effort, applied)
    q, dq = _replay(panda, [lambda q: applied] * 4)  # held for every period
    np.testing.assert_allclose(arm.q, q, atol=1e-12)
    np.testing.assert_allclose(arm.dq, dq, atol=1e-12)
    np.testing.assert_array_equal(arm._msg.position, arm.q)
    np.testing.assert_array_equal(arm._msg.velocity, arm.dq)


def test_a_command_through_dds_is_read_from_its_bytes_by_the_arm(ros, panda):
    """A real publisher on the arm's command topic: the arm takes it serialized and holds
    its values; one of the wrong length is refused."""
    from std_msgs.msg import Float64MultiArray

    arm = _arm(ros, panda)
    assert arm._sub.raw
    pub = ros.node.create_publisher(Float64MultiArray, arm.commands_topic, ros.qos(10))
    try:
        assert _wait_for(pub.get_subscription_count)
        cmd = np.array([0.5, -1.0, 1.5, -2.0, 2.5, -3.0, 3.25])
        pub.publish(_command(cmd))
        _wait_for(lambda: (arm._take_command(), arm.commands)[1])
        assert arm.commands == 1 and arm.rejected == 0
        np.testing.assert_array_equal(arm._command, cmd)
        pub.publish(_command(cmd[:5]))
        _wait_for(lambda: (arm._take_command(), arm.rejected)[1])
        assert arm.rejected == 1 and arm.commands == 1
        np.testing.assert_array_equal(arm._command, cmd)
    finally:
        ros.node.destroy_publisher(pub)


def test_an_arm_that_adds_gravity_applies_command_plus_g_clipped(ros, panda):
    import pinocchio as pin

    model = panda.plant.model
    zero = np.zeros(7)

    def g(q):
        return np.array(pin.rnea(model, model.createData(), q, zero, zero))

    limit = np.full(7, 30.0)
    arm = _arm(ros, panda, gravity=panda.plant.gravity_torque, limit=limit)
    cmd = np.array([0.5, -0.5, 0.0, 40.0, 0.0, -40.0, 0.1])
    arm._on_command(_command(cmd))
    arm.run(0.003)
    q, dq = _replay(panda, [lambda q: np.clip(cmd + g(q), -limit, limit)] * 3)
    np.testing.assert_allclose(arm.q, q, atol=1e-9)
    np.testing.assert_allclose(arm.dq, dq, atol=1e-9)
    # the effort published: the total of the last period, at its start's position
    q2, _ = _replay(panda, [lambda q: np.clip(cmd + g(q), -limit, limit)] * 2)
    np.testing.assert_allclose(arm.tau, np.clip(cmd + g(q2), -limit, limit), atol=1e-9)
    np.testing.assert_array_equal(arm._msg.effort, arm.tau)  # the total, not the command
    # a zero command holds it: the gravity of the arm's own model
    arm = _arm(ros, panda, gravity=panda.plant.gravity_torque)
    arm._on_command(_command(np.zeros(7)))
    arm.run(0.002)
    q, dq = _replay(panda, [g] * 2)
    np.testing.assert_allclose(arm.q, q, atol=1e-9)


def test_stop_returns_at_the_next_period(ros, panda):
    arm = _arm(ros, panda)
    arm.stop()
    arm.run(None)  # no duration: until stopped
    assert arm.steps == 0


def test_a_late_wake_steps_the_missed_periods_but_never_past_the_duration(ros, panda, monkeypatch):
    """A node descheduled for 20 periods (its sleep returns late): it steps and publishes
    every period it missed, counted late, and still runs round(duration / P) periods."""
    import hmpc_pin.ros.arm as arm_module

    real = arm_module.sleep_until

    class LateWaker:  # the arm's wake at each period, 20 periods late
        def __init__(self, clock, period, spin=None):
            self.clock = clock

        def until(self, deadline):
            real(deadline + 20e-3, self.clock)

    monkeypatch.setattr(arm_module, "Waker", LateWaker)
    arm = _arm(ros, panda)
    sent = []  # every state published: its stamp (recorded at the publisher)
    publish = arm._pub.publish
    arm._pub = SimpleNamespace(
        publish=lambda m: (sent.append(m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec),
                           publish(m))
    )  # fmt: skip
    arm._on_command(_command(np.zeros(7)))
    arm.run(0.005)
    assert arm.steps == 5
    # one state per period, each stamped with its own period's instant t0 + k P
    assert len(sent) == 6
    np.testing.assert_allclose(np.diff(sent), 1e-3, atol=1e-6)
    assert arm.late >= 1 and arm.late <= 4
    q, _ = _replay(panda, [lambda q: np.zeros(7)] * 5)
    np.testing.assert_allclose(arm.q, q, atol=1e-12)


@pytest.mark.parametrize("realtime", [True, False])
def test_the_arm_spins_before_its_periods_only_under_a_realtime_policy(
    ros, panda, monkeypatch, realtime
):
    """Under SCHED_FIFO/RR the arm's Waker chooses its busy-wait from the measured
    wake-ups; otherwise it sleeps the whole wait (no spinning on a shared machine)."""
    import hmpc_pin.ros.arm as arm_module

    made = []

    class Recorded(arm_module.Waker):
        def __init__(self, clock, period, spin=None):
            made.append((period, spin))
            super().__init__(clock, period, spin)

    monkeypatch.setattr(arm_module, "Waker", Recorded)
    monkeypatch.setattr(arm_module, "realtime_policy", lambda: realtime)
    arm = _arm(ros, panda)
    arm.run(0.003)
    assert arm.steps == 3
    assert made == [(1e-3, None if realtime else 0.0)]
