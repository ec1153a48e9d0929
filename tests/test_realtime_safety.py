"""The stop's parts without a loop: the safe and held-safe torques against Pinocchio's RNEA
(an algorithm the package's G(q) and M(q) do not use), the brake's time constant against
the closed form and scipy's generalized eigenvalues, the settings' validation, and the
gravity-by-the-arm wrapper."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
import scipy.linalg

from hmpc_pin.exceptions import ConfigError
from hmpc_pin.model.robot import load_robot
from hmpc_pin.realtime.safety import (
    STOP_CAUSES,
    GravityByArm,
    SafeTorque,
    SafetySettings,
    brake_time_constant,
)

from .conftest import PLANAR3


@pytest.fixture(scope="module")
def robot():
    return load_robot(PLANAR3)


def _rnea_gravity(robot, q):
    """G(q) = RNEA(q, 0, 0), on a data of its own."""
    model = robot.model
    zero = np.zeros(model.nv)
    return np.array(pin.rnea(model, model.createData(), q, zero, zero))


def _rnea_inertia(robot, q):
    """M(q), column i = RNEA(q, 0, e_i) - G(q)."""
    model = robot.model
    data, zero, g = model.createData(), np.zeros(model.nv), _rnea_gravity(robot, q)
    return np.column_stack(
        [np.array(pin.rnea(model, data, q, zero, e)) - g for e in np.eye(model.nv)]
    )


Q = np.array([0.3, -0.7, 1.1])
DQ = np.array([0.5, -1.5, 2.0])


def test_the_safe_torque_is_gravity_minus_each_joints_damping(robot):
    d = np.array([1.0, 2.0, 3.0])
    safe = SafeTorque(robot, damping=d)
    np.testing.assert_allclose(safe(Q, DQ), _rnea_gravity(robot, Q) - d * DQ, atol=1e-9)
    # the input arrays are not changed (the loop reuses them)
    q, dq = Q.copy(), DQ.copy()
    safe(q, dq)
    np.testing.assert_array_equal(q, Q)
    np.testing.assert_array_equal(dq, DQ)
    # without gravity and without limits: only the damping, G nowhere
    no_g = SafeTorque(robot, damping=d, gravity=False)
    np.testing.assert_allclose(no_g(Q, DQ), -d * DQ, atol=1e-12)


def test_the_inertia_brake_is_minus_m_dq_over_the_brake_time(robot):
    T_b = 0.25
    M = _rnea_inertia(robot, Q)
    G = _rnea_gravity(robot, Q)
    safe = SafeTorque(robot, damping=7.0, brake_time=T_b)  # the damping is not used
    np.testing.assert_allclose(safe(Q, DQ), G - M @ DQ / T_b, atol=1e-8)
    no_g = SafeTorque(robot, brake_time=T_b, gravity=False)
    np.testing.assert_allclose(no_g(Q, DQ), -M @ DQ / T_b, atol=1e-8)


def test_the_limits_clip_the_total_joint_torque(robot):
    """With G(q) in the command the command is clipped to ±L; with the arm adding G(q)
    the total command + G is, so the command is clipped to [-L - G, L - G]."""
    limit = np.array([5.0, 3.0, 1.0])
    G = _rnea_gravity(robot, Q)
    big = 40.0 * DQ  # a brake far beyond the limits on every joint
    with_g = SafeTorque(robot, damping=40.0, effort_limit=limit)
    np.testing.assert_allclose(with_g(Q, DQ), np.clip(G - big, -limit, limit), atol=1e-9)
    no_g = SafeTorque(robot, damping=40.0, effort_limit=limit, gravity=False)
    np.testing.assert_allclose(no_g(Q, DQ), np.clip(-big + G, -limit, limit) - G, atol=1e-9)
    # a brake inside the limits is not clipped (either side)
    small = SafeTorque(robot, damping=1e-3, effort_limit=1e6, gravity=False)
    np.testing.assert_allclose(small(Q, DQ), -1e-3 * DQ, atol=1e-9)
    # one joint limited, the others not (inf): only that joint clipped
    one = SafeTorque(robot, damping=40.0, effort_limit=[np.inf, np.inf, 1.0])
    expected = G - big
    expected[2] = np.clip(expected[2], -1.0, 1.0)
    np.testing.assert_allclose(one(Q, DQ), expected, atol=1e-9)


def test_the_held_safe_torque_is_clipped_gravity_or_zero(robot):
    G = _rnea_gravity(robot, Q)
    assert np.abs(G).max() > 1.0  # the clip below is active
    np.testing.assert_allclose(SafeTorque(robot).held(Q), G, atol=1e-9)
    limit = np.abs(G) / 2 + 0.1
    np.testing.assert_allclose(
        SafeTorque(robot, effort_limit=limit).held(Q), np.clip(G, -limit, limit), atol=1e-9
    )
    np.testing.assert_array_equal(SafeTorque(robot, gravity=False).held(Q), np.zeros(3))
    np.testing.assert_array_equal(
        SafeTorque(robot, gravity=False, effort_limit=limit).held(Q), np.zeros(3)
    )
    # no velocity term: the held torque is the same whatever the (stale) velocity was
    safe = SafeTorque(robot, damping=5.0)
    np.testing.assert_allclose(safe.held(Q), safe(Q, np.zeros(3)), atol=1e-12)


def test_the_safe_torque_in_words(robot):
    assert SafeTorque(robot).describe() == "gravity compensation + damping 2 N·m·s/rad"
    assert SafeTorque(robot, damping=[1, 2.5, 3]).describe() == (
        "gravity compensation + damping [1, 2.5, 3] N·m·s/rad"
    )
    assert SafeTorque(robot, gravity=False, damping=0.5).describe() == "damping 0.5 N·m·s/rad"
    assert SafeTorque(robot, brake_time=0.4).describe() == (
        "gravity compensation + inertia brake M(q) dq / 0.4 s"
    )
    assert SafeTorque(robot, brake_time=0.4, gravity=False).describe() == (
        "inertia brake M(q) dq / 0.4 s"
    )
    assert SafeTorque(robot).describe_held() == "G(q)"
    assert SafeTorque(robot, gravity=False).describe_held() == "zero torque"


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [
        ({"damping": -1.0}, "realtime.damping"),
        ({"damping": [1.0, np.nan, 1.0]}, "realtime.damping"),
        ({"damping": np.inf}, "realtime.damping"),
        ({"brake_time": 0.0}, "realtime.brake_time"),
        ({"brake_time": -0.1}, "realtime.brake_time"),
        ({"brake_time": np.nan}, "realtime.brake_time"),
        ({"brake_time": np.inf}, "realtime.brake_time"),
        ({"effort_limit": 0.0}, "plant.effort_limit"),
        ({"effort_limit": [1.0, -1.0, 1.0]}, "plant.effort_limit"),
        ({"effort_limit": [1.0, np.nan, 1.0]}, "plant.effort_limit"),
    ],
)
def test_bad_safe_torque_settings_name_their_key(robot, kwargs, key):
    with pytest.raises(ConfigError) as info:
        SafeTorque(robot, **kwargs)
    assert info.value.key == key


def test_zero_damping_and_infinite_limits_are_accepted(robot):
    safe = SafeTorque(robot, damping=0.0, effort_limit=np.inf)
    np.testing.assert_allclose(safe(Q, DQ), _rnea_gravity(robot, Q), atol=1e-9)
    assert SafeTorque(robot, brake_time=1e-3).brake_time == 1e-3


def test_the_brake_time_constant_is_the_slowest_mode():
    """Diagonal M: max M_ii/d_i; a full M: the largest generalized eigenvalue of
    M v = λ D v (scipy); a joint without damping never stops (inf)."""
    M = np.diag([4.0, 1.0, 0.5])
    assert brake_time_constant(M, np.array([2.0, 4.0, 0.1])) == pytest.approx(5.0)
    rng = np.random.default_rng(7)
    A = rng.normal(size=(4, 4))
    M = A @ A.T + 0.5 * np.eye(4)
    d = np.array([0.5, 2.0, 1.0, 3.0])
    expected = scipy.linalg.eigh(M, np.diag(d), eigvals_only=True).max()
    assert brake_time_constant(M, d) == pytest.approx(expected, rel=1e-10)
    assert brake_time_constant(M, np.array([0.5, 0.0, 1.0, 3.0])) == np.inf
    assert brake_time_constant(M, np.array([0.5, -1.0, 1.0, 3.0])) == np.inf


@pytest.mark.parametrize("name", ["watchdog", "hold", "brake_speed"])
@pytest.mark.parametrize("value", [-1e-3, np.nan, np.inf, "0.1", None])
def test_bad_safety_settings_name_their_key(name, value):
    inf = np.full(2, np.inf)
    with pytest.raises(ConfigError) as info:
        SafetySettings(-inf, inf, inf, **{name: value})
    assert info.value.key == f"realtime.{name}"
    assert repr(value) in str(info.value)


def test_safety_settings_defaults_zero_and_unlimited():
    s = SafetySettings.unlimited(3, watchdog=0.0, hold=0.0, brake_speed=0.0, max_misses=4)
    assert (s.watchdog, s.hold, s.brake_speed, s.max_misses) == (0.0, 0.0, 0.0, 4)
    np.testing.assert_array_equal(s.lower, np.full(3, -np.inf))
    np.testing.assert_array_equal(s.upper, np.full(3, np.inf))
    np.testing.assert_array_equal(s.velocity, np.full(3, np.inf))
    d = SafetySettings.unlimited(2)
    assert (d.max_misses, d.watchdog, d.hold, d.brake_speed) == (10, 0.01, 0.1, 0.005)
    assert STOP_CAUSES == (
        "interrupted",
        "fault",
        "misses",
        "watchdog",
        "deactivated",
        "reflex",
        "network",
    )


class _Constant:
    """A controller whose torque is a constant (and an attribute of its own)."""

    latency = 3

    def __init__(self, tau):
        self.tau = np.asarray(tau, dtype=float)

    def step(self, t, q, dq, reference):
        return self.tau.copy()


def test_gravity_by_the_arm_sends_the_torque_minus_g_and_forwards_the_rest(robot):
    wrapped = GravityByArm(_Constant([1.0, 2.0, 3.0]), robot)
    np.testing.assert_allclose(
        wrapped.step(0.0, Q, DQ, None), np.array([1.0, 2.0, 3.0]) - _rnea_gravity(robot, Q),
        atol=1e-9,
    )  # fmt: skip
    assert wrapped.latency == 3  # the controller's own attributes
    with pytest.raises(AttributeError):
        _ = wrapped.no_such_attribute
