"""The Franka command filter against a numpy oracle written from the FCI's rules, the
quintic move against its closed form, and the checks before a motion (no robot needed)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hmpc_pin.exceptions import ArmError, NonFiniteError
from hmpc_pin.realtime.franka import (
    FRANKA_TORQUE_LIMIT,
    MAX_STEP,
    CommandFilter,
    check_joint_names,
    check_mass,
    check_move,
    quintic,
    quintic_duration,
)


def _oracle(requests, tau_J_d, limit, step, ramp):
    """Element by element in plain Python: ramp-in scale, then |tau - tau_J_d| <= step and
    |tau - previous| <= step (where both can hold), then |tau| <= limit."""
    out = []
    for k, (tau, last) in enumerate(zip(requests, tau_J_d, strict=True)):
        row = []
        for i in range(len(tau)):
            x = tau[i] * min(1.0, k / ramp)
            lo, hi = last[i] - step, last[i] + step
            if k > 0:
                p = out[-1][i]
                if max(lo, p - step) <= min(hi, p + step):
                    lo, hi = max(lo, p - step), min(hi, p + step)
            x = max(lo, min(hi, x))
            x = max(-limit[i], min(limit[i], x))
            row.append(x)
        out.append(row)
    return np.array(out)


def test_filter_matches_the_oracle_and_the_fci_rules():
    rng = np.random.default_rng(3)
    f = CommandFilter(FRANKA_TORQUE_LIMIT, ramp=20)
    requests = rng.normal(0.0, 60.0, (300, 7))
    sent, last, tau_J_d = [], np.zeros(7), []
    for tau in requests:
        tau_J_d.append(last.copy())
        cmd = f(tau, last).copy()
        sent.append(cmd)
        # the robot received it, or (one cycle in five) the state came before it did
        last = cmd if len(sent) % 5 else tau_J_d[-1] + rng.normal(0.0, 0.3, 7)
    sent = np.array(sent)
    np.testing.assert_allclose(
        sent, _oracle(requests, tau_J_d, FRANKA_TORQUE_LIMIT, MAX_STEP, 20), rtol=0, atol=1e-12
    )
    assert np.all(sent[0] == 0.0)  # the first command is zero
    assert np.abs(np.diff(sent, axis=0)).max() <= MAX_STEP + 1e-12
    assert np.all(np.abs(sent) <= FRANKA_TORQUE_LIMIT)
    assert np.abs(sent).max() > 10.0  # it does pass large torques, after the ramp


def test_filter_refuses_non_finite_and_ramps_to_zero():
    f = CommandFilter(FRANKA_TORQUE_LIMIT)
    with pytest.raises(NonFiniteError):
        f(np.array([0, 0, math.nan, 0, 0, 0, 0.0]), np.zeros(7))
    last = np.array([5.0, -0.5, 0.2, 0, 0, 0, -3.0])
    steps = 0
    while np.abs(last).max() > 0:
        nxt = f.toward_zero(last).copy()
        assert np.abs(nxt - last).max() <= MAX_STEP + 1e-12
        last, steps = nxt, steps + 1
    assert steps == math.ceil(5.0 / MAX_STEP)


def test_quintic_peaks_match_the_closed_form():
    delta = np.array([0.8, -0.3, 0.0, 0.5, 0, 0, 0])
    v, a = np.full(7, 0.5), np.full(7, 1.0)
    T = quintic_duration(delta, v, a)
    t = np.linspace(0.0, T, 20001)
    q = np.array([quintic(np.zeros(7), delta, T, x) for x in t])
    dq = np.gradient(q, t, axis=0)
    ddq = np.gradient(dq, t, axis=0)
    assert np.abs(dq).max() <= 0.5 * (1 + 1e-3)
    assert np.abs(ddq).max() <= 1.0 * (1 + 1e-2)
    # the binding bound is reached (the shortest T)
    assert max(np.abs(dq).max() / 0.5, np.abs(ddq).max() / 1.0) > 0.99
    np.testing.assert_allclose(q[-1], delta)


def test_checks_name_the_joint():
    with pytest.raises(ArmError, match="joint3"):
        check_joint_names(["joint1", "joint2", "elbow", "joint4", "joint5", "joint6", "joint7"])
    M = np.diag([1.0, 2, 1, 1, 0.05, 0.05, 0.01])
    wrong = M.copy()
    wrong[5, 5] *= 1.5
    with pytest.raises(ArmError, match="'j6'"):
        check_mass(wrong, M, [f"j{i + 1}" for i in range(7)])
    assert check_mass(M, M, [f"j{i + 1}" for i in range(7)]).max() == 0.0
    with pytest.raises(ArmError, match="'j2'"):
        names = [f"j{i + 1}" for i in range(7)]
        check_move(np.zeros(7), np.array([0, 1.2, 0, 0, 0, 0, 0]), 1.0, names)
