"""Every moving link's inertia is checked before the run (a rigid body's: mass >= 0,
rotational inertia positive semi-definite with principal moments satisfying the triangle
inequalities), the error naming the link; the check is compared with an independent
criterion (the second moment of the mass, which a set of point masses always has)."""

from __future__ import annotations

import warnings
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from hmpc_pin import load_robot
from hmpc_pin.apps.cli import main
from hmpc_pin.exceptions import URDFError, ValidityWarning
from hmpc_pin.model.urdf_checks import check_inertias

from .test_urdf_joints import CONFIG, chain, joint, rod

INERTIA = (
    '<link name="{name}"><inertial><origin xyz="0.25 0 0"/><mass value="{mass}"/>'
    '<inertia ixx="{ixx}" ixy="{ixy}" ixz="{ixz}" iyy="{iyy}" iyz="{iyz}" izz="{izz}"/>'
    "</inertial></link>"
)


def arm(end: dict, mass: float = 1.0, fixed_to_world: dict | None = None) -> str:
    """Three revolute joints; the end link ``l3`` has the inertia ``end``; optionally a
    link ``mount`` fixed to the base (it never moves) with ``fixed_to_world``."""
    full = {"ixy": 0, "ixz": 0, "iyz": 0, **end}
    parts = [rod("l1"), joint("j1", "revolute", "base", "l1", x=0.0),
             rod("l2"), joint("j2", "revolute", "l1", "l2"),
             INERTIA.format(name="l3", mass=mass, **full),
             joint("j3", "revolute", "l2", "l3")]  # fmt: skip
    if fixed_to_world is not None:
        bad = {"ixy": 0, "ixz": 0, "iyz": 0, **fixed_to_world}
        parts += [INERTIA.format(name="mount", mass=1.0, **bad),
                  joint("mount_joint", "fixed", "base", "mount")]  # fmt: skip
    return chain(*parts)


GOOD = {"ixx": 1e-3, "iyy": 2e-2, "izz": 2e-2}


@pytest.mark.parametrize(
    ("end", "mass", "words"),
    [
        ({**GOOD, "iyy": -2e-2}, 1.0, "not positive semi-definite"),
        ({"ixx": 1e-3, "iyy": 1e-3, "izz": 1e-3, "ixy": 2e-3}, 1.0, "not positive semi-definite"),
        (GOOD, -1.0, "expected a finite mass >= 0"),
        # a moment of -1e-7 kg·m² (1e-4 of the largest): small, but no rigid body has it
        (
            {"ixx": 1e-3, "iyy": 1e-3, "izz": 1e-3, "ixy": 1.0001e-3},
            1.0,
            "not positive semi-definite",
        ),
    ],
    ids=["negative_moment", "indefinite_off_diagonal", "negative_mass", "slightly_negative"],
)
def test_impossible_inertia_is_refused_naming_the_link(write_urdf, end, mass, words):
    path = write_urdf(arm(end, mass))
    with pytest.raises(URDFError, match=words) as info:
        load_robot(path)
    assert "link 'l3'" in str(info.value) and str(info.value).startswith(str(path))


def test_a_violated_triangle_inequality_warns_naming_the_link(write_urdf):
    """Moments (1, 1, 5)e-3: M(q) stays positive definite, so the arm loads, with a
    warning naming the link (published URDFs such as the Allegro hand have them)."""
    path = write_urdf(arm({"ixx": 1e-3, "iyy": 1e-3, "izz": 5e-3}))
    with pytest.warns(ValidityWarning, match=r"link 'l3'.*triangle inequality I1 \+ I2 >= I3"):
        robot = load_robot(path)
    assert np.linalg.eigvalsh(robot.mass_matrix(np.full(3, 0.3))).min() > 0


def test_a_link_fixed_to_a_moving_link_is_checked(write_urdf):
    """A tool fixed to the last link moves with it: its impossible inertia is refused."""
    tool = INERTIA.format(name="tool", mass=0.5, ixx=1e-3, iyy=-1e-3, izz=1e-3, ixy=0, ixz=0,
                          iyz=0)  # fmt: skip
    text = arm(GOOD).replace("</robot>", tool + joint("tool_joint", "fixed", "l3", "tool")
                             + "\n</robot>")  # fmt: skip
    with pytest.raises(URDFError, match="link 'tool'"):
        load_robot(write_urdf(text))


def test_valid_inertias_load_and_a_fixed_link_is_not_judged(write_urdf):
    # Off-diagonal terms of a valid body (diag(1, 2, 2.5)e-3 turned about z by 30°) pass.
    c, s = np.cos(np.pi / 6), np.sin(np.pi / 6)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    inertia = rot @ np.diag([1e-3, 2e-3, 2.5e-3]) @ rot.T
    end = {"ixx": inertia[0, 0], "iyy": inertia[1, 1], "izz": inertia[2, 2],
           "ixy": inertia[0, 1]}  # fmt: skip
    # A point mass (zero moments) at the end is a valid rigid body; a link fixed to the
    # world acts on nothing, so its (impossible) inertia is not judged.
    for urdf in (arm(end), arm({"ixx": 1e-3, "iyy": 2e-3, "izz": 2e-3},
                               fixed_to_world={"ixx": -1, "iyy": 1, "izz": 1})):  # fmt: skip
        assert load_robot(write_urdf(urdf)).nq == 3


def _second_moment_valid(inertia: np.ndarray) -> bool:
    """Independent criterion: ``inertia`` belongs to some mass distribution iff its
    second moment Σ = tr(I)/2·1 − I (= Σ m r rᵀ) is positive semi-definite."""
    sigma = 0.5 * np.trace(inertia) * np.eye(3) - inertia
    return bool(np.linalg.eigvalsh(sigma).min() >= 0)


def test_the_check_agrees_with_the_second_moment_criterion(make_rng):
    """Random symmetric matrices (away from the boundary) and the inertias of random
    clouds of point masses: the check accepts exactly the physical ones."""
    rng = make_rng(7)
    root = ET.fromstring(arm(GOOD))
    end = root.find("link[@name='l3']/inertial/inertia")
    verdicts = []
    samples = [rng.normal(size=(3, 3)) for _ in range(300)]
    for _ in range(50):  # bodies made of point masses: always valid
        m, r = rng.uniform(0.1, 1, 6), rng.normal(size=(6, 3))
        cloud = [mi * (ri @ ri * np.eye(3) - np.outer(ri, ri)) for mi, ri in zip(m, r, strict=True)]
        samples.append(sum(cloud))
    for a in samples:
        inertia = 0.5 * (a + a.T) + (0 if len(verdicts) >= 300 else rng.uniform(0, 3) * np.eye(3))
        sigma_min = np.linalg.eigvalsh(0.5 * np.trace(inertia) * np.eye(3) - inertia).min()
        if abs(sigma_min) < 1e-3 * np.abs(inertia).max():
            continue  # too close to the boundary to judge against the tolerance
        for key, (i, j) in {"ixx": (0, 0), "iyy": (1, 1), "izz": (2, 2), "ixy": (0, 1),
                            "ixz": (0, 2), "iyz": (1, 2)}.items():  # fmt: skip
            end.set(key, repr(float(inertia[i, j])))
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                check_inertias(root, "arm.urdf")
                accepted = not caught  # refused (negative moment) or warned (triangle)
            except URDFError:
                accepted = False
        assert accepted == _second_moment_valid(inertia), inertia
        verdicts.append(accepted)
    assert 50 < sum(verdicts) < len(verdicts) - 50  # both verdicts well represented


def test_run_refuses_a_negative_moment_before_the_run(write_urdf, tmp_path, capsys):
    """Before: the Pinocchio plant ran it (exit 0) or the error said the joint "moves no
    mass" although the link has both. Now: exit 2, one line naming the link, no file."""
    urdf = write_urdf(arm({**GOOD, "izz": -2e-2}))
    cfg = tmp_path / "arm.toml"
    cfg.write_text(CONFIG.format(urdf=urdf.as_posix(), offset=0.3, duration=0.2),
                   encoding="utf-8")  # fmt: skip
    out = tmp_path / "out"
    assert main(["run", str(cfg), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "link 'l3'" in err[0] and "not positive semi-definite" in err[0]
    assert "no mass" not in err[0] and not out.exists()
