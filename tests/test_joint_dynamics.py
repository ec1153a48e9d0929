"""The arm's own joint dynamics, the URDF's ``<dynamics damping friction>``.

- Parsed: Pinocchio's model carries them as yourdfpy reads them (Z1 declares both).
- Applied by the plants (RK4, Euler, MuJoCo) by default, against closed forms of a single
  joint without gravity: viscous damping :math:`I\\dot\\omega = u - b\\omega` (time constant
  2 ms, below the 10 ms period) and Coulomb friction :math:`I\\dot\\omega = -f`; switched
  off by ``joint_dynamics=False``; the compiled RK4 period equals its oracle with them; each
  MuJoCo dof gets its own joint's values.
- Compensated by the step (compiled observer or one called from Python alike): one
  period from the step's torque takes a damped joint to the velocity the MPC's double
  integrator predicts (the zero-order-hold gain), also from rest against Coulomb
  friction; without compensation it falls short by the closed-form factor; whole runs
  equal the oracle step.
- Config: the keys, the deprecated ``plant.mujoco.import_urdf_dynamics``, a key that does
  not apply.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import replace

import numpy as np
import pytest

import hmpc_pin
from hmpc_pin.compensation.base import NoCompensation
from hmpc_pin.exceptions import ConfigError
from hmpc_pin.experiment.config import ControllerConfig, PlantConfig, load_config
from hmpc_pin.model.catalogue import example_robot_urdf
from hmpc_pin.model.robot import load_robot
from hmpc_pin.sim.plants import EulerPlant, RK4Plant

from .conftest import CONFIGS

I_ZZ = 0.01  # the disc's inertia about the joint axis [kg·m²]
TS = 0.01


def disc_urdf(tmp_path, damping: float, friction: float) -> str:
    """One revolute joint about z turning a disc centred on its axis: no gravity torque,
    M = I_ZZ, and the joint dynamics given."""
    text = f"""<?xml version="1.0"?>
<robot name="disc">
  <link name="base"/>
  <link name="disc">
    <inertial><origin xyz="0 0 0" rpy="0 0 0"/><mass value="1.0"/>
      <inertia ixx="0.02" iyy="0.02" izz="{I_ZZ}" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <joint name="spin" type="revolute">
    <parent link="base"/><child link="disc"/><origin xyz="0 0 0" rpy="0 0 0"/>
    <axis xyz="0 0 1"/><limit lower="-1000" upper="1000" effort="100" velocity="1000"/>
    <dynamics damping="{damping}" friction="{friction}"/>
  </joint>
</robot>
"""
    path = tmp_path / f"disc_{damping}_{friction}.urdf"
    path.write_text(text)
    return str(path)


def damped(t, q0, w0, u, b):
    """Closed form of I ω̇ = u − b ω: (q(t), ω(t))."""
    T, w_inf = I_ZZ / b, u / b
    e = np.exp(-t / T)
    return q0 + w_inf * t + (w0 - w_inf) * T * (1 - e), w_inf + (w0 - w_inf) * e


def make_plant(kind: str, robot, dt: float, **kw):
    if kind == "rk4":
        return RK4Plant(robot, None, TS, dt, **kw)
    if kind == "euler":
        return EulerPlant(robot, None, TS, dt, **kw)
    pytest.importorskip("mujoco")
    from hmpc_pin.sim.mujoco import MuJoCoPlant, MuJoCoSettings

    integrator = kind.split("-")[1]
    return MuJoCoPlant(robot, None, TS, dt, MuJoCoSettings(integrator=integrator,
                                                            geometry="none"))  # fmt: skip


def test_pinocchio_reads_the_urdf_dynamics_as_yourdfpy_does():
    import yourdfpy

    robot = load_robot("z1", 9.81, {"jointGripper": 0.0})
    urdf = yourdfpy.URDF.load(str(example_robot_urdf("z1")), build_scene_graph=False,
                              load_meshes=False)  # fmt: skip
    joints = {j.name: j for j in urdf.robot.joints}
    for j, name in enumerate(robot.joint_names):
        assert robot.joint_damping[j] == float(joints[name].dynamics.damping)
        assert robot.joint_friction[j] == float(joints[name].dynamics.friction)
    assert robot.joint_damping.min() > 0 and robot.joint_friction.min() > 0


# Per integrator: step [s] and the error bound of the method on the damped joint (h/T =
# 0.05): RK4's local error (h/T)^5/120 of the exponential, a first-order method's h/T.
@pytest.mark.parametrize("kind, dt, rtol", [
    ("rk4", 1e-4, 1e-6), ("euler", 1e-4, 0.05), ("mujoco-rk4", 1e-4, 1e-6),
    ("mujoco-implicitfast", 1e-4, 0.05),
])  # fmt: skip
def test_damping_applied_by_the_plants_equals_the_closed_form(tmp_path, kind, dt, rtol):
    b = 5.0  # T = I/b = 2 ms < Ts
    robot = load_robot(disc_urdf(tmp_path, b, 0.0), 9.81)
    plant = make_plant(kind, robot, dt)
    q0, w0, u = 0.2, 3.0, 1.5  # ω from 3 to u/b = 0.3 rad/s
    plant.reset(np.array([q0]), np.array([w0]))
    scale = abs(w0 - u / b)
    for k in range(1, 6):
        q, dq = plant.advance(np.array([u]))
        q_want, w_want = damped(k * TS, q0, w0, u, b)
        assert abs(dq[0] - w_want) <= rtol * scale, (k, dq[0], w_want)
        assert abs(q[0] - q_want) <= rtol * scale * I_ZZ / b + 2 * dt * rtol * scale
    # the key turns it off: the free disc, q̈ = u/I
    if not kind.startswith("mujoco"):
        free = make_plant(kind, robot, dt, joint_dynamics=False)
        free.reset(np.array([q0]), np.array([w0]))
        _, dq = free.advance(np.array([u]))
        assert dq[0] == pytest.approx(w0 + u / I_ZZ * TS, rel=1e-9)


@pytest.mark.parametrize("kind, tol", [("rk4", 1e-12), ("euler", 2e-3), ("mujoco-rk4", 0.02)])
def test_coulomb_friction_decelerates_the_joint_at_f_over_inertia(tmp_path, kind, tol):
    """I ω̇ = −f sgn ω: ω = ω0 − (f/I) t until it stops (at 0.5 s here; checked to 0.3 s).
    MuJoCo's frictionloss is a soft constraint: within 2 % of the dry-friction law."""
    f, w0 = 0.02, 1.0  # f/I = 2 rad/s²
    robot = load_robot(disc_urdf(tmp_path, 0.0, f), 9.81)
    plant = make_plant(kind, robot, 1e-4)
    plant.reset(np.zeros(1), np.array([w0]))
    for k in range(1, 31):
        q, dq = plant.advance(np.zeros(1))
        t = k * TS
        assert dq[0] == pytest.approx(w0 - f / I_ZZ * t, abs=tol * w0)
        assert q[0] == pytest.approx(w0 * t - 0.5 * f / I_ZZ * t**2, abs=tol * w0 * t + 1e-12)


def _planar3_with_dynamics(tmp_path) -> str:
    """planar3 with distinct damping and friction per joint (0.4, 0.5, 0.6; 0.7, 0.8, 0.9)."""
    text = (CONFIGS.parent / "robots" / "planar3.urdf").read_text()
    parts = text.split('<axis xyz="0 -1 0"/>')
    assert len(parts) == 4, "planar3 changed: three joints about -y expected"
    out = parts[0]
    for j, rest in enumerate(parts[1:]):
        out += (f'<axis xyz="0 -1 0"/><dynamics damping="{0.4 + 0.1 * j}" '
                f'friction="{0.7 + 0.1 * j}"/>' + rest)  # fmt: skip
    path = tmp_path / "planar3_dyn.urdf"
    path.write_text(out)
    return str(path)


def test_rk4_period_with_joint_dynamics_equals_the_oracle(tmp_path):
    from .reference.rk4 import rk4_period

    robot = load_robot(_planar3_with_dynamics(tmp_path), 9.81)
    np.testing.assert_allclose(robot.joint_damping, [0.4, 0.5, 0.6])
    np.testing.assert_allclose(robot.joint_friction, [0.7, 0.8, 0.9])
    plant = RK4Plant(robot, None, TS, 0.001, coulomb="sign")  # the oracle's law (the
    # stick-slip law's: tests/test_plant_step.py)
    plant.reset(np.array([0.3, -0.4, 0.2]), np.array([0.5, -0.2, 0.1]))
    joint = (robot.joint_damping, robot.joint_friction)
    signs = set()
    for k in range(100):
        tau = np.array([5.0, 2.0, 1.0]) * np.sin(0.2 * k) + robot.gravity_torque(plant.q)
        want = rk4_period(robot.model, plant.q, plant.dq, tau, plant.disturbance, plant.t,
                          0.001, 10, joint=joint)  # fmt: skip
        q, dq = plant.advance(tau)
        signs.add(tuple(np.sign(dq)))
        np.testing.assert_allclose(q, want[0], rtol=0, atol=1e-12)
        np.testing.assert_allclose(dq, want[1], rtol=0, atol=1e-11)
    assert len(signs) > 2  # the friction's sign switched along the way


def test_each_mujoco_dof_gets_its_own_joints_dynamics(tmp_path):
    pytest.importorskip("mujoco")
    from hmpc_pin.sim.mujoco import mujoco_model

    robot = load_robot(_planar3_with_dynamics(tmp_path), 9.81)
    model = mujoco_model(robot)
    dofs = [model.joint(name).dofadr[0] for name in robot.joint_names]
    np.testing.assert_allclose(model.dof_damping[dofs], robot.joint_damping)
    np.testing.assert_allclose(model.dof_frictionloss[dofs], robot.joint_friction)


def _one_period(robot, dq0: float, joint_dynamics: bool = True):
    """The step's torque at (0, dq0) towards a ramp, and the RK4 plant over one period
    (h = 1e-5 s): (v, velocity gained)."""
    ctrl = hmpc_pin.HierarchicalMPC(
        robot, hmpc_pin.MPCSettings(joint_dynamics=joint_dynamics), NoCompensation(1), None
    )
    ref = hmpc_pin.SineReference(1, amplitude=0.5, frequency=0.5, offset=0.0)
    q0 = np.zeros(1)
    ctrl.reset(q0, np.array([dq0]))
    tau = ctrl.step(0.0, q0, np.array([dq0]), ref)
    plant = RK4Plant(robot, None, TS, 1e-5)
    plant.reset(q0, np.array([dq0]))
    _, dq = plant.advance(tau)
    return float(ctrl.v[0]), float(dq[0] - dq0)


@pytest.mark.parametrize("dq0", [0.8, -0.3])
def test_a_damped_joint_gains_the_velocity_the_mpc_predicts(tmp_path, dq0):
    """T = 2 ms, Ts = 10 ms: with B q̇_k compensated at the sampled velocity the joint
    gains v (1 − e^{−x})/x · Ts, x = Ts/T = 5 (a fifth); the zero-order-hold gain restores
    v·Ts (to the plant's RK4 accuracy)."""
    b = 5.0
    robot = load_robot(disc_urdf(tmp_path, b, 0.0), 9.81)
    v, gained = _one_period(robot, dq0)
    assert abs(v) > 1.0  # a real command
    assert gained == pytest.approx(v * TS, rel=1e-6)
    # without the gain (B q̇_k only): the closed form of the shortfall
    ctrl = hmpc_pin.HierarchicalMPC(robot, hmpc_pin.MPCSettings(), NoCompensation(1), None)
    ctrl._core.set_joint_dynamics(robot.joint_damping, robot.joint_friction, 0.0)
    ref = hmpc_pin.SineReference(1, amplitude=0.5, frequency=0.5, offset=0.0)
    ctrl.reset(np.zeros(1), np.array([dq0]))
    tau = ctrl.step(0.0, np.zeros(1), np.array([dq0]), ref)
    plant = RK4Plant(robot, None, TS, 1e-5)
    plant.reset(np.zeros(1), np.array([dq0]))
    _, dq = plant.advance(tau)
    x = TS * b / I_ZZ
    assert dq[0] - dq0 == pytest.approx(ctrl.v[0] * TS * (-math.expm1(-x)) / x, rel=1e-6)
    # uncompensated, τ = I v: the damped joint's closed form, ω(Ts) = τ/b + (ω0 − τ/b) e^{−x}
    v_off, gained_off = _one_period(robot, dq0, joint_dynamics=False)
    w_inf = I_ZZ * v_off / b
    assert dq0 + gained_off == pytest.approx(w_inf + (dq0 - w_inf) * math.exp(-x), rel=1e-6)


def test_a_joint_at_rest_is_not_left_to_stick(tmp_path):
    """At q̇ = 0 the Coulomb term takes the sign of the commanded velocity q̇ + v·Ts (sgn 0 = 0
    would leave the friction uncompensated): damped and dry, the joint gains v·Ts, to the
    plant's first RK4 stage, which sees sgn 0 = 0 (at most (f/I)·h)."""
    f = 0.5
    robot = load_robot(disc_urdf(tmp_path, 5.0, f), 9.81)
    v, gained = _one_period(robot, 0.0)
    assert gained == pytest.approx(v * TS, abs=f / I_ZZ * 1e-5)
    # uncompensated friction would lose f/b (1 − e^{−x}) = 0.1 rad/s, 200 times that bound


@pytest.mark.parametrize("at", ["end", "start"])
def test_whole_runs_with_joint_dynamics_equal_the_oracle_step(at):
    """Z1 (damping and friction on every joint, the wrist's time constant 0.8 ms) simulated
    with them: every step equals the oracle step (tests/reference/step.py), with the
    observer's model at the end or the start of the period."""
    from .reference.step import OracleHMPC, assert_run_matches

    config = load_config(CONFIGS / "z1_sine.toml")
    obs = replace(config.controller.observer, model_at=at)
    config = replace(
        config,
        controller=replace(config.controller, joint_dynamics=True, observer=obs),
        plant=replace(config.plant, joint_dynamics=True),
        simulation=replace(config.simulation, duration=1.0),
    )
    ex = hmpc_pin.Experiment.from_config(config)
    b, f = ex.controller.joint_dynamics
    assert b.min() > 0 and f.min() > 0
    oracle = OracleHMPC(ex.controller)
    r = ex.run()
    assert r.complete
    assert_run_matches(oracle, r, ex.reference, 5e-8)


def test_config_keys_of_the_joint_dynamics():
    assert PlantConfig().joint_dynamics is True
    assert PlantConfig(joint_dynamics=False).joint_dynamics is False
    assert ControllerConfig().joint_dynamics is True
    with pytest.raises(ConfigError, match="joint_dynamics"):
        ControllerConfig(kind="computed-torque", joint_dynamics=False)
    with pytest.raises(ConfigError, match="joint_dynamics"):
        PlantConfig(joint_dynamics="yes")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        pc = PlantConfig(engine="mujoco", mujoco={"import_urdf_dynamics": False})
    assert pc.joint_dynamics is False
    assert any(issubclass(w.category, DeprecationWarning)
               and "plant.joint_dynamics" in str(w.message) for w in caught)  # fmt: skip
    with pytest.raises(ConfigError, match="import_urdf_dynamics"):
        PlantConfig(engine="mujoco", joint_dynamics=False,
                    mujoco={"import_urdf_dynamics": True})  # fmt: skip


@pytest.mark.parametrize(("at", "latency"), [("end", 0.0), ("start", 0.0), ("start", 0.004)])
def test_a_python_compensation_gets_what_the_compiled_observer_gets(at, latency):
    """Z1 with its joint dynamics: the NDO called through the step's Compensation port
    (given C q̇ + G alone and the applied torque minus the step's joint torque J) gives the
    fused step's run bit for bit, with the observer's model at the end or the start of the
    period, with and without a latency."""
    from .test_native import _Unfused

    config = load_config(CONFIGS / "z1_sine.toml")
    obs = replace(config.controller.observer, model_at=at)
    config = replace(
        config,
        controller=replace(config.controller, joint_dynamics=True, observer=obs, latency=latency),
        plant=replace(config.plant, joint_dynamics=True),
        simulation=replace(config.simulation, duration=1.0),
    )
    runs = []
    for fused in (True, False):
        ex = hmpc_pin.Experiment.from_config(config)
        if not fused:
            ex.controller.compensation = _Unfused(ex.controller.compensation)
        assert ex.controller.fused is fused
        runs.append(ex.run())
    assert np.abs(runs[0].d_hat).max() > 0.01  # the observer was at work
    for name in ("q", "dq", "tau", "d_hat"):
        np.testing.assert_array_equal(getattr(runs[1], name), getattr(runs[0], name))


def test_mujoco_friction_is_coulomb_with_a_short_constraint_time_constant(tmp_path):
    """Damped (T = 2 ms) and dry: I ω̇ = −b ω − f until ω = 0 at t* = T ln((ω0 + f/b)/(f/b)),
    then held. With the friction constraint's time constant at 2 steps MuJoCo meets the
    closed form to 1.5 % of the friction's effect on q and holds the joint; with MuJoCo's
    default 0.02 s it misses it by more than the whole effect (its soft friction)."""
    pytest.importorskip("mujoco")
    from hmpc_pin.sim.mujoco import MuJoCoPlant, MuJoCoSettings

    b, f, w0 = 5.0, 0.5, 3.0
    T, wf = I_ZZ / b, f / b
    t_stop = T * math.log((w0 + wf) / wf)
    q_stop = T * w0 - wf * t_stop  # ∫ω from 0 to t*
    effect = T * w0 * (1 - math.exp(-TS / T)) - q_stop  # of the friction on q(Ts)
    robot = load_robot(disc_urdf(tmp_path, b, f), 9.81)
    for tc, ok in ((2e-4, True), (None, False)):
        settings = MuJoCoSettings(integrator="rk4", geometry="none", friction_timeconst=tc)
        plant = MuJoCoPlant(robot, None, TS, 1e-4, settings)
        plant.reset(np.zeros(1), np.array([w0]))
        q, dq = plant.advance(np.zeros(1))
        if ok:
            assert q[0] == pytest.approx(q_stop, abs=0.015 * effect)
            assert abs(dq[0]) < 1e-6
        else:
            assert abs(q[0] - q_stop) > effect
    with pytest.raises(ConfigError, match="friction_timeconst"):
        MuJoCoSettings(friction_timeconst=-1.0)
    with pytest.raises(ConfigError, match="2 timesteps"):
        PlantConfig(engine="mujoco", mujoco={"friction_timeconst": 0.001, "timestep": 0.001})


def test_a_plant_step_too_long_for_the_urdf_damping_is_refused_naming_the_joint(tmp_path):
    """Z1's wrist (b = 2 N·m·s/rad on a light link): the RK4 plant at 2 ms has
    dt·b·(M⁻¹)_jj above RK4's stability bound, so the run would diverge at once; the config is
    refused before anything runs, and a short enough step or no joint dynamics is accepted."""
    from dataclasses import replace

    from benchmarks.studies.damped_arm import config
    from hmpc_pin.exceptions import ConfigError
    from hmpc_pin.experiment.build import Experiment
    from hmpc_pin.experiment.plants import DAMPING_STEP_LIMIT

    base = config(tmp_path / "z1.toml")
    slow = replace(base, plant=replace(base.plant, dt=2e-3))
    ex = Experiment.from_config(base)  # 0.1 ms: accepted
    M = ex.robot.mass_matrix(ex.q0)
    lam = ex.robot.joint_damping * np.diag(np.linalg.inv(M))  # independent of the package
    assert 2e-3 * lam.max() > DAMPING_STEP_LIMIT["rk4"] >= 1e-4 * lam.max()
    name = ex.robot.joint_names[int(np.argmax(lam))]
    with pytest.raises(ConfigError, match=rf"plant\.dt.*{name}"):
        Experiment.from_config(slow)
    Experiment.from_config(replace(slow, plant=replace(slow.plant, joint_dynamics=False)))


def test_the_observer_model_key():
    """``[controller.observer] model_at`` reaches MPCSettings.model_at under its one name;
    another value is one ConfigError naming the key; the default is MPCSettings'."""
    from hmpc_pin.controllers.hierarchical import MPCSettings
    from hmpc_pin.experiment.config.controller import ObserverConfig
    from hmpc_pin.experiment.controllers import mpc_settings

    assert ObserverConfig().model_at == MPCSettings().model_at == "end"
    cc = ControllerConfig(compensation="general", observer={"model_at": "start"})
    assert mpc_settings(cc, 3).model_at == "start"
    assert mpc_settings(ControllerConfig(compensation="none"), 3).model_at == "end"
    with pytest.raises(ConfigError, match=r"^model_at: expected one of \('end', 'start'\)"):
        ObserverConfig(model_at="middle")
    with pytest.raises(ConfigError, match=r"^MPCSettings\.model_at: expected one of"):
        MPCSettings(model_at="middle")


def test_the_observer_model_name_of_0_2_still_works_with_a_deprecation_warning():
    from dataclasses import replace

    from hmpc_pin.controllers.hierarchical import MPCSettings

    with pytest.warns(DeprecationWarning, match="write model_at"):
        settings = MPCSettings(observer_model="start")
    assert settings.model_at == "start"
    with pytest.warns(DeprecationWarning, match="read model_at"):
        assert settings.observer_model == "start"
    with pytest.warns(DeprecationWarning), pytest.raises(ConfigError, match="model_at"):
        MPCSettings(observer_model="middle")
    with pytest.warns(DeprecationWarning), pytest.raises(ConfigError, match="model_at only"):
        MPCSettings(observer_model="start", model_at="end")
    # replace() passes the fields only: the alias neither warns nor undoes a change
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        assert replace(settings, model_at="end").model_at == "end"
        assert replace(settings, latency=0.002).model_at == "start"


def test_damping_time_constant_uses_the_inertia_with_the_other_joints_free():
    """T_j = 1/(b_j (M⁻¹)_jj): for M = [[2, 1], [1, 1]] (det 1), (M⁻¹)_11 = M_22/det = 1,
    so joint 1 with b = 4 has T = 0.25 s (M_11/b would say 0.5 s); undamped: inf."""
    from hmpc_pin.model.robot import damping_time_constants

    class Arm:
        joint_damping = np.array([4.0, 0.0])

        def mass_matrix(self, q):
            return np.array([[2.0, 1.0], [1.0, 1.0]])

    T = damping_time_constants(Arm(), np.zeros(2))
    assert T[0] == pytest.approx(0.25, rel=1e-12)
    assert np.isinf(T[1])
    Arm.joint_damping = np.zeros(2)
    assert np.isinf(damping_time_constants(Arm(), np.zeros(2))).all()


def test_the_one_joint_law_is_b_dq_plus_f_sign_dq_with_sign_0_zero(make_rng):
    """The compiled law every part evaluates (the RK4 period, the step, the fused friction,
    and from Python the Euler plant, a friction term, dynamics from Python): B q̇ + F sgn q̇
    against numpy, at random velocities and at rest (sgn 0 = 0: no torque at rest), and
    the Coulomb–viscous term is its negative, with scalar coefficients broadcast."""
    from hmpc_pin import native
    from hmpc_pin.sim.disturbances import CoulombViscousFriction

    rng = make_rng(3)
    b, f = rng.uniform(0.0, 5.0, 6), rng.uniform(0.0, 2.0, 6)
    v = np.concatenate([rng.standard_normal(4), [0.0, -0.0]])
    law = native.load().joint_torque(b, f, v)
    np.testing.assert_array_equal(law, b * v + f * np.sign(v))
    assert law[4] == 0.0 and law[5] == 0.0
    term = CoulombViscousFriction(2.0, 0.5)
    np.testing.assert_array_equal(term(0.0, v, v), -(2.0 * v + 0.5 * np.sign(v)))
    with pytest.raises(ValueError, match="one value per joint"):
        native.load().joint_torque(b[:2], f, v)
