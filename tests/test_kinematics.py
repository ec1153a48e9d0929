"""Tests of :mod:`hmpc_pin.model.planar` and :class:`hmpc_pin.tasks.references.QuinticReference`.

The inverse-kinematics answers are checked with Pinocchio's forward kinematics called
directly here (``pin.framesForwardKinematics`` on a fresh ``pin.Data``), not through
the module under test. Poses are the paper's Section 5.4 ones: the tool point (end
of link 3) starts at (1.2, 0.5) with link 3 at −90° to the x axis and ends at
(2.423, 2.234) with link 3 parallel to the x axis; joint limits are Eq (27).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from hmpc_pin.exceptions import ConfigError, DimensionError, HmpcError, NonFiniteError
from hmpc_pin.model.planar import (
    KinematicsError,
    planar_chain,
    planar_ik,
    solve_pose,
    tool_pose,
    workspace_points,
)
from hmpc_pin.model.robot import load_robot
from hmpc_pin.tasks import QuinticReference, sample_horizon

URDF = Path(__file__).resolve().parents[1] / "robots" / "planar3.urdf"
LENGTHS = np.array([1.5, 1.2, 1.0])
Q_LIMIT = np.array([np.pi / 2, np.pi / 2, 3 * np.pi / 4])  # Eq (27), symmetric
START = ((1.2, 0.5), -np.pi / 2)
GOAL = ((2.423, 2.234), 0.0)
POSE_TOL = 1e-6


def fk_pose(robot, q) -> tuple[float, float, float]:
    """Tool (x, z, φ) by Pinocchio FK, independent of hmpc_pin.model.planar."""
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, np.asarray(q, dtype=float))
    m = data.oMf[robot.model.getFrameId("tool")]
    return m.translation[0], m.translation[2], math.atan2(m.rotation[2, 0], m.rotation[0, 0])


def assert_reaches(robot, q, position, angle, tol=POSE_TOL):
    x, z, phi = fk_pose(robot, q)
    assert abs(x - position[0]) < tol and abs(z - position[1]) < tol, (x, z, position)
    assert abs(math.remainder(phi - angle, 2 * math.pi)) < tol, (phi, angle)


def assert_within_limits(robot, q, tol=1e-12):
    assert np.all(q >= robot.lower - tol) and np.all(q <= robot.upper + tol), q


@pytest.fixture(scope="module")
def arm():
    return load_robot(URDF)


def variant(tmp_path, old: str, new: str, count: int = 1):
    """planar3.urdf with one text replacement, loaded."""
    text = URDF.read_text(encoding="utf-8")
    assert text.count(old) >= count
    path = tmp_path / "variant.urdf"
    path.write_text(text.replace(old, new, count), encoding="utf-8")
    return load_robot(path)


# ---------------------------------------------------------------- geometry / FK
def test_planar_chain_reads_lengths_from_the_model(arm):
    np.testing.assert_allclose(planar_chain(arm), LENGTHS, atol=1e-12)
    np.testing.assert_allclose(planar_chain(arm, "tool"), LENGTHS, atol=1e-12)


def test_tool_pose_matches_hand_kinematics(arm):
    rng = np.random.default_rng(3)
    for q in rng.uniform(arm.lower, arm.upper, size=(20, 3)):
        th = np.cumsum(q)
        x, z, phi = tool_pose(arm, q)
        assert x == pytest.approx(LENGTHS @ np.cos(th), abs=1e-12)
        assert z == pytest.approx(LENGTHS @ np.sin(th), abs=1e-12)
        assert math.remainder(phi - th[-1], 2 * math.pi) == pytest.approx(0.0, abs=1e-12)
    # Positive angles lift: q1 = π/2 points the whole arm straight up.
    x, z, phi = tool_pose(arm, [np.pi / 2, 0, 0])
    assert (x, z, phi) == pytest.approx((0.0, LENGTHS.sum(), np.pi / 2), abs=1e-12)


# ---------------------------------------------------------------- paper's poses
def test_paper_start_pose(arm):
    sols = planar_ik(arm, *START)
    assert len(sols) == 1  # the other elbow branch needs q3 ≈ −192.7°, beyond −135°
    for q in sols:
        assert_reaches(arm, q, *START)
        assert_within_limits(arm, q)
    np.testing.assert_allclose(sols[0], [np.pi / 2, -np.pi / 2, -np.pi / 2], atol=1e-12)
    np.testing.assert_allclose(solve_pose(arm, *START), sols[0])


def test_limits_are_inclusive_within_tol(arm):
    """A pose needing q1 a hair beyond its limit is accepted onto the limit within ``tol``."""
    q_out = np.array([np.pi / 2 + 1e-10, -np.pi / 2, -np.pi / 2])
    x, z, phi = fk_pose(arm, q_out)
    (q,) = planar_ik(arm, (x, z), phi)  # default tol = 1e-9 rad
    assert q[0] == arm.upper[0]
    assert_reaches(arm, q, (x, z), phi, tol=1e-9)
    assert planar_ik(arm, (x, z), phi, tol=1e-11) == []
    with pytest.raises(KinematicsError, match="tol"):
        planar_ik(arm, (x, z), phi, tol=-1.0)


def test_paper_goal_pose(arm):
    sols = planar_ik(arm, *GOAL)
    assert len(sols) == 2
    for q in sols:
        assert_reaches(arm, q, *GOAL)
        assert_within_limits(arm, q)
    q_start = solve_pose(arm, *START)
    q_goal = solve_pose(arm, *GOAL, near=q_start)
    assert_reaches(arm, q_goal, *GOAL)
    # The branch nearest the start is elbow-up (q2 < 0), about (3π/8, −π/8, −π/4):
    # the paper's goal is that configuration rounded to three decimals.
    np.testing.assert_allclose(q_goal, [3 * np.pi / 8, -np.pi / 8, -np.pi / 4], atol=2e-3)
    other = next(q for q in sols if not np.allclose(q, q_goal))
    assert np.linalg.norm(q_goal - q_start) < np.linalg.norm(other - q_start)
    # Branch ordering by ``prefer``.
    assert planar_ik(arm, *GOAL, prefer="elbow_up")[0][1] < 0
    assert planar_ik(arm, *GOAL, prefer="elbow_down")[0][1] > 0


def test_goal_outside_workspace_raises_naming_the_pose(arm):
    assert planar_ik(arm, (4.0, 0.0), 0.0) == []
    with pytest.raises(KinematicsError) as exc:
        solve_pose(arm, (4.0, 0.0), 0.0)
    msg = str(exc.value)
    assert "tool (4, 0) with link-3 angle 0°" in msg
    assert "outside the workspace" in msg and "2.7" in msg
    assert isinstance(exc.value, HmpcError) and isinstance(exc.value, ValueError)
    assert exc.value.value == (4.0, 0.0, 0.0)


def test_goal_reachable_only_outside_the_limits_raises(arm):
    # Tool at (−2.5, 0) pointing along −x: both branches need |q1| ≈ 132.8° > 90°.
    pose = ((-2.5, 0.0), np.pi)
    assert planar_ik(arm, *pose) == []
    with pytest.raises(KinematicsError) as exc:
        solve_pose(arm, *pose)
    msg = str(exc.value)
    assert "tool (-2.5, 0) with link-3 angle 180°" in msg
    assert "joint limits" in msg and "joint1" in msg and "elbow_up" in msg and "elbow_down" in msg
    # And such a pose is reachable without limits: the FK of the reported branch.
    assert_reaches(arm, [2.318558, 1.982313, -1.159279], *pose, tol=1e-5)


def test_roundtrip_random_configurations(arm):
    rng = np.random.default_rng(2022)
    for q in rng.uniform(arm.lower, arm.upper, size=(50, 3)):
        x, z, phi = fk_pose(arm, q)
        assert tool_pose(arm, q) == pytest.approx((x, z, phi), abs=1e-12)
        sols = planar_ik(arm, (x, z), phi)
        assert 1 <= len(sols) <= 2
        for s in sols:
            assert_reaches(arm, s, (x, z), phi)
            assert_within_limits(arm, s)
        assert min(np.abs(s - q).max() for s in sols) < 1e-8
        np.testing.assert_allclose(solve_pose(arm, (x, z), phi, near=q), q, atol=1e-8)


def test_flipped_joint_axis_is_supported(tmp_path):
    """Axis +y on joint 2 flips its sign; IK must follow from the model."""
    flipped = variant(
        tmp_path,
        '<origin xyz="1.5 0 0" rpy="0 0 0"/>\n    <axis xyz="0 -1 0"/>',
        '<origin xyz="1.5 0 0" rpy="0 0 0"/>\n    <axis xyz="0 1 0"/>',
    )
    q = np.array([0.4, 0.7, -0.3])  # link-2 absolute angle 0.4 − 0.7
    x, z, phi = fk_pose(flipped, q)
    assert phi == pytest.approx(0.4 - 0.7 - 0.3, abs=1e-12)
    sols = planar_ik(flipped, (x, z), phi)
    assert min(np.abs(s - q).max() for s in sols) < 1e-9


def test_non_planar_arm_is_rejected(tmp_path):
    tilted = variant(
        tmp_path,
        '<origin xyz="1.2 0 0" rpy="0 0 0"/>\n    <axis xyz="0 -1 0"/>',
        '<origin xyz="1.2 0 0" rpy="0 0 0"/>\n    <axis xyz="0 0 1"/>',
    )
    with pytest.raises(KinematicsError, match=r"joint3.*planar 3R arms only"):
        planar_chain(tilted)
    with pytest.raises(KinematicsError, match="planar 3R"):
        planar_ik(tilted, (2.0, 1.0), 0.0)


def test_link_out_of_plane_is_rejected(tmp_path):
    offset = variant(tmp_path, '<origin xyz="1.2 0 0" rpy="0 0 0"/>', '<origin xyz="1.2 0.1 0"/>')
    with pytest.raises(KinematicsError, match="y offset"):
        planar_chain(offset)


def test_bad_arguments(arm):
    with pytest.raises(KinematicsError, match="shape"):
        planar_ik(arm, (1.0, 2.0, 3.0), 0.0)
    with pytest.raises(KinematicsError, match="not finite"):
        planar_ik(arm, (np.nan, 2.0), 0.0)
    with pytest.raises(KinematicsError, match="prefer"):
        planar_ik(arm, *GOAL, prefer="sideways")
    with pytest.raises(KinematicsError, match="frame 'nope'"):
        planar_chain(arm, "nope")
    with pytest.raises(DimensionError):
        solve_pose(arm, *GOAL, near=[0.0, 0.0])


# -------------------------------------------------------------------- workspace
@pytest.mark.parametrize("rng", [None, 7])
def test_workspace_points_within_reach(arm, rng):
    pts = workspace_points(arm, samples=2000, rng=rng)
    assert pts.ndim == 2 and pts.shape[1] == 2
    assert len(pts) == (2000 if rng is not None else round(2000 ** (1 / 3)) ** 3)
    assert np.all(np.hypot(pts[:, 0], pts[:, 1]) <= LENGTHS.sum() + 1e-12)
    if rng is None:
        # The grid contains q = (π/2, −π/2, −π/2), the paper's start pose.
        assert np.min(np.hypot(pts[:, 0] - 1.2, pts[:, 1] - 0.5)) < 1e-12
    np.testing.assert_array_equal(pts, workspace_points(arm, samples=2000, rng=rng))


def test_workspace_points_bad_samples(arm):
    with pytest.raises(KinematicsError, match="samples"):
        workspace_points(arm, samples=1)


# ------------------------------------------------------------- quintic reference
Q0 = np.array([np.pi / 2, -np.pi / 2, -np.pi / 2])
Q1 = np.array([3 * np.pi / 8, -np.pi / 8, -np.pi / 4])


@pytest.fixture
def quintic():
    return QuinticReference(Q0, Q1, t_start=0.5, duration=2.0)


def test_quintic_endpoints_and_flat_ends(quintic):
    for t, q_expected in ((-1.0, Q0), (0.5, Q0), (2.5, Q1), (10.0, Q1)):
        q, dq = quintic.sample(t)
        np.testing.assert_allclose(q, q_expected, atol=1e-15)
        np.testing.assert_allclose(dq, 0.0, atol=1e-15)
        np.testing.assert_allclose(quintic.acceleration(t), 0.0, atol=1e-15)
    q_mid, _ = quintic.sample(1.5)
    np.testing.assert_allclose(q_mid, 0.5 * (Q0 + Q1), atol=1e-15)  # symmetric profile
    assert quintic.t_end == 2.5


def test_quintic_derivatives_match_finite_differences(quintic):
    h = 1e-6
    # Offset from the grid so that no point sits on t_start or t_end, where the jerk
    # jumps and a central difference of the velocity has an O(h) error.
    for t in np.linspace(0.3, 2.7, 25) + 0.013:
        q_p, dq_p = quintic.sample(t + h)
        q_m, dq_m = quintic.sample(t - h)
        _, dq = quintic.sample(t)
        np.testing.assert_allclose(dq, (q_p - q_m) / (2 * h), atol=1e-8)
        np.testing.assert_allclose(quintic.acceleration(t), (dq_p - dq_m) / (2 * h), atol=1e-7)


def test_quintic_sample_many_equals_sample(quintic):
    """The vectorised form (expanded polynomials, products) equals the factored one of
    sample() up to rounding: a few ulp of the O(1) values."""
    times = np.linspace(-0.5, 3.5, 41)
    q, dq = quintic.sample_many(times)
    assert q.shape == dq.shape == (41, 3)
    buffers = (np.full((41, 3), np.nan), np.full((41, 3), np.nan))
    q_out, dq_out = quintic.sample_many(times, buffers)
    assert q_out is buffers[0] and dq_out is buffers[1]
    for k, t in enumerate(times):
        q_k, dq_k = quintic.sample(t)
        for a, b in ((q[k], q_k), (dq[k], dq_k), (q_out[k], q_k), (dq_out[k], dq_k)):
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-14)
    q_h, dq_h = sample_horizon(quintic, times)
    np.testing.assert_array_equal(q_h, q)
    np.testing.assert_array_equal(dq_h, dq)


def test_quintic_rejects_bad_arguments():
    with pytest.raises(DimensionError, match="same shape"):
        QuinticReference([0.0, 1.0], [0.0, 1.0, 2.0], 0.0, 1.0)
    with pytest.raises(NonFiniteError):
        QuinticReference([0.0, np.nan], [0.0, 1.0], 0.0, 1.0)
    with pytest.raises(ConfigError, match="duration"):
        QuinticReference([0.0], [1.0], 0.0, 0.0)


def test_paper_cartesian_move_end_to_end(arm):
    """IK start/goal joined by the quintic: the reference stays within the limits."""
    q_start = solve_pose(arm, *START)
    q_goal = solve_pose(arm, *GOAL, near=q_start)
    ref = QuinticReference(q_start, q_goal, t_start=0.0, duration=5.0)
    q, _ = ref.sample_many(np.linspace(-1.0, 6.0, 701))
    assert np.all(q >= arm.lower - 1e-12) and np.all(q <= arm.upper + 1e-12)
    assert_reaches(arm, q[-1], *GOAL)
    assert_reaches(arm, q[0], *START)
