"""One conformance test per protocol: every implementation against an independent check.

- Reference: ``sample_many`` (with and without ``out``) equals ``sample`` point by point,
  and both equal the closed form; sample-only objects and callables are adapted once;
  anything else is an :class:`~hmpc_pin.InterfaceError`.
- Compensation: ``reset(q0, dq0)`` gives a zero estimate; ``update`` returns the (n,)
  estimate it stores; on an arm at rest under a constant disturbance every observer's
  estimate converges to it (Eq 18: physics, not a recorded value).
- Plant: ``advance`` moves time by Ts; under gravity compensation τ = G(q) and no
  disturbance an arm at rest stays at rest; ``disturbance_now`` is d at the state.
- Controller: ``Ts``, ``reset``, ``step`` → finite (n,) torque; a closed loop tracks.
- Robot interface: ``read`` → (stamp, q, dq); still until the first torque; at rest under
  gravity compensation while the stamp advances in whole periods.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

import hmpc_pin
from hmpc_pin.compensation import (
    Compensation,
    DisturbanceObserver,
    FeedbackGate,
    IntegralSlidingMode,
    MomentumObserver,
    NoCompensation,
)
from hmpc_pin.controllers import Controller, MeasuredController, TimedController
from hmpc_pin.controllers.wrappers import CollisionReaction, FrictionFeedforward
from hmpc_pin.realtime import PlantArm, ProcessArm, RobotInterface
from hmpc_pin.sim import EulerPlant, Plant, RK4Plant
from hmpc_pin.sim.mujoco import MuJoCoPlant
from hmpc_pin.tasks import QuinticReference, Reference, SineReference, as_reference

N_JOINTS = 3


@pytest.fixture(scope="module")
def robot():
    return hmpc_pin.load_robot("planar3")


def _sine():
    return SineReference(N_JOINTS, amplitude=[1.0, 0.5, 0.2], frequency=[0.1, 0.3, 0.7],
                         offset=[0.1, -0.2, 0.3], phase=[0.0, 1.0, 2.0])  # fmt: skip


def _closed_form(t):
    a = np.array([1.0, 0.5, 0.2])
    w = 2 * np.pi * np.array([0.1, 0.3, 0.7])
    o, p = np.array([0.1, -0.2, 0.3]), np.array([0.0, 1.0, 2.0])
    t = np.asarray(t)[:, None]
    return o + a * np.sin(w * t + p), a * w * np.cos(w * t + p)


class _SampleOnly:
    def sample(self, t):
        q, dq = _closed_form([t])
        return q[0], dq[0]


class _ManyNoOut:
    def sample_many(self, times):
        return _closed_form(times)


REFERENCES = {
    "sine": _sine,
    "sample-only object": lambda: as_reference(_SampleOnly()),
    "callable": lambda: as_reference(lambda t: tuple(a[0] for a in _closed_form([t]))),
    "sample_many without out": lambda: as_reference(_ManyNoOut()),
}


@pytest.mark.parametrize("name", sorted(REFERENCES))
def test_reference_conformance(name):
    ref = REFERENCES[name]()
    assert isinstance(ref, Reference)
    times = np.linspace(0.0, 3.0, 11)
    q, dq = ref.sample_many(times)
    q_cf, dq_cf = _closed_form(times)
    np.testing.assert_allclose(q, q_cf, rtol=0, atol=1e-14)
    np.testing.assert_allclose(dq, dq_cf, rtol=0, atol=1e-14)
    for k, t in enumerate(times):
        q1, dq1 = ref.sample(float(t))
        np.testing.assert_allclose(q1, q_cf[k], rtol=0, atol=1e-14)
        np.testing.assert_allclose(dq1, dq_cf[k], rtol=0, atol=1e-14)
    out = (np.full((11, N_JOINTS), np.nan), np.full((11, N_JOINTS), np.nan))
    got = ref.sample_many(times, out)
    np.testing.assert_allclose(out[0], q_cf, rtol=0, atol=1e-14)
    np.testing.assert_allclose(out[1], dq_cf, rtol=0, atol=1e-14)
    np.testing.assert_array_equal(got[0], out[0])


def test_quintic_conformance_against_finite_differences():
    ref = QuinticReference([0.0, 1.0], [1.0, -1.0], 0.5, 2.0)
    assert isinstance(ref, Reference)
    times = np.linspace(0.0, 3.0, 31)
    q, dq = ref.sample_many(times)
    h = 1e-6
    qp, _ = ref.sample_many(times + h)
    qm, _ = ref.sample_many(times - h)
    np.testing.assert_allclose(dq, (qp - qm) / (2 * h), atol=1e-7)
    np.testing.assert_allclose(q[0], [0.0, 1.0], atol=0)
    np.testing.assert_allclose(q[-1], [1.0, -1.0], atol=1e-15)


def _pose_reference():
    from hmpc_pin.tasks.pose import CirclePath, PoseReference, frame_pose, plane_axes

    robot = hmpc_pin.load_robot("planar3")
    q0 = np.array([0.3, 0.6, -0.9])
    p0, R0 = frame_pose(robot, robot.tool_frame, q0)
    u, v = plane_axes("xz")  # the planar arm's plane; orientation held
    return PoseReference.solve(
        robot, robot.tool_frame, CirclePath(p0[0] - 0.05 * u, 0.05, 0.2, u, v, R0[0]), 3.5, q0
    )


TASK_REFERENCES = {
    "trajectory (cubic spline)": lambda: hmpc_pin.JointTrajectory(
        np.linspace(0.0, 3.0, 13), _closed_form(np.linspace(0.0, 3.0, 13))[0]),
    "trajectory (quintic Hermite)": lambda: hmpc_pin.JointTrajectory(
        np.linspace(0.0, 3.0, 13), *_closed_form(np.linspace(0.0, 3.0, 13))),
    "waypoints (TOPP-RA)": lambda: hmpc_pin.retime_waypoints(
        np.array([[0.0, 0.0, 0.0], [0.5, -0.3, 0.2], [0.1, 0.4, -0.2]]), 1.0, 2.0),
    "pose (pink IK)": _pose_reference,
}  # fmt: skip


@pytest.mark.parametrize("name", sorted(TASK_REFERENCES))
def test_task_reference_conformance(name):
    """The references of the tasks layer: sample_many (with and without out) equals
    sample point by point, and the velocity is the derivative of the position (central
    finite differences, an independent computation)."""
    ref = TASK_REFERENCES[name]()
    assert isinstance(ref, Reference) and as_reference(ref) is ref
    times = np.linspace(-0.5, 4.0, 46)
    q, dq = ref.sample_many(times)
    n = q.shape[1]
    for k, t in enumerate(times):
        q1, dq1 = ref.sample(float(t))
        np.testing.assert_allclose(q1, q[k], rtol=0, atol=1e-14)
        np.testing.assert_allclose(dq1, dq[k], rtol=0, atol=1e-14)
    out = (np.full((46, n), np.nan), np.full((46, n), np.nan))
    got = ref.sample_many(times, out)
    assert got is out
    np.testing.assert_array_equal(out[0], q)
    np.testing.assert_array_equal(out[1], dq)
    h = 1e-6
    inner = times[(times > 0.05) & (times < 2.9)]
    fd = (ref.sample_many(inner + h)[0] - ref.sample_many(inner - h)[0]) / (2 * h)
    np.testing.assert_allclose(ref.sample_many(inner)[1], fd, atol=1e-6)
    assert ref.acceleration(1.0).shape == (n,)


def test_anything_else_is_an_interface_error_naming_what_is_missing():
    with pytest.raises(hmpc_pin.InterfaceError, match="sample_many"):
        as_reference(42)


def test_a_sample_only_reference_drives_the_controller_like_the_sine(robot):
    """The controller adapts a sample-only object once; same torques as the sine."""
    a, b = hmpc_pin.HierarchicalMPC(robot), hmpc_pin.HierarchicalMPC(robot)
    q0 = _closed_form([0.0])[0][0]
    for c in (a, b):
        c.reset(q0, np.zeros(N_JOINTS))
    sine, only = _sine(), _SampleOnly()
    for t in (0.0, 0.01, 0.02):
        np.testing.assert_allclose(
            a.step(t, q0, np.zeros(3), sine), b.step(t, q0, np.zeros(3), only), atol=1e-9
        )


COMPENSATIONS = {
    "chen": lambda r: DisturbanceObserver(r.nq, 0.01, 100.0, "chen"),
    "general": lambda r: DisturbanceObserver(r.nq, 0.01, 100.0, "general"),
    "momentum": lambda r: MomentumObserver(r, 0.01, 50.0),
    "ism": lambda r: IntegralSlidingMode(r.nq, 0.01, 200.0),
    "ism-bl": lambda r: IntegralSlidingMode(r.nq, 0.01, 200.0, 2.0),
    "none": lambda r: NoCompensation(r.nq),
    "gate(chen)": lambda r: FeedbackGate(DisturbanceObserver(r.nq, 0.01, 100.0, "chen")),
}


@pytest.mark.parametrize("name", sorted(COMPENSATIONS))
def test_compensation_conformance(robot, name):
    comp = COMPENSATIONS[name](robot)
    assert isinstance(comp, Compensation)
    rng = np.random.default_rng(3)
    q0 = rng.uniform(-1, 1, N_JOINTS)
    comp.reset(q0, np.zeros(N_JOINTS))
    np.testing.assert_array_equal(comp.estimate, np.zeros(N_JOINTS))
    # At rest under a constant disturbance d, the torque that holds the arm is
    # tau = G - d (M q̈ + n = tau + d with q̈ = 0): every observer's estimate → d.
    d = np.array([2.0, -1.0, 0.5])
    M, nle = robot.mass_matrix(q0), robot.nonlinear_effects(q0, np.zeros(N_JOINTS))
    tau = nle - d
    for _ in range(300):
        est = comp.update(M, nle, q0, np.zeros(N_JOINTS), tau, np.zeros(N_JOINTS))
        assert est.shape == (N_JOINTS,)
        np.testing.assert_array_equal(est, comp.estimate)
    if name in ("chen", "general", "momentum"):
        np.testing.assert_allclose(comp.estimate, d, atol=1e-6)
    else:  # ISM and none do not estimate d at rest without motion error
        assert np.all(np.isfinite(comp.estimate))


PLANTS = {"rk4": RK4Plant, "euler": EulerPlant, "mujoco": MuJoCoPlant}
#: Variants run by the conformance test: each plant.
PLANT_VARIANTS = {"rk4": RK4Plant, "euler": EulerPlant, "mujoco": MuJoCoPlant}


@pytest.mark.parametrize("name", sorted(PLANT_VARIANTS))
def test_plant_conformance(robot, name):
    kind = name.split("-")[0]
    plant = PLANT_VARIANTS[name](robot.copy(), None, 0.01, 0.001)
    assert isinstance(plant, Plant)
    assert hmpc_pin.sim.PLANTS[kind] is PLANTS[kind]
    q0 = np.array([0.3, -0.4, 0.2])
    plant.reset(q0, np.zeros(3), t0=1.0)
    G = robot.gravity_torque(q0)
    for k in range(1, 51):
        q, dq = plant.advance(G)
        assert plant.t == pytest.approx(1.0 + 0.01 * k, abs=1e-12)
    # no disturbance: gravity compensation holds the arm at rest (ABA(q, 0, G(q)) = 0)
    np.testing.assert_allclose(q, q0, atol=1e-9)
    np.testing.assert_allclose(dq, 0.0, atol=1e-9)
    d = hmpc_pin.CoulombViscousFriction([1.0, 1.0, 1.0], [0.1, 0.1, 0.1])
    plant = PLANT_VARIANTS[name](robot.copy(), d, 0.01, 0.001)
    plant.reset(q0, np.array([0.5, -0.5, 1.0]))
    np.testing.assert_allclose(plant.disturbance_now(), d(0.0, q0, np.array([0.5, -0.5, 1.0])))


def test_simulate_drives_a_plant_object_and_rejects_options_it_does_not_take(robot):
    ctrl = hmpc_pin.HierarchicalMPC(robot)
    ref = SineReference(3)
    q0 = ref.sample(0.0)[0]
    plant = EulerPlant(robot.copy(), None, 0.01, 0.001)
    res = hmpc_pin.simulate(robot, ctrl, ref, duration=1.0, q0=q0, plant=plant)
    assert res.complete and np.abs(res.error[-1]).max() < 0.05
    with pytest.raises(hmpc_pin.ConfigError, match="dt"):
        hmpc_pin.simulate(robot, ctrl, ref, duration=0.1, q0=q0, plant=plant, dt=0.002)


CONTROLLERS = {
    "hmpc+chen": lambda r: hmpc_pin.make_controller(r),
    "hmpc+momentum": lambda r: hmpc_pin.make_controller(
        r, hmpc_pin.ControllerConfig(compensation="momentum")
    ),
    "hmpc+none": lambda r: hmpc_pin.make_controller(
        r, hmpc_pin.ControllerConfig(compensation="none")
    ),
    "computed-torque+momentum": lambda r: hmpc_pin.make_controller(
        r, hmpc_pin.ControllerConfig(kind="computed-torque", compensation="momentum")
    ),
    "measured": lambda r: MeasuredController(hmpc_pin.make_controller(r)),
    "timed": lambda r: TimedController(hmpc_pin.make_controller(r)),
    "sensed": lambda r: _sensed(r),
    "hmpc+chen latency 4 ms": lambda r: hmpc_pin.make_controller(
        r, hmpc_pin.ControllerConfig(latency=0.004)
    ),
    "hmpc+momentum latency 12 ms": lambda r: hmpc_pin.make_controller(
        r, hmpc_pin.ControllerConfig(compensation="momentum", latency=0.012)
    ),
    "collision": lambda r: CollisionReaction(hmpc_pin.make_controller(r), 1e3, "stop"),
    # a friction model fed forward on a frictionless plant: the observer cancels it
    "friction-feedforward": lambda r: FrictionFeedforward(
        hmpc_pin.make_controller(r), [1.0, 0.8, 0.5], [0.3, 0.2, 0.1]
    ),
}


def _sensed(robot):
    from hmpc_pin.experiment.config.sensing import SensingConfig
    from hmpc_pin.sim.sensing import SensedController

    ctrl = hmpc_pin.make_controller(robot, hmpc_pin.ControllerConfig(latency=0.001))
    return SensedController(ctrl, SensingConfig().model(robot.nq), np.random.default_rng(0))


@pytest.mark.parametrize("name", sorted(CONTROLLERS))
def test_controller_conformance(robot, name):
    if name.endswith("-native") and not hmpc_pin.native.available():
        pytest.skip("native kernels unavailable here (tests/test_native.py says why)")
    ctrl = CONTROLLERS[name](robot)
    assert isinstance(ctrl, Controller)
    assert ctrl.Ts == 0.01
    ref = SineReference(3)
    q0 = ref.sample(0.0)[0]
    res = hmpc_pin.simulate(robot, ctrl, ref, duration=2.0, q0=q0)
    assert res.tau.shape == (201, 3) and np.all(np.isfinite(res.tau))
    # no disturbance: the loop tracks the 0.1 Hz sine (MPC bandwidth ≈ 16 rad/s)
    assert np.abs(res.error[100:]).max() < 0.01


def _interface_plant(kind="rk4", period=0.001):
    return PLANTS[kind](hmpc_pin.load_robot("planar3"), None, period, period)


class _Clock:
    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now

    def wait(self, seconds):
        self.now += seconds


def _wall_wait(seconds):
    import time

    time.sleep(seconds)


INTERFACES = {
    "in-process plant": lambda q0: (lambda c: (PlantArm(_interface_plant(), q0, clock=c), c.wait))(
        _Clock()
    ),
    "arm process": lambda q0: (ProcessArm(_interface_plant, q0), _wall_wait),
    # any Plant can be the arm: MuJoCo's, built in the arm's process
    "arm process (mujoco)": lambda q0: (
        ProcessArm(functools.partial(_interface_plant, "mujoco"), q0),
        _wall_wait,
    ),
}


@pytest.mark.parametrize("name", sorted(INTERFACES))
def test_robot_interface_conformance(robot, name):
    """read → (stamp, q, dq); the arm holds still until the first torque; under gravity
    compensation τ = G(q0) it stays at rest (ABA(q0, 0, G(q0)) = 0) while its stamp
    advances in whole periods; close is idempotent."""
    if "mujoco" in name:
        pytest.importorskip("mujoco", reason="mujoco is not installed (pip install -e '.[mujoco]')")
    q0 = np.array([0.3, -0.4, 0.2])
    arm, wait = INTERFACES[name](q0)
    try:
        assert isinstance(arm, RobotInterface)
        assert arm.nq == 3 and arm.period == 0.001
        stamp0, q, dq = arm.read()
        assert isinstance(stamp0, float) and q.shape == dq.shape == (3,)
        np.testing.assert_array_equal(q, q0)
        wait(0.05)
        np.testing.assert_array_equal(arm.read()[1], q0)  # on its brakes
        arm.write(robot.gravity_torque(q0))
        wait(0.1)
        stamp, q, dq = arm.read()
        assert stamp >= stamp0 + 0.05
        assert stamp / 0.001 == pytest.approx(round(stamp / 0.001), abs=1e-6)
        np.testing.assert_allclose(q, q0, atol=1e-9)
        np.testing.assert_allclose(dq, 0.0, atol=1e-9)
        # a torque moves it: zero torque, the arm falls (ABA(q0, 0, 0) = -M⁻¹G ≠ 0)
        arm.write(np.zeros(3))
        wait(0.05)
        assert np.abs(arm.read()[1] - q0).max() > 1e-4
    finally:
        arm.close()
        arm.close()
