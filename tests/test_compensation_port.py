"""The Compensation port (``cpp/include/hmpc/interfaces.hpp``): a compensation written in
Python runs inside the compiled step, which gives it the model, the measured state, the
applied torque and the acceleration by the same rules as the compiled NDO. Checked against
the step's oracle (``tests/reference/step.py``) with a numpy oracle of the same law."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import hmpc_pin
from hmpc_pin import native

from .reference.step import OracleHMPC, assert_run_matches

CONFIGS = Path(hmpc_pin.__file__).parent / "data" / "configs"
TAU_TOL = 5e-8  # [N·m], the QP tolerance through M (as tests/test_native.py)
GAIN = 0.2  # the filter's weight a per period


class ResidualFilter(native.load().Compensation):
    """d̂_k = d̂_{k-1} + a (M (q̇_k - q̇_{k-1}) / Ts + n - τ - d̂_{k-1}): the inverse-dynamics
    residual of the last period, filtered (a subclass of the bound port)."""

    def __init__(self, n: int, Ts: float, a: float):
        super().__init__(n)
        self.Ts, self.a = Ts, a
        self.dq_prev, self.d = np.zeros(n), np.zeros(n)

    def reset(self, q0, dq0):
        self.dq_prev, self.d = np.array(dq0, dtype=float), np.zeros(len(dq0))

    def update(self, M, nle, q, dq, tau, v):
        self.d = self.d + self.a * (M @ ((dq - self.dq_prev) / self.Ts) + nle - tau - self.d)
        self.dq_prev = np.array(dq, dtype=float)
        return self.d


class ResidualFilterLaw:
    """The numpy oracle of the same law, written as the convex combination
    d̂_k = (1 - a) d̂_{k-1} + a r_k, r_k = M (q̇_k - q̇_{k-1}) / Ts + n_k - τ_{k-1}."""

    def __init__(self, Ts: float, a: float):
        self.Ts, self.a = Ts, a

    def reset(self, q0, dq0):
        self.dq_prev, self.d = np.array(dq0, dtype=float), np.zeros(len(dq0))

    def update(self, M, nle, q, dq, tau, v):
        r = np.linalg.solve(np.linalg.inv(M), (dq - self.dq_prev) / self.Ts) + nle - tau
        self.d = (1.0 - self.a) * self.d + self.a * r
        self.dq_prev = np.array(dq, dtype=float)
        return self.d


class Duck:
    """The same law as a plain object of the Compensation protocol (no subclass)."""

    def __init__(self, n: int, Ts: float, a: float):
        self.inner = ResidualFilterLaw(Ts, a)
        self.estimate = np.zeros(n)
        self.Ts = Ts

    def reset(self, q0, dq0):
        self.inner.reset(q0, dq0)
        self.estimate = np.zeros(len(dq0))

    def update(self, M, nle, q, dq, tau, v):
        self.estimate = self.inner.update(M, nle, q, dq, tau, v)
        return self.estimate


def _experiment(model_at: str, compensation):
    config = hmpc_pin.load_config(CONFIGS / "paper_friction.toml")
    config = replace(config, simulation=replace(config.simulation, duration=1.0))
    ex = hmpc_pin.Experiment.from_config(config)
    ctrl = ex.controller
    ctrl.settings = replace(ctrl.settings, model_at=model_at)
    ctrl.compensation = compensation(ctrl.n, ctrl.Ts)  # rebuilds the step
    return ex


@pytest.mark.parametrize("model_at", ["end", "start"])
def test_a_python_subclass_runs_inside_the_compiled_step(model_at):
    """The subclass's estimate and the step's torque equal the oracle step with the numpy
    law at every step of a closed-loop run with friction (the model at the period's end or
    start)."""
    ex = _experiment(model_at, lambda n, Ts: ResidualFilter(n, Ts, GAIN))
    oracle = OracleHMPC(ex.controller, law=ResidualFilterLaw(ex.controller.Ts, GAIN))
    r = ex.run()
    assert r.complete
    assert np.abs(r.d_hat[-50:]).max() > 1.0  # the friction was estimated
    assert_run_matches(oracle, r, ex.reference, TAU_TOL)


def test_a_protocol_object_and_a_subclass_run_the_same_step():
    """An object of the Compensation protocol (not a subclass) goes through the port's
    adapter: the same law gives the same run."""
    runs = [
        _experiment("end", make).run()
        for make in (
            lambda n, Ts: ResidualFilter(n, Ts, GAIN),
            lambda n, Ts: Duck(n, Ts, GAIN),
        )
    ]
    for name in ("q", "dq", "tau", "d_hat"):
        np.testing.assert_allclose(getattr(runs[1], name), getattr(runs[0], name), atol=1e-9)


class _Short(native.load().Compensation):
    def update(self, M, nle, q, dq, tau, v):
        return np.zeros(len(dq) - 1)


class _NoUpdate(native.load().Compensation):
    pass


def test_a_wrong_estimate_or_a_missing_update_is_named(planar3):
    ref = hmpc_pin.SineReference(3)
    q0, dq0 = ref.sample(0.0)
    for comp, error, match in (
        (_Short(3), hmpc_pin.DimensionError, "Compensation.update"),
        (_NoUpdate(3), TypeError, "must define update"),
    ):
        ctrl = hmpc_pin.HierarchicalMPC(planar3, compensation=comp)
        ctrl.reset(q0, dq0)
        ctrl.step(0.0, q0, dq0, ref)  # the first step does not update
        with pytest.raises(error, match=match):
            ctrl.step(0.01, q0, dq0, ref)


class _LegacyForm:
    """A compensation of 0.3 offering its compiled observer as ``("ndo", observer)``."""

    def __init__(self, inner):
        self.inner = inner

    @property
    def estimate(self):
        return self.inner.estimate

    def reset(self, q0, dq0):
        self.inner.reset(q0, dq0)

    def update(self, M, nle, q, dq, tau, v):
        raise AssertionError("the compiled observer is advanced without Python")

    def compiled_form(self):
        return ("ndo", self.inner._core)


def test_the_tuples_of_03_are_decoded_once_with_a_deprecation_note(planar3):
    """compiled_form() of a user compensation and native_form() of a user reference still
    run compiled (the same torques), each with a DeprecationWarning."""

    class OldSine:
        def __init__(self):
            self.inner = hmpc_pin.SineReference(3)

        def sample_many(self, times, out=None):
            return self.inner.sample_many(times, out)

        def sample(self, t):
            return self.inner.sample(t)

        def native_form(self):
            return self.inner.compiled_sampling().as_tuple()

    ref = hmpc_pin.SineReference(3)
    q0, dq0 = ref.sample(0.0)
    taus = []
    for legacy in (False, True):
        ctrl = hmpc_pin.HierarchicalMPC(planar3)
        reference = ref
        if legacy:
            with pytest.warns(DeprecationWarning, match="compiled_form"):
                ctrl.compensation = _LegacyForm(ctrl.compensation)
            assert ctrl.fused  # the compiled observer, advanced without Python
            reference = OldSine()
        ctrl.reset(q0, dq0)
        out = []
        for k in range(5):
            if legacy and k == 0:
                with pytest.warns(DeprecationWarning, match="native_form"):
                    out.append(ctrl.step(0.01 * k, q0, dq0 + 0.1, reference))
                assert ctrl._native_ref
            else:
                out.append(ctrl.step(0.01 * k, q0, dq0 + 0.1, reference))
        taus.append(np.array(out))
    np.testing.assert_array_equal(taus[1], taus[0])
    assert np.any(taus[0][-1] != taus[0][0])
