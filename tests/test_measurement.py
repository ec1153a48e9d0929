"""The Measurement port (``cpp/include/hmpc/interfaces.hpp``): one conformance test for its
compiled implementations and a Python subclass, numpy oracles of the compiled interface
model written from its equations (quantisation, finite difference of a known signal, delay
by whole periods, noise statistics, the torque filter's step response), and a Python
measurement running inside the compiled loop."""

from __future__ import annotations

import contextlib
import math

import numpy as np
import pytest

import hmpc_pin
from hmpc_pin.controllers.wrappers import MeasuredController
from hmpc_pin.sim import sensing as s
from hmpc_pin.sim.plants import RK4Plant

from .reference import sensing as oracle
from .reference.loop import per_step

N = 3
TS = 0.01


class Quantised(s.Measurement):
    """A measurement written in Python: the angle on a grid of ``step`` [rad], the
    velocity as is, both one control period old; the torque as commanded."""

    def __init__(self, step: float):
        super().__init__()
        self.step, self.inputs = step, []

    def reset(self, q0, dq0):
        self.last = (self.step * np.round(q0 / self.step), dq0.copy())
        return self.last

    def measure(self, t, q, dq):
        self.inputs.append((t, q.copy(), dq.copy()))
        older, self.last = self.last, (self.step * np.round(q / self.step), dq.copy())
        return older


def _plain(delay: int = 0, q_noise: float = 0.0, dq_noise: float = 0.0, seed: int = 0):
    rng = np.random.default_rng(seed)
    ctrl = MeasuredController(_Probe(), q_noise=q_noise, dq_noise=dq_noise, delay=delay, rng=rng)
    return ctrl.measurement


def _sensing(**kw):
    model = s.Sensing(**kw)
    return model.compiled(TS, np.random.default_rng(0))


class _Probe:
    """A controller that records what it is handed and commands ``tau(t)``."""

    Ts = TS

    def __init__(self, tau=lambda t: np.zeros(N)):
        self.seen, self.tau = [], tau
        self.disturbance_estimate = np.zeros(N)

    def reset(self, q0, dq0):
        self.seen = [(np.array(q0), np.array(dq0))]

    def step(self, t, q, dq, reference):
        self.seen.append((np.array(q), np.array(dq)))
        return self.tau(t)


#: Each implementation of the port, and the age of what it hands over [s] (the controller
#: is told it: the MPC is not stable against a whole period it does not know of).
PORTS = {
    "plain": (lambda: _plain(delay=1, q_noise=1e-4, dq_noise=1e-3), TS),
    "sensing": (
        lambda: _sensing(
            rate=1000.0,
            encoder=s.Encoder(2.0**16),
            velocity=s.FiniteDifference(1e-3, 200.0),
            latency=s.Latency(0.001),
            noise=s.WhiteNoise(1e-5, 1e-4),
            torque=s.TorqueFilter(100.0, 1e-3),
        ),
        0.001,
    ),
    "python": (lambda: Quantised(1e-3), TS),
}


@pytest.mark.parametrize("name", sorted(PORTS))
def test_measurement_conformance(planar3, name):
    """Every implementation: a port instance; reset and measure hand over (q, dq) of n
    finite values; command returns n torques; behind a MeasuredController the paper's arm
    (its controller told the measurement's age) runs in the compiled loop and tracks its
    sine (MPC bandwidth about 16 rad/s)."""
    make, age = PORTS[name]
    port = make()
    assert isinstance(port, s.Measurement)
    q0, dq0 = np.full(N, 0.3), np.full(N, -0.1)
    for pair in (port.call_reset(q0, dq0), port.call_measure(TS, q0 + 0.01, dq0)):
        assert len(pair) == 2 and all(v.shape == (N,) and np.isfinite(v).all() for v in pair)
    for a, b in zip(port.current, pair, strict=True):
        np.testing.assert_array_equal(a, b)
    assert port.call_command(np.ones(N)).shape == (N,)
    inner = hmpc_pin.make_controller(planar3, hmpc_pin.ControllerConfig(latency=age))
    ctrl = MeasuredController(inner, measurement=make())
    ref = hmpc_pin.SineReference(N)
    result = hmpc_pin.simulate(planar3, ctrl, ref, duration=2.0, q0=ref.sample(0.0)[0])
    assert result.loop == "compiled" and result.complete
    assert np.abs(result.error[100:]).max() < 0.01


@pytest.mark.parametrize(
    "latency, rate, delay, cutoff",
    [(0.0, 100.0, 0, math.inf), (0.0037, 1000.0, 1, math.inf), (0.023, 500.0, 2, 60.0)],
)
def test_the_compiled_interface_model_equals_its_spline_oracle(latency, rate, delay, cutoff):
    """Random smooth states at the control instants through the compiled model (encoder,
    finite difference and its filter, a latency of a fraction or several periods, noise,
    delay) against tests/reference/sensing.py (SciPy's cubic Hermite spline): equal to the
    rounding of the interpolation (1e-12 on the angle; the velocity's difference divides
    that by T_if)."""
    rng = np.random.default_rng(8)
    K = 40
    t = TS * np.arange(K + 1)[:, None]
    w, phase, amp = rng.uniform(1, 8, N), rng.uniform(0, 6, N), rng.uniform(0.2, 1.0, N)
    q, dq = amp * np.sin(w * t + phase), amp * w * np.cos(w * t + phase)
    counts = np.array([2.0**14, 2.0**18, np.inf])
    sigma = (1e-4, 1e-3)
    model = s.Sensing(
        rate=rate,
        encoder=s.Encoder(counts),
        velocity=s.FiniteDifference(1 / rate, cutoff),
        latency=s.Latency(latency),
        noise=s.WhiteNoise(*sigma),
        delay=s.PeriodDelay(delay),
    )
    port = model.compiled(TS, np.random.default_rng(4))
    seen = [port.call_reset(q[0], dq[0])] + [
        port.call_measure(k * TS, q[k], dq[k]) for k in range(1, K + 1)
    ]
    expected = oracle.handed_over(
        TS,
        q,
        dq,
        rate=rate,
        latency=latency,
        step=2 * np.pi / counts,
        difference=True,
        gain=s.lowpass_gain(1 / rate, cutoff),
        noise=np.random.default_rng(4).standard_normal((K + 1, 2 * N)),
        sigma=sigma,
        delay=delay,
    )
    for k, ((q_m, v_m), (q_x, v_x)) in enumerate(zip(seen, expected, strict=True)):
        np.testing.assert_allclose(q_m, q_x, rtol=0, atol=1e-12, err_msg=f"q at step {k}")
        np.testing.assert_allclose(v_m, v_x, rtol=0, atol=1e-12 * rate, err_msg=f"dq at {k}")


def test_quantisation_is_the_grid_nearest_the_angle():
    """q̃ = Δ round(q/Δ), Δ = 2π/N, at the control instants (no latency): the angles of
    a known ramp, each on the grid and within Δ/2 of the true angle."""
    counts = np.array([2.0**10, 2.0**12, np.inf])
    port = _sensing(rate=100.0, encoder=s.Encoder(counts))
    delta = 2 * np.pi / counts
    speed = np.array([0.37, -0.91, 0.2])
    seen = [port.call_reset(np.zeros(N), speed)[0]]
    for k in range(1, 40):
        seen.append(port.call_measure(k * TS, speed * k * TS, speed)[0])
    q_true = speed * TS * np.arange(40)[:, None]
    seen = np.array(seen)
    grid = delta[:2] * np.round(q_true[:, :2] / delta[:2])
    np.testing.assert_allclose(seen[:, :2], grid, rtol=0, atol=1e-12)
    assert np.all(np.abs(seen[:, :2] - q_true[:, :2]) <= delta[:2] / 2 + 1e-12)
    np.testing.assert_allclose(seen[:, 2], q_true[:, 2], rtol=0, atol=1e-15)


def test_finite_difference_of_a_parabola_through_a_latency_is_exact():
    """q(t) = c t² from rest (q = 0 before the start): the cubic Hermite interpolant of
    the control instants is exact, so at t_k the interface reports
    q(t_k − L) and (q(t_k − L) − q(t_k − L − T_if))/T_if, low-passed by
    y_i = a x_i + (1 − a) y_{i−1} over every interface sample (numpy recursion)."""
    c = np.array([1.5, -0.7, 3.0])
    rate, L, fc = 1000.0, 0.0025, 80.0
    Tif = 1 / rate
    port = _sensing(rate=rate, latency=s.Latency(L), velocity=s.FiniteDifference(Tif, fc))

    def q_of(t):
        return c * max(t, 0.0) ** 2

    seen = [port.call_reset(np.zeros(N), np.zeros(N))]
    K = 30
    for k in range(1, K):
        t = k * TS
        seen.append(port.call_measure(t, q_of(t), 2 * c * t))
    a = hmpc_pin.sim.sensing.lowpass_gain(Tif, fc)
    m = round(TS * rate)
    y = np.zeros(N)  # the first sample: the interpolant's velocity at -L, at rest
    expected = [(q_of(-L), y.copy())]
    for k in range(1, K):
        for i in range(m - 1, -1, -1):
            t = k * TS - L - i * Tif
            x = (q_of(t) - q_of(t - Tif)) / Tif
            y = a * x + (1 - a) * y
        expected.append((q_of(k * TS - L), y.copy()))
    for (q, dq), (q_x, dq_x) in zip(seen, expected, strict=True):
        np.testing.assert_allclose(q, q_x, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(dq, dq_x, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("delay", [0, 1, 4])
def test_a_delay_of_d_periods_hands_over_the_state_d_periods_old(delay):
    """Measurement handed over at t_k = state at t_max(0, k−d)."""
    port = _plain(delay=delay)
    states = [(np.full(N, 1.0 * k), np.full(N, -2.0 * k)) for k in range(15)]
    seen = [port.call_reset(*states[0])]
    seen += [port.call_measure(k * TS, *states[k]) for k in range(1, 15)]
    for k, (q, dq) in enumerate(seen):
        np.testing.assert_array_equal(q, states[max(0, k - delay)][0])
        np.testing.assert_array_equal(dq, states[max(0, k - delay)][1])


def test_noise_is_the_generators_stream_with_the_stated_statistics():
    """2n draws of the seeded generator per measurement (the angles' first): the noise
    is q̃ − q; over 4000 measurements its mean is 0 and its standard deviation σ, to five
    standard errors (σ/√M and σ/√(2M))."""
    sq, sdq, M = 2e-3, 5e-2, 4000
    port = _plain(q_noise=sq, dq_noise=sdq, seed=5)
    q, dq = np.linspace(-1, 1, N), np.linspace(2, 3, N)
    seen = [port.call_reset(q, dq)] + [port.call_measure(k * TS, q, dq) for k in range(1, M)]
    noise = np.array([np.concatenate(pair) - np.r_[q, dq] for pair in seen])
    oracle = np.random.default_rng(5).standard_normal((M, 2 * N)) * np.repeat([sq, sdq], N)
    np.testing.assert_allclose(noise, oracle, rtol=1e-9, atol=1e-15)
    for part, sigma in ((noise[:, :N], sq), (noise[:, N:], sdq)):
        assert np.all(np.abs(part.mean(axis=0)) < 5 * sigma / math.sqrt(M))
        assert np.all(np.abs(part.std(axis=0) / sigma - 1) < 5 / math.sqrt(2 * M))


def test_torque_filter_step_response_in_closed_form():
    """A command of τ0 then τ1 from the second step: the filter starts settled at τ0,
    y_i = τ1 + (τ0 − τ1)(1 − a)^i, and the plant holds the mean of the m samples of each
    period, τ1 + (τ0 − τ1)(1 − a)^(m(j−1)+1) (1 − (1 − a)^m)/(m a) over period j."""
    rate, fc = 1000.0, 100.0
    port = _sensing(rate=rate, torque=s.TorqueFilter(fc, 1 / rate))
    port.call_reset(np.zeros(N), np.zeros(N))
    tau0, tau1 = np.array([1.0, -2.0, 0.5]), np.array([3.0, 0.0, -1.0])
    a, m = hmpc_pin.sim.sensing.lowpass_gain(1 / rate, fc), round(TS * rate)
    np.testing.assert_array_equal(port.call_command(tau0), tau0)
    for j in range(1, 8):
        held = port.call_command(tau1)
        decay = (1 - a) ** (m * (j - 1) + 1) * (1 - (1 - a) ** m) / (m * a)
        np.testing.assert_allclose(held, tau1 + (tau0 - tau1) * decay, rtol=1e-12, atol=1e-12)


class _Recording(Quantised):
    """The Python port above, keeping what it hands over too."""

    def measure(self, t, q, dq):
        out = super().measure(t, q, dq)
        self.outputs.append((out[0].copy(), out[1].copy()))
        return out


def test_a_python_measurement_runs_inside_the_compiled_loop(planar3):
    """The Python port above is called by the compiled loop with the plant's state at
    every t_k (k >= 1: the recorded trajectory), it hands over what the numpy oracle
    makes of the state one period earlier (Δ round(q_{k-1}/Δ), q̇_{k-1}), and the run
    equals the per-step loop's bit for bit (where the wrapper hands the controller what
    the port returns)."""
    results, ports = [], []
    for loop in ("compiled", "python"):
        port = _Recording(2e-3)
        port.outputs = []
        ctrl = MeasuredController(hmpc_pin.HierarchicalMPC(planar3), measurement=port)
        plant = RK4Plant(planar3.copy(), None, ctrl.Ts)
        ref = hmpc_pin.SineReference(N)
        with per_step() if loop == "python" else contextlib.nullcontext():
            res = hmpc_pin.simulate(
                planar3, ctrl, ref, duration=1.0, q0=np.full(N, 0.2), plant=plant
            )
        assert res.loop == {"python": "per-step"}.get(loop, loop) and res.complete
        results.append(res)
        ports.append(port)
    res, port = results[0], ports[0]
    K = len(res.t) - 1
    assert len(port.inputs) == K
    for k, (t, q, dq) in enumerate(port.inputs, start=1):
        assert t == res.t[k]
        np.testing.assert_array_equal(q, res.q[k])
        np.testing.assert_array_equal(dq, res.dq[k])
    for k, (q, dq) in enumerate(port.outputs, start=1):
        np.testing.assert_allclose(q, 2e-3 * np.round(res.q[k - 1] / 2e-3), rtol=0, atol=1e-15)
        np.testing.assert_array_equal(dq, res.dq[k - 1])
    for name in ("q", "dq", "tau", "d_hat", "tau_applied"):
        np.testing.assert_array_equal(getattr(results[1], name), getattr(res, name))


def test_a_python_command_filters_the_torque_in_the_compiled_loop(planar3):
    """command(tau) of a Python port is the torque recorded and applied."""

    class Halved(Quantised):
        def command(self, tau):
            return 0.5 * tau

    results = []
    for loop in ("compiled", "python"):
        ctrl = MeasuredController(hmpc_pin.HierarchicalMPC(planar3), measurement=Halved(1e-9))
        ref = hmpc_pin.SineReference(N)
        with per_step() if loop == "python" else contextlib.nullcontext():
            res = hmpc_pin.simulate(planar3, ctrl, ref, duration=0.3, q0=np.full(N, 0.2))
        results.append(res)
    np.testing.assert_array_equal(results[0].tau, results[1].tau)
    np.testing.assert_array_equal(results[0].tau_applied, results[0].tau)


def test_a_python_measurement_that_returns_the_wrong_shape_is_named(planar3):
    class Short(Quantised):
        def measure(self, t, q, dq):
            return q[:2], dq

    ctrl = MeasuredController(hmpc_pin.HierarchicalMPC(planar3), measurement=Short(1e-3))
    with pytest.raises(hmpc_pin.SimulationError) as info:
        ref = hmpc_pin.SineReference(N)
        hmpc_pin.simulate(planar3, ctrl, ref, duration=0.1, q0=np.zeros(N))
    assert isinstance(info.value.__cause__, hmpc_pin.DimensionError)
    assert "Measurement.measure" in str(info.value)


def test_options_that_do_not_apply_to_a_port_of_your_own_are_errors():
    with pytest.raises(hmpc_pin.ConfigError, match="do not apply"):
        MeasuredController(_Probe(), q_noise=0.1, measurement=Quantised(1e-3))
    with pytest.raises(hmpc_pin.ConfigError, match="subclass of"):
        MeasuredController(_Probe(), measurement=object())


def test_a_port_that_does_not_define_measure_is_refused_before_the_run():
    class Half(s.Measurement):
        def reset(self, q0, dq0):
            return q0, dq0

    with pytest.raises(hmpc_pin.ConfigError, match="does not define measure"):
        MeasuredController(_Probe(), measurement=Half())


def test_a_python_subclass_of_the_compiled_model_is_refused():
    """Its overrides would be called per step but not by the compiled loop."""

    class Spy(hmpc_pin.native.load().SensingMeasurement):
        def measure(self, t, q, dq):
            return q, dq

    settings = hmpc_pin.native.load().SensingSettings()
    settings.exact = True
    with pytest.raises(hmpc_pin.ConfigError, match="subclass Measurement instead"):
        MeasuredController(_Probe(), measurement=Spy(settings, None))
