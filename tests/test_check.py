"""``hmpc-pin check CONFIG`` (:mod:`hmpc_pin.apps.check`): pass and fail cases.

Each figure against an independent computation: the observer bandwidth from the gain and
M(q0) by Pinocchio's CRBA, the damping time constant from the URDF's value, the headroom
from RNEA at the reference's peak; MuJoCo against a Pinocchio model whose links were
scaled (the engines must then disagree)."""

from __future__ import annotations

import math
import warnings
from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest

from hmpc_pin.apps.check import ENGINE_RTOL, check_config
from hmpc_pin.apps.cli import main
from hmpc_pin.exceptions import ValidityWarning
from hmpc_pin.experiment.build import Experiment
from hmpc_pin.experiment.schema import load_config

from .conftest import CONFIGS

PAPER = CONFIGS / "paper_combined.toml"


def _paper(gain: float = 20.0, **plant):
    config = load_config(PAPER)
    obs = replace(config.controller.observer, gain=gain)
    return replace(config, controller=replace(config.controller, observer=obs),
                   plant=replace(config.plant, **plant))  # fmt: skip


def test_a_fine_config_passes_with_its_figures(capsys, tmp_path):
    config = _paper(1.0)
    report = check_config(config)
    assert report.problems == [], report.problems
    ex = Experiment.from_config(config)
    M0 = pin.crba(ex.robot.model, ex.robot.model.createData(), ex.q0)
    M0 = np.triu(M0) + np.triu(M0, 1).T
    Y = np.tril(np.ones((3, 3)))  # chen
    # the error dynamics w' = -cY M^-1 w: joint j's rate is (cY M^-1)_jj
    np.testing.assert_allclose(report.bandwidth, np.diag(1.0 * Y @ np.linalg.inv(M0)),
                               rtol=1e-10)  # fmt: skip
    assert report.latency == 0.0  # none declared: one period assumed unknown
    limit = 0.5 / (1.25 * (0.01 + 0.01))  # w r (Ts + L) <= 1/2, L = Ts, r = 1.25
    np.testing.assert_allclose(report.margin, limit / report.bandwidth, rtol=1e-12)
    assert np.isinf(report.damping_tau).all()  # planar3 declares no damping
    assert ((report.headroom > 0.1) & (report.headroom < 1)).all()
    if not isinstance(report.engine, str):  # MuJoCo installed: the same arm
        assert max(report.engine) < ENGINE_RTOL
    # the CLI: exit 0, the table
    path = tmp_path / "fine.toml"
    urdf = (CONFIGS.parent / "robots" / "planar3.urdf").resolve().as_posix()
    path.write_text(PAPER.read_text().replace("gain = 100.0", "gain = 1.0")
                    .replace('"../robots/planar3.urdf"', f'"{urdf}"'))  # fmt: skip
    assert main(["check", str(path)]) == 0
    out = capsys.readouterr().out
    assert "no problem found" in out and "joint3" in out


def test_the_papers_fast_observer_is_a_warning_for_an_arm_naming_each_joint(capsys):
    """The paper's gain c = 100: every joint's bandwidth (27, 120, 578 1/s) is above the
    rule's 20 1/s for one undeclared period of latency (Ts = 10 ms, r = 1.25). ``run``
    simulates no latency (the paper's setting): one warning for an arm, exit 0."""
    assert main(["check", str(PAPER), "--no-engine"]) == 0
    out = capsys.readouterr().out
    lines = [x for x in out.splitlines() if x.startswith("warning:")]
    assert len(lines) == 1 and not any(x.startswith("problem:") for x in out.splitlines())
    for name in ("joint1", "joint2", "joint3"):
        assert f"'{name}'" in lines[0]
    assert "above 20 1/s" in lines[0] and "declare its latency" in lines[0]
    assert "the paper's setting, kept" in lines[0] and "no problem found" in out


def test_a_declared_latency_is_compensated_and_lifts_the_bound():
    config = load_config(PAPER)
    config = replace(config, controller=replace(config.controller, latency=0.002))
    report = check_config(config, engines=False)
    assert report.latency == 0.002 and np.isinf(report.margin).all()
    assert report.problems == []


def test_an_explicit_observer_needs_w_ts_below_two():
    config = load_config(PAPER)
    obs = replace(config.controller.observer, discretization="explicit", gain=50.0)
    config = replace(config, controller=replace(config.controller, observer=obs, latency=0.002))
    report = check_config(config, engines=False)
    over = np.flatnonzero(report.bandwidth * 0.01 >= 2.0)
    assert over.size and len(report.problems) == over.size
    assert all("explicit" in p for p in report.problems)


def test_too_little_torque_is_a_problem_per_joint():
    config = _paper(1.0, effort_limit=np.array([1e3, 1e3, 0.5]))
    report = check_config(config, engines=False)
    assert len(report.problems) == 1 and "'joint3'" in report.problems[0]
    # independent: RNEA along the closed-form sine r = sin(0.2πt), r̈ = −(0.2π)² r
    ex = Experiment.from_config(config)
    w = 2 * math.pi * 0.1
    t = np.linspace(0.0, config.simulation.duration, 4001)
    data = ex.robot.model.createData()
    tau3 = [abs(pin.rnea(ex.robot.model, data, np.full(3, math.sin(w * tk)),
                         np.full(3, w * math.cos(w * tk)),
                         np.full(3, -w * w * math.sin(w * tk)))[2]) for tk in t]  # fmt: skip
    # the check samples every Ts/4 and differentiates ṙ centrally: O((w Ts)²) of r̈
    assert report.headroom[2] == pytest.approx(1 - max(tau3) / 0.5, rel=1e-3)


def test_fast_damping_is_a_problem_unless_compensated(tmp_path):
    text = (CONFIGS.parent / "robots" / "planar3.urdf").read_text()
    parts = text.split('<axis xyz="0 -1 0"/>')
    text = parts[0] + "".join(
        '<axis xyz="0 -1 0"/>' + ('<dynamics damping="200.0"/>' if j == 2 else "") + rest
        for j, rest in enumerate(parts[1:])
    )
    urdf = tmp_path / "damped.urdf"
    urdf.write_text(text)
    config = _paper(1.0, dt=1e-4)  # the RK4 plant's step for the 0.64 ms damping
    config = replace(config, robot=replace(config.robot, urdf=urdf, model=None))
    ex = Experiment.from_config(config)
    m3 = 1.0 / np.linalg.inv(ex.robot.mass_matrix(ex.q0))[2, 2]  # the others free
    with warnings.catch_warnings():
        warnings.simplefilter("error", ValidityWarning)  # compensated: no warning
        report = check_config(config, engines=False)
    assert report.damping_tau[2] == pytest.approx(m3 / 200.0)
    assert report.damping_tau[2] < 2 * config.controller.Ts
    assert report.problems == []  # compensated (controller.joint_dynamics = true)
    off = replace(config, controller=replace(config.controller, joint_dynamics=False))
    with pytest.warns(ValidityWarning, match="'joint3'"):  # building it warns as well
        report = check_config(off, engines=False)
    assert len(report.problems) == 1
    assert "'joint3'" in report.problems[0] and "damping time constant" in report.problems[0]


def test_engines_that_disagree_are_detected():
    """MuJoCo compiles the URDF; a controller's model whose last link is 1.5 times heavier
    than the URDF's (Robot.with_scaled_inertias) must differ from it."""
    pytest.importorskip("mujoco")
    from hmpc_pin.apps.check import _engines

    ex = Experiment.from_config(_paper(20.0))
    same = _engines(ex)
    assert max(same) < ENGINE_RTOL
    ex.robot = ex.robot.with_scaled_inertias([1.0, 1.0, 1.5])
    err_M, err_a = _engines(ex)
    assert err_M > 0.01 and err_a > 0.01


@pytest.mark.parametrize("compensation, expected", [("momentum", 100.0), ("ism", None),
                                                    ("none", None)])  # fmt: skip
def test_the_bandwidth_is_the_observers_own(compensation, expected):
    """Momentum observer: K [1/s] itself; no observer (ISM, none): no bandwidth, no margin."""
    from hmpc_pin.experiment.schema import ControllerConfig

    config = load_config(PAPER)
    config = replace(config, controller=ControllerConfig(compensation=compensation, latency=1e-3))
    report = check_config(config, engines=False)
    if expected is None:
        assert report.bandwidth is None and report.margin is None
    else:
        np.testing.assert_array_equal(report.bandwidth, expected)
    assert report.problems == []


def test_a_latency_declared_at_1khz_bounds_the_bandwidth_for_half_a_cycle_too_many():
    """Ts = 1 ms, latency 1 ms declared: the rule for it declared ΔL = 0.5 ms too long,
    ω (r Ts + 2ΔL − 2Ts) <= 1, allows 1/(0.25 ms) = 4000 1/s; the paper's joint 3
    (578 1/s) at 10× passes 4000, the others not: one warning for an arm naming it. In
    ``run`` (no latency) the latency is a whole period too long: Ts ω = 5.78 gives the
    observer's loop a pole outside the unit circle (independently: the roots of
    z³ − (1 − 2g) z² − g z, g = Ts ω/(1 + Ts ω)), a problem whose fix is latency = 0."""
    config = load_config(PAPER)
    obs = replace(config.controller.observer, gain=1000.0)  # 10× the paper's c = 100
    cc = replace(config.controller, Ts=0.001, latency=0.001, observer=obs)
    report = check_config(replace(config, controller=cc), engines=False)
    np.testing.assert_allclose(report.margin, 4000.0 / report.bandwidth, rtol=1e-9)
    over = np.flatnonzero(report.bandwidth > 4000.0)
    assert over.tolist() == [2] and len(report.warnings) == 1
    assert "'joint3'" in report.warnings[0] and "'joint2'" not in report.warnings[0]
    assert "alternate in sign" in report.warnings[0]
    g = 0.001 * report.bandwidth[2] / (1 + 0.001 * report.bandwidth[2])
    assert max(abs(np.roots([1.0, -(1 - 2 * g), -g, 0.0]))) > 1.0
    assert len(report.problems) == 1 and "'joint3'" in report.problems[0]
    assert report.fixes == [{"controller.latency": 0.0}]
