"""The compiled loop (hmpc_pin.sim.compiled_loop) against the per-step loop of
tests/reference/loop.py, its oracle: the same arrays on every shipped config, the same
faults and partial results, the same state of the parts afterwards, for every kind of part
(compiled or called through a port)."""

from __future__ import annotations

import contextlib
import copy
import signal
import threading
import warnings

import numpy as np
import pytest

import hmpc_pin
from hmpc_pin.compensation.base import step_compensation
from hmpc_pin.compensation.gate import FeedbackGate
from hmpc_pin.controllers.wrappers import CollisionReaction, MeasuredController, TimedController
from hmpc_pin.experiment.build import Experiment
from hmpc_pin.native import replaced
from hmpc_pin.sim.compiled_loop import LOOP_CHUNK
from hmpc_pin.sim.disturbances import CoulombViscousFriction, GaussianPulse
from hmpc_pin.sim.plants import EulerPlant, RK4Plant

from .conftest import CONFIGS
from .reference.loop import per_step

ARRAYS = ("t", "q", "dq", "tau", "d", "d_hat", "tau_applied", "q_ref", "dq_ref")
TOL = 1e-12
LOOP_NAMES = {"python": "per-step", "compiled": "compiled"}

# Shipped configs the compiled loop covers (the MuJoCo ones run per step: below).
COMPILED = [
    "panda_circle", "panda_sine", "panda_trajectory", "paper_cartesian",
    "paper_cartesian_no_ndo", "paper_combined", "paper_combined_no_ndo", "paper_external",
    "paper_external_no_ndo", "paper_friction", "paper_friction_literal",
    "paper_friction_literal_no_ndo", "paper_friction_no_ndo", "ur5_circle", "ur5_sine",
    "z1_sine",
]  # fmt: skip
SLOW = {"panda_circle", "panda_trajectory", "ur5_circle"}


def _experiment(name: str) -> Experiment:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return Experiment.from_config(hmpc_pin.load_config(CONFIGS / f"{name}.toml"))


def _same(a, b, what: str = "") -> None:
    """Every array of two results equal to TOL (absolute and relative)."""
    assert len(a.t) == len(b.t), (what, len(a.t), len(b.t))
    for name in ARRAYS:
        x, y = getattr(a, name), getattr(b, name)
        assert x.shape == y.shape, (what, name)
        np.testing.assert_allclose(y, x, rtol=TOL, atol=TOL, err_msg=f"{what} {name}")


def _controller_state(ctrl) -> list:
    """What a HierarchicalMPC carries to its next step (compiled step, QPs, observer)."""
    core = ctrl._core.state
    state = [
        np.array(core[1]),
        *map(np.array, core[2]),
        *map(np.array, core[3]),
        np.array(core[4]),
        np.array(core[5]),
        core[0],
        core[6],
        ctrl._started,
        copy.copy(ctrl.qps._core.stats),
        ctrl.v.copy(),
        ctrl.tau.copy(),
        ctrl.disturbance_estimate.copy(),
        ctrl._data.stack.copy(),
        ctrl.qps.solution.copy(),
        ctrl.qps.slack.copy(),
    ]
    decoded = step_compensation(ctrl.compensation)
    if decoded.compiled and decoded.port is not None:
        state += list(decoded.port.state)
    return state


def _assert_same_state(a, b) -> None:
    for x, y in zip(_controller_state(a), _controller_state(b), strict=True):
        if isinstance(x, np.ndarray):
            np.testing.assert_allclose(y, x, rtol=TOL, atol=TOL)
        else:
            assert x == y


def _loop(loop: str):
    """``"python"``: the per-step oracle loop (tests/reference/loop.py) within the block;
    otherwise the package's (compiled) loop."""
    return per_step() if loop == "python" else contextlib.nullcontext()


def _run(exp: Experiment, loop: str, duration: float):
    try:
        with _loop(loop):
            return exp.run(duration), None
    except hmpc_pin.SimulationError as exc:
        return exc.result, exc


def _both(make, duration: float, **sim):
    """Run the same setup (``make()`` -> (robot, controller, reference, plant)) per step
    and compiled through simulate; return the two (result, exception, parts)."""
    out = []
    for loop in ("python", "compiled"):
        robot, ctrl, ref, plant = make()
        try:
            with _loop(loop):
                res = hmpc_pin.simulate(robot, ctrl, ref, duration=duration, plant=plant, **sim)
            exc = None
        except hmpc_pin.SimulationError as e:
            res, exc = e.result, e
        out.append((res, exc, (robot, ctrl, ref, plant)))
    return out


@pytest.mark.parametrize(
    "name", [pytest.param(n, marks=pytest.mark.slow) if n in SLOW else n for n in COMPILED]
)
def test_compiled_loop_equals_the_per_step_loop_on_each_shipped_config(name):
    """1 s of each config: the same arrays, the same end, the same controller state (its
    next step gives the same torque)."""
    a, b = _experiment(name), _experiment(name)
    ra, ea = _run(a, "python", 1.0)
    rb, eb = _run(b, "compiled", 1.0)
    assert ra.loop == "per-step" and rb.loop == "compiled"
    assert (ea is None) == (eb is None) and ra.complete == rb.complete
    _same(ra, rb, name)
    assert ra.meta.get("saturation") == rb.meta.get("saturation")
    _assert_same_state(a.controller, b.controller)
    t, q, dq = float(ra.t[-1]) + a.controller.Ts, ra.q[-1], ra.dq[-1]
    np.testing.assert_allclose(
        b.controller.step(t, q, dq, b.reference),
        a.controller.step(t, q, dq, a.reference),
        rtol=TOL,
        atol=TOL,
    )


@pytest.mark.slow
def test_the_paper_run_is_the_same_over_its_10_s():
    a, b = _experiment("paper_combined"), _experiment("paper_combined")
    with per_step():
        ra = a.run()
    _same(ra, b.run(), "paper_combined 10 s")


def _paper(*, pulse=None, friction=True, effort=None, delay=None, settings=None):
    """A factory of the paper's arm, controller, sine reference and RK4 plant."""

    def make():
        robot = hmpc_pin.load_robot(CONFIGS.parent / "robots" / "planar3.urdf")
        ctrl = hmpc_pin.HierarchicalMPC(robot, settings)
        terms = [GaussianPulse(*pulse)] if pulse is not None else []
        if friction:
            terms.append(CoulombViscousFriction([10.0, 8.0, 5.0], [3.0, 2.4, 1.8]))
        dist = hmpc_pin.sim.SumDisturbance(*terms) if terms else None
        plant = RK4Plant(robot.copy(), dist, ctrl.Ts)
        if delay is not None:
            ctrl = MeasuredController(ctrl, q_noise=1e-3, dq_noise=1e-2, delay=delay,
                                      rng=np.random.default_rng(7))  # fmt: skip
        return robot, ctrl, hmpc_pin.SineReference(3), plant

    return make


def _same_fault(pair) -> None:
    (ra, ea, _), (rb, eb, _) = pair
    assert ea is not None and eb is not None
    assert type(ea) is type(eb) and str(ea) == str(eb)
    assert type(ea.__cause__) is type(eb.__cause__)
    assert ra.message == rb.message and ra.complete == rb.complete is False
    assert ra.meta["failed_step"] == rb.meta["failed_step"]
    assert ra.meta["failed_at"] == rb.meta["failed_at"]
    _same(ra, rb, str(ea))


@pytest.mark.parametrize("delay", [0, 1, 3])
def test_behind_a_measured_controller_the_noise_stream_and_delay_are_the_same(delay):
    """Noise drawn per chunk equals the wrapper's draw per step; afterwards its generator
    and its port's measurement are where the per-step loop leaves them."""
    (ra, _, pa), (rb, _, pb) = _both(
        _paper(pulse=([10.0, 8.0, 0.3], [0.3, 0.6, 0.9], [0.1] * 3), delay=delay),
        1.0,
        q0=np.ones(3),
    )
    assert rb.loop == "compiled"
    _same(ra, rb)
    wa, wb = pa[1], pb[1]
    assert wa.rng.bit_generator.state == wb.rng.bit_generator.state
    for a, b in zip(wa.measurement.current, wb.measurement.current, strict=True):
        np.testing.assert_array_equal(b, a)
    for j in range(delay + 1):  # the delay lines hold the same measurements
        t, q, dq = float(ra.t[-1]) + (j + 1) * 0.01, ra.q[-1] + j, ra.dq[-1] - j
        seen_a = wa.measurement.call_measure(t, q, dq)
        seen_b = wb.measurement.call_measure(t, q, dq)
        for a, b in zip(seen_a, seen_b, strict=True):
            np.testing.assert_array_equal(b, a)
    _assert_same_state(wa.controller, wb.controller)


def test_a_fault_behind_a_measured_controller_leaves_its_generator_where_per_step_does():
    """The compiled loop draws a chunk's noise at once: a fault mid-chunk gives back the
    draws of the steps not begun."""
    pulse = ([3e3, 0.0, 0.0], [0.5] * 3, [0.05] * 3)
    pair = _both(_paper(pulse=pulse, delay=1), 1.0, q0=np.ones(3), state_bound=20.0)
    _same_fault(pair)
    assert pair[0][0].meta["failed_step"] % LOOP_CHUNK != 0
    wa, wb = pair[0][2][1], pair[1][2][1]
    assert wa.rng.bit_generator.state == wb.rng.bit_generator.state


def test_a_sensed_controller_runs_compiled_with_the_per_step_loops_arrays():
    """The interface model of hmpc_pin.sim.sensing (encoder, finite difference, latency,
    noise, delay, torque filter) is a compiled port: the run goes through the compiled
    loop, with the per-step loop's arrays and generator."""
    from hmpc_pin.experiment.config.sensing import SensingConfig
    from hmpc_pin.sim.sensing import SensedController

    def make():
        robot, ctrl, ref, plant = _paper(pulse=([10.0, 8.0, 0.3], [0.3] * 3, [0.1] * 3))()
        model = SensingConfig(q_noise=1e-4, dq_noise=1e-3, delay=1).model(3)
        return robot, SensedController(ctrl, model, np.random.default_rng(3)), ref, plant

    (ra, _, pa), (rb, _, pb) = _both(make, 1.0, q0=np.ones(3))
    assert rb.loop == "compiled" and ra.loop == "per-step"
    _same(ra, rb)
    assert pa[1].rng.bit_generator.state == pb[1].rng.bit_generator.state


class _NoisyDisturbance:
    """A disturbance written in Python, d = 0.5 sin(3t) − 0.2 q̇ + 0.01 ε with its own
    random stream: the values depend on the order and number of its calls."""

    def __init__(self):
        self.rng, self.calls = np.random.default_rng(2), 0

    def __call__(self, t, q, dq):
        self.calls += 1
        return 0.5 * np.sin(3 * t) * np.ones(3) - 0.2 * dq + 0.01 * self.rng.standard_normal(3)


def test_a_callable_disturbance_is_called_by_the_compiled_loop_as_by_the_per_step_loop():
    """Through the Disturbance port: once per step for the record and at each of the 4
    stages of every substep of a period, in the per-step loop's order (same arrays, same
    stream)."""

    def make():
        robot = hmpc_pin.load_robot(CONFIGS.parent / "robots" / "planar3.urdf")
        ctrl = hmpc_pin.HierarchicalMPC(robot)
        plant = RK4Plant(robot.copy(), _NoisyDisturbance(), ctrl.Ts)
        return robot, ctrl, hmpc_pin.SineReference(3), plant

    (ra, _, pa), (rb, _, pb) = _both(make, 1.0, q0=np.ones(3))
    assert ra.loop == "per-step" and rb.loop == "compiled" and rb.complete
    _same(ra, rb)
    K, substeps = len(ra.t) - 1, pa[3].substeps
    assert pa[3].disturbance.calls == pb[3].disturbance.calls == (K + 1) + 4 * substeps * K
    assert pb[3].k == K and np.array_equal(pb[3].q, pa[3].q)


def test_an_on_step_callback_is_called_by_the_compiled_loop_as_by_the_per_step_loop():
    """Once per recorded step, with t_k, the plant's state and the reference sampled at
    t_k (recorded as the result's q_ref), as the per-step loop calls it."""
    seen = {}

    def make(loop):
        def on_step(t, q, q_ref):
            seen[loop].append((float(t), np.array(q), np.array(q_ref)))

        seen[loop] = []
        return on_step

    results = {}
    for loop in ("python", "compiled"):
        robot, ctrl, ref, plant = _paper()()
        kw = dict(duration=1.0, plant=plant, q0=np.ones(3), on_step=make(loop))
        with _loop(loop):
            results[loop] = hmpc_pin.simulate(robot, ctrl, ref, **kw)
    ra, rb = results["python"], results["compiled"]
    assert rb.loop == "compiled"
    _same(ra, rb)
    assert len(seen["compiled"]) == len(rb.t)
    for k, (t, q, q_ref) in enumerate(seen["compiled"]):
        assert t == rb.t[k]
        np.testing.assert_array_equal(q, rb.q[k])
        np.testing.assert_array_equal(q_ref, rb.q_ref[k])
        np.testing.assert_array_equal(q_ref, seen["python"][k][2])


def test_effort_saturation_is_counted_the_same():
    pair = _both(_paper(), 1.0, q0=np.ones(3), effort_limit=np.array([20.0, 5.0, np.inf]))
    (ra, _, _), (rb, _, _) = pair
    assert ra.meta["saturation"]["steps"][1] > 0
    assert ra.meta["saturation"] == rb.meta["saturation"]
    _same(ra, rb)


def test_a_non_finite_state_stops_both_loops_at_the_same_step():
    pair = _both(_paper(pulse=([1e308] * 3, [0.5] * 3, [0.002] * 3)), 1.0, q0=np.ones(3),
                 state_bound=np.inf)  # fmt: skip
    _same_fault(pair)
    assert "plant state" in str(pair[0][1]) and pair[0][0].meta["failed_step"] > 10


def test_a_state_beyond_the_bound_stops_both_loops_at_the_same_step():
    pair = _both(_paper(pulse=([3e3, 0.0, 0.0], [0.5] * 3, [0.05] * 3)), 1.0, q0=np.ones(3),
                 state_bound=20.0)  # fmt: skip
    _same_fault(pair)
    assert "diverged" in str(pair[0][1])


def test_a_qp_failure_stops_both_loops_at_the_same_step():
    """Started on the reference, then pushed off it until the acceleration bounds are
    active: ProxSuite with 3 iterations allowed fails (a SolverError) mid-run."""
    settings = hmpc_pin.MPCSettings(max_iter=3, Nc=3, v_min=-30.0, v_max=30.0)
    q0, dq0 = hmpc_pin.SineReference(3).sample(0.0)
    pair = _both(_paper(pulse=([3e3, 0.0, 0.0], [0.5] * 3, [0.05] * 3), settings=settings),
                 1.0, q0=q0, dq0=dq0)  # fmt: skip
    _same_fault(pair)
    assert isinstance(pair[0][1].__cause__, hmpc_pin.SolverError)
    assert pair[0][0].meta["failed_step"] > 10


class _InterruptingPulse(GaussianPulse):
    """A pulse whose values of the periods from ``at`` on (the plant asks for a period's
    stage times at once, through the pulse's Python port: its sample_times is its own) are
    made with a Ctrl-C (SIGINT) delivered to the process: the same instant of both loops
    (before step ``at``'s disturbance is recorded)."""

    def __init__(self, at_time):
        super().__init__([1.0] * 3, [0.5] * 3, [0.1] * 3)
        self.at_time = at_time

    def sample_times(self, times):
        if times.size > 1 and times.min() >= self.at_time - 1e-9:
            signal.raise_signal(signal.SIGINT)
        return super().sample_times(times)


def test_a_ctrl_c_between_chunks_keeps_the_same_partial_result():
    at = 2 * LOOP_CHUNK

    def make():
        robot, ctrl, ref, _ = _paper()()
        plant = RK4Plant(robot.copy(), _InterruptingPulse(at * ctrl.Ts), ctrl.Ts)
        return robot, ctrl, ref, plant

    out = []
    for loop in ("python", "compiled"):
        robot, ctrl, ref, plant = make()
        with pytest.raises(hmpc_pin.RunInterrupted) as info, _loop(loop):
            hmpc_pin.simulate(robot, ctrl, ref, duration=5.0, q0=np.ones(3), plant=plant)
        out.append(info.value)
    a, b = out
    assert str(a) == str(b) and a.result.message == b.result.message
    assert len(a.result.t) == at
    assert a.result.meta["interrupted_at"] == b.result.meta["interrupted_at"]
    _same(a.result, b.result)


def test_a_real_sigint_during_a_compiled_run_stops_it_with_a_prefix_of_the_run():
    """SIGINT from another thread while the compiled loop runs: RunInterrupted at once
    (signals are checked before every step), its samples those of the whole run."""
    whole = _both(_paper(), 3.0, q0=np.ones(3))[0][0]
    robot, ctrl, ref, plant = _paper()()
    timer = threading.Timer(0.02, signal.raise_signal, (signal.SIGINT,))
    timer.start()
    try:
        with pytest.raises(hmpc_pin.RunInterrupted) as info:
            hmpc_pin.simulate(robot, ctrl, ref, duration=600.0, q0=np.ones(3), plant=plant)
    finally:
        timer.cancel()
    part = info.value.result
    m = min(len(part.t), len(whole.t))
    assert 0 < len(part.t) < 60001 and part.meta["interrupted_at"] == part.t[-1]
    for name in ARRAYS:
        np.testing.assert_allclose(getattr(part, name)[:m], getattr(whole, name)[:m],
                                   rtol=TOL, atol=TOL)  # fmt: skip
    assert np.isfinite(part.tau_applied).all()


# ---- setups without a compiled form: the per-step loop, one per reason ----


class _PlainSine:
    """A sine reference sampled in Python (no native form)."""

    def sample(self, t):
        return np.full(3, np.sin(t)), np.full(3, np.cos(t))

    def sample_many(self, times, out=None):
        times = np.asarray(times, dtype=float)[:, None]
        return np.sin(times) * np.ones(3), np.cos(times) * np.ones(3)


class _CountedSine(_PlainSine):
    """The sine above, counting its horizon calls and the times they asked for."""

    def __init__(self, width: int = 3):
        self.calls, self.width = [], width

    def sample_many(self, times, out=None):
        self.calls.append(np.array(times))
        times = np.asarray(times, dtype=float)[:, None]
        return np.sin(times) * np.ones(self.width), np.cos(times) * np.ones(self.width)


def test_a_reference_sampled_in_python_is_called_by_the_compiled_loop_as_per_step():
    """Through the Reference port: one sample_many of the horizon t_k + j Ts per step,
    the same arrays as per step."""
    refs, results = {}, {}
    for loop in ("python", "compiled"):
        refs[loop] = _CountedSine()
        results[loop] = _short(ref=lambda loop=loop: refs[loop], loop=loop)
        assert results[loop].loop == LOOP_NAMES[loop] and results[loop].complete
    _same(results["python"], results["compiled"])
    a, b = refs["python"].calls, refs["compiled"].calls
    K = len(results["compiled"].t) - 1
    assert len(b) == K + 2  # the steps', then the recorded reference's (sample_many of t)
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(y, x)


def test_a_python_reference_of_the_wrong_width_stops_both_loops_alike():
    """sample_many returning 2 columns for 3 joints: the same DimensionError, at step 0."""
    pair = []
    for loop in ("python", "compiled"):
        robot = hmpc_pin.load_robot(CONFIGS.parent / "robots" / "planar3.urdf")
        ctrl = hmpc_pin.HierarchicalMPC(robot)
        ref = _CountedSine(width=2)
        ref.sample = lambda t: (np.full(3, np.sin(t)), np.full(3, np.cos(t)))
        with pytest.raises(hmpc_pin.SimulationError) as info, _loop(loop):
            hmpc_pin.simulate(robot, ctrl, ref, duration=0.3, q0=np.zeros(3))
        pair.append(info.value)
    assert str(pair[0]) == str(pair[1]) and "sample_many returned" in str(pair[1])
    assert isinstance(pair[1].__cause__, hmpc_pin.DimensionError)


def _short(ctrl=None, plant=None, ref=None, loop="compiled", **kw):
    robot = hmpc_pin.load_robot(CONFIGS.parent / "robots" / "planar3.urdf")
    ctrl = ctrl(robot) if callable(ctrl) else hmpc_pin.HierarchicalMPC(robot)
    plant = plant(robot, ctrl) if plant is not None else None
    ref = ref() if ref is not None else hmpc_pin.SineReference(3)
    with _loop(loop):
        return hmpc_pin.simulate(robot, ctrl, ref, duration=0.3, q0=np.zeros(3), plant=plant, **kw)


#: Controllers without a compiled step: called as a whole through the Controller port.
PYTHON_CONTROLLERS = {
    "computed torque": lambda r: hmpc_pin.ComputedTorque(r),
    "collision watch": lambda r: CollisionReaction(hmpc_pin.HierarchicalMPC(r), 5.0, "stop"),
    "timed": lambda r: TimedController(hmpc_pin.HierarchicalMPC(r)),
}

#: Compensations written in Python: the compiled step calls them through its Compensation
#: port (the loop steps the compiled step itself).
PYTHON_COMPENSATIONS = {
    "momentum": lambda r: hmpc_pin.MomentumObserver(r, 0.01, 50.0),
    "ism-bl": lambda r: hmpc_pin.IntegralSlidingMode(r.nq, 0.01, 200.0, 2.0),
    "gated NDO": lambda r: FeedbackGate(hmpc_pin.DisturbanceObserver(r.nq, 0.01, 100.0)),
}


@pytest.mark.parametrize("name", list(PYTHON_CONTROLLERS))
def test_a_python_controller_runs_in_the_compiled_loop_as_per_step(name):
    """The same arrays, the same number of steps, as the per-step loop."""

    def make():
        robot = hmpc_pin.load_robot(CONFIGS.parent / "robots" / "planar3.urdf")
        ctrl = PYTHON_CONTROLLERS[name](robot)
        terms = [GaussianPulse([10.0, 8.0, 3.0], [0.3] * 3, [0.1] * 3)]
        terms.append(CoulombViscousFriction([10.0, 8.0, 5.0], [3.0, 2.4, 1.8]))
        plant = RK4Plant(robot.copy(), hmpc_pin.sim.SumDisturbance(*terms), ctrl.Ts)
        return robot, ctrl, hmpc_pin.SineReference(3), plant

    (ra, ea, pa), (rb, eb, pb) = _both(make, 1.0, q0=np.ones(3))
    assert ra.loop == "per-step" and rb.loop == "compiled" and ea is None and eb is None
    _same(ra, rb, name)
    if name == "timed":
        assert len(pa[1].samples_ns) == len(pb[1].samples_ns) == len(rb.t)
    if name == "collision watch":
        assert pa[1].detected_at == pb[1].detected_at


@pytest.mark.parametrize("name", list(PYTHON_COMPENSATIONS))
@pytest.mark.parametrize("latency", [0.0, 0.013])
def test_a_python_compensation_runs_in_the_compiled_step_as_per_step(name, latency):
    """The compiled loop steps the compiled step, which calls the compensation through its
    port: the same arrays as the per-step loop (with and without a declared latency)."""

    def make():
        robot = hmpc_pin.load_robot(CONFIGS.parent / "robots" / "planar3.urdf")
        ctrl = hmpc_pin.HierarchicalMPC(
            robot,
            hmpc_pin.MPCSettings(latency=latency),
            compensation=PYTHON_COMPENSATIONS[name](robot),
        )
        assert not replaced(ctrl, hmpc_pin.HierarchicalMPC, "step")  # its port: the compiled step
        friction = CoulombViscousFriction([10.0, 8.0, 5.0], [3.0, 2.4, 1.8])
        plant = RK4Plant(robot.copy(), friction, ctrl.Ts)
        return robot, ctrl, hmpc_pin.SineReference(3), plant

    (ra, ea, _), (rb, eb, _) = _both(make, 1.0, q0=np.ones(3))
    assert rb.loop == "compiled" and ea is None and eb is None
    assert np.abs(ra.d_hat).max() > 0.1  # the compensation was at work
    _same(ra, rb, name)


def test_the_euler_plant_runs_in_the_compiled_loop_as_per_step():
    """Through the Plant port: advance(tau) and disturbance_now(), the same arrays."""

    def make():
        robot = hmpc_pin.load_robot(CONFIGS.parent / "robots" / "planar3.urdf")
        ctrl = hmpc_pin.HierarchicalMPC(robot)
        friction = CoulombViscousFriction([10.0, 8.0, 5.0], [3.0, 2.4, 1.8])
        plant = EulerPlant(robot.copy(), friction, ctrl.Ts)
        return robot, ctrl, hmpc_pin.SineReference(3), plant

    (ra, ea, pa), (rb, eb, pb) = _both(make, 1.0, q0=np.ones(3))
    assert ra.loop == "per-step" and rb.loop == "compiled" and ea is None and eb is None
    _same(ra, rb, "euler")
    assert pa[3].k == pb[3].k == len(rb.t) - 1


@pytest.mark.parametrize("name", ["paper_combined_mujoco", "panda_mujoco"])
def test_a_mujoco_config_runs_in_the_compiled_loop_as_per_step(name):
    pytest.importorskip("mujoco")
    ra, ea = _run(_experiment(name), "python", 0.3)
    rb, eb = _run(_experiment(name), "auto", 0.3)
    assert ra.loop == "per-step" and rb.loop == "compiled" and ea is None and eb is None
    _same(ra, rb, name)


def test_loop_must_be_one_of_the_three():
    with pytest.raises(hmpc_pin.ConfigError, match="expected one of"):
        robot = hmpc_pin.load_robot("planar3")
        ctrl, ref = hmpc_pin.HierarchicalMPC(robot), hmpc_pin.SineReference(3)
        hmpc_pin.simulate(robot, ctrl, ref, duration=0.1, q0=np.zeros(3), loop="fast")


@pytest.mark.parametrize("loop", ["auto", "compiled", "python"])
def test_the_loop_keyword_of_earlier_versions_warns_and_changes_nothing(loop):
    """``loop=`` still loads (users' scripts) with a DeprecationWarning; the run is the
    compiled loop's, bit for bit."""
    robot = hmpc_pin.load_robot("planar3")
    runs = []
    for kw in ({}, {"loop": loop}):
        ctrl, ref = hmpc_pin.HierarchicalMPC(robot), hmpc_pin.SineReference(3)
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            runs.append(hmpc_pin.simulate(robot, ctrl, ref, duration=0.2, q0=np.ones(3), **kw))
        deprecated = [w for w in seen if issubclass(w.category, DeprecationWarning)]
        assert len(deprecated) == (1 if kw else 0)
        assert not kw or "no effect" in str(deprecated[0].message)
    assert runs[1].loop == "compiled"
    for name in ARRAYS:
        np.testing.assert_array_equal(getattr(runs[1], name), getattr(runs[0], name))


def test_a_step_replaced_on_the_instance_is_called_at_every_step():
    """A spy on the controller's step or on the plant's advance is called at every step
    (through the compiled loop's Controller and Plant ports)."""
    calls = []

    def spied(r):
        ctrl = hmpc_pin.HierarchicalMPC(r)
        step = ctrl.step

        def spy(*args):
            calls.append(args[0])
            return step(*args)

        ctrl.step = spy
        return ctrl

    result = _short(ctrl=spied)
    assert result.loop == "compiled" and len(calls) == len(result.t)  # the Controller port

    def plant(r, c):
        p = RK4Plant(r.copy(), None, c.Ts)
        advance = p.advance
        p.advance = lambda tau: (calls.append(tau), advance(tau))[1]
        return p

    calls.clear()
    result = _short(plant=plant)
    assert result.loop == "compiled" and len(calls) == len(result.t) - 1  # the Plant port


@pytest.mark.parametrize("model", ["z1", "panda"])
def test_an_init_config_runs_compiled_as_per_step(tmp_path, model):
    """The config ``hmpc-pin init`` writes (observer in bandwidth units, its model at the
    start of the period, 1 ms latency declared, the URDF's joint dynamics in plant and
    controller where they suit): the same arrays and controller state in both loops."""
    from hmpc_pin.experiment.init import write_config

    path = write_config(model, tmp_path / f"{model}.toml", duration=0.5)
    text = path.read_text(encoding="utf-8")
    assert 'model_at = "start"' in text and "latency" in text
    a, b = (Experiment.from_config(hmpc_pin.load_config(path)) for _ in range(2))
    ra, ea = _run(a, "python", 0.5)
    rb, eb = _run(b, "compiled", 0.5)
    assert ra.loop == "per-step" and rb.loop == "compiled"
    assert ea is None and eb is None
    _same(ra, rb, model)
    _assert_same_state(a.controller, b.controller)
