"""Config loading and validation: defaults are the paper's, bad input names its key."""

from __future__ import annotations

import numpy as np
import pytest

import hmpc_pin
from hmpc_pin.experiment.build import Experiment
from hmpc_pin.experiment.schema import ControllerConfig, ObserverConfig, RobotConfig

from .conftest import CONFIGS

BASE = """
[robot]
urdf = "@URDF@"
[simulation]
q0 = [1.0, 1.0, 1.0]
"""


def test_controller_defaults_are_the_papers():
    c = ControllerConfig()
    assert (c.Ts, c.N, c.Nc, c.R) == (0.01, 10, 1, 1e-6)
    np.testing.assert_array_equal(c.Q, np.diag([50.0, 0.0]))
    np.testing.assert_array_equal(c.P, 2 * c.Q)
    assert float(c.v_min) == -100.0 and float(c.v_max) == 100.0
    # the paper's scheme: hmpc × Chen's NDO, with only the tables of that pair
    assert (c.kind, c.compensation, c.label) == ("hmpc", "chen", "hmpc+chen")
    assert c.observer.discretization == "implicit" and c.observer.gain == 100.0
    assert c.ism is None and c.computed_torque is None


@pytest.mark.parametrize("name", ["paper_combined", "paper_friction", "paper_external"])
def test_paper_configs_load_with_every_number_of_the_paper(name):
    cfg = hmpc_pin.load_config(CONFIGS / f"{name}.toml")
    c = cfg.controller
    assert c.label == "hmpc+chen"
    assert (c.Ts, c.N, c.Nc, c.R) == (0.01, 10, 1, 1e-6)
    np.testing.assert_array_equal(c.Q, np.diag([50.0, 0.0]))
    np.testing.assert_array_equal(c.P, np.diag([100.0, 0.0]))
    np.testing.assert_array_equal(cfg.simulation.q0, [1.0, 1.0, 1.0])
    assert cfg.simulation.duration == 10.0
    assert cfg.robot.gravity == 9.8 and cfg.robot.urdf.is_file()
    np.testing.assert_array_equal(cfg.reference.amplitude, 1.0)
    np.testing.assert_allclose(2 * np.pi * cfg.reference.frequency, 0.2 * np.pi)
    d = cfg.disturbance
    if name in ("paper_combined", "paper_friction"):
        np.testing.assert_array_equal(d.friction.viscous, [10, 8, 5])
        np.testing.assert_array_equal(d.friction.coulomb, [3.0, 2.4, 1.8])
    else:
        assert d.friction is None
    if name in ("paper_combined", "paper_external"):
        np.testing.assert_array_equal(d.pulse.amplitude, [10, 8, 0.3])
        np.testing.assert_array_equal(d.pulse.center, [1, 2, 3])
        np.testing.assert_array_equal(d.pulse.sigma, 0.3)
    else:
        assert d.pulse is None


def test_relative_urdf_is_resolved_against_the_config_file(tmp_path):
    (tmp_path / "sub").mkdir()
    urdf = (CONFIGS.parent / "robots" / "planar3.urdf").read_text()
    (tmp_path / "arm.urdf").write_text(urdf)
    cfg_path = tmp_path / "sub" / "c.toml"
    cfg_path.write_text('[robot]\nurdf = "../arm.urdf"\n')
    cfg = hmpc_pin.load_config(cfg_path)
    assert cfg.robot.urdf == (tmp_path / "arm.urdf").resolve()


BAD = [
    # (TOML appended to BASE or replacing it, expected key, expected words)
    ("[controller]\nN = 0", "controller.N", ">= 1"),
    ("[controller]\nNc = 0", "controller.Nc", ">= 1"),
    ("[controller]\nN = 5\nNc = 6", "controller.Nc", "Nc <= N"),
    ("[controller]\nTs = 0.0", "controller.Ts", "> 0"),
    ("[controller]\nTs = -0.01", "controller.Ts", "> 0"),
    ("[controller]\nv_min = 5.0\nv_max = 5.0", "controller.v_min", "must be < v_max"),
    ("[controller]\nN = 2.5", "controller.N", "integer"),
    ("[controller]\nN = true", "controller.N", "integer"),
    ('[controller]\nTs = "fast"', "controller.Ts", "number"),
    ("[controller]\nR = 0.0", "controller.R", "> 0"),
    ("[controller]\nR = nan", "controller.R", "finite"),
    ("[controller]\nQ = [-1.0, 0.0]", "controller.Q", "positive semi-definite"),
    ("[controller]\nP = [1.0, 2.0, 3.0]", "controller.P", "2x2"),
    ("[controller]\nhorizon = 3", "controller.horizon", "unknown key"),
    ("[controller.observer]\ngain = -1.0", "controller.observer.gain", "> 0"),
    ('[controller.observer]\nkind = "magic"', "controller.observer.kind", "one of"),
    ("[controller.observer]\nspeed = 1", "controller.observer.speed", "unknown key"),
    ("[simulation]\nduration = 0", "simulation.duration", "> 0"),
    ("[disturbance.pulse]\nsigma = 0.0", "disturbance.pulse.sigma", "> 0"),
    ('[plant]\nintegrator = "leapfrog"', "plant.integrator", "one of"),
    ("[oops]\nx = 1", "oops", "unknown key"),
    ("[controller.constraints]\nslack_weight = 0", "controller.constraints.slack_weight", "> 0"),
    ("[controller.constraints]\nsoft = 1", "controller.constraints.soft", "unknown key"),
    (
        '[controller.observer]\nkind = "momentum"\ndiscretization = "explicit"',
        "controller.observer.discretization",
        "semi-implicit",
    ),
    ('[disturbance]\nscale = "mass"', "disturbance.scale", "one of"),
    ('[controller]\nkind = "lqr"', "controller.kind", "computed-torque-pid"),
    ("[controller.ism]\ngain = 0.0", "controller.ism.gain", "> 0"),
    ("[controller.ism]\nwidth = 1.0", "controller.ism.width", "unknown key"),
    ("[controller.computed_torque]\nkp = -5.0", "controller.computed_torque.kp", "> 0"),
    ("[plant]\neffort_limit = [1.0, -1.0, 1.0]", "plant.effort_limit", "> 0"),
]


@pytest.mark.parametrize(("extra", "key", "words"), BAD, ids=[b[1] for b in BAD])
def test_bad_value_names_its_key(write_config, extra, key, words):
    text = BASE + "\n" + extra + "\n"
    if extra.startswith("[simulation]"):
        text = '[robot]\nurdf = "@URDF@"\n' + extra + "\n"
    path = write_config(text)
    with pytest.raises(hmpc_pin.ConfigError) as info:
        hmpc_pin.load_config(path)
    msg = str(info.value)
    assert info.value.key == key, msg
    assert str(path) in msg and key in msg and words in msg, msg


def test_wrong_length_q0_names_key(write_config):
    path = write_config('[robot]\nurdf = "@URDF@"\n[simulation]\nq0 = [1.0, 1.0]\n')
    with pytest.raises(hmpc_pin.ConfigError, match=r"simulation\.q0.*2 entries.*3 joints"):
        hmpc_pin.load_config(path)


def test_missing_file_and_bad_toml(tmp_path):
    with pytest.raises(hmpc_pin.ConfigError, match="not found"):
        hmpc_pin.load_config(tmp_path / "nope.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[controller\nN = 3\n")
    with pytest.raises(hmpc_pin.ConfigError, match="not valid TOML"):
        hmpc_pin.load_config(bad)


def test_bad_urdf_in_config_is_a_urdf_error(write_config, tmp_path):
    path = write_config(f'[robot]\nurdf = "{(tmp_path / "missing.urdf").as_posix()}"\n')
    with pytest.raises(hmpc_pin.URDFError, match=r"missing\.urdf: file not found"):
        hmpc_pin.load_config(path)


def test_dataclasses_validate_when_built_directly():
    with pytest.raises(hmpc_pin.ConfigError, match="Nc"):
        ControllerConfig(N=3, Nc=4)
    with pytest.raises(hmpc_pin.ConfigError, match="gain"):
        ObserverConfig(gain=float("inf"))
    with pytest.raises(hmpc_pin.ConfigError, match="R"):
        ControllerConfig(R=-1.0)


def test_config_is_frozen():
    c = ControllerConfig()
    with pytest.raises(AttributeError):
        c.N = 3


@pytest.mark.parametrize(
    ("robot", "key", "words"),
    [
        ('urdf = "@URDF@"\nmodel = "ur5"', "robot.model", "not both"),
        ("model = 5", "robot.model", "robot name string"),
        ('model = "panda"\nlocked_joints = 3', "robot.locked_joints", "table"),
        ('model = "panda"\n[robot.locked_joints]\npanda_finger_joint1 = "open"',
         "robot.locked_joints.panda_finger_joint1", "number"),
    ],
)  # fmt: skip
def test_bad_robot_section_names_its_key(write_config, robot, key, words):
    path = write_config(f"[robot]\n{robot}\n")
    with pytest.raises(hmpc_pin.ConfigError) as info:
        hmpc_pin.load_config(path)
    assert info.value.key == key and words in str(info.value), str(info.value)


def test_unknown_robot_name_in_config_lists_close_names(write_config):
    path = write_config('[robot]\nmodel = "pandas"\n')
    with pytest.raises(hmpc_pin.URDFError, match="did you mean 'panda'"):
        hmpc_pin.load_config(path)


@pytest.mark.parametrize("name", ["ur5_sine", "panda_sine", "z1_sine"])
def test_arm_configs_load(name):
    cfg = hmpc_pin.load_config(CONFIGS / f"{name}.toml")
    assert cfg.robot.model and cfg.disturbance.scale == "inertia"
    assert cfg.controller.observer.kind == "general"
