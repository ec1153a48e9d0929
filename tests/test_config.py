"""Config loading and validation: defaults are the paper's, bad input names its key."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import hmpc_pin
from hmpc_pin.experiment.build import Experiment
from hmpc_pin.experiment.config import ControllerConfig, ObserverConfig, RobotConfig

from .conftest import CONFIGS, PLANAR3

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
    assert cfg.robot.gravity == 9.8 and cfg.robot.source == "planar3"
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
    # controller × compensation: contradictions and tables that do not apply to the pair
    ('[controller]\ncompensation = "magic"', "controller.compensation", "one of"),
    ('[controller]\nkind = "hmpc+momentum"', "controller.kind", "compensation"),
    ('[controller]\nkind = "hmpc-ism"\ncompensation = "chen"', "controller.compensation",
     "contradicts"),
    ('[controller]\nkind = "hmpc-momentum"\n[controller.observer]\nenabled = false',
     "controller.observer.enabled", "hmpc-momentum"),
    ('[controller]\nkind = "hmpc-momentum"\n[controller.observer]\nkind = "chen"',
     "controller.observer.kind", "hmpc-momentum"),
    ('[controller]\ncompensation = "chen"\n[controller.observer]\nenabled = true',
     "controller.observer.enabled", "superseded"),
    ('[controller]\nkind = "hmpc-ism"\n[controller.observer]\ngain = 50.0',
     "controller.observer", "does not apply"),
    ('[controller]\ncompensation = "none"\n[controller.observer]\ngain = 50.0',
     "controller.observer", "does not apply"),
    ('[controller]\nkind = "computed-torque"\n[controller.observer]\nkind = "chen"',
     "controller.observer.kind", "does not apply"),
    ("[controller.ism]\ngain = 100.0", "controller.ism", "does not apply"),
    ("[controller.computed_torque]\nkp = 5.0", "controller.computed_torque", "does not apply"),
    ('[controller]\nkind = "computed-torque"\n[controller.constraints]\nenabled = false',
     "controller.constraints", "does not apply"),
    ('[controller]\nkind = "computed-torque"\neps_abs = 1e-8', "controller.eps_abs",
     "does not apply"),
    ('[controller]\nkind = "computed-torque-pid"\nmax_iter = 10', "controller.max_iter",
     "does not apply"),
    ('[controller]\nkind = "computed-torque"\nqp_layout = "joint"', "controller.qp_layout",
     "does not apply"),
    ('[controller]\nkind = "hmpc-ism"\n[controller.ism]\nboundary_layer = 1.0',
     "controller.ism.boundary_layer", "ism-bl"),
    ('[controller]\nkind = "computed-torque"\n[controller.computed_torque]\nki = 5.0',
     "controller.computed_torque.ki", "computed-torque-pid"),
]  # fmt: skip

# Checks that need the robot: the file loads, building the experiment raises.
BAD_BUILD = [
    ("[controller]\nv_min = [-1.0, -1.0]", "controller.v_min", "3 joints"),
    ("[reference]\namplitude = [1.0, 2.0]", "reference.amplitude", "3 joints"),
    ("[disturbance.friction]\nviscous = [1.0, 2.0]", "disturbance.friction.viscous", "3 joints"),
    ("[controller.constraints]\nlower = [-1.0, -1.0]", "controller.constraints.lower", "3 joints"),
    ("[controller.constraints]\nupper = -5.0", "controller.constraints.upper", "lower < upper"),
    ("[plant]\neffort_limit = [1.0, 1.0]", "plant.effort_limit", "3 joints"),
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


@pytest.mark.parametrize(("extra", "key", "words"), BAD_BUILD, ids=[b[1] for b in BAD_BUILD])
def test_bad_value_for_the_robot_names_its_key_when_built(write_config, extra, key, words):
    path = write_config(BASE + "\n" + extra + "\n")
    config = hmpc_pin.load_config(path)  # the TOML alone is valid
    with pytest.raises(hmpc_pin.ConfigError) as info:
        Experiment.from_config(config)
    msg = str(info.value)
    assert info.value.key == key, msg
    assert str(path) in msg and key in msg and words in msg, msg


def test_wrong_length_q0_names_key(write_config):
    path = write_config('[robot]\nurdf = "@URDF@"\n[simulation]\nq0 = [1.0, 1.0]\n')
    config = hmpc_pin.load_config(path)
    with pytest.raises(hmpc_pin.ConfigError, match=r"simulation\.q0.*2 entries.*3 joints"):
        Experiment.from_config(config)


def test_missing_file_and_bad_toml(tmp_path):
    with pytest.raises(hmpc_pin.ConfigError, match="not found"):
        hmpc_pin.load_config(tmp_path / "nope.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[controller\nN = 3\n")
    with pytest.raises(hmpc_pin.ConfigError, match="not valid TOML"):
        hmpc_pin.load_config(bad)


def test_missing_urdf_in_config_is_a_config_error_naming_the_key(write_config, tmp_path):
    path = write_config(f'[robot]\nurdf = "{(tmp_path / "missing.urdf").as_posix()}"\n')
    with pytest.raises(hmpc_pin.ConfigError, match=r"robot\.urdf: .*missing\.urdf' not found"):
        hmpc_pin.load_config(path)  # the boundary: before anything is built


def test_bad_urdf_in_config_is_a_urdf_error(write_config, tmp_path):
    (tmp_path / "bad.urdf").write_text("<robot name='x'><link name='a'>", encoding="utf-8")
    path = write_config(f'[robot]\nurdf = "{(tmp_path / "bad.urdf").as_posix()}"\n')
    config = hmpc_pin.load_config(path)  # the file exists: its content is read on build
    with pytest.raises(hmpc_pin.URDFError, match=r"bad\.urdf: malformed XML"):
        Experiment.from_config(config)


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
    config = hmpc_pin.load_config(path)
    with pytest.raises(hmpc_pin.URDFError, match="did you mean 'panda'"):
        Experiment.from_config(config)


@pytest.mark.parametrize("name", ["ur5_sine", "panda_sine", "z1_sine"])
def test_arm_configs_load(name):
    cfg = hmpc_pin.load_config(CONFIGS / f"{name}.toml")
    assert cfg.robot.model and cfg.disturbance.scale == "inertia"
    assert cfg.controller.compensation == "general" and cfg.controller.label == "hmpc+general"
    assert cfg.controller.observer.gain == 100.0


# ------------------------------------------------------- controller × compensation
@pytest.mark.parametrize(
    ("kwargs", "kind", "compensation", "tables"),
    [
        ({}, "hmpc", "chen", {"observer", "constraints"}),
        ({"kind": "hmpc-none"}, "hmpc", "none", {"constraints"}),
        ({"kind": "hmpc-momentum"}, "hmpc", "momentum", {"observer", "constraints"}),
        ({"kind": "hmpc-ism"}, "hmpc", "ism", {"ism", "constraints"}),
        ({"kind": "hmpc-ism-bl"}, "hmpc", "ism-bl", {"ism", "constraints"}),
        ({"kind": "hmpc", "compensation": "general"}, "hmpc", "general",
         {"observer", "constraints"}),
        ({"kind": "computed-torque"}, "computed-torque", "none", {"computed_torque"}),
        ({"kind": "computed-torque-pid", "compensation": "momentum"}, "computed-torque-pid",
         "momentum", {"observer", "computed_torque"}),
        # the 0.1 spelling: the observer table decides the compensation of "hmpc"
        ({"observer": {"enabled": False}}, "hmpc", "none", {"constraints"}),
        ({"observer": {"kind": "momentum"}}, "hmpc", "momentum", {"observer", "constraints"}),
        ({"kind": "hmpc-momentum", "observer": {"kind": "momentum", "enabled": True}}, "hmpc",
         "momentum", {"observer", "constraints"}),
    ],
)  # fmt: skip
def test_controller_names_resolve_to_one_pair_with_its_tables(kwargs, kind, compensation, tables):
    c = ControllerConfig(**kwargs)
    assert (c.kind, c.compensation) == (kind, compensation)
    assert c.label == f"{kind}+{compensation}"
    present = {
        name
        for name in ("observer", "constraints", "ism", "computed_torque")
        if getattr(c, name) is not None
    }
    assert present == tables
    if c.observer is not None:  # the 0.1 keys are resolved, not kept
        assert (c.observer.enabled, c.observer.kind) == (None, None)
    hmpc_only = (c.eps_abs, c.max_iter, c.qp_layout)
    assert hmpc_only == ((1e-9, 1000, "auto") if kind == "hmpc" else (None, None, None))


def test_observer_gain_of_the_01_spelling_is_kept():
    c = ControllerConfig(observer={"kind": "momentum", "gain": 50.0})
    assert c.label == "hmpc+momentum" and c.observer.gain == 50.0


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [
        ({"kind": "hmpc-momentum", "observer": {"enabled": False}}, "observer.enabled"),
        ({"kind": "hmpc-momentum", "observer": {"kind": "chen"}}, "observer.kind"),
        ({"kind": "hmpc-ism", "observer": {}}, "observer"),
        ({"kind": "hmpc", "compensation": "none", "observer": {}}, "observer"),
        ({"ism": {}}, "ism"),
        ({"kind": "hmpc-ism-bl", "computed_torque": {}}, "computed_torque"),
        ({"kind": "computed-torque", "constraints": {}}, "constraints"),
        ({"kind": "computed-torque", "eps_abs": 1e-8}, "eps_abs"),
        ({"kind": "computed-torque", "max_iter": 10}, "max_iter"),
        ({"kind": "computed-torque-pid", "qp_layout": "joint"}, "qp_layout"),
        ({"kind": "hmpc-ism", "ism": {"boundary_layer": 1.0}}, "ism.boundary_layer"),
        ({"kind": "computed-torque", "computed_torque": {"ki": 1.0}}, "computed_torque.ki"),
        ({"kind": "hmpc-ism", "compensation": "chen"}, "compensation"),
    ],
)
def test_contradictions_and_tables_that_do_not_apply_are_errors(kwargs, key):
    with pytest.raises(hmpc_pin.ConfigError) as info:
        ControllerConfig(**kwargs)
    assert info.value.key == key and key in str(info.value), str(info.value)


def test_default_robot_is_the_packaged_planar3(write_config, planar3):
    assert RobotConfig().source == "planar3"
    packaged = hmpc_pin.load_robot("planar3")
    assert packaged.nq == 3 and packaged.joint_names == planar3.joint_names
    q = np.array([0.3, -0.7, 1.1])
    np.testing.assert_array_equal(packaged.mass_matrix(q), planar3.mass_matrix(q))
    path = write_config("[simulation]\nq0 = [1.0, 1.0, 1.0]\n")  # no [robot] table
    config = hmpc_pin.load_config(path)
    assert config.robot.urdf is None and config.robot.model is None
    exp = Experiment.from_config(config)
    assert exp.robot.source == packaged.source
    assert Path(exp.robot.source).samefile(PLANAR3)


def test_load_robot_config_loads_the_robot_table(planar3):
    from hmpc_pin.experiment.build import load_robot_config

    robot = load_robot_config(RobotConfig(urdf=PLANAR3, gravity=3.0))
    q = np.array([0.3, -0.7, 1.1])
    np.testing.assert_allclose(robot.gravity_torque(q), 3.0 / 9.8 * planar3.gravity_torque(q),
                               rtol=1e-12)  # fmt: skip
    np.testing.assert_array_equal(robot.mass_matrix(q), planar3.mass_matrix(q))


def test_packaged_config_loads_by_name():
    by_name = hmpc_pin.load_config("paper_combined")
    by_path = hmpc_pin.load_config(CONFIGS / "paper_combined.toml")
    assert by_name.name == by_path.name == "paper_combined"
    assert by_name.source.samefile(by_path.source)
    assert by_name.robot.source == by_path.robot.source == "planar3"
    assert by_name.controller.label == by_path.controller.label == "hmpc+chen"


def test_the_controller_table_states_no_default_of_the_mpcs_settings():
    """Each MPC default is stated once, in MPCSettings: the [controller] table's fields
    read it (no literal there but a field's name), the computed-torque settings' bounds
    too, and the table's resolved values are MPCSettings' own."""
    import ast
    import inspect
    from dataclasses import fields

    from hmpc_pin.controllers.computed_torque import CTSettings
    from hmpc_pin.controllers.hierarchical import MPCSettings
    from hmpc_pin.experiment.config import controller as module
    from hmpc_pin.experiment.controllers import mpc_settings

    mpc = {f.name for f in fields(MPCSettings)}
    checked = 0
    for cls, names in (
        (module.ControllerConfig, mpc),
        (module.ObserverConfig, {"model_at"}),
        (CTSettings, {"v_min", "v_max"}),
    ):
        tree = ast.parse(inspect.getsource(cls).lstrip())
        for node in ast.walk(tree):
            if isinstance(node, ast.AnnAssign) and node.target.id in names and node.value:
                literals = [
                    n.value
                    for n in ast.walk(node.value)
                    if isinstance(n, ast.Constant) and n.value is not None and n.value not in mpc
                ]
                assert not literals, f"{cls.__name__}.{node.target.id} = {literals}"
                checked += 1
    assert checked == 14 + 1 + 2  # [controller]'s MPC keys, model_at, CTSettings' bounds
    ours, theirs = mpc_settings(module.ControllerConfig(), 3), MPCSettings()
    for name in mpc:
        a, b = getattr(ours, name), getattr(theirs, name)
        assert np.array_equal(np.broadcast_to(b, np.shape(a)), a), name
