"""The compiled Reference and Disturbance implementations against numpy oracles (the closed
forms of ``tests/reference/``), the parts that hand over their ports (``loop_port``), and the
chunk hooks of the Measurement port."""

from __future__ import annotations

import numpy as np
import pytest

import hmpc_pin
from hmpc_pin.controllers.wrappers import MeasuredController
from hmpc_pin.native import load as load_native
from hmpc_pin.sim.disturbances import (
    CoulombViscousFriction,
    GaussianPulse,
    TimeOnly,
    ZeroDisturbance,
    disturbance_port,
)
from hmpc_pin.sim.plants import RK4Plant

from .reference import disturbances as oracle
from .reference import sampling

RNG = np.random.default_rng(3)
N = 4


def _sample(port, times):
    q, dq = np.empty((len(times), port.n)), np.empty((len(times), port.n))
    port.sample(np.asarray(times, dtype=float), q, dq)
    return q, dq


def test_the_compiled_sine_is_the_closed_form():
    class Sine:
        omega, phase = RNG.uniform(0.5, 7.0, N), RNG.uniform(-3, 3, N)
        amplitude, offset = RNG.uniform(-1, 1, N), RNG.uniform(-1, 1, N)

    port = load_native().SineReference(
        Sine.omega, Sine.phase, Sine.amplitude, Sine.offset, Sine.amplitude * Sine.omega
    )
    times = RNG.uniform(-5.0, 50.0, 200)
    q, dq = _sample(port, times)
    q_o, dq_o = sampling.sine(Sine, times)
    np.testing.assert_allclose(q, q_o, rtol=0, atol=1e-13)
    np.testing.assert_allclose(dq, dq_o, rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="sine coefficients"):
        load_native().SineReference(np.ones(N), np.ones(N - 1), *(np.ones(N),) * 3)


def test_the_steps_sine_horizon_is_the_closed_form_at_each_offset(planar3):
    # The step samples the sine's horizon by angle addition (sin/cos at t turned by the
    # offsets' angles, computed once): against the closed form at t + o_j, over many steps
    # with the same offsets and long times (|ω t| up to ~600 rad: the closed form's own
    # argument is rounded to ~1e-13 there, the tolerance below).
    ctrl = hmpc_pin.HierarchicalMPC(planar3)
    ref = hmpc_pin.SineReference(
        3, RNG.uniform(-1, 1, 3), RNG.uniform(0.1, 2.0, 3), RNG.uniform(-1, 1, 3),
        RNG.uniform(-3, 3, 3),
    )  # fmt: skip
    ctrl.reset(np.zeros(3), np.zeros(3))
    offsets = ctrl.settings.Ts * np.arange(1, ctrl.settings.N + 1)
    for t in np.r_[0.0, RNG.uniform(-5.0, 50.0, 40)]:
        ctrl.step(float(t), np.zeros(3), np.zeros(3), ref)
        q_o, dq_o = sampling.sine(ref, t + offsets)
        np.testing.assert_allclose(ctrl._data.q_ref, q_o, rtol=0, atol=1e-13)
        np.testing.assert_allclose(ctrl._data.dq_ref, dq_o, rtol=0, atol=1e-12)


def test_the_compiled_piecewise_polynomial_is_the_polynomial_evaluated():
    K, degree = 5, 5
    breakpoints = np.sort(RNG.uniform(0.0, 4.0, K))
    origins = np.r_[0.0, breakpoints]
    coef = RNG.normal(size=((K + 1) * (degree + 1), 2 * N))
    port = load_native().PolynomialReference(breakpoints, origins, coef, degree)
    times = np.r_[RNG.uniform(-1.0, 5.0, 300), breakpoints]  # the breakpoints themselves too
    q, dq = _sample(port, times)
    q_o, dq_o = sampling.ppoly(breakpoints, origins, coef, degree, N, times)
    np.testing.assert_allclose(q, q_o, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(dq, dq_o, rtol=1e-12, atol=1e-12)
    with pytest.raises(ValueError, match="wrong shape"):
        load_native().PolynomialReference(breakpoints, origins[1:], coef, degree)


def test_a_reference_hands_over_the_compiled_port_it_samples_with():
    ref = hmpc_pin.SineReference(N)
    port = ref.loop_port()
    assert port is not None and port is ref.loop_port()  # built once, kept
    times = np.linspace(0.0, 2.0, 7)
    np.testing.assert_array_equal(_sample(port, times)[0], ref.sample_many(times)[0])

    class Shifted(hmpc_pin.SineReference):  # samples otherwise: sampled in Python
        def sample_many(self, times, out=None):
            return super().sample_many(np.asarray(times) + 1.0, out)

    assert Shifted(N).loop_port() is None


def test_the_compiled_pulses_are_eq_33():
    a, b, s = RNG.uniform(-10, 10, N), RNG.uniform(0, 3, N), RNG.uniform(0.05, 0.5, N)
    port = load_native().GaussianPulses(a, b, s)
    times = RNG.uniform(-1.0, 4.0, 100)
    expected = oracle.pulses(a, b, s, times)
    # to the rounding of the exponent k (t - b)², relative to the amplitude
    np.testing.assert_allclose(port.at_times(times, N), expected, rtol=1e-14, atol=1e-14 * 10)
    at = port.at(1.3, np.zeros(N), np.zeros(N))
    np.testing.assert_allclose(at, oracle.pulses(a, b, s, [1.3])[0], rtol=1e-13)
    assert port.kind == "time_only"
    with pytest.raises(ValueError, match="n values each"):
        load_native().GaussianPulses(a, b[:-1], s)


def test_the_compiled_friction_is_eq_32_with_sgn_0_0():
    a, b = RNG.uniform(0, 10, N), RNG.uniform(0, 3, N)
    port = load_native().CoulombViscousFriction(a, b)
    for dq in (RNG.normal(size=N), np.array([0.0, -0.0, 1e-300, -2.0])):
        np.testing.assert_allclose(
            port.at(0.0, np.zeros(N), dq), oracle.friction(a, b, dq), rtol=1e-15, atol=0
        )
    assert port.kind == "friction"
    np.testing.assert_array_equal(port.coefficients[0], a)
    np.testing.assert_array_equal(port.coefficients[1], b)


def test_a_sum_of_compiled_and_python_terms_is_their_sum():
    a, b, s = RNG.uniform(-10, 10, N), RNG.uniform(0, 3, N), np.full(N, 0.3)
    va, vb = RNG.uniform(0, 10, N), RNG.uniform(0, 3, N)
    user = lambda t, q, dq: q * t  # noqa: E731
    d = GaussianPulse(a, b, s) + CoulombViscousFriction(va, vb) + user
    port = disturbance_port(d, N)
    assert port.kind == "general" and len(port.terms) == 3
    t, q, dq = 0.7, RNG.normal(size=N), RNG.normal(size=N)
    expected = oracle.pulses(a, b, s, [t])[0] + oracle.friction(va, vb, dq) + q * t
    np.testing.assert_allclose(port.at(t, q, dq), expected, rtol=1e-13)
    np.testing.assert_allclose(port.at(t, q, dq), d(t, q, dq), rtol=1e-13)
    zero = disturbance_port(ZeroDisturbance(N), N)
    np.testing.assert_array_equal(zero.at(t, q, dq), np.zeros(N))


def test_a_time_only_term_of_the_users_is_asked_once_per_period(planar3):
    """A user's TimeOnly (and a pulse whose sample_times is replaced, e.g. by a spy) keeps
    its Python sampling: the plant calls it with the 3·substeps stage times of a period."""
    asked = []

    class Ramp(TimeOnly):
        def sample_times(self, times):
            asked.append(np.array(times))
            return np.outer(times, np.ones(3))

    pulse = GaussianPulse(np.ones(3), np.ones(3), np.ones(3))
    pulse.sample_times = lambda times: asked.append(np.array(times)) or np.zeros((len(times), 3))
    for term in (Ramp(), pulse):
        asked.clear()
        assert disturbance_port(term, 3).kind == "time_only"
        plant = RK4Plant(planar3.copy(), term, Ts=0.01, dt=0.005)
        plant.reset(np.zeros(3), np.zeros(3), t0=0.2)
        plant.advance(np.zeros(3))
        plant.advance(np.zeros(3))
        assert len(asked) == 2
        h = 0.005
        stage = [0.2, 0.2 + h, 0.2 + 0.5 * h, 0.2 + h + 0.5 * h, 0.2 + h, 0.2 + 2 * h]
        np.testing.assert_allclose(asked[0], stage, rtol=0, atol=1e-15)
    bad = type("Bad", (TimeOnly,), {"sample_times": lambda self, t: np.zeros((len(t), 2))})()
    plant = RK4Plant(planar3.copy(), bad, Ts=0.01)
    plant.reset(np.zeros(3), np.zeros(3))
    with pytest.raises(hmpc_pin.DimensionError, match="sample_times returned"):
        plant.advance(np.zeros(3))


def test_a_plant_with_a_replaced_method_hands_over_no_port(planar3):
    plant = RK4Plant(planar3.copy(), None, 0.01)
    assert plant.loop_port() is plant.port
    plant.advance = lambda tau: None
    assert plant.loop_port() is None


def test_the_measurement_chunk_hooks_leave_the_generator_where_draws_one_by_one_do():
    settings = load_native().SensingSettings()
    settings.exact, settings.q_noise, settings.dq_noise = True, 1e-3, 1e-2
    rngs = [np.random.default_rng(5) for _ in range(2)]
    a, b = (load_native().SensingMeasurement(settings, rng) for rng in rngs)
    q0 = np.zeros(N)
    for port in (a, b):
        port.call_reset(q0, q0)
    a.reserve(10)  # ten steps ahead: the noise of ten measurements drawn at once
    seen_a = [a.hand_over(0.01 * k, q0, q0) for k in range(4)]
    assert rngs[0].bit_generator.state != rngs[1].bit_generator.state
    a.give_back()  # the unused draws given back
    seen_b = [b.hand_over(0.01 * k, q0, q0) for k in range(4)]
    for x, y in zip(seen_a, seen_b, strict=True):
        np.testing.assert_array_equal(x[0], y[0])
        np.testing.assert_array_equal(x[1], y[1])
    assert rngs[0].bit_generator.state == rngs[1].bit_generator.state
    assert a.started and b.started
    a.call_reset(q0, q0)
    assert not a.started


def test_a_measured_controller_hands_over_its_port_unless_its_step_is_replaced(planar3):
    ctrl = MeasuredController(hmpc_pin.HierarchicalMPC(planar3), q_noise=1e-3)
    ctrl.reset(np.zeros(3), np.zeros(3))
    assert ctrl.loop_port(hmpc_pin.SineReference(3)) is not None
    assert not ctrl._started
    ctrl.step(0.0, np.zeros(3), np.zeros(3), hmpc_pin.SineReference(3))
    assert ctrl._started and ctrl.measurement.started
    ctrl.step = lambda *args: np.zeros(3)
    assert ctrl.loop_port(hmpc_pin.SineReference(3)) is None
    timed = hmpc_pin.controllers.wrappers.TimedController(hmpc_pin.HierarchicalMPC(planar3))
    assert timed.loop_port(hmpc_pin.SineReference(3)) is None  # a wrapper: called as a whole


def test_the_chunk_of_earlier_versions_still_imports_with_a_warning():
    from hmpc_pin.sim import plants
    from hmpc_pin.sim.compiled_loop import LOOP_CHUNK

    with pytest.warns(DeprecationWarning, match="LOOP_CHUNK"):
        assert plants.PULSE_CHUNK == LOOP_CHUNK


class _Delegating:
    """A user's wrapper that hands every other attribute on to the part it wraps
    (``__getattr__``) and counts the calls of the one method it wraps."""

    def __init__(self, part, method: str):
        self.part, self.calls = part, 0
        inner = getattr(part, method)

        def counted(*args):
            self.calls += 1
            return inner(*args)

        setattr(self, method, counted)

    def __getattr__(self, name):
        return getattr(self.part, name)


def test_a_delegating_wrapper_hands_on_no_port_so_the_loop_never_goes_around_it(planar3):
    """The port is looked up on the part's class: a wrapper that delegates its other
    attributes (a timer, a logger) is called itself, and the run is the one without it."""
    reference = hmpc_pin.SineReference(3)
    runs = []
    for wrap in (False, True):
        ctrl = hmpc_pin.HierarchicalMPC(planar3)
        plant = RK4Plant(
            planar3.copy(),
            GaussianPulse(np.ones(3), np.full(3, 0.5), 0.1 * np.ones(3)),
            Ts=ctrl.Ts,
            dt=0.001,
        )
        if wrap:
            ctrl, plant = _Delegating(ctrl, "step"), _Delegating(plant, "advance")
        result = hmpc_pin.simulate(
            planar3, ctrl, reference, duration=0.3, q0=np.zeros(3), plant=plant
        )
        runs.append((result, ctrl, plant))
    (plain, _, _), (wrapped, ctrl, plant) = runs
    steps = len(plain.t)
    assert ctrl.calls == steps and plant.calls >= steps - 1  # every period through the wrappers
    np.testing.assert_allclose(wrapped.q, plain.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(wrapped.tau, plain.tau, rtol=0, atol=1e-9)
