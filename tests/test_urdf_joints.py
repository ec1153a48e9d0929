"""URDF joints and defects (issue 15): continuous, mimic, prismatic and fixed joints load
with the right dynamics; zero mass, missing inertials and zero or inverted limit ranges
are refused before a run with one message naming the link or joint.

Every fixture is a hand-written three-link chain (:func:`chain`) with the one defect or
feature under test, so each URDF reads in the test that uses it. The dynamics of the
models hmpc_pin builds are compared with independent computations: Pinocchio's own
continuous joint (two coordinates cos θ, sin θ), the full model with the mimic follower
as an independent joint projected onto the leader (:math:`S^T M S`), and closed forms.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from hmpc_pin.apps.cli import main
from hmpc_pin.exceptions import URDFError, ValidityWarning
from hmpc_pin.experiment.build import Experiment
from hmpc_pin.experiment.config import load_config
from hmpc_pin.model.robot import load_robot

# A link: a rod of mass m along x, centre of mass at x = 0.25, inertia about its centre.
ROD = (
    '<link name="{name}"><inertial><origin xyz="0.25 0 0"/><mass value="{mass}"/>'
    '<inertia ixx="{ix}" ixy="0" ixz="0" iyy="{i}" iyz="0" izz="{i}"/></inertial></link>'
)
BARE = '<link name="{name}"/>'


def joint(name, kind, parent, child, *, x=0.5, axis="0 1 0", limit=None, extra=""):
    """A joint ``name`` of type ``kind`` at ``x`` along the parent link."""
    if limit is None:
        limit = (
            ""
            if kind in ("fixed",)
            else '<limit lower="-2" upper="2" effort="100" velocity="3"/>'
            if kind != "continuous"
            else '<limit effort="100" velocity="3"/>'
        )
    return (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{x} 0 0"/><axis xyz="{axis}"/>{limit}{extra}</joint>'
    )


def rod(name, mass=1.0):
    # a massless link has no inertia either (a mass of 0 with moments is no rigid body)
    return ROD.format(name=name, mass=mass, i=mass * 0.5**2 / 12, ix=min(0.001, 0.001 * mass))


def chain(*parts: str) -> str:
    """A URDF: the fixed base link ``base`` plus ``parts``."""
    return (
        '<?xml version="1.0"?>\n<robot name="chain">\n'
        + "\n".join([rod("base"), *parts])
        + "\n</robot>\n"
    )


def three_links(kinds=("revolute", "revolute", "revolute"), masses=(1.0, 1.0, 1.0), **kw):
    """base -j1- l1 -j2- l2 -j3- l3, with joint ``i`` of type ``kinds[i]``."""
    parts = []
    parent = "base"
    for i, (kind, mass) in enumerate(zip(kinds, masses, strict=True), start=1):
        parts.append(BARE.format(name=f"l{i}") if mass is None else rod(f"l{i}", mass))
        parts.append(joint(f"j{i}", kind, parent, f"l{i}", x=0.0 if i == 1 else 0.5,
                           **kw.get(f"j{i}", {})))  # fmt: skip
        parent = f"l{i}"
    return chain(*parts)


CONFIG = """
[robot]
urdf = "{urdf}"
gravity = 9.81
[controller]
compensation = "general"
[reference]
amplitude = 0.2
frequency = 0.2
offset = {offset}
[simulation]
duration = {duration}
"""


@pytest.fixture
def make_config(tmp_path, write_urdf):
    """Factory: a URDF text and config extras -> the path of a config running it."""

    def _make(urdf_text, offset=0.3, duration=1.0, extra=""):
        urdf = write_urdf(urdf_text)
        path = tmp_path / "arm.toml"
        path.write_text(
            CONFIG.format(urdf=urdf, offset=offset, duration=duration) + extra, encoding="utf-8"
        )
        return path

    return _make


# ---------------------------------------------------------------- mass and inertia
@pytest.mark.parametrize(
    ("masses", "link", "why"),
    [
        ((1.0, 1.0, 0.0), "l3", "mass 0 kg"),
        ((1.0, 1.0, None), "l3", "no <inertial>"),
    ],
    ids=["zero_mass_at_end", "no_inertial_at_end"],
)
def test_massless_end_link_is_refused_naming_it(write_urdf, masses, link, why):
    path = write_urdf(three_links(masses=masses))
    with pytest.raises(URDFError) as info:
        load_robot(path)
    message = str(info.value)
    assert message.startswith(str(path))
    assert "joint 'j3'" in message and f"'{link}' ({why})" in message
    assert "not positive definite" in message


def test_a_light_but_massive_end_link_loads(write_urdf):
    """No false alarm: a 1 mg end link (M_33 ≈ 8e-8 against M_11 ≈ 5) is a valid arm; M
    is positive definite (eigenvalues computed here) and the check passes."""
    robot = load_robot(write_urdf(three_links(masses=(1.0, 1.0, 1e-6))))
    M = robot.mass_matrix(np.full(3, 0.3))
    assert 0 < np.linalg.eigvalsh(M).min() < 1e-6


def test_massless_end_link_exits_2_with_one_line(make_config, capsys, tmp_path):
    config = make_config(three_links(masses=(1.0, 1.0, 0.0)))
    code = main(["run", str(config), "--out", str(tmp_path)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and "'l3' (mass 0 kg)" in err[0]


def test_zero_mass_in_the_middle_is_fine(write_urdf):
    """A massless middle link still leaves M positive definite (the joint before it moves
    the links after it): it loads, and M agrees with the closed form of the planar
    chain at q = 0 (a zero mass contributes nothing)."""
    robot = load_robot(write_urdf(three_links(masses=(1.0, 0.0, 1.0))), gravity=9.81)
    assert robot.nq == 3
    M = robot.mass_matrix(np.zeros(3))
    # Closed form at q = 0 (links along x, axes along y): link i's centre at x_i, the
    # joint j at p_j; M_jk = sum over links i beyond both of m_i (x_i - p_j)(x_i - p_k) + I_i.
    p = np.array([0.0, 0.5, 1.0])
    x = p + 0.25
    m = np.array([1.0, 0.0, 1.0])
    inertia = m * 0.5**2 / 12
    expected = np.zeros((3, 3))
    for i in range(3):
        for j in range(i + 1):
            for k in range(i + 1):
                expected[j, k] += m[i] * (x[i] - p[j]) * (x[i] - p[k]) + inertia[i]
    np.testing.assert_allclose(M, expected, atol=1e-12)
    assert np.linalg.eigvalsh(M).min() > 0


def test_fixed_joint_in_the_middle_merges_the_links(write_urdf):
    """base -j1- l1 =fixed= l1b -j2- l2: two coordinates, and the fixed link's mass
    loads joint 1 (gravity torque at q = 0 equals the closed-form moment)."""
    text = chain(
        rod("l1"), joint("j1", "revolute", "base", "l1", x=0.0),
        rod("l1b"), joint("weld", "fixed", "l1", "l1b", x=0.5),
        rod("l2"), joint("j2", "revolute", "l1b", "l2", x=0.5),
    )  # fmt: skip
    robot = load_robot(write_urdf(text), gravity=9.81)
    assert robot.joint_names == ("j1", "j2")
    # Centres of mass along x at q = 0: 0.25, 0.75, 1.25. A turn θ about +y takes a point
    # at x to height z = −x sin θ, so V = −g Σ m x sin θ and G = ∂V/∂θ = −g Σ m x at 0.
    g = 9.81
    np.testing.assert_allclose(
        robot.gravity_torque(np.zeros(2)), [-g * (0.25 + 0.75 + 1.25), -g * 0.25], atol=1e-12
    )


# --------------------------------------------------------------------- limit ranges
@pytest.mark.parametrize(
    ("limit", "what"),
    [
        ('<limit lower="0" upper="0" effort="100" velocity="3"/>', "a zero"),
        ('<limit lower="1" upper="-1" effort="100" velocity="3"/>', "an inverted"),
    ],
    ids=["zero_range", "inverted_range"],
)
def test_bad_limit_range_names_the_urdf_and_honours_position_false(make_config, limit, what):
    path = make_config(three_links(j2={"limit": limit}), offset=0.0)
    with pytest.raises(URDFError) as info:
        Experiment.from_config(load_config(path))
    message = str(info.value)
    urdf = str(load_config(path).robot.urdf)
    assert message.startswith(urdf)
    assert f"joint 'j2' has {what} position range" in message
    assert "controller.constraints.position = false" in message
    # The way out the message names works: without position limits it builds and runs.
    path = make_config(
        three_links(j2={"limit": limit}), offset=0.0, duration=0.2,
        extra="[controller.constraints]\nposition = false\n",
    )  # fmt: skip
    result = Experiment.from_config(load_config(path)).run()
    assert result.complete
    # The bad range is no range: the metrics measure no excursion against it.
    from hmpc_pin.apps.metrics import compute_metrics

    assert result.meta["limits"]["lower"][1] == -np.inf
    assert result.meta["limits"]["upper"][1] == np.inf
    assert result.meta["limits"]["lower"][0] == -2.0
    assert compute_metrics(result, after=0.0).limit_violation[1] == 0.0


def test_bad_limit_range_exits_2(make_config, capsys, tmp_path):
    limit = '<limit lower="0" upper="0" effort="100" velocity="3"/>'
    code = main(["run", str(make_config(three_links(j1={"limit": limit}))), "--out", str(tmp_path)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "joint 'j1' has a zero position range" in err[0]


# ------------------------------------------------------------------ continuous joints
def test_continuous_joint_is_revolute_without_limits(write_urdf, make_rng):
    """nq = nv = 3; the continuous joint has limits ±inf; M, nle and ABA equal those of
    Pinocchio's own continuous joint (coordinates cos θ, sin θ) at random states."""
    path = write_urdf(three_links(kinds=("revolute", "continuous", "revolute")))
    robot = load_robot(path, gravity=9.81)
    assert robot.nq == robot.model.nv == 3
    assert robot.continuous_joints == ("j2",)
    assert robot.lower[1] == -np.inf and robot.upper[1] == np.inf
    assert robot.velocity_limit[1] == 3.0 and robot.effort_limit[1] == 100.0
    ref = pin.buildModelFromUrdf(str(path))
    ref.gravity.linear = np.array([0.0, 0.0, -9.81])
    assert ref.nq == 4 and ref.joints[2].shortname() == "JointModelRUBY"
    data = ref.createData()
    rng = make_rng(0)
    for _ in range(10):
        q = rng.uniform(-7.0, 7.0, 3)  # beyond ±π: the angle does not wrap
        dq, tau = rng.normal(0, 1, 3), rng.normal(0, 5, 3)
        q_ref = np.array([q[0], np.cos(q[1]), np.sin(q[1]), q[2]])
        M = pin.crba(ref, data, q_ref)
        M = np.triu(M) + np.triu(M, 1).T
        np.testing.assert_allclose(robot.mass_matrix(q), M, atol=1e-12)
        np.testing.assert_allclose(
            robot.nonlinear_effects(q, dq), pin.nonLinearEffects(ref, data, q_ref, dq),
            atol=1e-12,
        )  # fmt: skip
        np.testing.assert_allclose(
            robot.forward_dynamics(q, dq, tau), pin.aba(ref, data, q_ref, dq, tau), atol=1e-10
        )


def test_continuous_joint_tracks_beyond_pi(make_config):
    """Tracking a sine around 3.5 rad (beyond π) on the continuous joint: the angle is
    not wrapped, the error stays small."""
    path = make_config(
        three_links(kinds=("revolute", "continuous", "revolute")),
        offset="[0.3, 3.5, 0.3]", duration=2.0,
    )  # fmt: skip
    result = Experiment.from_config(load_config(path)).run()
    assert result.complete and result.q[:, 1].max() > np.pi
    after = result.t >= 1.0
    assert np.abs(result.q[after] - result.q_ref[after]).max() < 5e-3


# ---------------------------------------------------------------------- mimic joints
MIMIC = '<mimic joint="j2" multiplier="-0.5" offset="0.1"/>'


def mimic_chain():
    return three_links(j3={"extra": MIMIC})


def test_mimic_joint_follows_its_leader(write_urdf, make_rng):
    """j3 mimics j2 (q3 = −0.5 q2 + 0.1): two coordinates; M, nle, G and the forward
    dynamics are the projection of the full model (j3 independent) onto the leader,
    S^T M S and S^T h at q3 = −0.5 q2 + 0.1, dq3 = −0.5 dq2."""
    path = write_urdf(mimic_chain())
    robot = load_robot(path, gravity=9.81)
    assert robot.joint_names == ("j1", "j2")
    assert robot.mimic_joints == {"j3": ("j2", -0.5, 0.1)}
    full = pin.buildModelFromUrdf(str(path))  # j3 an independent joint
    full.gravity.linear = np.array([0.0, 0.0, -9.81])
    data = full.createData()
    S = np.array([[1.0, 0.0], [0.0, 1.0], [0.0, -0.5]])
    o = np.array([0.0, 0.0, 0.1])
    rng = make_rng(1)
    for _ in range(10):
        q, dq, tau = rng.uniform(-2, 2, 2), rng.normal(0, 1, 2), rng.normal(0, 5, 2)
        Mf = pin.crba(full, data, S @ q + o)
        Mf = np.triu(Mf) + np.triu(Mf, 1).T
        # S is constant, so the Coriolis term of the reduced system is S^T C(q, S dq) S dq.
        hf = pin.nonLinearEffects(full, data, S @ q + o, S @ dq)
        np.testing.assert_allclose(robot.mass_matrix(q), S.T @ Mf @ S, atol=1e-12)
        np.testing.assert_allclose(robot.nonlinear_effects(q, dq), S.T @ hf, atol=1e-12)
        ddq = np.linalg.solve(S.T @ Mf @ S, tau - S.T @ hf)
        np.testing.assert_allclose(robot.forward_dynamics(q, dq, tau), ddq, atol=1e-10)


def test_mimic_leader_locked_locks_the_follower(write_urdf):
    path = write_urdf(mimic_chain())
    robot = load_robot(path, locked_joints={"j2": 0.4})
    assert robot.joint_names == ("j1",)
    assert robot.locked_joints == {"j2": 0.4, "j3": pytest.approx(-0.5 * 0.4 + 0.1)}
    with pytest.raises(URDFError, match="locked joint 'j3' mimics 'j2', which is not locked"):
        load_robot(path, locked_joints={"j3": 0.0})


def test_mimic_arm_runs_and_tracks(make_config):
    """The plant integrates the mimic model (CRBA forward dynamics) and the two
    coordinates track; the follower has no column of its own."""
    path = make_config(mimic_chain(), offset=0.3, duration=2.0)
    result = Experiment.from_config(load_config(path)).run()
    assert result.complete and result.q.shape[1] == 2 and result.joint_names == ("j1", "j2")
    after = result.t >= 1.0
    assert np.abs(result.q[after] - result.q_ref[after]).max() < 5e-3


# ------------------------------------------------------------------ prismatic joints
def test_prismatic_joint_kind_and_dynamics(write_urdf):
    """A vertical prismatic joint carrying everything after it: its gravity force is the
    total mass it lifts times g [N], and it is reported as prismatic."""
    text = three_links(
        kinds=("prismatic", "revolute", "revolute"),
        j1={"axis": "0 0 1", "limit": '<limit lower="-0.2" upper="0.2" effort="100" '
            'velocity="0.5"/>'},
    )  # fmt: skip
    robot = load_robot(write_urdf(text), gravity=9.81)
    assert robot.joint_kinds == ("prismatic", "revolute", "revolute")
    assert robot.gravity_torque(np.zeros(3))[0] == pytest.approx(3 * 9.81, abs=1e-12)


# --------------------------------------------------------------- floating base, Chen
def test_floating_joint_in_the_urdf_is_refused(write_urdf):
    text = chain(rod("l1"), joint("free", "floating", "base", "l1", limit=""))
    with pytest.raises(URDFError, match=r"has a floating base: joint.s. 'free' .floating."):
        load_robot(write_urdf(text))


@pytest.mark.parametrize("name", ["so100", "so101"])
def test_fixed_base_arms_flagged_free_flyer_load(name):
    """example-robot-data flags so100/so101 as free flyers; their URDFs have no floating
    joint, so they load as the fixed-base 6-joint arms they are."""
    assert load_robot(name).nq == 6


def test_chen_on_a_spatial_arm_warns_naming_the_alternative(make_config):
    path = make_config(three_links(kinds=("revolute", "revolute", "revolute"),
                                   j1={"axis": "0 0 1"}))  # fmt: skip
    config = load_config(path)
    from hmpc_pin.experiment.build import with_controller

    with pytest.warns(ValidityWarning, match="compensation = 'general'"):
        Experiment.from_config(with_controller(config, compensation="chen"))


def test_chen_on_a_planar_chain_does_not_warn(make_config, recwarn):
    from hmpc_pin.experiment.build import with_controller

    config = with_controller(load_config(make_config(three_links())), compensation="chen")
    Experiment.from_config(config)
    assert not [w for w in recwarn if issubclass(w.category, ValidityWarning)]


def test_prismatic_joint_reported_in_metres_and_newtons(make_config, tmp_path, capsys):
    """`run` prints, writes (CSV) and compares a prismatic joint in m, m/s and N."""
    import csv

    from hmpc_pin.apps.compare import markdown_table, run_comparison

    text = three_links(
        kinds=("prismatic", "revolute", "revolute"),
        j1={"axis": "0 0 1", "limit": '<limit lower="-0.3" upper="0.3" effort="100" '
            'velocity="0.5"/>'},
    )  # fmt: skip
    path = make_config(text, offset="[0.0, 0.3, 0.3]", duration=1.2)
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "j1 (m, N)" in printed and "[rad|m]" in printed and "[N·m|N]" in printed
    with open(out / "arm.csv", encoding="utf-8") as f:
        header = next(csv.reader(f))
    assert {"q_j1 [m]", "dq_j1 [m/s]", "tau_j1 [N]", "d_hat_j1 [N]", "q_j2"} <= set(header)
    table = markdown_table(run_comparison(load_config(path), ("hmpc",)))
    assert "j1 (m, N)" in table and "RMS e after 1 s [rad\\|m]" in table


def test_robots_with_mimic_and_continuous_joints_pickle(write_urdf, make_rng):
    """A Robot crosses process boundaries (sweeps): the round trip keeps its dynamics."""
    import pickle

    text = three_links(kinds=("revolute", "continuous", "revolute"), j3={"extra": MIMIC})
    robot = load_robot(write_urdf(text), gravity=9.81)
    copy = pickle.loads(pickle.dumps(robot))
    rng = make_rng(4)
    q, dq, tau = rng.normal(size=2), rng.normal(size=2), rng.normal(size=2)
    np.testing.assert_array_equal(
        copy.forward_dynamics(q, dq, tau), robot.forward_dynamics(q, dq, tau)
    )
    assert copy.mimic_joints == robot.mimic_joints
    assert copy.continuous_joints == ("j2",)
    # A perturbed copy (sweeps scale link inertias) survives the round trip too: scaling
    # every link by 1.5 scales M by 1.5 exactly.
    scaled = pickle.loads(pickle.dumps(robot.with_scaled_inertias([1.5, 1.5, 1.5])))
    np.testing.assert_allclose(scaled.mass_matrix(q), 1.5 * robot.mass_matrix(q), rtol=1e-12)
