"""Tests of :mod:`hmpc_pin.experiment.build` and of the limit handling it wires together:
arms from example-robot-data in closed loop, joint limits as MPC state constraints,
reference and initial-state checks, effort saturation, inertia-scaled disturbances."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import hmpc_pin
from hmpc_pin.apps.metrics import compute_metrics
from hmpc_pin.exceptions import LimitError
from hmpc_pin.experiment.build import Experiment
from hmpc_pin.experiment.config import ConstraintConfig, ControllerConfig, load_config
from hmpc_pin.sim.simulate import simulate

from .conftest import CONFIGS, PLANAR3


@pytest.mark.parametrize("name", ["ur5_sine", "panda_sine", "z1_sine"])
def test_arm_closed_loop_meets_bounds(name):
    """Every joint tracks within RMS 5e-3 rad after 1 s, no limit crossed by 1e-3 rad,
    under inertia-scaled friction + pulses (3 s of the 10 s scenario: the first pulses)."""
    result = Experiment.from_config(load_config(CONFIGS / f"{name}.toml")).run(3.0)
    m = compute_metrics(result)
    assert result.complete
    assert (m.rms_error <= 5e-3).all(), m.rms_error
    assert (m.limit_violation <= 1e-3).all(), m.limit_violation
    # the disturbance was real: without the observer the error is far larger
    base = Experiment.from_config(load_config(CONFIGS / f"{name}.toml"), observer=False).run(3.0)
    assert compute_metrics(base).rms_error.max() > 5 * m.rms_error.max()


def pushed_run(planar3, enabled: bool):
    """Joint 1 told to follow a sine of amplitude 2 rad against its ±π/2 limit."""
    config = ControllerConfig(constraints=ConstraintConfig(enabled=enabled))
    ctrl = hmpc_pin.make_controller(planar3, config)
    ref = hmpc_pin.SineReference(3, amplitude=np.array([2.0, 0.3, 0.3]), frequency=0.25)
    return simulate(planar3, ctrl, ref, duration=3.0, q0=np.zeros(3)), ctrl


def test_state_constraints_keep_a_pushed_joint_inside_its_limit(planar3):
    """The constrained MPC holds joint 1 within limit + 1e-3 rad; unconstrained it crosses."""
    upper = planar3.upper[0]
    free, _ = pushed_run(planar3, enabled=False)
    held, _ = pushed_run(planar3, enabled=True)
    assert free.q[:, 0].max() > upper + 0.1
    assert held.q[:, 0].max() <= upper + 1e-3
    assert held.q[:, 0].max() > upper - 0.05  # it did go to the limit
    # away from the limit both track alike: the constraint is not active there
    early = held.t < 0.3
    np.testing.assert_allclose(held.q[early], free.q[early], atol=1e-9)


def test_reference_outside_limits_names_joint_and_time(write_config):
    path = write_config(
        '[robot]\nurdf = "@URDF@"\n[reference]\namplitude = [1.0, 1.6, 1.0]\n'
        "frequency = 0.1\n[simulation]\nduration = 10.0\n"
    )
    with pytest.raises(LimitError) as info:
        Experiment.from_config(load_config(path))
    err = info.value
    assert err.joint == "joint2" and err.value > planar3_upper()
    # sin(0.2πt) first exceeds π/2 / 1.6 at t = asin(π/3.2) / 0.2π ≈ 2.18 s
    t_cross = np.arcsin(np.pi / 2 / 1.6) / (0.2 * np.pi)
    assert t_cross <= err.time <= t_cross + 0.01
    assert "joint2" in str(err) and "t=" in str(err)


def planar3_upper():
    return np.pi / 2


def test_initial_state_outside_limits_is_refused(write_config):
    path = write_config('[robot]\nurdf = "@URDF@"\n[simulation]\nq0 = [0.0, 1.7, 0.0]\n')
    with pytest.raises(
        LimitError, match=r"initial position \(simulation\.q0\) of joint 'joint2' is 1\.7"
    ):
        Experiment.from_config(load_config(path))


def test_disabled_constraints_skip_the_limit_checks(write_config):
    path = write_config(
        '[robot]\nurdf = "@URDF@"\n[controller.constraints]\nenabled = false\n'
        "[simulation]\nq0 = [0.0, 1.7, 0.0]\n"
    )
    exp = Experiment.from_config(load_config(path))
    assert exp.controller.limits is None and exp.q0[1] == 1.7


class ClippingController:
    """Wraps a controller and clips its torque itself: the independent saturation path."""

    def __init__(self, inner, limit):
        self.inner, self.limit = inner, limit
        self.Ts = inner.Ts

    def reset(self, q0, dq0):
        self.inner.reset(q0, dq0)

    @property
    def disturbance_estimate(self):
        return self.inner.disturbance_estimate

    def step(self, t, q, dq, reference):
        return np.clip(self.inner.step(t, q, dq, reference), -self.limit, self.limit)


def test_effort_saturation_equals_clipping_in_the_controller(planar3):
    """Plant saturation gives the same trajectory as a controller that clips its own
    output, and reports the number of saturated periods and the largest excess."""
    limit = np.array([150.0, 80.0, 40.0])
    ref = hmpc_pin.SineReference(3)
    q0 = np.ones(3)
    sat = simulate(planar3, hmpc_pin.HierarchicalMPC(planar3), ref, duration=1.0, q0=q0,
                   effort_limit=limit)  # fmt: skip
    own = simulate(planar3, ClippingController(hmpc_pin.HierarchicalMPC(planar3), limit), ref,
                   duration=1.0, q0=q0)  # fmt: skip
    np.testing.assert_allclose(sat.q, own.q, atol=1e-12)
    report = sat.meta["saturation"]
    commanded = sat.tau[:-1]  # the last sample's torque is never applied
    np.testing.assert_array_equal(report["steps"], (np.abs(commanded) > limit).sum(axis=0))
    np.testing.assert_allclose(report["max_excess"], (np.abs(commanded) - limit).max(axis=0))
    assert min(report["steps"]) > 0


def test_inertia_scaled_disturbance_uses_diagonal_of_mass_matrix():
    import pinocchio as pin

    cfg = load_config(CONFIGS / "panda_sine.toml")
    exp = Experiment.from_config(cfg)
    full = pin.buildModelFromUrdf(exp.robot.source)
    full.gravity.linear = np.array([0.0, 0.0, -9.81])
    M_full = pin.crba(full, full.createData(), np.concatenate([exp.q0, [0.02, 0.02]]))
    Mii = np.diag(M_full)[:7]
    dq = np.full(7, 0.5)
    # at t = 0 the pulses (centres 1..7 s, σ = 0.3 s) are below 1e-2 of their peak
    d = exp.disturbance(0.0, exp.q0, dq)
    pulse = Mii * np.exp(-((0.0 - np.arange(1, 8)) ** 2) / (2 * 0.3**2))
    np.testing.assert_allclose(d, -(2.0 * Mii * dq + 0.5 * Mii) + pulse, rtol=1e-10)


def test_replace_keeps_validation():
    cfg = load_config(CONFIGS / "ur5_sine.toml")
    with pytest.raises(hmpc_pin.ConfigError):
        replace(cfg.controller, N=0)


@pytest.mark.parametrize(
    ("kind", "observer", "expected"),
    [
        ("hmpc", False, "hmpc+none"),
        ("hmpc", None, "hmpc+chen"),
        ("hmpc-momentum", False, "hmpc+none"),
        ("hmpc-momentum", None, "hmpc+momentum"),
        ("hmpc-momentum", True, "hmpc+momentum"),
        ("hmpc-none", True, "hmpc+chen"),
        ("hmpc-none", None, "hmpc+none"),
        ("hmpc-ism", False, "hmpc+none"),  # observer=False: no compensation at all
        ("hmpc-ism", None, "hmpc+ism"),
        ("hmpc-ism-bl", True, "hmpc+chen"),
        ("computed-torque", False, "computed-torque+none"),
        ("computed-torque", None, "computed-torque+none"),
        ("computed-torque-pid", True, "computed-torque-pid+chen"),
        ("hmpc+general", None, "hmpc+general"),
        ("hmpc+general", False, "hmpc+none"),
    ],
)
def test_observer_override_maps_controller_kinds(kind, observer, expected):
    from hmpc_pin.experiment.build import uses_observer, with_controller

    cfg = with_controller(hmpc_pin.ExperimentConfig(), kind, observer)
    cc = cfg.controller
    controller, compensation = expected.split("+")
    assert (cc.kind, cc.compensation, cc.label) == (controller, compensation, expected)
    observing = compensation in ("chen", "general", "momentum")
    assert uses_observer(cc) == observing
    # exactly the tables of the new pair remain
    assert (cc.observer is not None) == observing
    assert (cc.ism is not None) == compensation.startswith("ism")
    assert (cc.computed_torque is not None) == controller.startswith("computed-torque")
    assert (cc.constraints is not None) == (controller == "hmpc")


def test_observer_override_keeps_the_configs_observer():
    from hmpc_pin.experiment.build import uses_observer, with_controller

    cfg = load_config(CONFIGS / "ur5_sine.toml")  # hmpc × general NDO
    assert cfg.controller.label == "hmpc+general"
    on = with_controller(cfg, "hmpc-ism", True)
    assert on.controller.label == "hmpc+general" and uses_observer(on.controller)
    assert on.controller.observer is cfg.controller.observer
    assert with_controller(cfg, compensation="momentum").controller.label == "hmpc+momentum"
    assert with_controller(cfg, "computed-torque").controller.label == "computed-torque+none"
    assert with_controller(cfg, observer=False).controller.label == "hmpc+none"
    assert with_controller(cfg) is cfg  # nothing to change


def test_kind_from_a_config_file_builds_that_controller(write_config):
    from hmpc_pin.controllers.computed_torque import ComputedTorque

    path = write_config(
        '[robot]\nurdf = "@URDF@"\n[controller]\nkind = "computed-torque-pid"\n'
        "[controller.computed_torque]\nki = 500.0\n[simulation]\nduration = 0.5\n"
    )
    exp = Experiment.from_config(hmpc_pin.load_config(path))
    assert isinstance(exp.controller, ComputedTorque) and exp.controller.ki == 500.0
    meta = exp.run().meta
    assert meta["controller"] == "computed-torque-pid+none" and meta["observer"] is False


def test_make_controller_takes_a_whole_experiment_config(planar3):
    """``make_controller(robot, cfg)`` with the ExperimentConfig of a file builds the same
    controller as with its ``controller`` table: same torques on the same states."""
    cfg = load_config(CONFIGS / "paper_combined.toml")
    whole = hmpc_pin.make_controller(planar3, cfg)
    table = hmpc_pin.make_controller(planar3, cfg.controller)
    assert type(whole) is type(table) and whole.Ts == cfg.controller.Ts
    ref = hmpc_pin.SineReference(3)
    rng = np.random.default_rng(3)
    q0 = np.zeros(3)
    whole.reset(q0, q0)
    table.reset(q0, q0)
    for k in range(5):
        q, dq = rng.normal(0, 0.3, 3), rng.normal(0, 0.3, 3)
        np.testing.assert_array_equal(whole.step(k * whole.Ts, q, dq, ref),
                                      table.step(k * table.Ts, q, dq, ref))  # fmt: skip


@pytest.mark.parametrize("bad", [{"kind": "hmpc"}, "configs/paper_combined.toml"])
def test_make_controller_rejects_other_objects_with_the_fix(planar3, bad):
    with pytest.raises(hmpc_pin.exceptions.InterfaceError, match="load_config"):
        hmpc_pin.make_controller(planar3, bad)


def test_reuse_robots_gives_copies_equal_to_a_fresh_load_and_reloads_a_changed_file(tmp_path):
    """Within reuse_robots: a copy per call (independent models), the same dynamics as a
    fresh load; a file changed since is parsed again."""
    from hmpc_pin.experiment.build import load_robot_config, reuse_robots
    from hmpc_pin.experiment.config.robot import RobotConfig

    urdf = tmp_path / "arm.urdf"
    urdf.write_text(PLANAR3.read_text())
    rc = RobotConfig(urdf=str(urdf))
    fresh = load_robot_config(rc)
    q, dq = np.array([0.3, -0.2, 0.5]), np.array([0.1, 0.4, -0.3])
    with reuse_robots():
        a, b = load_robot_config(rc), load_robot_config(rc)
        assert a is not b and a.model is not b.model
        a.model.inertias[1].mass = 99.0  # a copy: the next load does not see it
        c = load_robot_config(rc)
        np.testing.assert_array_equal(c.mass_matrix(q), fresh.mass_matrix(q))
        np.testing.assert_array_equal(c.nonlinear_effects(q, dq), fresh.nonlinear_effects(q, dq))
        np.testing.assert_array_equal(c.joint_damping, fresh.joint_damping)
        urdf.write_text(PLANAR3.read_text().replace('<mass value="1.0"/>', '<mass value="2.50"/>'))
        heavier = load_robot_config(rc)
        assert heavier.mass_matrix(q)[2, 2] > fresh.mass_matrix(q)[2, 2]
