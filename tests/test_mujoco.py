"""The MuJoCo plant (hmpc_pin/sim/mujoco.py) against a second engine: Pinocchio.

- Accelerations: MuJoCo's ``qacc`` (``mj_forward``) equals Pinocchio's ABA at random
  states on planar3, UR5, Panda (fingers locked and free) and Z1, to 1e-8 rad/s².
- The URDF cases: ``package://`` and relative mesh paths, a missing or unreadable mesh,
  ``<mimic>`` (dropped as Pinocchio does; MuJoCo's own import adds an equality that
  changes the accelerations), ``<dynamics damping friction>`` (imported by default,
  as the Pinocchio plants apply them: MuJoCo's acceleration is ABA with the damping torque
  −D·q̇), locked joints
  with rotated origins, a URDF MuJoCo cannot compile.
- Contacts: the generalized contact force from the constraint rows equals the sum of
  ``mj_contactForce`` mapped by the contact-point Jacobians, and in steady contact the
  static balance G(q) − τ of Pinocchio's model.
- Closed loops: the NDO on each arm's ``*_mujoco.toml`` (the arm's own joint friction +
  pulses); the contact config (estimate vs contact force, first-contact flag, stop).
- Config and CLI: bad ``[plant]``/``[plant.mujoco]``/``[collision]`` values, missing extra.
"""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

mujoco = pytest.importorskip("mujoco")

from hmpc_pin.apps.cli import main  # noqa: E402
from hmpc_pin.exceptions import ConfigError, ExtraError, URDFError, install_command  # noqa: E402
from hmpc_pin.experiment.build import Experiment  # noqa: E402
from hmpc_pin.experiment.config import PlantConfig, load_config  # noqa: E402
from hmpc_pin.model.catalogue import example_robot_urdf  # noqa: E402
from hmpc_pin.model.robot import load_robot  # noqa: E402
from hmpc_pin.sim.mjcf import mujoco_model, resolve_mesh_path, urdf_for_mujoco  # noqa: E402
from hmpc_pin.sim.mujoco import MuJoCoPlant  # noqa: E402
from hmpc_pin.sim.mujoco_settings import MuJoCoSettings, Obstacle  # noqa: E402
from hmpc_pin.sim.simulate import simulate  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
CONFIGS = ROOT / "configs"
PANDA_FINGERS = {"panda_finger_joint1": 0.02, "panda_finger_joint2": 0.02}
ARMS = {
    "planar3": ("planar3", None),
    "ur5": ("ur5", None),
    "panda": ("panda", PANDA_FINGERS),
    "z1": ("z1", None),
}

#: The bare arm (the URDF's <dynamics> dropped): the rigid-body dynamics alone.
BARE = MuJoCoSettings(import_urdf_dynamics=False)


def _qacc(model, robot, q, dq, tau):
    """MuJoCo's forward dynamics at (q, dq) with tau applied, in the robot's joint order."""
    data = mujoco.MjData(model)
    qadr = [model.joint(j).qposadr[0] for j in robot.joint_names]
    vadr = [model.joint(j).dofadr[0] for j in robot.joint_names]
    data.qpos[qadr] = q
    data.qvel[vadr] = dq
    data.qfrc_applied[vadr] = tau
    mujoco.mj_forward(model, data)
    return data.qacc[vadr].copy()


def _random_states(robot, rng, count=20):
    lo = np.maximum(robot.lower, -3.0)
    hi = np.minimum(robot.upper, 3.0)
    for _ in range(count):
        # strictly inside the limits: MuJoCo's limit constraints stay inactive
        yield (rng.uniform(lo + 0.01 * (hi - lo), hi - 0.01 * (hi - lo)),
               rng.standard_normal(robot.nq), 5.0 * rng.standard_normal(robot.nq))  # fmt: skip


def _planar3_variant(tmp_path, edit, name="variant.urdf") -> Path:
    text = (ROOT / "robots" / "planar3.urdf").read_text()
    path = tmp_path / name
    path.write_text(edit(text))
    return path


# ---------------------------------------------------------------- accelerations
@pytest.mark.parametrize("arm", sorted(ARMS))
def test_accelerations_equal_pinocchio_aba(arm, make_rng):
    source, locked = ARMS[arm]
    robot = load_robot(source, 9.81, locked)
    model = mujoco_model(robot, BARE)
    assert model.nq == robot.nq and model.neq == 0
    for q, dq, tau in _random_states(robot, make_rng(1)):
        expected = pin.aba(robot.model, robot.data, q, dq, tau)
        np.testing.assert_allclose(_qacc(model, robot, q, dq, tau), expected, rtol=0, atol=1e-8)


def test_visual_geometry_adds_no_mass(planar3, make_rng):
    # planar3's tool link has a visual box but no <inertial>: massless for Pinocchio, and
    # so for MuJoCo (inertiafromgeom off), also when visual shapes become collision ones.
    model = mujoco_model(planar3, MuJoCoSettings(geometry="visual"))
    assert model.ngeom > 0
    for q, dq, tau in _random_states(planar3, make_rng(2), 5):
        expected = pin.aba(planar3.model, planar3.data, q, dq, tau)
        np.testing.assert_allclose(_qacc(model, planar3, q, dq, tau), expected, atol=1e-8)


def test_scaled_plant_inertias_scale_mujoco_links(make_rng):
    # The sweep's mass draws: Robot.with_scaled_inertias on the plant, MuJoCo the same.
    robot = load_robot("panda", 9.81, PANDA_FINGERS)
    factors = make_rng(3).uniform(0.8, 1.2, robot.nq)
    scaled = robot.with_scaled_inertias(factors)
    plant = MuJoCoPlant(scaled, None, 0.01, 0.001, BARE)
    for q, dq, tau in _random_states(robot, make_rng(4), 5):
        expected = pin.aba(scaled.model, scaled.data, q, dq, tau)
        np.testing.assert_allclose(_qacc(plant.model, robot, q, dq, tau), expected, atol=1e-8)
        unscaled = pin.aba(robot.model, robot.data, q, dq, tau)
        assert np.abs(expected - unscaled).max() > 1e-3  # the scaling matters here


def test_joints_are_matched_by_name_not_order(planar3, tmp_path, make_rng):
    # The same arm with its joints declared in reverse order in the file.
    text = (ROOT / "robots" / "planar3.urdf").read_text()
    head, rest = text.split("<joint ", 1)
    blocks = ["<joint " + b for b in rest.split("<joint ")]
    tail_split = blocks[-1].split("</joint>", 1)
    blocks[-1] = tail_split[0] + "</joint>"
    links = tail_split[1]
    path = tmp_path / "reversed.urdf"
    path.write_text(head + "".join(reversed(blocks)) + links)
    robot = load_robot(path, 9.8)
    model = mujoco_model(robot)
    for q, dq, tau in _random_states(robot, make_rng(5), 5):
        expected = pin.aba(robot.model, robot.data, q, dq, tau)
        np.testing.assert_allclose(_qacc(model, robot, q, dq, tau), expected, atol=1e-8)


# ----------------------------------------------------------------- URDF cases
def test_package_mesh_paths_resolve_to_files():
    urdf = example_robot_urdf("ur5")
    mesh = "package://example-robot-data/robots/ur_description/meshes/ur5/collision/base.stl"
    path = resolve_mesh_path(mesh, urdf)
    assert path.is_file() and path.name == "base.stl"
    model = mujoco_model(load_robot("ur5"))
    assert model.nmesh >= 7  # every collision mesh compiled
    with pytest.raises(URDFError, match="no-such-package"):
        resolve_mesh_path("package://no-such-package/x.stl", urdf)


def test_relative_and_missing_mesh_paths(tmp_path):
    mesh = tmp_path / "meshes" / "tip.obj"
    mesh.parent.mkdir()
    mesh.write_text(  # a tetrahedron
        "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nv 0 0 0.1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
    )
    collision = '<collision><geometry><mesh filename="meshes/tip.obj"/></geometry></collision>'

    def add_mesh(text):
        return text.replace('<link name="link3">', '<link name="link3">' + collision, 1)

    path = _planar3_variant(tmp_path, add_mesh)
    model = mujoco_model(load_robot(path, 9.8))
    assert model.nmesh == 1
    mesh.unlink()
    with pytest.raises(URDFError, match=r"tip\.obj"):
        mujoco_model(load_robot(path, 9.8))
    # without geometry the missing mesh does not matter (dynamics only)
    assert mujoco_model(load_robot(path, 9.8), MuJoCoSettings(geometry="none")).ngeom == 0


def test_mesh_format_mujoco_cannot_read(tmp_path):
    (tmp_path / "tip.dae").write_text("<COLLADA/>")
    collision = '<collision><geometry><mesh filename="tip.dae"/></geometry></collision>'
    path = _planar3_variant(
        tmp_path, lambda t: t.replace('<link name="link3">', '<link name="link3">' + collision)
    )
    with pytest.raises(URDFError, match=r"tip.dae.*\.stl"):
        mujoco_model(load_robot(path, 9.8))


def test_mimic_joint_is_a_stiff_equality_as_in_pinocchio(tmp_path, make_rng):
    # joint3 mimics joint2 (q3 = 0.5 q2 + 0.1): Pinocchio's mimic joint (no coordinate of
    # its own), MuJoCo's joint equality made stiff: MuJoCo's soft constraint leaves a
    # relative (1 - d)/d = 1e-4 of the constraint's acceleration (3e-4 of the largest
    # acceleration allows for a constraint part up to three times it).
    mimic = '<mimic joint="joint2" multiplier="0.5" offset="0.1"/></joint>'

    def add_mimic(text):
        i = text.index('<joint name="joint3"')
        j = text.index("</joint>", i)
        return text[:j] + mimic + text[j + len("</joint>") :]

    path = _planar3_variant(tmp_path, add_mimic)
    robot = load_robot(path, 9.8)
    assert robot.nq == 2 and robot.mimic_joints == {"joint3": ("joint2", 0.5, 0.1)}
    plant = MuJoCoPlant(robot, None, 0.01, 0.001)
    assert plant.model.neq == 1
    worst_default = 0.0
    raw = mujoco.MjModel.from_xml_path(str(path))  # MuJoCo's own import: default softness
    raw.opt.gravity[:] = plant.model.opt.gravity
    for q, dq, tau in _random_states(robot, make_rng(6), 5):
        plant.reset(q, dq)  # puts the follower on its constraint
        d = plant.data
        d.qfrc_applied[:] = 0.0
        d.qfrc_applied[plant.vadr] = tau
        mujoco.mj_forward(plant.model, d)
        expected = robot.forward_dynamics(q, dq, tau)
        scale = np.abs(expected).max()
        np.testing.assert_allclose(d.qacc[plant.vadr], expected, atol=3e-4 * scale)
        # the constraint's residual acceleration: (1 - d)/d of the unconstrained one
        follower = plant.model.joint("joint3").dofadr[0]
        residual = d.qacc[follower] - 0.5 * d.qacc[plant.vadr[1]]
        plant.model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_EQUALITY)
        mujoco.mj_forward(plant.model, d)
        free = d.qacc[follower] - 0.5 * d.qacc[plant.vadr[1]]
        plant.model.opt.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_EQUALITY)
        assert abs(residual) <= 2e-4 * abs(free)
        rd = mujoco.MjData(raw)
        rd.qpos[:], rd.qvel[:] = plant.data.qpos, plant.data.qvel
        rd.qfrc_applied[:] = d.qfrc_applied
        mujoco.mj_forward(raw, rd)
        worst_default = max(worst_default, np.abs(rd.qacc[plant.vadr] - expected).max() / scale)
    assert worst_default > 1e-2  # MuJoCo's default equality is far softer
    # a follower the controller controls as its own coordinate loses the tag; one that is
    # neither controlled, nor a mimic joint of the model, nor locked cannot be matched
    assert "<mimic" not in urdf_for_mujoco(path, ("joint1", "joint2", "joint3"))
    with pytest.raises(URDFError, match="mimics"):
        urdf_for_mujoco(path, ("joint1", "joint2"))


def test_panda_mimic_fingers_free_and_locked(make_rng):
    # Panda's finger 2 mimics finger 1: free, one equality and 8 coordinates; locked, none.
    free = load_robot("panda")
    plant = MuJoCoPlant(free, settings=BARE)
    locked = mujoco_model(load_robot("panda", 9.81, PANDA_FINGERS), BARE)
    assert (plant.model.neq, plant.model.nq, free.nq, locked.neq, locked.nq) == (1, 9, 8, 0, 7)
    for q, dq, tau in _random_states(free, make_rng(10), 5):
        plant.reset(q, dq)
        plant.data.qfrc_applied[plant.vadr] = tau
        mujoco.mj_forward(plant.model, plant.data)
        expected = free.forward_dynamics(q, dq, tau)
        scale = np.abs(expected).max()
        np.testing.assert_allclose(plant.data.qacc[plant.vadr], expected, atol=3e-4 * scale)


def test_urdf_damping_imported_by_default_and_dropped_on_request(tmp_path, make_rng):
    def add_dynamics(text):
        return text.replace(
            '<axis xyz="0 -1 0"/>', '<axis xyz="0 -1 0"/><dynamics damping="0.7" friction="0.4"/>'
        )

    robot = load_robot(_planar3_variant(tmp_path, add_dynamics), 9.8)
    dropped = mujoco_model(robot, BARE)
    np.testing.assert_array_equal(dropped.dof_damping, 0.0)
    np.testing.assert_array_equal(dropped.dof_frictionloss, 0.0)
    np.testing.assert_allclose(robot.joint_damping, 0.7)  # Pinocchio's model carries them
    np.testing.assert_allclose(robot.joint_friction, 0.4)
    imported = mujoco_model(robot, MuJoCoSettings(damping=0.1))  # the default imports
    np.testing.assert_allclose(imported.dof_damping, 0.8)  # URDF's + configured
    np.testing.assert_allclose(imported.dof_frictionloss, 0.4)
    imported.dof_frictionloss[:] = 0.0  # damping alone: M q̈ = τ − D q̇ − C q̇ − G
    for q, dq, tau in _random_states(robot, make_rng(7), 5):
        expected = pin.aba(robot.model, robot.data, q, dq, tau - 0.8 * dq)
        np.testing.assert_allclose(_qacc(imported, robot, q, dq, tau), expected, atol=1e-8)


def test_per_joint_friction_damping_armature_in_controller_order(planar3):
    s = MuJoCoSettings(frictionloss=(1.0, 2.0, 3.0), damping=(4.0, 5.0, 6.0), armature=0.5)
    model = mujoco_model(planar3, s)
    order = [model.joint(j).dofadr[0] for j in planar3.joint_names]
    np.testing.assert_allclose(model.dof_frictionloss[order], [1.0, 2.0, 3.0])
    np.testing.assert_allclose(model.dof_damping[order], [4.0, 5.0, 6.0])
    np.testing.assert_allclose(model.dof_armature[order], 0.5)
    with pytest.raises(ConfigError, match="3 joints"):
        mujoco_model(planar3, MuJoCoSettings(damping=(1.0, 2.0)))


def test_armature_is_rotor_inertia_on_the_diagonal(planar3, make_rng):
    model = mujoco_model(planar3, MuJoCoSettings(armature=(0.1, 0.2, 0.3)))
    for q, dq, tau in _random_states(planar3, make_rng(8), 3):
        M = planar3.mass_matrix(q) + np.diag([0.1, 0.2, 0.3])
        expected = np.linalg.solve(M, tau - planar3.nonlinear_effects(q, dq))
        np.testing.assert_allclose(_qacc(model, planar3, q, dq, tau), expected, atol=1e-8)


@pytest.mark.parametrize(
    "arm,joint,value",
    [("ur5", "wrist_2_joint", 0.7), ("panda", "panda_joint4", -2.0), ("planar3", "joint2", -0.4)],
)
def test_locked_joint_is_fixed_at_its_position(arm, joint, value, make_rng):
    locked = {joint: value, **(PANDA_FINGERS if arm == "panda" else {})}
    robot = load_robot(arm, 9.81, locked)  # pin.buildReducedModel
    model = mujoco_model(robot, BARE)
    assert model.nq == robot.nq and joint not in [model.joint(i).name for i in range(model.njnt)]
    for q, dq, tau in _random_states(robot, make_rng(9), 5):
        expected = pin.aba(robot.model, robot.data, q, dq, tau)
        np.testing.assert_allclose(_qacc(model, robot, q, dq, tau), expected, atol=1e-8)


def test_urdf_mujoco_cannot_compile_names_file_and_reason(tmp_path, capsys):
    # The tip link as a point mass (zero rotational inertia about its centre of mass):
    # Pinocchio takes it (M(q) stays positive definite), MuJoCo's compiler does not.
    def massless_tip(text):
        i = text.index('<link name="link3">')
        j = text.index("/>", text.index("<inertia ", i)) + 2
        k = text.index("<inertia ", i)
        return text[:k] + '<inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/>' + text[j:]

    path = _planar3_variant(tmp_path, massless_tip, "massless.urdf")
    robot = load_robot(path, 9.8)
    with pytest.raises(URDFError, match="MuJoCo cannot compile") as info:
        mujoco_model(robot)
    assert str(path) in str(info.value) and "inertia of moving bodies" in str(info.value)
    cfg = tmp_path / "cfg.toml"
    cfg.write_text(f'[robot]\nurdf = "{path.as_posix()}"\n[plant]\nengine = "mujoco"\n')
    assert main(["run", str(cfg), "--out", str(tmp_path), "--duration", "0.1"]) == 2
    err = capsys.readouterr().err
    assert "MuJoCo cannot compile" in err and "massless.urdf" in err
    assert not list(tmp_path.glob("*.npz"))


def test_missing_extra_names_it(monkeypatch, tmp_path, capsys):
    monkeypatch.setitem(sys.modules, "mujoco", None)  # `import mujoco` raises ImportError
    with pytest.raises(ExtraError, match=r"hmpc_pin\[mujoco\]"):
        MuJoCoPlant(load_robot("planar3"))
    assert main(["run", str(CONFIGS / "paper_combined_mujoco.toml"), "--out", str(tmp_path)]) == 2
    assert install_command("mujoco") in capsys.readouterr().err


def test_package_and_configs_load_without_mujoco():
    # mujoco is imported only when a MuJoCo plant is built
    import subprocess

    code = (
        "import sys; sys.modules['mujoco'] = None; import hmpc_pin; "
        "from hmpc_pin.experiment.config import load_config; "
        f"print(load_config({str(CONFIGS / 'paper_combined_mujoco.toml')!r}).plant.engine)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "mujoco"


# ----------------------------------------------------------------- the plant
def test_disturbance_is_applied_as_generalized_force(planar3):
    # A constant d: MuJoCo with d applied equals MuJoCo with τ + d (and the record says d).
    d = np.array([3.0, -2.0, 0.5])
    a = MuJoCoPlant(planar3, lambda t, q, dq: d, 0.01, 0.001)
    b = MuJoCoPlant(planar3, None, 0.01, 0.001)
    q0 = np.array([0.3, -0.2, 0.1])
    for p in (a, b):
        p.reset(q0, np.zeros(3))
    tau = planar3.gravity_torque(q0)
    for _ in range(20):
        qa, _ = a.advance(tau)
        qb, _ = b.advance(tau + d)
    np.testing.assert_allclose(qa, qb, atol=1e-12)
    np.testing.assert_allclose(a.disturbance_now(), d, atol=1e-12)  # no engine forces here


def test_rk4_integrator_agrees_with_pinocchio_rk4_plant(planar3):
    # Same dynamics, same integrator and step: the two engines' trajectories agree.
    from hmpc_pin.sim.plants import RK4Plant

    mj = MuJoCoPlant(planar3, None, 0.01, 0.001, MuJoCoSettings(integrator="rk4"))
    pn = RK4Plant(planar3.copy(), None, 0.01, 0.001)
    q0 = np.array([0.5, -0.3, 0.2])
    for p in (mj, pn):
        p.reset(q0, np.zeros(3))
    for k in range(50):
        tau = np.array([2.0 * np.sin(k / 10), 1.0, -0.5])
        q1, dq1 = mj.advance(tau)
        q2, dq2 = pn.advance(tau)
    np.testing.assert_allclose(q1, q2, atol=1e-9)
    np.testing.assert_allclose(dq1, dq2, atol=1e-8)


def test_dry_friction_holds_the_arm_below_its_breakaway_torque(planar3):
    # frictionloss F: a torque |τ - G| < F leaves the arm (almost) at rest; above, it moves.
    s = MuJoCoSettings(frictionloss=(3.0, 2.4, 1.8))
    q0 = np.array([0.3, -0.2, 0.1])
    G = planar3.gravity_torque(q0)
    for extra, moves in ((np.array([2.0, 1.5, 1.0]), False), (np.array([6.0, 5.0, 4.0]), True)):
        p = MuJoCoPlant(planar3, None, 0.01, 0.001, s)
        p.reset(q0, np.zeros(3))
        for _ in range(50):
            q, _ = p.advance(G + extra)
        assert (np.abs(q - q0).max() > 0.05) == moves


# ------------------------------------------------------------------- contacts
@pytest.fixture(scope="module")
def contact_runs():
    """The contact config (4 s) with both reactions, with the plants kept."""
    config = load_config(CONFIGS / "planar3_contact_mujoco.toml")
    out = {}
    for reaction in ("ignore", "stop"):
        cfg = replace(config, collision=replace(config.collision, reaction=reaction))
        exp = Experiment.from_config(cfg)
        plant = exp.make_plant()
        exp.make_plant = lambda plant=plant: plant  # keep the plant of the run
        out[reaction] = (exp, plant, exp.run())
    return out


def test_contact_force_equals_mj_contact_force_mapped_by_jacobians(contact_runs):
    _, plant, _ = contact_runs["stop"]
    m, d = plant.model, plant.data
    assert d.ncon > 0
    total = np.zeros(m.nv)
    f6, jacp, jacr = np.zeros(6), np.zeros((3, m.nv)), np.zeros((3, m.nv))
    for i in range(d.ncon):
        c = d.contact[i]
        mujoco.mj_contactForce(m, d, i, f6)  # in the contact frame: geom1 on geom2
        force = c.frame.reshape(3, 3).T @ f6[:3]
        for geom, sign in ((c.geom1, -1.0), (c.geom2, 1.0)):
            mujoco.mj_jac(m, d, jacp, jacr, c.pos, m.geom_bodyid[geom])
            total += sign * jacp.T @ force
    np.testing.assert_allclose(plant.generalized_contact_force(), total[plant.vadr], atol=1e-9)


def test_steady_contact_force_is_the_static_balance_of_pinocchio(contact_runs):
    # At rest in contact (stop: the position held): τ + f = G(q) on Pinocchio's model.
    exp, _, res = contact_runs["stop"]
    f = res.extra["contact_force"]
    late = res.t >= 2.5
    assert np.abs(res.dq[late]).max() < 1e-3
    balance = np.array([exp.robot.gravity_torque(q) for q in res.q[late]]) - res.tau[late]
    np.testing.assert_allclose(f[late], balance, atol=0.01 * np.abs(balance).max())


@pytest.mark.parametrize("reaction,settle", [("ignore", 0.1), ("stop", 0.5)])
def test_observer_estimates_the_contact_force(contact_runs, reaction, settle):
    _, _, res = contact_runs[reaction]
    f = res.extra["contact_force"]
    t_contact = res.meta["first_contact"]
    assert t_contact is not None
    # flagged within 3 control periods of the first contact
    detected = res.meta["collision"]["detected_at"]
    assert t_contact <= detected + 1e-9 <= t_contact + 3 * 0.01 + 1e-9
    assert not np.any(np.abs(res.d_hat[res.t < detected - 1e-9]) > 2.0)
    w = res.t >= t_contact + settle
    rms_f = np.sqrt(np.mean(f[w] ** 2, axis=0))
    rms_e = np.sqrt(np.mean((res.d_hat[w] - f[w]) ** 2, axis=0))
    carry = rms_f >= 0.1 * rms_f.max()
    assert carry.sum() >= 2
    assert np.all(rms_e[carry] <= 0.1 * rms_f[carry])


def test_stop_holds_the_position_reached_ignore_pushes_on(contact_runs):
    _, _, stop = contact_runs["stop"]
    _, _, ignore = contact_runs["ignore"]
    k = int(np.searchsorted(stop.t, stop.meta["collision"]["detected_at"]))
    late = stop.t >= 2.5
    np.testing.assert_allclose(stop.q[late], np.broadcast_to(stop.q[k], stop.q[late].shape),
                               atol=0.02)  # fmt: skip
    f_stop = np.abs(stop.extra["contact_force"][late]).max()
    f_ignore = np.abs(ignore.extra["contact_force"][ignore.t >= 2.5]).max()
    assert f_ignore > 100 * f_stop  # the observer cancels the contact and the arm presses on


def test_contact_force_saved_and_loaded(contact_runs, tmp_path):
    from hmpc_pin.sim.result import Result

    _, _, res = contact_runs["stop"]
    back = Result.load(res.save(tmp_path / "r.npz"))
    np.testing.assert_array_equal(back.extra["contact_force"], res.extra["contact_force"])
    assert back.meta["engine"] == "mujoco" and back.meta["engine_version"] == mujoco.__version__


def test_without_obstacle_contacts_are_off(planar3):
    model = mujoco_model(planar3, MuJoCoSettings(geometry="visual"))
    assert model.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    with_box = mujoco_model(
        planar3, MuJoCoSettings(geometry="visual", obstacle=Obstacle((1, 0, 0), (0.1,) * 3))
    )
    assert not with_box.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_CONTACT)


# ---------------------------------------------------------------- closed loops
@pytest.mark.slow
@pytest.mark.parametrize("name", ["paper_combined_mujoco", "ur5_mujoco", "panda_mujoco"])
def test_ndo_against_the_arms_own_joint_friction(name):
    config = load_config(CONFIGS / f"{name}.toml")
    worst = {}
    for observer in (None, False):
        res = Experiment.from_config(config, observer=observer).run()
        assert res.complete and res.meta["engine"] == "mujoco"
        e = res.error[res.t >= 1.0]
        worst[observer] = np.sqrt(np.mean(e * e, axis=0)).max()
    assert worst[None] <= 5e-3
    assert worst[None] * 10 <= worst[False]


@pytest.mark.parametrize("name", ["paper_combined_mujoco", "ur5_mujoco", "panda_mujoco"])
def test_closed_loop_short(name):
    # 2 s (the first pulse included): tracks, and the record holds the friction MuJoCo
    # applied (d = pulses + the arm's own friction and damping, not the pulses alone).
    config = load_config(CONFIGS / f"{name}.toml")
    exp = Experiment.from_config(config)
    res = exp.run(duration=2.0)
    e = res.error[res.t >= 1.0]
    assert np.sqrt(np.mean(e * e, axis=0)).max() <= 5e-3
    pulses = np.array([exp.disturbance(t, q, dq) for t, q, dq in zip(res.t, res.q, res.dq,
                                                                      strict=True)])  # fmt: skip
    assert np.abs(res.d - pulses).max() > 0.1 * np.abs(pulses).max()


def test_simulate_runs_a_mujoco_plant_by_name(planar3):
    # The same closed loop on both engines (no friction): the same trajectory, up to
    # the first-order error of MuJoCo's default implicitfast step (h = 1 ms, |q̈| ≲ 1).
    import hmpc_pin

    runs = [
        simulate(planar3, hmpc_pin.HierarchicalMPC(planar3), hmpc_pin.SineReference(3),
                 duration=1.0, q0=np.zeros(3), integrator=name)
        for name in ("mujoco", "rk4")
    ]  # fmt: skip
    assert runs[0].complete
    np.testing.assert_allclose(runs[0].q, runs[1].q, atol=1e-3)


# ------------------------------------------------------------------- config
@pytest.mark.parametrize(
    "plant,match",
    [
        ('engine = "mujoco"\ndt = 0.001', "plant.dt.*plant.mujoco.timestep"),
        ('engine = "mujoco"\nintegrator = "rk4"', "plant.integrator.*plant.mujoco.integrator"),
        ('engine = "bullet"', "engine.*pinocchio"),
        ('[plant.mujoco]\ntimestep = 0.001', "plant.mujoco.*engine = 'mujoco'"),
        ('engine = "mujoco"\n[plant.mujoco]\nintegrator = "verlet"', "integrator.*implicitfast"),
        ('engine = "mujoco"\n[plant.mujoco]\nfrictionloss = -1.0', "frictionloss.*>= 0"),
        ('engine = "mujoco"\n[plant.mujoco]\ngeometry = "none"\n[plant.mujoco.obstacle]\n'
         'position = [1, 0, 0]\nsize = [0.1, 0.1, 0.1]', "geometry.*obstacle"),
        ('engine = "mujoco"\n[plant.mujoco.obstacle]\nposition = [1, 0]\nsize = 0.1',
         "position.*\\[x, y, z\\]"),
        ('engine = "mujoco"\n[plant.mujoco]\nsurface = 1', "unknown key"),
    ],
)  # fmt: skip
def test_bad_plant_tables(write_config, plant, match):
    path = write_config(f'[robot]\nurdf = "@URDF@"\n[plant]\n{plant}\n')
    with pytest.raises(ConfigError, match=match):
        load_config(path)


def test_bad_lengths_and_timestep_fail_at_build(write_config):
    base = '[robot]\nurdf = "@URDF@"\n[plant]\nengine = "mujoco"\n[plant.mujoco]\n'
    with pytest.raises(ConfigError, match=r"plant.mujoco.damping.*3 joints"):
        Experiment.from_config(load_config(write_config(base + "damping = [1.0, 2.0]\n")))
    with pytest.raises(ConfigError, match="does not divide"):
        Experiment.from_config(load_config(write_config(base + "timestep = 0.003\n")))


def test_collision_needs_an_observer(write_config):
    text = ('[robot]\nurdf = "@URDF@"\n[controller]\ncompensation = "none"\n'
            '[collision]\nthreshold = 1.0\n')  # fmt: skip
    with pytest.raises(ConfigError, match=r"collision.*observer"):
        load_config(write_config(text))
    ok = load_config(write_config(text.replace('"none"', '"chen"')))
    assert Experiment.from_config(ok, observer=False).config.controller.compensation == "none"


def test_pinocchio_result_records_its_engine():
    res = Experiment.from_config(replace(load_config(CONFIGS / "paper_combined.toml"),
                                         plant=PlantConfig())).run(duration=0.05)  # fmt: skip
    assert res.meta["engine"] == "pinocchio" and res.meta["engine_version"] == pin.__version__
    assert "contact_force" not in res.extra


# ------------------------------------------------------------------- views
def test_cli_live_view_and_replay_show_the_obstacle(tmp_path, capsys):
    pytest.importorskip("meshcat")
    from .test_viz import _commands

    cfg = str(CONFIGS / "planar3_contact_mujoco.toml")
    html = tmp_path / "run.html"
    argv = ["run", cfg, "--out", str(tmp_path), "--duration", "2", "--viz", "--speed", "100",
            "--replay", str(html)]  # fmt: skip
    assert main(argv) == 0
    assert "Meshcat live view: open http://127.0.0.1:" in capsys.readouterr().out
    saved = tmp_path / "planar3_contact_mujoco.npz"
    again = tmp_path / "again.html"
    assert main(["replay", str(saved), "--out", str(again)]) == 0
    for page in (html, again):
        commands = _commands(page.read_text())
        (box,) = [
            c for c in commands if c["type"] == "set_object" and c["path"].endswith("obstacle")
        ]
        geometry = box["object"]["geometries"][0]
        assert (geometry["width"], geometry["height"], geometry["depth"]) == (0.6, 1.0, 0.7)
        (place,) = [c for c in commands if c["type"] == "set_transform"
                    and c["path"].endswith("obstacle")]  # fmt: skip
        np.testing.assert_allclose(np.reshape(place["matrix"], (4, 4)).T[:3, 3], [1.5, 0, 0.35])


def test_plant_pickles_mid_run_and_continues_identically(planar3):
    # (a real-time loop may run the plant in another process)
    import pickle

    from hmpc_pin.sim.disturbances import GaussianPulse

    pulse = GaussianPulse([10.0, 8.0, 0.3], [0.05, 0.1, 0.15], 0.03)
    plant = MuJoCoPlant(planar3, pulse, 0.01, 0.001, MuJoCoSettings(frictionloss=1.0))
    plant.reset(np.array([0.3, -0.2, 0.1]), np.zeros(3))
    tau = np.array([5.0, 2.0, 0.5])
    for _ in range(5):
        plant.advance(tau)
    copy = pickle.loads(pickle.dumps(plant))
    for _ in range(10):
        q1, dq1 = plant.advance(tau)
        q2, dq2 = copy.advance(tau)
    np.testing.assert_array_equal(q1, q2)
    np.testing.assert_array_equal(dq1, dq2)
    assert copy.t == plant.t


def test_obstacle_the_arm_cannot_touch_is_an_error(planar3):
    # planar3.urdf has no <collision> tags: with geometry = "collision" nothing could touch
    box = Obstacle((1.0, 0.0, 0.0), (0.1, 0.1, 0.1))
    with pytest.raises(URDFError, match=r"no collision geometry.*geometry = 'visual'"):
        mujoco_model(planar3, MuJoCoSettings(obstacle=box))
    assert mujoco_model(planar3, MuJoCoSettings(geometry="visual", obstacle=box)).ngeom > 1


def test_cli_compare_and_sweep_run_on_mujoco(tmp_path, capsys):
    cfg = str(CONFIGS / "paper_combined_mujoco.toml")
    assert main(["compare", cfg, "--out", str(tmp_path), "--duration", "0.3"]) == 0
    argv = ["sweep", cfg, "--out", str(tmp_path), "--samples", "1", "--duration", "0.3",
            "--jobs", "1", "--quiet"]  # fmt: skip
    assert main(argv) == 0
    rows = (tmp_path / "paper_combined_mujoco_sweep.csv").read_text().strip().splitlines()
    # header + the NDO and no-NDO runs of the one sample under each of the 4 conditions
    assert len(rows) == 1 + 2 * 4
    assert all(",True," in row for row in rows[1:])
    assert {row.split(",")[2] for row in rows[1:]} == {"sensing", "latency", "plant", "all"}


def test_csv_holds_the_contact_force(contact_runs, tmp_path):
    import csv

    from hmpc_pin.apps.run import write_csv

    _, _, res = contact_runs["stop"]
    with open(write_csv(res, tmp_path / "r.csv"), encoding="utf-8") as f:
        rows = list(csv.reader(f))
    col = rows[0].index("contact_force_joint1")
    np.testing.assert_allclose([float(r[col]) for r in rows[1:]], res.extra["contact_force"][:, 0])


def test_contact_example_prints_and_plots(tmp_path, capsys):
    import runpy

    example = runpy.run_path(str(ROOT / "examples" / "mujoco_contact.py"))
    assert example["main"](["--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "ignore: first contact 1.50 s, flagged 1.51 s" in out and "stop:" in out
    assert (tmp_path / "mujoco_contact.png").stat().st_size > 10_000


def test_continuous_joint_is_an_unlimited_hinge(tmp_path, make_rng):
    # Pinocchio's model: a revolute joint without limits (one angle); MuJoCo's: a hinge.
    def continuous(text):
        i = text.index('<joint name="joint1" type="revolute">')
        return text[:i] + text[i:].replace('type="revolute"', 'type="continuous"', 1)

    robot = load_robot(_planar3_variant(tmp_path, continuous), 9.8)
    assert robot.continuous_joints == ("joint1",)
    model = mujoco_model(robot)
    assert not model.jnt_limited[model.joint("joint1").id]
    for q, dq, tau in _random_states(robot, make_rng(11), 5):
        q[0] = 7.0  # beyond 2π: the angle does not wrap in either model
        expected = pin.aba(robot.model, robot.data, q, dq, tau)
        np.testing.assert_allclose(_qacc(model, robot, q, dq, tau), expected, atol=1e-8)
