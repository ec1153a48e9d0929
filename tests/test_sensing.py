"""The interface models (hmpc_pin.sim.sensing) against their definitions: the encoder's
quantisation step, the finite difference, the low-pass's step response, the latency, the
torque filter; and the sensed controller in a closed loop."""

from __future__ import annotations

import math

import numpy as np
import pytest

import hmpc_pin
from hmpc_pin.exceptions import ConfigError
from hmpc_pin.experiment.config.sensing import SensingConfig
from hmpc_pin.sim.sensing import (
    Encoder,
    FiniteDifference,
    Latency,
    LowPass,
    SensedController,
    Sensing,
    TorqueFilter,
    lowpass_gain,
)


def test_encoder_quantises_to_its_step(make_rng):
    enc = Encoder(np.array([2.0**19, 4096.0, math.inf]))
    step = 2 * np.pi / np.array([2.0**19, 4096.0])
    q = make_rng(0).uniform(-3, 3, (200, 3))
    out = np.array([enc(x) for x in q])
    # a whole number of steps, within half a step of the truth; the exact joint untouched
    np.testing.assert_allclose(out[:, :2] / step, np.round(out[:, :2] / step), atol=1e-6)
    assert np.all(np.abs(out[:, :2] - q[:, :2]) <= step / 2 + 1e-15)
    np.testing.assert_array_equal(out[:, 2], q[:, 2])
    with pytest.raises(ConfigError, match="encoder_counts"):
        Encoder(np.array([-1.0]))


def test_lowpass_step_response_is_libfrankas():
    """y_i = a x + (1 - a) y_{i-1}, a = T/(T + 1/(2π f_c)): after i samples of a unit step
    from 0, y_i = 1 - (1 - a)^i; for T << 1/f_c that is the continuous 1 - exp(-2π f_c t)."""
    T, fc = 1e-4, 10.0
    lp = LowPass(fc, T)
    a = T / (T + 1 / (2 * np.pi * fc))
    assert lp.gain == pytest.approx(a, rel=1e-15)
    y = np.zeros(1)
    out = []
    for _ in range(2000):
        y = lp.step(y, np.ones(1))
        out.append(y[0])
    i = np.arange(1, 2001)
    np.testing.assert_allclose(out, 1 - (1 - a) ** i, rtol=1e-12)
    np.testing.assert_allclose(out, 1 - np.exp(-2 * np.pi * fc * i * T), atol=2e-3)
    assert lowpass_gain(T, math.inf) == 1.0


class _Probe:
    """A controller that records what it is handed and returns a fixed torque."""

    def __init__(self, n, Ts, tau=None):
        self.n, self._Ts = n, Ts
        self.seen: list = []
        self.tau = np.zeros(n) if tau is None else tau
        self.disturbance_estimate = np.zeros(n)

    @property
    def Ts(self):
        return self._Ts

    def reset(self, q0, dq0):
        self.seen = [(np.array(q0), np.array(dq0))]

    def step(self, t, q, dq, reference):
        self.seen.append((np.array(q), np.array(dq)))
        return self.tau(t) if callable(self.tau) else self.tau


def _feed(wrapper, traj, Ts, K):
    """Feed the wrapper the states of the trajectory ``traj(t) -> (q, dq)`` at t_k."""
    q0, dq0 = traj(0.0)
    wrapper.reset(q0, dq0)
    out = []
    for k in range(K):
        q, dq = traj(k * Ts)
        out.append(wrapper.step(k * Ts, q, dq, None))
    return out


def _sine(t):
    w = 2 * np.pi * 1.3
    return np.array([0.4 * np.sin(w * t)]), np.array([0.4 * w * np.cos(w * t)])


def test_latency_interpolates_the_past_state():
    """A latency of 0.37 Ts: the controller gets q(t - L) (cubic Hermite between the
    control instants: error O(Ts^4 q''''))."""
    Ts, L = 0.01, 0.0037
    probe = _Probe(1, Ts)
    sensed = SensedController(probe, Sensing(rate=100.0, latency=Latency(L)))
    _feed(sensed, _sine, Ts, 60)
    for k, (q, dq) in enumerate(probe.seen[2:], start=1):
        t = k * Ts - L
        q_true, dq_true = _sine(t)
        w = 2 * np.pi * 1.3
        assert abs(q[0] - q_true[0]) < 0.4 * w**4 * Ts**4 / 384 + 1e-15
        assert abs(dq[0] - dq_true[0]) < 0.4 * w**4 * Ts**3 / 10


def test_finite_difference_of_the_quantised_angle():
    """Velocity = (q̃_i − q̃_{i−1}) / T_if of the reported angles, at the interface rate
    (10 samples per control period here), optionally low-passed."""
    Ts, rate = 0.01, 1000.0
    enc = Encoder(np.array([2.0**12]))
    step = 2 * np.pi / 2**12
    for cutoff in (math.inf, 50.0):
        probe = _Probe(1, Ts)
        model = Sensing(rate=rate, encoder=enc, velocity=FiniteDifference(1 / rate, cutoff))
        _feed(SensedController(probe, model), _sine, Ts, 40)
        # the oracle: every interface sample of the true angle, quantised, differenced
        t = np.arange(0, 39 * Ts + 1e-12, 1 / rate)
        qq = step * np.round(0.4 * np.sin(2 * np.pi * 1.3 * t) / step)
        dq = np.diff(qq) * rate
        if cutoff != math.inf:
            a = lowpass_gain(1 / rate, cutoff)
            y, filt = 0.0, []
            for x in dq:
                y = a * x + (1 - a) * y
                filt.append(y)
            dq = np.array(filt)
        for k in range(1, 40):
            q_seen, dq_seen = probe.seen[k + 1]
            i = round(k * Ts * rate)  # sample index of t_k
            assert q_seen[0] == pytest.approx(qq[i], abs=1e-9 * step)
            # the Hermite interpolant may move a sample by one count: one count / T_if
            assert abs(dq_seen[0] - dq[i - 1]) <= 2 * step * rate + 1e-9


def test_torque_filter_holds_the_mean_of_its_samples():
    """A torque step from 0 to 1 at t_1 through a 100 Hz filter at 1 kHz, Ts = 5 ms: the
    plant holds, over each period, the mean of the filter's 5 samples."""
    Ts, rate, fc = 0.005, 1000.0, 100.0
    probe = _Probe(1, Ts, tau=lambda t: np.array([0.0 if t < Ts / 2 else 1.0]))
    sensed = SensedController(probe, Sensing(rate=rate, torque=TorqueFilter(fc, 1 / rate)))
    out = np.array(_feed(sensed, lambda t: (np.zeros(1), np.zeros(1)), Ts, 6))[:, 0]
    a = lowpass_gain(1 / rate, fc)
    y = 1 - (1 - a) ** np.arange(1, 26)  # the filter's samples after the step
    expected = np.concatenate([[0.0], y.reshape(5, 5).mean(axis=1)])
    np.testing.assert_allclose(out, expected, rtol=1e-12, atol=1e-15)


def test_control_period_must_be_whole_interface_periods():
    with pytest.raises(ConfigError, match="interface periods"):
        Sensing(rate=250.0).ticks(0.01)


def test_sensing_config_defaults_and_parts():
    sc = SensingConfig()
    full = sc.model(7)
    assert full.encoder is not None and full.encoder.step[0] == pytest.approx(2 * np.pi / 2**19)
    assert full.velocity is not None and full.velocity.period == pytest.approx(1e-3)
    assert full.latency.seconds == pytest.approx(1e-3) and full.torque is not None
    only = sc.model(7, ("sensing",))
    assert only.latency.seconds == 0 and only.torque is None and only.encoder is not None
    assert sc.model(7, ()).ideal
    with pytest.raises(ConfigError, match="velocity_filter"):
        SensingConfig(velocity="exact", velocity_filter=100.0)
    with pytest.raises(ConfigError, match="encoder_counts"):
        SensingConfig(encoder_counts=[1, 2]).model(3)


def test_sensed_closed_loop_tracks():
    """The paper's arm through the default interface model (with the controller told the
    latency): it tracks to within a few encoder steps' worth of error."""
    cfg = hmpc_pin.load_config("paper_friction")
    exp = hmpc_pin.Experiment.from_config(cfg)
    exp.controller.set_latency(1e-3)
    exp.controller = SensedController(exp.controller, SensingConfig().model(3),
                                      np.random.default_rng(0))  # fmt: skip
    res = exp.run()
    e = res.error[res.t >= 1.0]
    assert np.sqrt(np.mean(e * e, axis=0)).max() < 5e-3


BASE = """
[robot]
urdf = "@URDF@"
[sweep]
"""


def test_sweep_sensing_table_loads(write_config):
    cfg = hmpc_pin.load_config(write_config(BASE + "conditions = ['latency', 'all']\n"
                                            "[sweep.sensing]\nlatency = 0.002\n"
                                            "encoder_counts = [4096, 4096, 0]\n"))  # fmt: skip
    sc = cfg.sweep
    assert sc.conditions == ("latency", "all") and not sc.legacy
    assert sc.interface.latency == 0.002
    model = sc.interface.model(3)
    assert model.encoder is not None and np.isinf(model.encoder.counts[2])
    assert hmpc_pin.load_config(write_config(BASE)).sweep.interface.latency == 0.001


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("[sweep.sensing]\nlatncy = 0.002\n", "sweep.sensing.latncy"),
        ("q_noise = 1e-3\n[sweep.sensing]\nlatency = 0.002\n", "not both"),
        ("conditions = ['noise']\n", "conditions"),
        ("[sweep.sensing]\nlatency = -1.0\n", "latency"),
        ("[sweep.sensing]\nvelocity = 'kalman'\n", "velocity"),
    ],
)
def test_sweep_sensing_bad_input(write_config, text, match):
    with pytest.raises(ConfigError, match=match):
        hmpc_pin.load_config(write_config(BASE + text))


def test_latency_key_applies_to_hmpc_only(write_config):
    with pytest.raises(ConfigError, match="latency"):
        hmpc_pin.load_config(write_config(
            "[robot]\nurdf = '@URDF@'\n[controller]\nkind = 'computed-torque'\nlatency = 0.001\n"
        ))  # fmt: skip
    cfg = hmpc_pin.load_config(write_config("[robot]\nurdf = '@URDF@'\n[controller]\n"
                                            "latency = 0.001\n"))  # fmt: skip
    assert cfg.controller.latency == 0.001


def test_a_run_started_in_motion_is_seen_moving_from_its_first_measurement():
    """An arm at constant velocity v (q = q0 + v t, also before t = 0), a 2.5 ms latency,
    finite-difference velocities at 1 kHz, Ts = 1 ms: every measurement, the first ones
    included, is q0 + v (t_k − L) and v (the angle exactly, the difference of a ramp
    within one encoder count per interface period)."""
    Ts, rate, L = 0.001, 1000.0, 0.0025
    enc = Encoder(np.array([2.0**19]))
    step = 2 * np.pi / 2**19
    q0, v = 0.3, 1.5
    probe = _Probe(1, Ts)
    model = Sensing(rate=rate, encoder=enc, velocity=FiniteDifference(1 / rate),
                    latency=Latency(L))  # fmt: skip
    _feed(SensedController(probe, model), lambda t: (np.array([q0 + v * t]), np.array([v])),
          Ts, 10)  # fmt: skip
    for k, (q_seen, dq_seen) in enumerate(probe.seen[1:]):
        assert abs(q_seen[0] - (q0 + v * (k * Ts - L))) <= 0.5 * step + 1e-12
        assert abs(dq_seen[0] - v) <= step * rate + 1e-9
