"""Numerical faults injected during a run (issue 7, item 2).

Each fault is injected at a chosen control step; the run must stop at exactly that
step, keep everything computed before it bit-for-bit (compared with an undisturbed
run), and save a result marked ``complete = False``.
"""

from __future__ import annotations

import numpy as np
import pytest

import hmpc_pin
from hmpc_pin.apps.cli import main
from hmpc_pin.sim.plants import RK4Plant

from .conftest import CONFIGS, PLANAR3

TS = 0.01
K0 = 37  # the step at which the faults are injected (t = 0.37 s)


class Faulty:
    """Wraps a controller (same duck-typed interface) and breaks it from step ``k0`` on."""

    def __init__(self, controller, k0: int, fault: str):
        self.controller, self.k0, self.fault = controller, k0, fault
        self.Ts = controller.Ts

    @property
    def disturbance_estimate(self):
        return self.controller.disturbance_estimate

    def reset(self, q0, dq0):
        self.controller.reset(q0, dq0)

    def step(self, t, q, dq, reference):
        k = round(t / self.Ts)
        if k >= self.k0 and self.fault == "iteration cap":
            # the real ProxSuite QPs, capped at one iteration: the solver stops with
            # PROXQP_MAX_ITER_REACHED and the status check must catch it
            qps = self.controller.qps
            qps.max_iter = 1
            qps.shortcut = False  # no unconstrained shortcut: every QP to ProxSuite
        tau = self.controller.step(t, q, dq, reference)
        if k >= self.k0 and self.fault == "nan torque":
            tau[1] = np.nan
        return tau


def _run(planar3, controller=None, disturbance=None, **kw):
    controller = controller or hmpc_pin.HierarchicalMPC(planar3)
    dist = hmpc_pin.CoulombViscousFriction([10.0, 8.0, 5.0], [3.0, 2.4, 1.8])
    if disturbance is not None:
        dist = dist + disturbance
    # The same plant in every run (a user callable: called per stage), and the runs are
    # compared bit for bit with the clean one.
    # (The sign law: the fused friction and the sum with a function equal bit for bit; the
    # stick-slip law's function path adds the friction back and subtracts it: to rounding.)
    plant = RK4Plant(planar3.copy(), dist, 0.01, 0.001, coulomb="sign")
    return hmpc_pin.simulate(
        planar3, controller, hmpc_pin.SineReference(3), plant=plant,
        duration=kw.pop("duration", 0.6), q0=np.ones(3), **kw,
    )  # fmt: skip


@pytest.fixture(scope="module")
def clean(planar3):
    return _run(planar3)


def _check_prefix(partial, clean, kept: int):
    """``partial`` holds exactly the first ``kept`` samples of ``clean``, bit for bit."""
    assert not partial.complete and len(partial.t) == kept
    for name in ("t", "q", "dq", "d", "d_hat", "q_ref", "dq_ref"):
        np.testing.assert_array_equal(getattr(partial, name), getattr(clean, name)[:kept])


def _saved_incomplete(result, tmp_path):
    back = hmpc_pin.Result.load(result.save(tmp_path / "partial.npz"))
    assert back.complete is False and back.message == result.message
    np.testing.assert_array_equal(back.q, result.q)
    return back


def test_nan_torque_stops_at_that_step(planar3, clean, tmp_path):
    ctrl = Faulty(hmpc_pin.HierarchicalMPC(planar3), K0, "nan torque")
    with pytest.raises(hmpc_pin.SimulationError, match=r"step 37 \(t=0\.37 s\)") as info:
        _run(planar3, ctrl)
    r = info.value.result
    assert "tau is not finite at t=0.37" in r.message
    assert r.meta["failed_step"] == K0 and r.meta["failed_at"] == pytest.approx(0.37)
    # the step's own state and bad torque are recorded: K0 + 1 samples
    _check_prefix(r, clean, K0 + 1)
    np.testing.assert_array_equal(r.tau[:K0], clean.tau[:K0])
    assert np.isnan(r.tau[K0, 1])
    _saved_incomplete(r, tmp_path)


def test_non_finite_plant_state_from_a_disturbance(planar3, clean, tmp_path):
    """The disturbance returns inf from t = 0.375 s on, inside the period [0.37, 0.38):
    detected at the end of that period (step 37), every sample up to t = 0.37 kept."""

    def blow_up(t, q, dq):
        return np.full(3, np.inf) if t >= 0.375 else np.zeros(3)

    with pytest.raises(hmpc_pin.SimulationError, match=r"step 37 \(t=0\.37 s\)") as info:
        _run(planar3, disturbance=blow_up)
    r = info.value.result
    assert "plant state is not finite at t=0.38" in r.message
    assert r.meta["failed_step"] == K0
    _check_prefix(r, clean, K0 + 1)
    np.testing.assert_array_equal(r.tau, clean.tau[: K0 + 1])
    _saved_incomplete(r, tmp_path)


@pytest.mark.parametrize("layout", ["block", "joint"])
def test_qp_iteration_cap_is_a_solver_error_at_that_step(planar3, clean, tmp_path, layout):
    # the compiled QPs are capped below (JointQPs.max_iter, the shortcut off)
    config = hmpc_pin.ControllerConfig(qp_layout=layout)
    base = hmpc_pin.make_controller(planar3, config)
    ctrl = Faulty(base, K0, "iteration cap")
    with pytest.raises(hmpc_pin.SimulationError, match=r"step 37 \(t=0\.37 s\)") as info:
        _run(planar3, ctrl)
    assert isinstance(info.value.__cause__, hmpc_pin.SolverError)
    r = info.value.result
    assert "MAX_ITER_REACHED" in r.message and "QP was not solved" in r.message
    # the controller failed before returning a torque for step 37: steps 0..36 kept
    assert r.meta["failed_step"] == K0
    assert len(r.t) == K0
    np.testing.assert_allclose(r.q, clean.q[:K0], rtol=0, atol=1e-9)  # layouts agree to tol
    _saved_incomplete(r, tmp_path)


def test_divergence_beyond_the_configured_bound(planar3, clean, tmp_path):
    """state_bound below the start-up transient's peak speed: the run stops after the
    first period that ends beyond it, the samples before are the undisturbed run's."""
    bound = 3.0
    peak = np.maximum(np.abs(clean.q), np.abs(clean.dq)).max(axis=1)
    first = int(np.argmax(peak > bound))  # first sample beyond the bound
    assert 0 < first < len(clean.t) - 1
    with pytest.raises(hmpc_pin.SimulationError, match="diverged") as info:
        _run(planar3, state_bound=bound)
    r = info.value.result
    assert r.meta["failed_step"] == first - 1 and f"t={clean.t[first]:.6g}" in r.message
    _check_prefix(r, clean, first)
    _saved_incomplete(r, tmp_path)


def test_cli_divergence_from_config_state_bound_exits_1(tmp_path, capsys):
    text = (CONFIGS / "paper_combined.toml").read_text()
    text = text.replace('model = "planar3"', f'urdf = "{PLANAR3.as_posix()}"')
    text = text.replace("state_bound = 1000.0", "state_bound = 3.0")
    cfg = tmp_path / "paper_combined.toml"
    cfg.write_text(text)
    out = tmp_path / "out"
    assert main(["run", str(cfg), "--out", str(out), "--duration", "2"]) == 1
    err = capsys.readouterr().err
    assert "run failed" in err and "state_bound=3" in err
    r = hmpc_pin.Result.load(out / "paper_combined.npz")
    assert r.complete is False and r.meta["state_bound"] == 3.0
    assert 0 < r.t[-1] < 0.5 and r.meta["failed_at"] == pytest.approx(r.t[-1])
    peak = np.maximum(np.abs(r.q), np.abs(r.dq)).max(axis=1)
    assert peak.max() <= 3.0  # every sample kept is inside the bound
    assert not list(out.glob("*.part"))
