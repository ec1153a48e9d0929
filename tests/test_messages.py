"""Messages a new user meets: the arms init accepts, "did you mean" among arms only,
0-based indices said, a config without description, one version string."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

import hmpc_pin
from hmpc_pin.apps.cli import main
from hmpc_pin.exceptions import TrajectoryError, URDFError
from hmpc_pin.model.catalogue import example_robot_names
from hmpc_pin.model.robot import load_robot

from .conftest import CONFIGS

ROOT = Path(__file__).resolve().parent.parent


def test_init_list_prints_every_accepted_name(capsys):
    assert main(["init", "--list"]) == 0
    out = capsys.readouterr().out
    listed = {line.split()[0] for line in out.splitlines() if line and not line.startswith("or")}
    from hmpc_pin.data import robot_names

    assert listed == {*robot_names(), *example_robot_names()}  # planar3, fr3 and the rest
    assert "ur5" in listed and "iris" not in listed  # a drone is no arm


def test_init_without_a_robot_says_what_to_give(capsys):
    assert main(["init"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == "error: ROBOT: give a URDF path or a robot name (--list lists the names)"


def test_did_you_mean_offers_arms_only():
    with pytest.raises(URDFError) as info:
        load_robot("iiwa")
    message = str(info.value)
    offered = re.findall(r"'([^']+)'", message.split("did you mean", 1)[-1].split("?")[0])
    assert "iris" not in message
    assert set(offered) <= {"planar3", *example_robot_names()}
    with pytest.raises(URDFError, match="did you mean 'ur5'"):
        load_robot("ur5x")


def test_indices_in_messages_say_they_are_0_based(tmp_path):
    with pytest.raises(TrajectoryError, match=r"waypoint 2 equals waypoint 1 \(0-based\)"):
        hmpc_pin.retime_waypoints(np.array([[0.0], [1.0], [1.0]]), [1.0], [1.0])
    path = tmp_path / "t.csv"
    path.write_text("t,j1\n0,0\n0.1,0.1\n0.1,0.2\n", encoding="utf-8")
    with pytest.raises(TrajectoryError, match=r"at sample 2 \(0-based\)"):
        hmpc_pin.load_trajectory(path, ["j1"])


def test_a_config_without_description_prints_no_empty_part(tmp_path, capsys):
    text = (CONFIGS / "paper_combined.toml").read_text(encoding="utf-8")
    text = re.sub(r"(?m)^description = .*\n", "", text)
    cfg = tmp_path / "bare.toml"
    cfg.write_text(text, encoding="utf-8")
    assert main(["run", str(cfg), "--duration", "0.2", "--out", str(tmp_path)]) == 0
    title = capsys.readouterr().out.splitlines()[0]
    assert title.startswith("paper_combined: (hmpc+") and ":  (" not in title


def test_one_version_string():
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    assert hmpc_pin.__version__ == meta["project"]["version"]
    # what the messages call "since 0.3" is this version or an earlier one
    major_minor = tuple(int(x) for x in hmpc_pin.__version__.split(".")[:2])
    for path in (ROOT / "hmpc_pin").rglob("*.py"):
        for since in re.findall(r"since (\d+)\.(\d+)", path.read_text(encoding="utf-8")):
            assert tuple(map(int, since)) <= major_minor, (path, since)


def test_a_limit_without_effort_names_the_joint(write_urdf):
    from .test_urdf_joints import chain, joint, rod

    text = chain(rod("l1"), joint("j1", "revolute", "base", "l1", x=0.0), rod("l2"),
                 joint("j2", "revolute", "l1", "l2",
                       limit='<limit lower="-1" upper="1" velocity="2"/>'))  # fmt: skip
    with pytest.raises(URDFError) as info:
        load_robot(write_urdf(text))
    message = str(info.value)
    assert "joint 'j2': <limit> has no effort attribute" in message
    assert message.count("effort") == 3 and 'effort="0" is no torque limit' in message


def test_a_header_typo_points_at_the_column(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("t,joint1,jiont2\n0,0,0\n0.1,0.1,0.1\n", encoding="utf-8")
    with pytest.raises(TrajectoryError, match=r"no column for joint 'joint2' \(column "
                       r"'jiont2' is not a joint: a typo of 'joint2'\?\)"):  # fmt: skip
        hmpc_pin.load_trajectory(path, ["joint1", "joint2"])


def test_init_says_what_it_assumes(write_urdf, tmp_path, capsys):
    """A URDF effort of 0 is said to be no torque limit; a model example-robot-data puts
    on a floating base is said to be controlled with its base fixed."""
    from .test_urdf_joints import chain, joint, rod

    free = '<limit lower="-2" upper="2" effort="0" velocity="3"/>'
    text = chain(rod("l1"), joint("j1", "revolute", "base", "l1", x=0.0), rod("l2"),
                 joint("j2", "revolute", "l1", "l2", limit=free))  # fmt: skip
    assert main(["init", str(write_urdf(text)), "--out", str(tmp_path / "a.toml")]) == 0
    err = capsys.readouterr().err
    assert "joint(s) ['j2'] have effort=\"0\" in the URDF: taken as no torque limit" in err
    assert "floating base" not in err
    from hmpc_pin.experiment.init import plan

    with pytest.warns(hmpc_pin.ValidityWarning, match="so100: example-robot-data gives it a "
                      "floating base"):  # fmt: skip
        plan("so100")


def test_a_trajectory_in_degrees_is_called_so_and_a_position_error_does_not_say_slower(
    tmp_path, capsys
):
    """planar3's first joint is limited to ±π/2: a sine of 45° amplitude written in
    degrees leaves it: the one line suggests degrees; a slow motion in rad beyond the
    limits says to move it inside them, not to slow down."""
    t = np.linspace(0.0, 2.0, 201)
    cfg = tmp_path / "c.toml"
    text = (CONFIGS / "paper_combined.toml").read_text(encoding="utf-8")
    cfg.write_text(text)
    robot = load_robot("planar3")
    lo, hi = robot.lower[0], robot.upper[0]
    assert (lo, hi) == pytest.approx((-np.pi / 2, np.pi / 2))
    for values, words, absent in (
        (np.degrees(0.5 * lo) * np.sin(np.pi * t), "look like degrees", None),
        (np.full_like(t, hi + 0.2), "positions inside the limits", "slower"),
    ):
        path = tmp_path / "traj.csv"
        pairs = zip(t, values, strict=True)
        rows = ["t,joint1,joint2,joint3"] + [f"{float(a)!r},{float(b)!r},0,0" for a, b in pairs]
        path.write_text("\n".join(rows) + "\n", encoding="utf-8")
        assert main(["run", str(cfg), "--reference", str(path), "--out", str(tmp_path)]) == 2
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and words in err, err
        assert absent is None or absent not in err
