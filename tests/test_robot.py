"""Tests of :mod:`hmpc_pin.model.robot` against an independent closed-form model.

The reference dynamics of the vertical three-link planar arm (``robots/planar3.urdf``)
are derived here by hand from the Lagrangian, without Pinocchio:

* absolute link angles ``θ1 = q1``, ``θ2 = q1 + q2``, ``θ3 = q1 + q2 + q3``;
* link ``i`` is a uniform rod (mass ``m_i``, length ``l_i``, centre of mass at
  ``c_i = l_i / 2``, inertia ``I_i = m_i l_i² / 12`` about the joint axis);
* motion in the URDF x-z plane, gravity ``g`` along ``-z``.

With ``u(θ) = (cos θ, sin θ)`` and ``u'(θ) = (-sin θ, cos θ)`` the centre of mass of
link ``i`` is ``p_i = Σ_j a_ij u(θ_j)`` where ``a_ij = l_j`` for ``j < i``,
``a_ii = c_i`` and ``a_ij = 0`` for ``j > i``. Since ``∂θ_j/∂q_k = [k <= j]``:

* ``Jv_i[:, k] = Σ_{j >= k} a_ij u'(θ_j)``, ``Jw_i[k] = [k <= i]``;
* ``M = Σ_i m_i Jv_iᵀ Jv_i + I_i Jw_iᵀ Jw_i``;
* ``∂Jv_i[:, k]/∂q_p = -Σ_{j >= max(k, p)} a_ij u(θ_j)`` gives ``∂M/∂q_p`` exactly;
* ``(C q̇)_k = Σ_ij Γ_kij q̇_i q̇_j`` with the Christoffel symbols
  ``Γ_kij = ½ (∂M_kj/∂q_i + ∂M_ki/∂q_j - ∂M_ij/∂q_k)``;
* ``G_k = ∂V/∂q_k`` with ``V = g Σ_i m_i z_i``, i.e. ``G_k = g Σ_i m_i Σ_{j >= k} a_ij cos θ_j``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hmpc_pin.exceptions import URDFError
from hmpc_pin.model.robot import Robot, load_robot

URDF = Path(__file__).resolve().parents[1] / "robots" / "planar3.urdf"

MASSES = np.array([1.5, 1.2, 1.0])
LENGTHS = np.array([1.5, 1.2, 1.0])
GRAVITY = 9.8
Q_LIMIT = np.array([np.pi / 2, np.pi / 2, 3 * np.pi / 4])
N_STATES = 25
ATOL = 1e-9


# --------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def robot() -> Robot:
    """The planar 3-link arm, loaded once per module (read-only use)."""
    return load_robot(URDF, gravity=GRAVITY)


@pytest.fixture
def make_state(make_rng):
    """Factory of ``count`` random states ``(q, dq)`` with q inside the joint limits."""

    def _make(count: int = N_STATES, seed: int = 0) -> list[tuple[np.ndarray, np.ndarray]]:
        rng = make_rng(seed)
        states = []
        for _ in range(count):
            q = rng.uniform(-Q_LIMIT, Q_LIMIT)
            dq = rng.normal(0.0, 2.0, size=3)
            states.append((q, dq))
        return states

    return _make


# ------------------------------------------------------- closed-form reference
def _lever_arms() -> np.ndarray:
    """``a[i, j]``: length of link ``j`` on the way to the centre of mass of link ``i``."""
    a = np.zeros((3, 3))
    for i in range(3):
        a[i, :i] = LENGTHS[:i]
        a[i, i] = LENGTHS[i] / 2.0
    return a


def _abs_angles(q: np.ndarray) -> np.ndarray:
    """Absolute link angles θ = (q1, q1 + q2, q1 + q2 + q3)."""
    return np.cumsum(q)


def _com_jacobians(q: np.ndarray) -> list[np.ndarray]:
    """Linear Jacobians (2x3, x-z plane) of the three link centres of mass."""
    a = _lever_arms()
    theta = _abs_angles(q)
    du = np.array([-np.sin(theta), np.cos(theta)])  # u'(θ_j) in column j
    jacs = []
    for i in range(3):
        jac = np.zeros((2, 3))
        for k in range(3):
            for j in range(k, 3):
                jac[:, k] += a[i, j] * du[:, j]
        jacs.append(jac)
    return jacs


def _com_jacobian_derivatives(q: np.ndarray) -> list[list[np.ndarray]]:
    """``d[i][p] = ∂Jv_i/∂q_p`` (2x3), from ``∂u'(θ_j)/∂q_p = -u(θ_j) [p <= j]``."""
    a = _lever_arms()
    theta = _abs_angles(q)
    u = np.array([np.cos(theta), np.sin(theta)])
    out = []
    for i in range(3):
        per_p = []
        for p in range(3):
            d = np.zeros((2, 3))
            for k in range(3):
                for j in range(max(k, p), 3):
                    d[:, k] -= a[i, j] * u[:, j]
            per_p.append(d)
        out.append(per_p)
    return out


def _angular_jacobians() -> list[np.ndarray]:
    """Angular Jacobians (1x3): link ``i`` turns with ``θ_i = Σ_{k <= i} q_k``."""
    return [np.array([[1.0 if k <= i else 0.0 for k in range(3)]]) for i in range(3)]


def reference_mass_matrix(q: np.ndarray) -> np.ndarray:
    """``M(q) = Σ_i m_i Jv_iᵀ Jv_i + I_i Jw_iᵀ Jw_i``."""
    inertia = MASSES * LENGTHS**2 / 12.0
    m = np.zeros((3, 3))
    for i, (jv, jw) in enumerate(zip(_com_jacobians(q), _angular_jacobians(), strict=True)):
        m += MASSES[i] * jv.T @ jv + inertia[i] * jw.T @ jw
    return m


def reference_mass_matrix_derivatives(q: np.ndarray) -> np.ndarray:
    """``dM[p] = ∂M/∂q_p`` (the rotational term does not depend on q)."""
    jacs = _com_jacobians(q)
    djacs = _com_jacobian_derivatives(q)
    dm = np.zeros((3, 3, 3))
    for p in range(3):
        for i in range(3):
            cross = djacs[i][p].T @ jacs[i]
            dm[p] += MASSES[i] * (cross + cross.T)
    return dm


def reference_coriolis(q: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """``C(q, q̇) q̇`` from the Christoffel symbols of the first kind."""
    dm = reference_mass_matrix_derivatives(q)  # dm[p, r, s] = ∂M_rs/∂q_p
    gamma = 0.5 * (
        np.einsum("ikj->kij", dm) + np.einsum("jki->kij", dm) - np.einsum("kij->kij", dm)
    )  # gamma[k, i, j] = ½ (∂M_kj/∂q_i + ∂M_ki/∂q_j - ∂M_ij/∂q_k)
    return np.einsum("kij,i,j->k", gamma, dq, dq)


def reference_gravity(q: np.ndarray) -> np.ndarray:
    """``G_k = ∂V/∂q_k`` with ``V = g Σ_i m_i z_i`` and ``z_i = Σ_j a_ij sin θ_j``."""
    a = _lever_arms()
    theta = _abs_angles(q)
    g = np.zeros(3)
    for k in range(3):
        for i in range(3):
            g[k] += GRAVITY * MASSES[i] * sum(a[i, j] * np.cos(theta[j]) for j in range(k, 3))
    return g


def reference_tool_position(q: np.ndarray) -> np.ndarray:
    """Tool point ``(x, y, z) = (Σ l_i cos θ_i, 0, Σ l_i sin θ_i)``."""
    theta = _abs_angles(q)
    return np.array([LENGTHS @ np.cos(theta), 0.0, LENGTHS @ np.sin(theta)])


# -------------------------------------------------- self-checks of the reference
def test_reference_mass_matrix_matches_textbook_closed_form(make_state):
    """The Jacobian construction equals the explicit entries of the 3-link arm's M."""
    m1, m2, m3 = MASSES
    l1, l2, _ = LENGTHS
    c1, c2, c3 = LENGTHS / 2
    i1, i2, i3 = MASSES * LENGTHS**2 / 12
    for q, _ in make_state(seed=11):
        cos2, cos3, cos23 = np.cos(q[1]), np.cos(q[2]), np.cos(q[1] + q[2])
        m33 = i3 + m3 * c3**2
        m23 = m33 + m3 * l2 * c3 * cos3
        m13 = m23 + m3 * l1 * c3 * cos23
        m22 = i2 + m2 * c2**2 + i3 + m3 * (l2**2 + c3**2 + 2 * l2 * c3 * cos3)
        m12 = m22 + m2 * l1 * c2 * cos2 + m3 * (l1 * l2 * cos2 + l1 * c3 * cos23)
        m11 = (
            i1
            + m1 * c1**2
            + i2
            + m2 * (l1**2 + c2**2 + 2 * l1 * c2 * cos2)
            + i3
            + m3
            * (
                l1**2
                + l2**2
                + c3**2
                + 2 * l1 * l2 * cos2
                + 2 * l1 * c3 * cos23
                + 2 * l2 * c3 * cos3
            )
        )
        expected = np.array([[m11, m12, m13], [m12, m22, m23], [m13, m23, m33]])
        np.testing.assert_allclose(reference_mass_matrix(q), expected, rtol=0, atol=1e-12)


def test_reference_mass_matrix_derivative_matches_finite_differences(make_state):
    """The analytic ∂M/∂q used for the Christoffel symbols agrees with central differences."""
    h = 1e-6
    for q, _ in make_state(count=5, seed=12):
        dm = reference_mass_matrix_derivatives(q)
        for p in range(3):
            e = np.zeros(3)
            e[p] = h
            fd = (reference_mass_matrix(q + e) - reference_mass_matrix(q - e)) / (2 * h)
            np.testing.assert_allclose(dm[p], fd, rtol=0, atol=1e-8)


def test_reference_gravity_is_gradient_of_potential(make_state):
    """The hand-written G is the gradient of V = g Σ m_i z_i (central differences)."""

    def potential(q: np.ndarray) -> float:
        theta = _abs_angles(q)
        z = _lever_arms() @ np.sin(theta)
        return float(GRAVITY * MASSES @ z)

    h = 1e-6
    for q, _ in make_state(count=5, seed=13):
        fd = np.array([(potential(q + h * e) - potential(q - h * e)) / (2 * h) for e in np.eye(3)])
        np.testing.assert_allclose(reference_gravity(q), fd, rtol=0, atol=1e-7)


# ------------------------------------------- Robot against the reference model
def test_robot_structure(robot):
    """Three revolute joints with the limits of Eq (27), gravity 9.8 along -z."""
    assert robot.nq == 3
    assert robot.joint_names == ("joint1", "joint2", "joint3")
    np.testing.assert_allclose(robot.upper, Q_LIMIT, rtol=0, atol=1e-15)
    np.testing.assert_allclose(robot.lower, -Q_LIMIT, rtol=0, atol=1e-15)
    assert robot.tool_frame == "tool"


def test_mass_matrix_matches_closed_form(robot, make_state):
    for q, _ in make_state():
        np.testing.assert_allclose(
            robot.mass_matrix(q), reference_mass_matrix(q), rtol=0, atol=ATOL, err_msg=f"{q=}"
        )


def test_gravity_torque_matches_closed_form(robot, make_state):
    for q, _ in make_state(seed=1):
        np.testing.assert_allclose(
            robot.gravity_torque(q), reference_gravity(q), rtol=0, atol=ATOL, err_msg=f"{q=}"
        )


def test_nonlinear_effects_match_closed_form(robot, make_state):
    for q, dq in make_state(seed=2):
        expected = reference_coriolis(q, dq) + reference_gravity(q)
        np.testing.assert_allclose(
            robot.nonlinear_effects(q, dq), expected, rtol=0, atol=ATOL, err_msg=f"{q=} {dq=}"
        )


def test_coriolis_alone_matches_closed_form(robot, make_state):
    """C q̇ isolated: nonlinear effects minus the gravity torque, both from the Robot."""
    for q, dq in make_state(seed=3):
        coriolis = robot.nonlinear_effects(q, dq) - robot.gravity_torque(q)
        np.testing.assert_allclose(
            coriolis, reference_coriolis(q, dq), rtol=0, atol=ATOL, err_msg=f"{q=} {dq=}"
        )


def test_gravity_torque_is_nle_at_rest(robot, make_state):
    for q, _ in make_state(count=5, seed=4):
        np.testing.assert_allclose(
            robot.nonlinear_effects(q, np.zeros(3)), robot.gravity_torque(q), rtol=0, atol=1e-12
        )


def test_gravity_torque_at_horizontal_pose(robot):
    """All links along +x: G = g (Σ m_i x_com,i, ...) lever arms about each joint."""
    expected = np.array(
        [
            GRAVITY * (1.5 * 0.75 + 1.2 * (1.5 + 0.6) + 1.0 * (1.5 + 1.2 + 0.5)),
            GRAVITY * (1.2 * 0.6 + 1.0 * (1.2 + 0.5)),
            GRAVITY * (1.0 * 0.5),
        ]
    )
    np.testing.assert_allclose(robot.gravity_torque(np.zeros(3)), expected, rtol=0, atol=1e-12)


# ------------------------------------------------- structural dynamics checks
def test_mass_matrix_is_symmetric_positive_definite(robot, make_state):
    for q, _ in make_state(seed=5):
        m = robot.mass_matrix(q)
        np.testing.assert_array_equal(m, m.T)
        assert np.linalg.eigvalsh(m).min() > 0.0


def test_mass_matrix_returns_a_copy(robot):
    q = np.zeros(3)
    m = robot.mass_matrix(q)
    m[:] = 0.0
    assert robot.mass_matrix(q)[0, 0] > 0.0


def test_forward_and_inverse_dynamics_are_inverse(robot, make_rng, make_state):
    rng = make_rng(6)
    for q, dq in make_state(seed=6):
        tau = rng.normal(0.0, 20.0, size=3)
        ddq = robot.forward_dynamics(q, dq, tau)
        np.testing.assert_allclose(
            robot.mass_matrix(q) @ ddq + robot.nonlinear_effects(q, dq), tau, rtol=0, atol=ATOL
        )
        np.testing.assert_allclose(robot.inverse_dynamics(q, dq, ddq), tau, rtol=0, atol=ATOL)

        ddq_in = rng.normal(0.0, 3.0, size=3)
        tau_in = robot.inverse_dynamics(q, dq, ddq_in)
        np.testing.assert_allclose(robot.forward_dynamics(q, dq, tau_in), ddq_in, rtol=0, atol=ATOL)


def test_forward_dynamics_matches_closed_form(robot, make_rng, make_state):
    rng = make_rng(7)
    for q, dq in make_state(seed=7):
        tau = rng.normal(0.0, 20.0, size=3)
        expected = np.linalg.solve(
            reference_mass_matrix(q), tau - reference_coriolis(q, dq) - reference_gravity(q)
        )
        np.testing.assert_allclose(robot.forward_dynamics(q, dq, tau), expected, rtol=0, atol=ATOL)


# ------------------------------------------------------------------ kinematics
@pytest.mark.parametrize(
    "q",
    [
        (0.0, 0.0, 0.0),
        (np.pi / 2, 0.0, 0.0),
        (-np.pi / 2, np.pi / 2, 0.0),
        (0.3, -0.7, 2.0),
        (-1.2, 1.1, -2.3),
        (np.pi / 4, np.pi / 4, np.pi / 4),
    ],
)
def test_tool_position_matches_closed_form(robot, q):
    q = np.array(q)
    placement = robot.frame_placement(q)
    np.testing.assert_allclose(
        placement.translation, reference_tool_position(q), rtol=0, atol=1e-12
    )
    np.testing.assert_allclose(
        robot.frame_placement(q, "tool").translation, placement.translation, rtol=0, atol=0
    )


def test_positive_angle_lifts_the_arm(robot):
    """Joint axis (0, -1, 0): a positive q1 raises the tool (z > 0)."""
    assert robot.frame_placement(np.array([0.5, 0.0, 0.0])).translation[2] > 0.0
    assert robot.frame_placement(np.array([-0.5, 0.0, 0.0])).translation[2] < 0.0


@pytest.mark.parametrize("gravity", [9.8, 9.81, 0.0, 1.62])
def test_gravity_vector(gravity):
    model = load_robot(URDF, gravity=gravity).model
    np.testing.assert_array_equal(model.gravity.linear, [0.0, 0.0, -gravity])
    np.testing.assert_array_equal(model.gravity.angular, [0.0, 0.0, 0.0])


def test_default_gravity_is_9_8():
    np.testing.assert_array_equal(load_robot(URDF).model.gravity.linear, [0.0, 0.0, -9.8])


# ------------------------------------------------------------------ bad inputs
_LINK = (
    '<link name="{name}"><inertial><mass value="1"/>'
    '<inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>'
)
_LIMIT = '<limit lower="-1" upper="1" effort="10" velocity="1"/>'


def _urdf(*body: str) -> str:
    return '<?xml version="1.0"?>\n<robot name="bad">\n' + "\n".join(body) + "\n</robot>\n"


def _joint(kind: str, limit: str = _LIMIT) -> str:
    return (
        f'<joint name="j1" type="{kind}"><parent link="a"/><child link="b"/>'
        f'<axis xyz="0 0 1"/>{limit}</joint>'
    )


_TWO_LINKS = (_LINK.format(name="a"), _LINK.format(name="b"))

#: case id -> (URDF text, or None for "no file" / "a directory", expected hint)
BAD_URDFS = {
    "missing_file": (None, "not found"),
    "directory": ("<dir>", "is not a file"),
    "malformed_xml": (
        '<?xml version="1.0"?>\n<robot name="bad">\n<link name="a">\n</robot>\n',
        "malformed XML at line 4",
    ),
    "wrong_root": ('<?xml version="1.0"?>\n<model name="bad"/>\n', "expected <robot>"),
    "revolute_without_limit": (_urdf(*_TWO_LINKS, _joint("revolute", limit="")), "limit"),
    "links_only": (_urdf(*_TWO_LINKS), "no actuated joint"),
    "floating_joint": (
        _urdf(*_TWO_LINKS, _joint("floating", limit="")),
        "has a floating base",
    ),
    "planar_joint": (
        _urdf(*_TWO_LINKS, _joint("planar", limit="")),
        "has a floating base",
    ),
    # The structure the specification requires (a traceback of the URDF reader before)
    "robot_without_name": (
        _urdf(*_TWO_LINKS, _joint("revolute")).replace('<robot name="bad">', "<robot>"),
        "the <robot> tag has no 'name' attribute",
    ),
    "link_without_name": (
        _urdf(_LINK.format(name="a"), _LINK.replace(' name="{name}"', ""), _joint("revolute")),
        "a <link> has no 'name' attribute",
    ),
    "joint_without_parent": (
        _urdf(*_TWO_LINKS, _joint("revolute").replace('<parent link="a"/>', "")),
        "<joint> 'j1' has no <parent>",
    ),
    "empty_geometry": (
        _urdf(
            _LINK.format(name="a"),
            '<link name="b"><visual><geometry/></visual></link>',
            _joint("revolute"),
        ),
        "<link> 'b': the <geometry> of a <visual> holds nothing; expected one of <box>",
    ),
    "limit_not_a_number": (
        _urdf(*_TWO_LINKS, _joint("revolute", _LIMIT.replace('upper="1"', 'upper="one"'))),
        "<joint> 'j1': <limit upper='one'>: expected a number",
    ),
    "origin_of_two_numbers": (
        _urdf(*_TWO_LINKS, _joint("revolute").replace("<axis", '<origin xyz="0 1"/><axis')),
        "<joint> 'j1': <origin xyz='0 1'>: expected 3 numbers",
    ),
}


@pytest.fixture
def make_bad_path(tmp_path, write_urdf):
    """Factory turning a ``BAD_URDFS`` entry into a path under ``tmp_path``."""

    def _make(text: str | None) -> Path:
        if text is None:
            return tmp_path / "does_not_exist.urdf"
        if text == "<dir>":
            directory = tmp_path / "a_directory.urdf"
            directory.mkdir()
            return directory
        return write_urdf(text)

    return _make


@pytest.mark.parametrize(("text", "hint"), BAD_URDFS.values(), ids=BAD_URDFS.keys())
def test_bad_urdf_raises_urdf_error(make_bad_path, text, hint):
    path = make_bad_path(text)
    with pytest.raises(URDFError) as info:
        load_robot(path)
    message = str(info.value)
    assert message.startswith(str(path))
    assert hint in message
    assert info.value.path == str(path)
    assert isinstance(info.value, ValueError)


#: URDFs missing what the specification requires, each reported by yourdfpy's validation.
INCOMPLETE_URDFS = {
    "no_limit": _urdf(*_TWO_LINKS, _joint("revolute", limit="")),
    "no_lower_no_upper": _urdf(
        *_TWO_LINKS,
        _joint("prismatic", '<limit effort="1" velocity="1"/>'),
    ),
    "no_type": _urdf(*_TWO_LINKS, _joint("revolute").replace(' type="revolute"', "")),
    "unknown_type": _urdf(*_TWO_LINKS, _joint("hinge")),
    "empty_type_and_name": _urdf(*_TWO_LINKS, _joint("").replace('name="j1"', 'name=""')),
    "empty_link_names": _urdf(
        _LINK.format(name=""),
        _LINK.format(name="b"),
        _joint("revolute").replace('<parent link="a"/>', '<parent link=""/>'),
    ),
    "fixed_limit_without_effort": _urdf(
        *_TWO_LINKS,
        _joint("revolute"),
        _joint("fixed", '<limit velocity="1"/>').replace('"j1"', '"j2"').replace('"b"', '"c"'),
        _LINK.format(name="c"),
    ),
}


@pytest.mark.parametrize("text", INCOMPLETE_URDFS.values(), ids=INCOMPLETE_URDFS.keys())
def test_incomplete_urdf_is_named_as_yourdfpy_validates_it(write_urdf, text):
    """The completeness check lists what yourdfpy's ``URDF.validate`` (an independent
    reader of the specification) lists, in its words and order."""
    import yourdfpy

    path = write_urdf(text)
    urdf = yourdfpy.URDF.load(str(path), build_scene_graph=False, load_meshes=False)
    assert not urdf.validate()
    expected = "; ".join(str(e) for e in urdf.errors)
    with pytest.raises(URDFError) as info:
        load_robot(path)
    assert str(info.value) == f"{path}: incomplete or invalid URDF: {expected}"


def test_malformed_xml_reports_line_and_column(write_urdf):
    path = write_urdf('<?xml version="1.0"?>\n<robot name="bad">\n  <link name="a"\n</robot>\n')
    with pytest.raises(URDFError, match=r"malformed XML at line \d+, column \d+"):
        load_robot(path)


def test_sanity_good_minimal_urdf_loads(write_urdf):
    """The bad-input fixtures differ from a loadable file only by the defect."""
    robot = load_robot(write_urdf(_urdf(*_TWO_LINKS, _joint("revolute"))))
    assert robot.nq == 1


@pytest.mark.parametrize("gravity", [-1.0, float("nan"), float("inf")])
def test_bad_gravity(gravity):
    with pytest.raises(URDFError, match="gravity") as info:
        load_robot(URDF, gravity=gravity)
    assert str(URDF) in str(info.value)


# ------------------------------------------------------ other arms (issue: any URDF)
PANDA_FINGERS = {"panda_finger_joint1": 0.02, "panda_finger_joint2": 0.02}
ARMS = {
    "planar3": (str(Path(__file__).resolve().parent.parent / "robots" / "planar3.urdf"), None),
    "ur5": ("ur5", None),
    "panda": ("panda", PANDA_FINGERS),
    "z1": ("z1", {"jointGripper": 0.0}),
}


@pytest.fixture(scope="module", params=sorted(ARMS))
def arm(request):
    source, locked = ARMS[request.param]
    return load_robot(source, gravity=9.81, locked_joints=locked)


def random_state(robot, rng):
    lo, hi = np.clip(robot.lower, -np.pi, np.pi), np.clip(robot.upper, -np.pi, np.pi)
    return rng.uniform(lo, hi), rng.normal(0.0, 1.0, robot.nq)


def test_arm_dynamics_agree_with_rnea(arm, make_rng):
    """M·ABA(τ) + nle = τ and RNEA(ABA(τ)) = τ at random states (Pinocchio's RNEA is the
    independent algorithm; ABA and CRBA are the controller's and the plant's)."""
    rng = make_rng(1)
    for _ in range(20):
        q, dq = random_state(arm, rng)
        tau = rng.normal(0.0, 5.0, arm.nq)
        ddq = arm.forward_dynamics(q, dq, tau)
        M, nle = arm.mass_matrix(q), arm.nonlinear_effects(q, dq)
        np.testing.assert_allclose(M @ ddq + nle, tau, atol=1e-8 * (1 + np.abs(tau).max()))
        np.testing.assert_allclose(arm.inverse_dynamics(q, dq, ddq), tau, atol=1e-8 * 10)
        np.testing.assert_allclose(M, M.T, atol=1e-12)
        assert np.linalg.eigvalsh(M).min() > 0


def test_arm_coriolis_matrix_gives_mass_matrix_derivative(arm, make_rng):
    """Ṁ = C + Cᵀ (checked by a central difference of M along q̇) and C·q̇ = nle − G."""
    rng = make_rng(2)
    q, dq = random_state(arm, rng)
    C = arm.coriolis_matrix(q, dq)
    h = 1e-6
    Mdot = (arm.mass_matrix(q + h * dq) - arm.mass_matrix(q - h * dq)) / (2 * h)
    np.testing.assert_allclose(C + C.T, Mdot, atol=1e-6 * (1 + np.abs(Mdot).max()))
    np.testing.assert_allclose(
        C @ dq, arm.nonlinear_effects(q, dq) - arm.gravity_torque(q), atol=1e-9
    )


def test_example_robot_names_resolve_to_urdf_files():
    from hmpc_pin.model.catalogue import example_robot_names, example_robot_urdf

    names = example_robot_names()
    assert {"ur5", "ur10", "panda", "z1"} <= set(names)
    assert "solo12" not in names  # floating base
    for name in ("ur5", "panda", "z1"):
        assert example_robot_urdf(name).is_file()


def test_locked_fingers_still_load_the_arm(make_rng):
    """The reduced Panda's gravity equals the full model's with the fingers at their
    locked positions (their mass is kept, not dropped)."""
    import pinocchio as pin

    reduced = load_robot("panda", gravity=9.81, locked_joints=PANDA_FINGERS)
    full = pin.buildModelFromUrdf(str(reduced.source))
    full.gravity.linear = np.array([0.0, 0.0, -9.81])
    data = full.createData()
    rng = make_rng(3)
    assert reduced.nq == 7 and full.nq == 9
    for _ in range(5):
        q, _ = random_state(reduced, rng)
        q_full = np.concatenate([q, [0.02, 0.02]])
        g_full = pin.computeGeneralizedGravity(full, data, q_full)[:7]
        np.testing.assert_allclose(reduced.gravity_torque(q), g_full, atol=1e-10)


@pytest.mark.parametrize(
    ("source", "locked", "words"),
    [
        ("ur5x", None, "did you mean 'ur5'"),
        ("panda", {"finger": 0.0}, "locked joint(s) ['finger'] not found"),
        ("panda", {"panda_finger_joint1": 0.5}, "outside its limits"),
        ("panda", {"panda_finger_joint1": float("nan")}, "expected a finite value"),
    ],
)
def test_bad_arm_requests_name_the_problem(source, locked, words):
    with pytest.raises(URDFError) as exc:
        load_robot(source, locked_joints=locked)
    assert words in str(exc.value)


def test_continuous_joints_can_be_locked():
    """Kinova's continuous joints may be locked (or controlled, tests/test_urdf_joints.py)."""
    locked = {"j2s6s200_joint_1": 0.0, "j2s6s200_joint_4": 0.5, "j2s6s200_joint_6": 0.0}
    robot = load_robot("kinova", locked_joints=locked)
    assert robot.nq == 3 and "j2s6s200_joint_4" not in robot.joint_names


def test_prismatic_joint_is_controlled(write_urdf):
    """A prismatic joint is one coordinate like a revolute one: loaded, limits in metres."""
    path = write_urdf(PRISMATIC_URDF)
    robot = load_robot(path)
    assert robot.nq == 2 and robot.upper[1] == pytest.approx(0.3)
    q, dq = np.array([0.2, 0.1]), np.array([0.3, -0.2])
    tau = np.array([1.0, 2.0])
    ddq = robot.forward_dynamics(q, dq, tau)
    np.testing.assert_allclose(robot.inverse_dynamics(q, dq, ddq), tau, atol=1e-10)


PRISMATIC_URDF = """<robot name="rp">
  <link name="base"/>
  <link name="l1"><inertial><origin xyz="0.5 0 0"/><mass value="1"/>
    <inertia ixx="0.01" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="l2"><inertial><origin xyz="0 0 0"/><mass value="0.5"/>
    <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <axis xyz="0 -1 0"/><limit lower="-1.5" upper="1.5" effort="100" velocity="5"/></joint>
  <joint name="j2" type="prismatic"><parent link="l1"/><child link="l2"/>
    <origin xyz="1 0 0"/><axis xyz="1 0 0"/>
    <limit lower="0" upper="0.3" effort="100" velocity="1"/></joint>
</robot>
"""
