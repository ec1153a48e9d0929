"""The step owns its data (Crocoddyl's model/data split): the compiled step, the joint QPs and
the observer allocate their memory, and Python reads named views of it
(``hmpc_pin._core.StepData``, ``JointQPs.solution``/``slack``, ``DisturbanceObserver.z``/
``estimate``). Each view is checked against an independent computation of its quantity after
real steps: the reference sampled by the reference itself, the gradients from
``CondensedMPC.gradient`` on the interleaved horizon, the inputs as the box QP's
unconstrained minimiser −H⁻¹g from numpy, Eq (4) from Pinocchio's own M and C q̇ + G, and the
observer's d̂ = z + cY q̇ (Eq 13 with z = d̂ − p)."""

from __future__ import annotations

import copy
import pickle

import numpy as np
import pinocchio as pin
import pytest

import hmpc_pin
from hmpc_pin.compensation.observers import DisturbanceObserver


def _stepped(planar3, steps: int = 5):
    """A controller without state limits after ``steps`` steps on a slow, small sine (every
    joint QP inside its box: its solution is the unconstrained minimiser), with the states
    it was given."""
    settings = hmpc_pin.MPCSettings(N=12, Nc=4)
    ctrl = hmpc_pin.HierarchicalMPC(planar3, settings, limits=None)
    ref = hmpc_pin.SineReference(3, amplitude=0.05, frequency=0.3)
    rng = np.random.default_rng(3)
    q, dq = np.zeros(3), np.zeros(3)
    ctrl.reset(q, dq)
    states = []
    for k in range(steps):
        t = 0.1 + k * settings.Ts
        q, dq = ref.sample(t)  # near the reference, off by a little
        q, dq = q + 1e-3 * rng.standard_normal(3), dq + 1e-3 * rng.standard_normal(3)
        ctrl.step(t, q, dq, ref)
        states.append((t, q, dq))
    return ctrl, ref, states


def test_the_views_are_the_step_data_and_read_only(planar3):
    """Every view the controller exposes is read-only where only the step writes, keeps its
    identity across steps and a rebuilt step (a new compensation), and updates in place."""
    ctrl, ref, states = _stepped(planar3)
    views = (ctrl.v, ctrl.tau, ctrl.disturbance_estimate, ctrl.qps.solution, ctrl.qps.slack)
    for view in views:
        assert not view.flags.writeable
        with pytest.raises(ValueError, match="read-only"):
            view[0] = 1.0
    data = ctrl.data
    for view in (data.M, data.nle):
        assert not view.flags.writeable
    # the stack's rows are Python's to write (a reference sampled in Python fills them)
    assert data.q_ref.flags.writeable and data.q_ref.shape == (12, 3)
    assert np.shares_memory(data.q, data.stack) and np.shares_memory(data.dq_ref, data.stack)
    tau_before = ctrl.tau.copy()
    ctrl.compensation = DisturbanceObserver(3, ctrl.Ts, gain=30.0)  # the step is rebuilt
    assert ctrl.v is views[0] and ctrl.tau is views[1]
    t, q, dq = states[-1]
    out = ctrl.step(t + ctrl.Ts, q, dq, ref)
    np.testing.assert_array_equal(ctrl.tau, out)  # the same view, updated in place
    assert not np.array_equal(tau_before, ctrl.tau)


def test_the_views_track_the_step(planar3):
    """After each step the views equal independent computations of their quantities."""
    ctrl, ref, _ = _stepped(planar3, steps=1)
    mpc, data, robot = ctrl.mpc, ctrl.data, planar3
    pdata = robot.model.createData()
    for k in range(6):
        t = 0.2 + k * ctrl.Ts
        q, dq = ref.sample(t)
        q, dq = q + 1e-3 * np.sin([k, k + 1, k + 2]), dq - 2e-3 * np.cos([k, 2 * k, 3 * k])
        ctrl.step(t, q, dq, ref)
        np.testing.assert_array_equal(data.q, q)
        np.testing.assert_array_equal(data.dq, dq)
        np.testing.assert_array_equal(ctrl.state[0], q)
        times = t + ctrl.Ts * np.arange(1, mpc.N + 1)
        q_ref, dq_ref = ref.sample_many(times)
        np.testing.assert_allclose(data.q_ref, q_ref, rtol=0, atol=1e-12)
        np.testing.assert_allclose(data.dq_ref, dq_ref, rtol=0, atol=1e-12)
        # the gradients from the interleaved horizon of CondensedMPC, the inputs −H⁻¹g
        horizon = np.empty((2 * mpc.N, 3))
        horizon[0::2], horizon[1::2] = q_ref, dq_ref
        G = mpc.gradient(np.vstack([q, dq]), horizon)
        scale_g = np.abs(G).max()
        np.testing.assert_allclose(ctrl._core.gradients, G, rtol=0, atol=1e-12 * scale_g)
        U = -np.linalg.solve(mpc.H, G.T)  # (Nc, n), every joint inside its box
        assert np.all(np.abs(U) < 0.5 * ctrl.settings.bounds(3)[1])
        np.testing.assert_allclose(ctrl.qps.solution, U, rtol=1e-9, atol=1e-12)
        np.testing.assert_array_equal(ctrl.v, ctrl.qps.solution[0])
        np.testing.assert_array_equal(ctrl.qps.slack, 0.0)
        # Eq (4) from Pinocchio, with the observer's d̂ (the same view) and Eq (13)'s z
        M = pin.crba(robot.model, pdata, q)
        M = np.triu(M) + np.triu(M, 1).T
        nle = pin.nonLinearEffects(robot.model, pdata, q, dq)
        d_hat = ctrl.disturbance_estimate
        np.testing.assert_array_equal(d_hat, ctrl.compensation.estimate)
        obs = ctrl.compensation
        np.testing.assert_allclose(obs.z + obs.cY @ dq, d_hat, rtol=0, atol=1e-12)
        scale = np.abs(M @ ctrl.v).max() + np.abs(nle).max()
        np.testing.assert_allclose(ctrl.tau, M @ ctrl.v + nle - d_hat, rtol=0, atol=1e-12 * scale)


def test_warm_up_restores_the_data(planar3):
    """A dry step leaves the step's data, the QPs' solution and slack as they were."""
    ctrl, ref, states = _stepped(planar3)
    t, q, dq = states[-1]
    data = ctrl.data
    views = (data.stack, data.v, data.tau, data.d_hat, ctrl.qps.solution, ctrl.qps.slack)
    before = [v.copy() for v in views]
    ctrl.warm_up(t + ctrl.Ts, q + 0.01, dq - 0.02, ref)
    for a, b in zip(before, views, strict=True):
        np.testing.assert_array_equal(a, b)


def test_the_observer_owns_its_state_and_pickles():
    """z and d̂ are read-only views of the compiled observer's vectors; a pickled or copied
    observer carries them (its own new compiled object) and goes on as the original."""
    obs = DisturbanceObserver(2, 0.001, gain=20.0)
    obs.reset(np.zeros(2), np.array([0.1, -0.2]))
    M, nle = np.diag([1.0, 2.0]), np.array([0.3, 0.4])
    obs.update(M, nle, np.zeros(2), np.array([0.1, -0.2]), np.zeros(2), np.zeros(2))
    assert not obs.z.flags.writeable and not obs.estimate.flags.writeable
    np.testing.assert_allclose(obs.z + obs.cY @ np.array([0.1, -0.2]), obs.estimate, atol=1e-15)
    for other in (pickle.loads(pickle.dumps(obs)), copy.deepcopy(obs)):
        np.testing.assert_array_equal(other.z, obs.z)
        assert other.compiled_port() is not obs.compiled_port()
        a = obs.update(M, nle, np.zeros(2), np.array([0.2, 0.1]), np.ones(2), np.zeros(2))
        b = other.update(M, nle, np.zeros(2), np.array([0.2, 0.1]), np.ones(2), np.zeros(2))
        np.testing.assert_array_equal(a, b)
        obs.reset(np.zeros(2), np.array([0.1, -0.2]))
        obs.update(M, nle, np.zeros(2), np.array([0.1, -0.2]), np.zeros(2), np.zeros(2))


@pytest.mark.filterwarnings("ignore::hmpc_pin.exceptions.ValidityWarning")
def test_a_python_model_fills_the_data():
    """Without compiled dynamics (mimic joints) the step keeps the model's M and C q̇ + G
    (+ the URDF's joint terms) in its data: equal to Pinocchio's at the state it was given."""
    robot = hmpc_pin.load_robot("panda")
    assert robot.mimic_joints
    ctrl = hmpc_pin.HierarchicalMPC(robot, hmpc_pin.MPCSettings(joint_dynamics=False))
    q = 0.5 * (robot.lower + robot.upper)
    dq = np.full(robot.nq, 0.1)
    ctrl.reset(q, dq)
    ctrl.step(0.0, q, dq, hmpc_pin.SineReference(robot.nq, amplitude=0.1, offset=q))
    np.testing.assert_allclose(ctrl.data.M, robot.mass_matrix(q), rtol=0, atol=1e-12)
    np.testing.assert_allclose(ctrl.data.nle, robot.nonlinear_effects(q, dq), rtol=0, atol=1e-12)


def test_the_step_refuses_data_of_another_shape(planar3):
    """A step built on data for another horizon or arm, or data assigned from another shape,
    is refused with a message naming the mismatch (nothing is written out of bounds)."""
    from hmpc_pin.native import load

    native = load()
    ctrl = hmpc_pin.HierarchicalMPC(planar3)
    N = ctrl.settings.N
    for n, horizon in ((3, N + 1), (4, N)):
        with pytest.raises(ValueError, match="shapes do not match"):
            data = native.StepData(n, horizon)
            native.HierarchicalStep(None, ctrl.mpc.FT, N, ctrl.qps._core, None, data)
    with pytest.raises(ValueError, match="another shape"):
        ctrl.data.assign(native.StepData(3, N + 1))
