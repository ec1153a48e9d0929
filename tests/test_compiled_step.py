"""``HierarchicalMPC.step`` called without its Python frame (``hmpc_pin._core.CompiledStep``):
for a reference with a compiled port, ``ctrl.step`` is the compiled step bound to the
controller. Checked: its torque is Eq (4) from Pinocchio's own M and C q̇ + G, the step's v
and d̂; a new array each step; every call it does not take (another reference, keywords,
other argument types, wrong shapes, non-finite values) gets what the Python method gives; a
subclass's override and a step set on the instance are kept; the controller is freed."""

from __future__ import annotations

import gc
import weakref

import numpy as np
import pinocchio as pin
import pytest

import hmpc_pin
from hmpc_pin.exceptions import DimensionError, NonFiniteError
from hmpc_pin.native import load, replaced


def _controller(planar3):
    ctrl = hmpc_pin.HierarchicalMPC(planar3)
    ctrl.reset(np.zeros(3), np.zeros(3))
    return ctrl


def test_the_step_is_compiled_and_is_eq4(planar3):
    """After the first step with a compiled reference, ``ctrl.step`` is the compiled step
    (still the class's method for ``replaced``); τ = M v + C q̇ + G − d̂ with M, C q̇ + G
    from Pinocchio's Python API, a new array each step."""
    ctrl = _controller(planar3)
    ref = hmpc_pin.SineReference(3, amplitude=0.2, frequency=0.5)
    ctrl.step(0.0, np.zeros(3), np.zeros(3), ref)
    assert isinstance(ctrl.__dict__["step"], load().CompiledStep)
    assert ctrl.step.__func__ is hmpc_pin.HierarchicalMPC.step and ctrl.step.__self__ is ctrl
    assert not replaced(ctrl, hmpc_pin.HierarchicalMPC, "step")
    assert ctrl.loop_port(ref) is not None
    compiled = ctrl.step
    rng = np.random.default_rng(5)
    model, data = planar3.model, planar3.model.createData()
    previous = None
    for k in range(1, 6):
        q, dq = 0.1 * rng.standard_normal(3), 0.1 * rng.standard_normal(3)
        tau = ctrl.step(k * 0.01, q, dq, ref)
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        nle = pin.nonLinearEffects(model, data, q, dq)
        want = M @ ctrl.v + nle - ctrl.disturbance_estimate
        assert np.max(np.abs(tau - want)) <= 1e-12 * max(1.0, float(np.max(np.abs(want))))
        assert tau is not ctrl.tau and not np.shares_memory(tau, ctrl.tau)
        if previous is not None:
            assert not np.shares_memory(tau, previous)
        previous = tau
    assert compiled.handed_over == 0  # every step above ran without the Python method
    ctrl.step(0.1, q, dq, reference=ref)
    assert compiled.handed_over == 1


def test_the_calls_it_does_not_take_get_the_python_methods_answers(planar3):
    """Keywords, an integer or numpy time, lists, a strided vector: the same torque as the
    Python method on a twin controller; wrong shapes and non-finite values: its errors."""
    ref = hmpc_pin.SineReference(3, amplitude=0.2, frequency=0.5)
    a, b = _controller(planar3), _controller(planar3)
    q, dq = np.full(3, 0.05), np.full(3, -0.02)
    wide = np.zeros(6)
    wide[::2] = q
    calls = [
        ((0.0, q, dq, ref), {}),
        ((np.float64(0.01), q, dq, ref), {}),
        ((0.02, q.tolist(), dq.tolist(), ref), {}),
        ((0.03, wide[::2], dq, ref), {}),
        ((0.04,), {"q": q, "dq": dq, "reference": ref}),
    ]
    for args, kwargs in calls:
        got = a.step(*args, **kwargs)
        want = hmpc_pin.HierarchicalMPC.step(b, *args, **kwargs)
        assert np.array_equal(got, want)
    assert isinstance(a.__dict__["step"], load().CompiledStep)
    with pytest.raises(DimensionError):
        a.step(0.05, np.zeros(4), dq, ref)
    with pytest.raises(DimensionError):
        a.step(0.05, q, np.zeros(2), ref)
    with pytest.raises(NonFiniteError):
        a.step(0.05, np.array([0.0, np.nan, 0.0]), dq, ref)
    with pytest.raises(NonFiniteError):
        a.step(float("inf"), q, dq, ref)


def test_another_reference_is_taken_and_the_compiled_step_follows_it(planar3):
    ctrl = _controller(planar3)
    slow = hmpc_pin.SineReference(3, amplitude=0.2, frequency=0.5)
    fast = hmpc_pin.SineReference(3, amplitude=0.2, frequency=2.0)
    ctrl.step(0.0, np.zeros(3), np.zeros(3), slow)
    ctrl.step(0.5, np.zeros(3), np.zeros(3), fast)
    assert ctrl.step.reference is fast
    # the horizon the step sampled is the new reference's
    q_ref, _ = fast.sample_many(0.5 + ctrl.Ts * np.arange(1, ctrl.settings.N + 1))
    assert np.max(np.abs(ctrl.data.q_ref - q_ref)) <= 1e-12


def test_a_python_reference_drops_the_compiled_step(planar3):
    """A reference sampled in Python (no compiled port) goes through the Python method."""

    class Still:
        def sample(self, t):
            return np.full(3, 0.1), np.zeros(3)

    ctrl = _controller(planar3)
    ctrl.step(0.0, np.zeros(3), np.zeros(3), hmpc_pin.SineReference(3))
    assert "step" in ctrl.__dict__
    ctrl.step(0.01, np.zeros(3), np.zeros(3), Still())
    assert "step" not in ctrl.__dict__
    assert np.allclose(ctrl.data.q_ref, 0.1)


def test_a_new_compensation_drops_the_compiled_step_of_the_old_core(planar3):
    ctrl = _controller(planar3)
    ref = hmpc_pin.SineReference(3)
    ctrl.step(0.0, np.zeros(3), np.zeros(3), ref)
    ctrl.compensation = hmpc_pin.compensation.observers.DisturbanceObserver(3, ctrl.Ts, 50.0)
    assert "step" not in ctrl.__dict__
    ctrl.reset(np.zeros(3), np.zeros(3))
    ctrl.step(0.0, np.zeros(3), np.zeros(3), ref)
    assert ctrl._core.started  # the step ran on the new core


def test_an_override_or_a_spy_is_kept(planar3):
    calls = []

    class Counted(hmpc_pin.HierarchicalMPC):
        def step(self, t, q, dq, reference):
            calls.append(t)
            return super().step(t, q, dq, reference)

    ref = hmpc_pin.SineReference(3)
    sub = Counted(planar3)
    sub.reset(np.zeros(3), np.zeros(3))
    for k in range(3):
        sub.step(0.01 * k, np.zeros(3), np.zeros(3), ref)
    assert calls == [0.0, 0.01, 0.02] and "step" not in sub.__dict__

    ctrl = _controller(planar3)
    ctrl.step(0.0, np.zeros(3), np.zeros(3), ref)
    inner = ctrl.step
    spied = []

    def spy(*args):
        spied.append(args[0])
        return inner(*args)

    ctrl.step = spy
    ctrl.step(0.01, np.zeros(3), np.zeros(3), ref)
    ctrl.step(0.02, np.zeros(3), np.zeros(3), hmpc_pin.SineReference(3))  # a new reference
    assert spied == [0.01, 0.02] and ctrl.step is spy
    assert replaced(ctrl, hmpc_pin.HierarchicalMPC, "step")


def test_the_controller_is_freed(planar3):
    ctrl = _controller(planar3)
    ctrl.step(0.0, np.zeros(3), np.zeros(3), hmpc_pin.SineReference(3))
    step = ctrl.step
    alive = weakref.ref(ctrl)
    del ctrl
    gc.collect()
    assert alive() is None
    with pytest.raises(ReferenceError):
        step(0.01, np.zeros(3), np.zeros(3), None)
