"""Controller × compensation: every 0.1 name is an alias of one pair (same objects, same
run), every table or key that does not apply to a pair is refused, and two spellings of
one pair can never be two variants."""

from __future__ import annotations

import numpy as np
import pytest

import hmpc_pin
from hmpc_pin import ConfigError, ControllerConfig
from hmpc_pin.apps.compare import parse_controllers
from hmpc_pin.apps.sweep import resolve_variants
from hmpc_pin.experiment.build import Experiment, make_compensation, with_controller
from hmpc_pin.experiment.config import load_config

ALIASES = {
    "hmpc": ("hmpc", "chen"),
    "hmpc-none": ("hmpc", "none"),
    "hmpc-momentum": ("hmpc", "momentum"),
    "hmpc-ism": ("hmpc", "ism"),
    "hmpc-ism-bl": ("hmpc", "ism-bl"),
    "computed-torque": ("computed-torque", "none"),
    "computed-torque-pid": ("computed-torque-pid", "none"),
}
COMPENSATION_CLASS = {
    "chen": hmpc_pin.DisturbanceObserver,
    "general": hmpc_pin.DisturbanceObserver,
    "momentum": hmpc_pin.MomentumObserver,
    "ism": hmpc_pin.IntegralSlidingMode,
    "ism-bl": hmpc_pin.IntegralSlidingMode,
    "none": hmpc_pin.NoCompensation,
}


@pytest.mark.parametrize("alias", sorted(ALIASES))
def test_old_name_is_the_pair_and_runs_identically(alias):
    controller, comp = ALIASES[alias]
    old = ControllerConfig(kind=alias)
    new = ControllerConfig(kind=controller, compensation=comp)
    assert (old.kind, old.compensation) == (controller, comp)
    assert old.label == new.label == f"{controller}+{comp}"
    config = load_config("paper_combined")
    runs = []
    for cc in (old, new):
        cfg = with_controller(config, cc.label)
        exp = Experiment.from_config(cfg)
        assert type(exp.controller.compensation) is COMPENSATION_CLASS[comp]
        runs.append(exp.run(1.0))
    np.testing.assert_array_equal(runs[0].tau, runs[1].tau)


def test_every_pair_builds():
    robot = hmpc_pin.load_robot("planar3")
    for controller in hmpc_pin.CONTROLLERS:
        for comp in hmpc_pin.COMPENSATIONS:
            cc = ControllerConfig(kind=controller, compensation=comp)
            ctrl = hmpc_pin.make_controller(robot, cc)
            assert isinstance(ctrl, hmpc_pin.Controller)
            assert type(ctrl.compensation) is COMPENSATION_CLASS[comp]
            assert type(make_compensation(robot, cc)) is COMPENSATION_CLASS[comp]


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [
        ({"kind": "hmpc-ism", "observer": {"gain": 5.0}}, "observer"),
        ({"kind": "hmpc", "compensation": "none", "observer": {"gain": 5.0}}, "observer"),
        ({"kind": "hmpc", "compensation": "chen", "ism": {"gain": 5.0}}, "ism"),
        ({"kind": "hmpc-ism", "ism": {"boundary_layer": 1.0}}, "ism.boundary_layer"),
        ({"kind": "hmpc", "computed_torque": {"kp": 1.0}}, "computed_torque"),
        ({"kind": "computed-torque", "computed_torque": {"ki": 1.0}}, "computed_torque.ki"),
        ({"kind": "computed-torque", "constraints": {"enabled": False}}, "constraints"),
        ({"kind": "computed-torque", "qp_layout": "joint"}, "qp_layout"),
        ({"kind": "computed-torque", "eps_abs": 1e-6}, "eps_abs"),
        ({"kind": "computed-torque", "observer": {"gain": 5.0}}, "observer"),
        ({"kind": "hmpc-momentum", "observer": {"enabled": False}}, "observer.enabled"),
        ({"kind": "hmpc-momentum", "observer": {"kind": "chen"}}, "observer.kind"),
        ({"compensation": "chen", "observer": {"kind": "general"}}, "observer.kind"),
        ({"kind": "hmpc-ism", "compensation": "chen"}, "compensation"),
        ({"kind": "hmpc", "compensation": "momentum", "observer": {"discretization": "explicit"}},
         "observer.discretization"),
        ({"kind": "hmpc+chen"}, "kind"),
        ({"kind": "pid"}, "kind"),
        ({"kind": "hmpc", "compensation": "kalman"}, "compensation"),
    ],
)  # fmt: skip
def test_inapplicable_or_contradictory_key_is_refused_by_name(kwargs, key):
    with pytest.raises(ConfigError) as info:
        ControllerConfig(**kwargs)
    assert info.value.key.endswith(key), (info.value.key, str(info.value))


def _toml(tmp_path, controller_lines: str):
    path = tmp_path / "c.toml"
    path.write_text(f"[controller]\n{controller_lines}\n[simulation]\nduration = 1.0\n")
    return load_config(path)


@pytest.mark.parametrize(
    ("text", "pair"),
    [
        ("[controller.observer]\nenabled = false\nkind = 'chen'\ngain = 100.0", ("hmpc", "none")),
        ("[controller.observer]\nenabled = true\nkind = 'general'", ("hmpc", "general")),
        ("[controller.observer]\nkind = 'momentum'\ngain = 50.0", ("hmpc", "momentum")),
        ("kind = 'hmpc-momentum'\n[controller.observer]\ngain = 50.0", ("hmpc", "momentum")),
        ("", ("hmpc", "chen")),
    ],
)
def test_version_01_files_load_as_their_pair(tmp_path, text, pair):
    cc = _toml(tmp_path, text).controller
    assert (cc.kind, cc.compensation) == pair
    assert (cc.observer is None) == (pair[1] == "none")


def test_hmpc_with_momentum_observer_kind_is_hmpc_momentum_and_cannot_be_two_variants(tmp_path):
    cfg = _toml(tmp_path, "[controller.observer]\nkind = 'momentum'")
    assert with_controller(cfg, "hmpc-momentum").controller.label == cfg.controller.label
    with pytest.raises(ConfigError, match="same controller"):
        parse_controllers("hmpc,hmpc-momentum", cfg)
    from dataclasses import replace

    cfg2 = replace(cfg, sweep=replace(cfg.sweep, variants=("ndo", "hmpc-momentum")))
    with pytest.raises(ConfigError, match="same controller"):
        resolve_variants(cfg2)


def test_ism_config_sweep_variants_are_two_different_controllers():
    cfg = with_controller(load_config("paper_combined"), "hmpc-ism")
    from dataclasses import replace

    cfg = replace(cfg, sweep=replace(cfg.sweep, variants=None))
    assert resolve_variants(cfg) == ("hmpc+ism", "hmpc+none")
    with pytest.raises(ConfigError, match="observer"):
        resolve_variants(replace(cfg, sweep=replace(cfg.sweep, variants=("ndo",))))


def test_every_shipped_config_loads_and_builds():
    from hmpc_pin.data import config_names

    for name in config_names():
        Experiment.from_config(load_config(name))


def test_the_controller_registry_states_what_is_built_and_its_names():
    """Each registry entry builds its class; its 0.1 names and default compensation are
    this file's (written out independently above); an unknown name is one error listing
    every controller."""
    from hmpc_pin.controllers.registry import REGISTRY, controller_kinds, controller_spec

    robot = hmpc_pin.load_robot("planar3")
    for name, spec in REGISTRY.items():
        ctrl = hmpc_pin.make_controller(robot, ControllerConfig(kind=name))
        assert type(ctrl) is spec.cls
        assert ALIASES[name] == (name, spec.default_compensation)
        assert {a: (name, c) for a, c in spec.aliases.items()} == {
            a: pair for a, pair in ALIASES.items() if a != pair[0] and pair[0] == name
        }
    assert set(controller_kinds()) == set(ALIASES)
    with pytest.raises(ConfigError) as err:
        controller_spec("mpc")
    assert all(name in str(err.value) for name in REGISTRY)
