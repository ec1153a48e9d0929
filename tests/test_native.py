"""The native kernels (hmpc_pin.native) against the Python path and Pinocchio's Python API.

Every comparison is with an independent evaluation: Pinocchio's own Python bindings for the
dynamics, the Python RK4 loop for the plant, the Python controller (numpy + ProxSuite's
Python QP) for the step. Tolerances: rounding (1e-12 relative) where both sides run the same
arithmetic; the solver's tolerance where a QP is solved (ProxSuite eps_abs = 1e-9 on the
scaled QP, whose Hessian is ~1: |Δv| ≲ 1e-9 rad/s², a torque difference ≲ |M|·1e-9 ≈ 1e-8 N·m,
5e-8 allowed).

Where the compiled module is not installed these tests are skipped, unless
``HMPC_PIN_REQUIRE_NATIVE=1`` (``make test`` sets it) makes that a failure.
"""

from __future__ import annotations

import os
import subprocess
import sys
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import hmpc_pin
from hmpc_pin import native
from hmpc_pin.sim.plants import RK4Plant

from .conftest import CONFIGS, PLANAR3, ROOT

if not native.available():  # pragma: no cover - depends on the machine
    if os.environ.get("HMPC_PIN_REQUIRE_NATIVE") == "1":
        raise RuntimeError(f"HMPC_PIN_REQUIRE_NATIVE=1 but: {native._error}")
    pytest.skip(f"native kernels unavailable: {native._error}", allow_module_level=True)

TAU_TOL = 5e-8  # [N·m], the QP tolerance through M (module docstring)


def _arm(name):
    if name == "planar3":
        return hmpc_pin.load_robot(PLANAR3)
    if name == "panda":  # the fingers locked: a mimic joint has no native path
        return hmpc_pin.load_robot(name, locked_joints={"panda_finger_joint1": 0.0,
                                                         "panda_finger_joint2": 0.0})  # fmt: skip
    return hmpc_pin.load_robot(name)


@pytest.mark.parametrize("name", ["planar3", "ur5", "panda"])
def test_dynamics_equal_pinocchio_python(name, make_rng):
    """CRBA (both triangles), RNEA's C·q̇ + G and ABA equal Pinocchio's Python API."""
    robot = _arm(name)
    kernel = native.load().RK4(native.model_string(robot))
    model, data = robot.model, robot.model.createData()
    rng = make_rng(1)
    for _ in range(5):
        q = rng.uniform(-2, 2, robot.nq)
        v, tau = rng.normal(size=robot.nq), rng.normal(size=robot.nq) * 10
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        np.testing.assert_allclose(kernel.mass_matrix(q), M, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(kernel.nle(q, v), pin.nonLinearEffects(model, data, q, v),
                                   rtol=1e-12, atol=1e-12)  # fmt: skip
        np.testing.assert_allclose(kernel.aba(q, v, tau), pin.aba(model, data, q, v, tau),
                                   rtol=1e-10, atol=1e-10)  # fmt: skip


def _paper_disturbance():
    return hmpc_pin.CoulombViscousFriction([10, 8, 5], [3, 2.4, 1.8]) + hmpc_pin.GaussianPulse(
        [10, 8, 0.3], [0.05, 0.1, 0.15], 0.03
    )


def test_a_native_plant_survives_pickling(planar3):
    import pickle

    plant = RK4Plant(planar3.copy(), _paper_disturbance(), 0.01, 0.001)
    plant.reset(np.array([0.3, -0.4, 0.2]), np.zeros(3))
    plant.advance(np.ones(3))
    twin = pickle.loads(pickle.dumps(plant))
    assert twin.native
    np.testing.assert_array_equal(twin.advance(np.ones(3))[0], plant.advance(np.ones(3))[0])


class _Described:
    """A user's disturbance object with an attribute of its own named ``terms`` (not the
    package's sum: it must still be called, not taken for the zero disturbance)."""

    terms = ()

    def __call__(self, t, q, dq):
        return -0.5 * dq + np.cos(2.0 * t) * np.array([1.0, -0.5, 0.2])


@pytest.mark.parametrize(
    "disturbance", ["none", "friction+pulse", "pulse", "callable", "object with terms"]
)
def test_rk4_period_equals_the_oracle(planar3, disturbance):
    """Every period of a 3 s run (through the pulses, across velocity sign changes of the
    friction) equals the plain RK4 loop of tests/reference/rk4.py started from the same
    state, to rounding; a disturbance that is not fused is called from C++ per stage."""
    from .reference.rk4 import rk4_period

    d = {
        "none": hmpc_pin.ZeroDisturbance(3),
        "friction+pulse": _paper_disturbance(),
        "pulse": hmpc_pin.GaussianPulse([10, 8, 0.3], [0.05, 0.1, 0.15], 0.03),
        "callable": lambda t, q, dq: -0.5 * dq + np.sin(3.0 * t) * np.array([1.0, 0.5, 0.2]),
        "object with terms": _Described(),
    }[disturbance]
    plant = RK4Plant(planar3.copy(), d, 0.01, 0.001, coulomb="sign")  # the oracle's law
    assert plant.fused is (disturbance not in ("callable", "object with terms"))
    q, dq = np.array([0.3, -0.4, 0.2]), np.array([0.5, -0.2, 0.1])
    plant.reset(q, dq)
    signs = set()
    for k in range(300):
        tau = np.array([5.0, 2.0, 1.0]) * np.sin(0.07 * k)
        want = rk4_period(planar3.model, plant.q, plant.dq, tau, d, plant.t, 0.001, 10)
        np.testing.assert_allclose(plant.disturbance_now(), d(plant.t, plant.q, plant.dq),
                                   rtol=0, atol=1e-12)  # fmt: skip
        q, dq = plant.advance(tau)
        signs.add(tuple(np.sign(dq)))
        np.testing.assert_allclose(q, want[0], rtol=0, atol=1e-12)
        np.testing.assert_allclose(dq, want[1], rtol=0, atol=1e-11)
    assert len(signs) > 2  # the friction's sign switched along the way


def _experiment(path, backend, **changes):
    config = hmpc_pin.load_config(path)
    cc = replace(config.controller, backend=backend, **changes)
    pc = replace(config.plant, backend=backend)
    return hmpc_pin.Experiment.from_config(replace(config, controller=cc, plant=pc))


@pytest.mark.parametrize(
    "config, changes",
    [
        ("paper_combined", {}),
        ("paper_combined", {"compensation": "none", "observer": None}),
        ("paper_combined", {"compensation": "general"}),
        ("paper_combined", {"Nc": 4, "qp_layout": "joint"}),
        ("paper_combined", {"Nc": 4, "qp_layout": "block"}),
        ("panda_sine", {}),
        ("paper_cartesian", {}),  # a quintic move
        ("panda_trajectory", {}),  # a trajectory file (cubic spline)
    ],
)
def test_closed_loop_equals_the_oracle_step(config, changes):
    """Whole runs (1 s; the paper's friction + pulses) of the compiled step: at every step,
    the oracle step (tests/reference/step.py: Pinocchio's Python API, the numpy NDO, every
    QP solved from scratch) fed the run's measured states and applied torques gives the
    recorded torque and estimate to the solver's tolerance."""
    from .reference.step import OracleHMPC, assert_run_matches

    ex = _experiment(CONFIGS / f"{config}.toml", "auto", **changes)
    ex.config = replace(ex.config, simulation=replace(ex.config.simulation, duration=1.0))
    oracle = OracleHMPC(ex.controller)
    r = ex.run()
    assert r.complete
    assert_run_matches(oracle, r, ex.reference, TAU_TOL)


class _Unfused:
    """A compensation with no compiled form: the step calls it from C++ through its
    Compensation port (what the momentum observer, ISM and user classes take)."""

    def __init__(self, inner):
        self.inner = inner

    @property
    def estimate(self):
        return self.inner.estimate

    def reset(self, q0, dq0):
        self.inner.reset(q0, dq0)

    def update(self, M, nle, q, dq, tau, v):
        return self.inner.update(M, nle, q, dq, tau, v)


@pytest.mark.parametrize("config", ["paper_combined", "panda_sine"])
def test_python_compensations_take_the_same_compiled_step(config):
    """The NDO called through the step's Compensation port gives the fused step's run
    bit for bit: the same compiled dynamics, QPs and Eq (4) either way."""
    runs = []
    for fused in (True, False):
        ex = _experiment(CONFIGS / f"{config}.toml", "auto")
        ex.config = replace(ex.config, simulation=replace(ex.config.simulation, duration=1.0))
        if not fused:
            ex.controller.compensation = _Unfused(ex.controller.compensation)
        assert ex.controller.fused is fused
        runs.append(ex.run())
    for name in ("q", "dq", "tau", "d_hat"):
        np.testing.assert_array_equal(getattr(runs[1], name), getattr(runs[0], name))


def _references(n):
    rng = np.random.default_rng(3)
    times = np.linspace(0.0, 0.8, 9)
    w, p = rng.uniform(1, 3, n), rng.normal(size=n)
    q, dq = np.sin(np.outer(times, w) + p), w * np.cos(np.outer(times, w) + p)
    return {
        "sine": hmpc_pin.SineReference(n, amplitude=rng.uniform(0.1, 1, n), frequency=0.7,
                                       offset=rng.normal(size=n), phase=rng.normal(size=n)),
        "quintic": hmpc_pin.QuinticReference(rng.normal(size=n), rng.normal(size=n), 0.2, 0.5),
        "cubic spline": hmpc_pin.JointTrajectory(times, q),
        "quintic Hermite": hmpc_pin.JointTrajectory(times, q, dq),
    }  # fmt: skip


def _oracle_sampling(ref, times):
    from .reference import sampling

    if isinstance(ref, hmpc_pin.SineReference):
        return sampling.sine(ref, times)
    if isinstance(ref, hmpc_pin.QuinticReference):
        return sampling.quintic(ref, times)
    form = ref.compiled_sampling()
    return sampling.ppoly(
        form.breakpoints, form.origins, form.coefficients, form.degree, ref.n, times
    )


@pytest.mark.parametrize("name", ["sine", "quintic", "cubic spline", "quintic Hermite"])
def test_compiled_sampling_equals_the_oracle(planar3, name):
    """The compiled sampler, through the references' sample_many and through the fused
    step's horizon (before, across and after the segments), equals the closed forms of
    tests/reference/sampling.py to rounding (|q| and |q̇| up to a few units here)."""
    ref = _references(3)[name]
    times = np.linspace(-0.5, 2.0, 301)
    q, dq = ref.sample_many(times)
    q_o, dq_o = _oracle_sampling(ref, times)
    np.testing.assert_allclose(q, q_o, rtol=0, atol=1e-12)
    np.testing.assert_allclose(dq, dq_o, rtol=0, atol=1e-11)
    grid = ref.sample_many(times.reshape(7, 43))  # any shape of times
    np.testing.assert_array_equal(grid[0].reshape(-1, 3), q)
    ctrl = hmpc_pin.HierarchicalMPC(planar3, hmpc_pin.MPCSettings(N=30))
    q0 = np.zeros(3)
    ctrl.reset(q0, q0)
    for t in (-0.5, 0.0, 0.15, 0.19, 0.37, 0.55, 0.7, 0.81, 2.0):
        ctrl.step(t, q0, q0, ref)
        assert ctrl._native_ref
        q_ref, dq_ref = _oracle_sampling(ref, t + ctrl._offsets)
        np.testing.assert_allclose(ctrl._data.q_ref, q_ref, rtol=0, atol=1e-12)
        np.testing.assert_allclose(ctrl._data.dq_ref, dq_ref, rtol=0, atol=1e-11)


def test_a_reference_subclass_that_samples_otherwise_is_sampled_in_python(planar3):
    class Shifted(hmpc_pin.SineReference):
        def sample_many(self, times, out=None):
            return super().sample_many(np.asarray(times) + 0.25, out)

        def sample(self, t):
            return super().sample(t + 0.25)

    ref, plain = Shifted(3), hmpc_pin.SineReference(3)
    assert ref.compiled_sampling() is None and plain.compiled_sampling() is not None
    ctrl = hmpc_pin.HierarchicalMPC(planar3, hmpc_pin.MPCSettings(backend="native"))
    ctrl.reset(np.zeros(3), np.zeros(3))
    ctrl.step(0.0, np.zeros(3), np.zeros(3), ref)
    assert not ctrl._native_ref
    np.testing.assert_allclose(ctrl._data.q_ref, plain.sample_many(0.25 + ctrl._offsets)[0])


@pytest.mark.parametrize("layout, Nc", [("block", 1), ("joint", 3)])
def test_soft_joint_limits_equal_the_oracle_step(planar3, layout, Nc):
    """Steps whose box-only prediction leaves the position limits: the soft QPs are solved
    and the torques equal the oracle step's (soft QPs from scratch, tests/reference)."""
    from .reference.step import OracleHMPC

    ctrl = hmpc_pin.HierarchicalMPC(planar3, hmpc_pin.MPCSettings(Nc=Nc, qp_layout=layout))
    oracle = OracleHMPC(ctrl)
    upper = planar3.upper[0]
    ref = hmpc_pin.SineReference(3, amplitude=[upper + 0.5, 0.2, 0.2], frequency=0.5)
    q, dq = np.array([upper - 0.05, 0.0, 0.0]), np.array([2.0, 0.0, 0.0])
    ctrl.reset(q, dq)
    oracle.reset(dq)
    active, prev = 0, None
    for k in range(40):
        t = 0.01 * k
        qk, dqk = q + dq * t * (0.98**k), dq * (0.98**k)
        ta = ctrl.step(t, qk, dqk, ref)
        tb, _ = oracle.step(t, qk, dqk, ref, prev)
        prev = ta
        # soft QPs agree to 1e-4 rad/s² (tests/test_joint_mpc.py), through M (~1 kg·m²)
        np.testing.assert_allclose(ta, tb, rtol=0, atol=1e-3)
        active += ctrl.qps.constrained
    assert active > 5  # the soft QPs were really exercised


def test_step_failures_are_one_error_each_and_change_nothing(planar3):
    """A non-finite input (no state changed) and an unsolved QP (max_iter = 1): the
    solver's status and the joint it happened at."""
    ref = hmpc_pin.SineReference(3)
    q0, dq0 = ref.sample(0.0)
    ctrl = hmpc_pin.HierarchicalMPC(planar3)
    ctrl.reset(q0, dq0)
    tau0 = ctrl.step(0.0, q0, dq0, ref)
    with pytest.raises(hmpc_pin.NonFiniteError, match="dq"):
        ctrl.step(0.01, q0, np.array([0.0, np.nan, 0.0]), ref)
    with pytest.raises(hmpc_pin.NonFiniteError, match="t"):
        ctrl.step(np.inf, q0, dq0, ref)
    with pytest.raises(hmpc_pin.DimensionError, match="q"):
        ctrl.step(0.01, q0[:2], dq0, ref)
    with pytest.raises(hmpc_pin.DimensionError):
        ctrl.step(0.01, np.zeros((3, 3)), dq0, ref)
    np.testing.assert_allclose(ctrl.tau, tau0)  # unchanged
    for layout in ("block", "joint"):
        c = hmpc_pin.HierarchicalMPC(planar3, hmpc_pin.MPCSettings(max_iter=1, qp_layout=layout))
        c.qps.shortcut = False
        c.reset(q0, dq0)
        with pytest.raises(hmpc_pin.SolverError, match="MAX_ITER") as info:
            for k in range(50):
                c.step(0.01 * k, q0 + 0.3, dq0 - 1.0, ref)
        assert info.value.joint is None if layout == "block" else info.value.joint == 0


class _NaNAfter:
    """A sine reference (sampled in Python: no compiled form) that is NaN from ``t_bad`` on."""

    def __init__(self, n, t_bad):
        self.sine, self.t_bad = hmpc_pin.SineReference(n), t_bad

    def sample(self, t):
        q, dq = self.sine.sample(t)
        return (q, dq) if t < self.t_bad else (q * np.nan, dq)


def test_the_compiled_steps_faults_read_as_the_python_checks_of_the_same_input(planar3):
    """Each fault of the compiled step arrives as the exceptions.py error a check of the same
    input in Python raises, message for message: a vector of the wrong size (the robot's own
    check_vector), a non-finite state, the first non-finite row of the reference's horizon
    at its own time, and an unsolved QP naming its joint."""
    ref = hmpc_pin.SineReference(3)
    q0, dq0 = ref.sample(0.0)
    ctrl = hmpc_pin.HierarchicalMPC(planar3)
    ctrl.reset(q0, dq0)
    ctrl.step(0.0, q0, dq0, ref)
    for name, q, dq in (("q", q0[:2], dq0), ("dq", q0, np.zeros(4))):
        with pytest.raises(hmpc_pin.DimensionError) as got:
            ctrl.step(0.01, q, dq, ref)
        with pytest.raises(hmpc_pin.DimensionError) as want:
            planar3.check_vector(name, q if name == "q" else dq)
        assert str(got.value) == str(want.value)
    bad = np.array([0.1, np.inf, 0.0])
    with pytest.raises(hmpc_pin.NonFiniteError) as got:
        ctrl.step(0.01, bad, dq0, ref)
    assert str(got.value) == str(hmpc_pin.NonFiniteError("q", bad))
    Ts, N = ctrl.Ts, ctrl.settings.N
    late = _NaNAfter(3, 0.5 + 3.5 * Ts)  # rows j = 1..N at t + j Ts: row 4 is the first
    c = hmpc_pin.HierarchicalMPC(planar3)
    c.reset(q0, dq0)
    with pytest.raises(hmpc_pin.NonFiniteError) as got:
        c.step(0.5, q0, dq0, late)
    assert got.value.name == "reference" and N >= 4
    np.testing.assert_array_equal(got.value.value[1], late.sine.sample(0.5 + 4 * Ts)[1])
    assert f"at t={0.5 + 4 * Ts:.6g}" in str(got.value)
    c = hmpc_pin.HierarchicalMPC(planar3, hmpc_pin.MPCSettings(max_iter=1, qp_layout="joint"))
    c.qps.shortcut = False
    c.reset(q0, dq0)
    with pytest.raises(hmpc_pin.SolverError) as got:
        for k in range(50):
            c.step(0.01 * k, q0 + 0.3, dq0 - 1.0, ref)
    assert f"joint 0 ({planar3.joint_names[0]!r}) MPC QP was not solved" in str(got.value)


def test_a_model_with_mimic_joints_takes_its_dynamics_from_python():
    """Pinocchio 4.1 restores mimic joints badly from a serialized model: the plant's
    compiled period calls Pinocchio's Python ABA (equal to the oracle's period), and the
    controller's compiled step takes M and C q̇ + G from its Python API (Eq 4 with them)."""
    robot = hmpc_pin.load_robot("panda")  # finger joint 2 mimics joint 1
    assert robot.mimic_joints
    with pytest.raises(hmpc_pin.ConfigError, match="mimic"):
        native.model_string(robot)
    from .reference.rk4 import rk4_period

    plant = RK4Plant(robot, None, 0.01, 0.001)  # the compiled period on the Python ABA
    q0 = 0.5 * (robot.lower + robot.upper)
    plant.reset(q0, np.zeros(robot.nq))
    tau = robot.gravity_torque(q0) + 0.1
    data = robot.model.createData()
    want = rk4_period(robot.model, q0, np.zeros(robot.nq), tau, plant.disturbance, 0.0, 0.001,
                      10, aba=lambda q, v, u: robot.aba(robot.model, data, q, v, u),
                      joint=(robot.joint_damping, robot.joint_friction))  # fmt: skip
    q, dq = plant.advance(tau)
    np.testing.assert_allclose(q, want[0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(dq, want[1], rtol=0, atol=1e-10)
    ctrl = hmpc_pin.HierarchicalMPC(robot)
    assert not ctrl.fused
    q = 0.5 * (robot.lower + robot.upper)
    dq = np.full(robot.nq, 0.1)
    ref = hmpc_pin.SineReference(robot.nq, amplitude=0.1, offset=q)
    ctrl.reset(q, dq)
    tau = ctrl.step(0.0, q, dq, ref)
    M, nle = robot.mass_matrix(q), robot.nonlinear_effects(q, dq)
    # Eq 4 with the URDF's joint damping and friction compensated (tests/reference/step.py)
    B, F = robot.joint_damping, robot.joint_friction
    minv = np.diag(np.linalg.inv(M))
    x = B * minv * 0.01
    g = np.where(x > 0, x / -np.expm1(-np.where(x > 0, x, 1.0)), 1.0)
    want = M @ ctrl.v + nle + B * dq + F * np.sign(dq) + (g - 1) / minv * ctrl.v
    np.testing.assert_allclose(tau, want - ctrl.disturbance_estimate,
                               rtol=0, atol=1e-9 * max(1.0, np.abs(tau).max()))  # fmt: skip


def test_native_buffers_are_the_objects_the_controller_exposes(planar3):
    """disturbance_estimate and the QPs' solution are updated in place by the native step,
    and the observer object is the one the fused step advanced (its z and d̂ are true)."""
    ref = hmpc_pin.SineReference(3)
    q0, dq0 = ref.sample(0.0)
    ctrl = hmpc_pin.HierarchicalMPC(planar3, hmpc_pin.MPCSettings(backend="native"))
    ctrl.reset(q0, dq0)
    for k in range(30):
        tau = ctrl.step(0.01 * k, q0, dq0 + 0.1, ref)
    comp = ctrl.compensation
    np.testing.assert_array_equal(comp.estimate, ctrl.disturbance_estimate)
    assert np.any(comp.estimate != 0.0)
    np.testing.assert_array_equal(comp.estimate, comp.z + comp.p(dq0 + 0.1))
    M = planar3.mass_matrix(q0)
    nle = planar3.nonlinear_effects(q0, dq0 + 0.1)
    np.testing.assert_allclose(tau, M @ ctrl.v + nle - ctrl.disturbance_estimate, atol=1e-10)
    np.testing.assert_array_equal(ctrl.v, ctrl.qps.solution[0])


def test_backend_options_are_validated(write_config):
    base = (
        '[robot]\nurdf = "@URDF@"\n[reference]\namplitude = 1.0\n[controller]\n{c}\n[plant]\n{p}\n'
    )
    with pytest.raises(hmpc_pin.ConfigError, match="backend"):
        hmpc_pin.load_config(write_config(base.format(c='backend = "fast"', p="")))
    with pytest.raises(hmpc_pin.ConfigError, match=r"backend.*does not apply"):
        hmpc_pin.load_config(write_config(base.format(c="", p='integrator = "euler"\n'
                                                            'backend = "native"')))  # fmt: skip
    with pytest.raises(hmpc_pin.ConfigError, match="backend"):
        hmpc_pin.load_config(write_config(base.format(
            c='kind = "computed-torque"\nbackend = "python"', p="")))  # fmt: skip
    # a compensation written in Python takes the compiled step too, with no warning
    cfg = hmpc_pin.load_config(write_config(base.format(
        c='compensation = "momentum"\nbackend = "native"', p="")))  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ex = hmpc_pin.Experiment.from_config(cfg)
    assert ex.controller.native and not ex.controller.fused
    # backend = "python" (0.2) loads, with a deprecation note, and runs the compiled step
    cfg = hmpc_pin.load_config(write_config(base.format(c='backend = "python"', p="")))
    with pytest.warns(DeprecationWarning, match="backend"):
        ex = hmpc_pin.Experiment.from_config(cfg)
    assert ex.controller.fused


_BLOCK_CORE = "import sys; sys.modules['hmpc_pin._core'] = None\n"


def test_without_the_compiled_module_the_package_imports_and_says_how_to_install():
    """The compiled module missing (a source tree used without ``pip install``): ``import
    hmpc_pin`` works; the controller (compiled step, QPs, observer) and the RK4 plant are
    each one NativeError saying how to install."""
    code = (
        _BLOCK_CORE
        + """
import warnings, numpy as np, hmpc_pin
from hmpc_pin.sim.plants import RK4Plant
robot = hmpc_pin.load_robot(PATH)
makers = (lambda: hmpc_pin.HierarchicalMPC(robot),
          lambda: hmpc_pin.HierarchicalMPC(robot, compensation=hmpc_pin.NoCompensation(3)),
          lambda: RK4Plant(robot, None, 0.01, 0.001))
for make in makers:
    try:
        make()
    except hmpc_pin.NativeError as exc:
        print("error:", exc)
""".replace("PATH", repr(str(PLANAR3)))
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=ROOT, timeout=120)  # fmt: skip
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert len(lines) == 3
    for line in lines:
        assert line.startswith("error:") and "hmpc_pin._core is not installed" in line
        assert "pip install" in line


def test_a_version_mismatch_is_one_message_naming_both_versions():
    """A module built against another Pinocchio than the one installed: one NativeError
    naming both versions and the reinstall, never a crash inside the kernels."""
    code = """
import pinocchio
pinocchio.__version__ = "0.0.1"
from hmpc_pin import native
try:
    native.load()
except native.NativeError as exc:
    print(exc.reason)
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=ROOT, timeout=120)  # fmt: skip
    assert out.returncode == 0, out.stderr
    built = native.build_info()["pinocchio"]
    assert f"built against pinocchio {built}" in out.stdout
    assert "this environment has pinocchio 0.0.1" in out.stdout and "reinstall" in out.stdout


def test_cli_native_prints_the_module_and_its_build():
    out = subprocess.run([sys.executable, "-m", "hmpc_pin", "native"], capture_output=True,
                         text=True, cwd=ROOT, timeout=600)  # fmt: skip
    assert out.returncode == 0, out.stderr
    first, second = out.stdout.splitlines()[:2]
    assert first.startswith("native kernels: ") and first.endswith(".so")
    assert Path(first.split(": ", 1)[1]).is_file()
    assert f"pinocchio {pin.__version__}" in second


def test_native_build_is_a_deprecated_alias_that_compiles_nothing():
    with pytest.warns(DeprecationWarning, match="built when the package is installed"):
        path = native.build()
    assert path == Path(native.load().__file__)


def test_long_horizon_per_joint_qps_equal_the_oracle():
    """Panda at Ts = 1 ms, N = Nc = 100 (auto: one QP per joint, the unconstrained
    shortcut where the box is inactive): torques along a start-up (box active) and a steady
    sine (inactive) equal the oracle step's, and the shortcut was taken but not always."""
    from .reference.step import OracleHMPC

    robot = _arm("panda")
    home = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])  # inside the limits
    ref = hmpc_pin.SineReference(robot.nq, amplitude=0.3, frequency=0.1, offset=home)
    ctrl = hmpc_pin.HierarchicalMPC(robot, hmpc_pin.MPCSettings(Ts=0.001, N=100, Nc=100))
    assert ctrl.qps.layout == "joint"
    oracle = OracleHMPC(ctrl)
    q0, dq0 = ref.sample(0.0)
    ctrl.reset(q0 + 0.2, dq0)
    oracle.reset(dq0)
    prev = None
    for k in range(60):
        t = 0.001 * k
        q, dq = ref.sample(t)
        q = q + 0.2 * np.exp(-0.05 * k)
        ta = ctrl.step(t, q, dq, ref)
        tb, _ = oracle.step(t, q, dq, ref, prev)
        prev = ta
        np.testing.assert_allclose(ta, tb, rtol=0, atol=1e-6 * max(1.0, np.abs(tb).max()))
    took = ctrl.qps.unconstrained_solves
    assert 0 < took < 60 * robot.nq


def test_the_deprecated_backend_argument_is_checked_and_changes_nothing(planar3):
    """``backend`` of 0.2 on a controller or an RK4 plant: an unknown value is one
    ConfigError naming the key; ``"python"`` warns and gives the same run bit for bit."""
    with pytest.raises(hmpc_pin.ConfigError, match=r"plant\.backend"):
        RK4Plant(planar3, None, 0.01, 0.001, backend="fast")
    with pytest.raises(hmpc_pin.ConfigError, match=r"MPCSettings\.backend"):
        hmpc_pin.MPCSettings(backend="fast")
    runs = []
    for backend in ("auto", "python"):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            ctrl = hmpc_pin.HierarchicalMPC(planar3, hmpc_pin.MPCSettings(backend=backend))
            plant = RK4Plant(planar3.copy(), _paper_disturbance(), 0.01, 0.001, backend=backend)
        deprecations = [w for w in caught if issubclass(w.category, DeprecationWarning)]
        assert len(deprecations) == (2 if backend == "python" else 0)
        runs.append(hmpc_pin.simulate(planar3, ctrl, hmpc_pin.SineReference(3), plant=plant,
                                      duration=0.3, q0=np.zeros(3)))  # fmt: skip
    np.testing.assert_array_equal(runs[0].q, runs[1].q)
    np.testing.assert_array_equal(runs[0].tau, runs[1].tau)


def test_the_qp_settings_are_typed_fields_that_default_to_proxsuites_own():
    """``QPSettings`` (the compiled QPs' ProxSuite settings): a default one holds ProxSuite's
    defaults (read from ProxSuite's Python API), each field keeps its type, and the
    package's choice differs from them where it says so."""
    from proxsuite import proxqp

    from hmpc_pin.mpc.condensed import solver_settings

    core = native.load()
    ours, theirs = core.QPSettings(), proxqp.dense.QP(2, 0, 0).settings
    fields = [name for name in dir(ours) if not name.startswith("_")]
    assert len(fields) == 10 and "initial_guess" in fields
    fields.remove("initial_guess")
    for name in fields:
        assert getattr(ours, name) == getattr(theirs, name), name
    assert ours.initial_guess.name == theirs.initial_guess.name
    with pytest.raises(TypeError):
        ours.eps_abs = "tight"
    chosen = solver_settings(1e-9, 77)
    assert (chosen.eps_abs, chosen.max_iter, chosen.check_duality_gap) == (1e-9, 77, True)
    assert chosen.initial_guess == core.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
    assert solver_settings(1e-9, 77, warm=False).initial_guess.name == "NO_INITIAL_GUESS"


def test_the_rk4_plant_is_a_compiled_plant_port_that_holds_its_state(planar3):
    """RK4Plant's state lives in its compiled plant (the loop's Plant port): what Python
    reads is what the port advanced; its disturbance is the pulse's compiled port, fused,
    or a callable called as it is."""
    pulse = hmpc_pin.GaussianPulse([10, 8, 0.3], [0.05, 0.1, 0.15], 0.03)
    plant = RK4Plant(planar3.copy(), pulse, 0.01, 0.001)
    plant.reset(np.array([0.3, -0.4, 0.2]), np.zeros(3), t0=0.5)
    for _ in range(3):
        q, dq = plant.advance(np.ones(3))
    port = plant.port
    assert port.k == plant.k == 3 and plant.t == port.t == pytest.approx(0.53, abs=1e-15)
    np.testing.assert_array_equal(port.q, q)
    np.testing.assert_array_equal(plant.dq, dq)
    assert plant.fused and plant.loop_port() is port
    a, b, s = np.array([10, 8, 0.3]), np.array([0.05, 0.1, 0.15]), 0.03
    t = 0.5 + 3 * 0.01  # the pulse at period 3, closed form (Eq 33)
    np.testing.assert_allclose(
        port.disturbance_now(), a * np.exp(-((t - b) ** 2) / (2 * s**2)), rtol=1e-14
    )
    port.set_disturbance(lambda t, q, dq: np.full(3, t))  # a callable: called per stage
    assert not port.fused
    np.testing.assert_array_equal(port.disturbance_now(), np.full(3, port.t))


def test_a_fused_term_is_defined_by_its_fused_form_alone(planar3):
    """A time-only term is its sample_times (a subclass defining __call__ is refused: the
    plant would never see it); a term of the same shape that is not one is called per
    stage, and both give the plain RK4 of the same d(t) to rounding."""
    from hmpc_pin.sim.disturbances import TimeOnly

    from .reference.rk4 import rk4_period

    with pytest.raises(hmpc_pin.InterfaceError, match=r"sample_times\(\) alone"):

        class Shifted(hmpc_pin.GaussianPulse):
            def __call__(self, t, q, dq):
                return super().__call__(t + 1.0, q, dq)

    class Ramp(TimeOnly):  # d(t) = t·c, defined once
        def sample_times(self, times):
            return np.asarray(times, dtype=float)[:, None] * np.array([1.0, -0.5, 0.25])

    class DuckRamp:  # the same values, not a TimeOnly: called at every stage
        def __call__(self, t, q, dq):
            return t * np.array([1.0, -0.5, 0.25])

        def sample_times(self, times):
            raise AssertionError("not fused: never tabulated")

    q0, dq0, tau = np.array([0.3, -0.4, 0.2]), np.zeros(3), np.array([1.0, 0.5, 0.2])
    ends = []
    for d in (Ramp(), DuckRamp()):
        plant = RK4Plant(planar3.copy(), d, 0.01, 0.001)
        assert plant.fused is isinstance(d, TimeOnly)
        plant.reset(q0, dq0)
        want = rk4_period(planar3.model, q0, dq0, tau, Ramp(), 0.0, 0.001, 10)
        q, dq = plant.advance(tau)
        np.testing.assert_allclose(q, want[0], rtol=0, atol=1e-12)
        np.testing.assert_allclose(dq, want[1], rtol=0, atol=1e-11)
        ends.append(q)
    np.testing.assert_allclose(ends[1], ends[0], rtol=0, atol=1e-12)
