"""The latency-aware step: the observer's torque alignment, the prediction over the
latency, and the latency-free step untouched (``HierarchicalStep.set_latency``,
cpp/src/step.cpp)."""

from __future__ import annotations

import numpy as np
import pytest

import hmpc_pin
from hmpc_pin.compensation.observers import DisturbanceObserver
from hmpc_pin.controllers.hierarchical import MPCSettings
from hmpc_pin.exceptions import ConfigError
from tests.reference.latency import aligned, predict, split
from tests.reference.observers import NumpyNDO

Q0 = np.array([0.3, -0.5, 0.8])


class Recorder:
    """A compensation (called through the step's Compensation port) that records what
    it is fed and estimates a fixed value."""

    def __init__(self, n):
        self.estimate = np.zeros(n)
        self.calls: list[tuple] = []
        self.resets = 0

    def reset(self, q0, dq0):
        self.resets += 1
        self.estimate = np.zeros(len(q0))

    def update(self, M, nle, q, dq, tau, v):
        self.calls.append((q.copy(), dq.copy(), np.array(tau), np.array(v)))
        self.estimate = np.full(len(q), 0.5)
        return self.estimate


def _ref(n=3):
    return hmpc_pin.SineReference(n)


def _states(k, seed=0):
    rng = np.random.default_rng(seed)
    return [(Q0 + 0.05 * rng.standard_normal(3), 0.2 * rng.standard_normal(3)) for _ in range(k)]


def test_split_of_the_latency():
    assert split(0.004, 0.01) == (0, pytest.approx(0.4))
    assert split(0.01, 0.01) == (1, 0.0)
    assert split(0.025, 0.01) == (2, pytest.approx(0.5))


def test_alignment_hand_computed_two_steps(planar3):
    """L = 0.4 Ts: the observer is first advanced at step 2, over [t_1 - L, t_2 - L] =
    [0.6 Ts, 1.6 Ts], which saw τ_0 for 0.4 Ts and τ_1 for 0.6 Ts."""
    Ts, L = 0.01, 0.004
    rec = Recorder(3)
    ctrl = hmpc_pin.HierarchicalMPC(planar3, MPCSettings(Ts=Ts, latency=L), rec)
    ctrl.reset(Q0, np.zeros(3))
    states = _states(3)
    taus, vs = [], []
    for k, (q, dq) in enumerate(states):
        taus.append(ctrl.step(k * Ts, q, dq, _ref()))
        vs.append(ctrl.v.copy())
        if k < 2:  # the interval begins before the start: the observer restarts
            assert rec.calls == []
    assert rec.resets == 1 + 2  # reset, then restarted at steps 0 and 1
    ((q2, _, tau_fed, v_fed),) = rec.calls
    np.testing.assert_array_equal(q2, states[2][0])  # fed the measurement, not the prediction
    np.testing.assert_allclose(tau_fed, 0.4 * taus[0] + 0.6 * taus[1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(tau_fed, aligned(taus, 2, L, Ts), rtol=0, atol=1e-12)
    np.testing.assert_allclose(v_fed, 0.4 * vs[0] + 0.6 * vs[1], rtol=0, atol=1e-12)


@pytest.mark.parametrize("at", ["end", "start"])
@pytest.mark.parametrize("L", [0.004, 0.01, 0.023])
def test_compiled_observer_fed_the_aligned_torque(planar3, L, at):
    """The fused step's NDO against the numpy NDO fed the oracle's aligned torque, with M
    and C q̇ + G at the measured (not the predicted) state: the measurement ending the
    interval (``model_at = "end"``) or the one starting it (``"start"``)."""
    Ts = 0.01
    obs = DisturbanceObserver(3, Ts, 50.0, "chen")
    settings = MPCSettings(Ts=Ts, latency=L, model_at=at)
    ctrl = hmpc_pin.HierarchicalMPC(planar3, settings, obs)
    assert ctrl.fused
    oracle = NumpyNDO(obs.cY, Ts)
    ctrl.reset(Q0, np.zeros(3))
    oracle.reset(np.zeros(3))
    m, alpha = split(L, Ts)
    first = m + 1 + (alpha > 0)
    taus = []
    states = _states(first + 3, seed=1)
    for k, (q, dq) in enumerate(states):
        taus.append(ctrl.step(k * Ts, q, dq, _ref()))
        if k < first:
            oracle.reset(dq)
            expected = np.zeros(3)
        else:
            qm, dqm = states[k - 1] if at == "start" else (q, dq)
            M = planar3.mass_matrix(qm)
            nle = _nle(planar3, qm, dqm)
            expected = oracle.update(M, nle, dq, aligned(taus[:-1], k, L, Ts))
        np.testing.assert_allclose(ctrl.disturbance_estimate, expected, rtol=0, atol=1e-9)


def _nle(robot, q, dq):
    import pinocchio as pin

    return pin.nonLinearEffects(robot.model, robot.data, q, dq)


@pytest.mark.parametrize("L", [0.004, 0.02, 0.027])
def test_prediction_matches_the_oracle(planar3, L):
    Ts = 0.01
    ctrl = hmpc_pin.HierarchicalMPC(planar3, MPCSettings(Ts=Ts, latency=L),
                                    hmpc_pin.NoCompensation(3))  # fmt: skip
    ctrl.reset(Q0, np.zeros(3))
    vs = []
    for k, (q, dq) in enumerate(_states(5, seed=2)):
        ctrl.step(k * Ts, q, dq, _ref())
        q_p, dq_p = predict(q, dq, vs, k, L, Ts)
        np.testing.assert_allclose(ctrl.state[0], q_p, rtol=0, atol=1e-12)
        np.testing.assert_allclose(ctrl.state[1], dq_p, rtol=0, atol=1e-12)
        vs.append(ctrl.v.copy())


class _Stale:
    """Hands the wrapped controller the plant state ``d`` periods old (exact, no noise)
    and records the true states."""

    def __init__(self, controller, d):
        self.controller, self.d = controller, d
        self.true: list = []
        self.predicted: list = []

    Ts = property(lambda self: self.controller.Ts)
    disturbance_estimate = property(lambda self: self.controller.disturbance_estimate)

    def reset(self, q0, dq0):
        self.true = []
        self.controller.reset(q0, dq0)

    def step(self, t, q, dq, reference):
        self.true.append((q.copy(), dq.copy()))
        q_m, dq_m = self.true[max(len(self.true) - 1 - self.d, 0)]
        tau = self.controller.step(t, q_m, dq_m, reference)
        self.predicted.append((self.controller.state[0].copy(), q_m))
        return tau


def test_prediction_against_the_plant(planar3):
    """Two periods of latency, the plant = the model, no disturbance: the predicted state
    is the plant's at t_k to within the change of the real acceleration against v over
    the latency, a small fraction of the stale measurement's offset."""
    Ts, d = 0.01, 2
    ctrl = hmpc_pin.HierarchicalMPC(planar3, MPCSettings(Ts=Ts, latency=d * Ts),
                                    hmpc_pin.NoCompensation(3))  # fmt: skip
    stale = _Stale(ctrl, d)
    ref = hmpc_pin.SineReference(3)
    hmpc_pin.simulate(planar3, stale, ref, duration=1.0, q0=ref.sample(0.0)[0])
    k0 = d + 1  # from here the latency interval lies after the start
    pred = np.array([p for p, _ in stale.predicted[k0:]])
    meas = np.array([m for _, m in stale.predicted[k0:]])
    true = np.array([q for q, _ in stale.true[k0:]])
    stale_err = np.abs(meas - true).max()
    pred_err = np.abs(pred - true).max()
    assert stale_err > 1e-3  # the latency matters here
    assert pred_err < 0.02 * stale_err


def test_latency_free_step_untouched(planar3):
    """L = 0 is the step without latency; a latency far below the resolution of the
    split (the latency path with m = 0, α = 0) gives the same torques to 1e-12, and
    switching a latency off again restores the latency-free step bit for bit. (The run
    starts at its first measurement, as a run does.)"""
    Ts = 0.01
    states = _states(20, seed=3)
    runs = {}
    for name, L in (("none", 0.0), ("tiny", 1e-15), ("off-again", 0.0)):
        obs = DisturbanceObserver(3, Ts, 100.0, "chen")
        ctrl = hmpc_pin.HierarchicalMPC(planar3, MPCSettings(Ts=Ts), obs)
        if name == "tiny":
            ctrl.set_latency(L)
        if name == "off-again":
            ctrl.set_latency(0.03)
            ctrl.set_latency(0.0)
        ctrl.reset(*states[0])
        runs[name] = np.array([ctrl.step(k * Ts, q, dq, _ref())
                               for k, (q, dq) in enumerate(states)])  # fmt: skip
    np.testing.assert_allclose(runs["tiny"], runs["none"], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(runs["off-again"], runs["none"])


def test_negative_latency_is_refused(planar3):
    with pytest.raises(ConfigError, match="latency"):
        MPCSettings(latency=-0.001)
    ctrl = hmpc_pin.HierarchicalMPC(planar3)
    with pytest.raises(ConfigError, match="latency"):
        ctrl.set_latency(float("nan"))


def test_python_dynamics_path_compensates_a_period_of_latency(write_urdf):
    """A mimic joint (M and C q̇ + G from Pinocchio's Python API, the compensation called
    between the compiled halves): a one-period delay unknown to the controller wrecks the
    tracking; declared, the observer is aligned and the state predicted."""
    from tests.test_urdf_joints import three_links

    robot = hmpc_pin.load_robot(write_urdf(three_links(
        j3={"extra": '<mimic joint="j2" multiplier="-0.5" offset="0.1"/>'})))  # fmt: skip
    ref = hmpc_pin.SineReference(robot.nq)
    worst = {}
    for L in (0.0, 0.01):
        ctrl = hmpc_pin.make_controller(robot, hmpc_pin.ControllerConfig(latency=L))
        assert not ctrl.fused
        res = hmpc_pin.simulate(robot, _Stale(ctrl, 1), ref, duration=2.0, q0=ref.sample(0.0)[0])
        worst[L] = np.abs(res.error[res.t >= 1.0]).max()
    assert worst[0.0] > 0.1 and worst[0.01] < 5e-3
