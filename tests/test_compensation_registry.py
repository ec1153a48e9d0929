"""The compensation registry (:mod:`hmpc_pin.compensation.registry`): every entry builds,
its table validates as the entry says, its Y is Eq 28's (closed form and the observer's own
p(q̇) by finite differences), an unknown name is one error listing the registry, and the
config, the builder, identify, tune and the benchmarks read it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from hmpc_pin.compensation.base import Compensation, step_compensation
from hmpc_pin.compensation.registry import (
    REGISTRY,
    CompensationSpec,
    build_compensation,
    compensation_names,
    compensation_spec,
)
from hmpc_pin.exceptions import ConfigError
from hmpc_pin.experiment.build import make_compensation, make_controller
from hmpc_pin.experiment.config.controller import ControllerConfig, parse_combination

NAMES = tuple(REGISTRY)


def _config(name: str, **kwargs) -> ControllerConfig:
    """``hmpc`` × the compensation ``name`` with the default table (and ``kwargs``)."""
    return ControllerConfig(compensation=name, **kwargs)


@pytest.mark.parametrize("name", NAMES)
def test_every_entry_builds_its_class_and_runs_one_period(name, planar3, make_rng):
    spec = REGISTRY[name]
    assert spec.name == name
    comp = make_compensation(planar3, _config(name))
    assert isinstance(comp, spec.cls) and isinstance(comp, Compensation)
    assert step_compensation(comp).compiled == spec.compiled
    n = planar3.nq
    rng = make_rng(3)
    q, dq = rng.uniform(-1, 1, n), rng.uniform(-1, 1, n)
    comp.reset(q, dq)
    assert np.array_equal(comp.estimate, np.zeros(n))
    M, nle = planar3.mass_matrix(q), rng.normal(size=n)
    d_hat = comp.update(M, nle, q, dq, rng.normal(size=n), rng.normal(size=n))
    assert np.shape(d_hat) == (n,) and np.all(np.isfinite(d_hat))
    if name == "none":
        assert np.array_equal(d_hat, np.zeros(n))


@pytest.mark.parametrize("name", NAMES)
def test_the_table_of_each_entry_is_the_one_set_and_takes_the_keys_it_says(name):
    spec = REGISTRY[name]
    cc = _config(name)
    for table in ("observer", "ism"):
        assert (getattr(cc, table) is not None) == (table == spec.table), table
    other = "ism" if spec.table == "observer" else "observer"
    with pytest.raises(ConfigError, match=f"^{other}: does not apply"):
        _config(name, **{other: {}})
    if spec.observer:
        for form in ("implicit", "explicit"):
            if form in spec.discretizations:
                assert _config(name, observer={"discretization": form}).observer
            else:
                with pytest.raises(ConfigError, match=r"observer\.discretization"):
                    _config(name, observer={"discretization": form})
        if spec.bandwidth:
            assert _config(name, observer={"bandwidth": 20.0}).observer.bandwidth == 20.0
        else:
            with pytest.raises(ConfigError, match=r"observer\.bandwidth.*'chen'"):
                _config(name, observer={"bandwidth": 20.0})
    if spec.table == "ism":
        table = {"boundary_layer": 0.5}
        if spec.boundary_layer:
            assert _config(name, ism=table).ism.width(0.01) == 0.5
        else:
            with pytest.raises(ConfigError, match=r"ism\.boundary_layer.*'ism-bl'"):
                _config(name, ism=table)


@pytest.mark.parametrize("n", [1, 2, 3, 7])
def test_Y_is_eq_28_in_closed_form(n):
    # Eq 28: Chen's p_i = c Σ_{j<=i} q̇_j (lower-triangular ones); the general design Y = I.
    chen = REGISTRY["chen"].Y(n)
    assert chen.shape == (n, n)
    for i in range(n):
        for j in range(n):
            assert chen[i, j] == (1.0 if j <= i else 0.0)
    assert np.array_equal(REGISTRY["general"].Y(n), np.eye(n))
    assert {name for name, spec in REGISTRY.items() if spec.Y is not None} == {
        "chen",
        "general",
    }


@pytest.mark.parametrize("name", [name for name, spec in REGISTRY.items() if spec.Y])
def test_the_built_observers_p_has_the_jacobian_c_Y(name, planar3, make_rng):
    """p(q̇) = cYq̇ (Eq 28) of the built observer, differentiated by central differences."""
    gain = 37.0
    obs = make_compensation(planar3, _config(name, observer={"gain": gain}))
    n, h = planar3.nq, 1e-6
    dq0 = make_rng(5).normal(size=n)
    J = np.empty((n, n))
    for j in range(n):
        e = np.zeros(n)
        e[j] = h
        J[:, j] = (obs.p(dq0 + e) - obs.p(dq0 - e)) / (2 * h)
    # p is linear: the central difference is exact up to the rounding of p (|p| ~ 1e2).
    np.testing.assert_allclose(J, gain * REGISTRY[name].Y(n), rtol=0, atol=1e-6)


def test_an_observer_without_Y_has_its_gain_as_bandwidth(planar3):
    # the momentum observer's error decays by 1/(1 + Ts K_O) per period: K_O per joint
    from hmpc_pin.compensation.bandwidth import compensation_bandwidth

    for name in (name for name, s in REGISTRY.items() if s.observer and s.Y is None):
        comp = make_compensation(planar3, _config(name, observer={"gain": 12.5}))
        w = compensation_bandwidth(comp, planar3.mass_matrix(np.zeros(planar3.nq)))
        np.testing.assert_array_equal(w, np.full(planar3.nq, 12.5))


@pytest.mark.parametrize(
    "call",
    [
        lambda: compensation_spec("ndo"),
        lambda: ControllerConfig(compensation="ndo"),
        lambda: parse_combination("hmpc+ndo"),
        lambda: build_compensation("ndo", None, 0.01),
    ],
)
def test_an_unknown_name_is_one_error_listing_the_registry(call):
    with pytest.raises(ConfigError) as info:
        call()
    text = str(info.value)
    assert "'ndo'" in text and str(NAMES) in text
    assert text.count("unknown compensation") == 1


def test_an_unknown_name_in_a_file_names_the_key_and_the_registry(write_config):
    from hmpc_pin.experiment.config.experiment import load_config

    path = write_config('[robot]\nurdf = "@URDF@"\n[controller]\ncompensation = "ndo"\n')
    with pytest.raises(ConfigError, match=r"controller\.compensation") as info:
        load_config(path)
    assert str(NAMES) in str(info.value)


def test_a_table_missing_for_its_entry_is_named(planar3):
    with pytest.raises(ConfigError, match=r"controller.observer.*\[controller.observer\]"):
        build_compensation("general", planar3, 0.01)


def test_the_names_everywhere_are_the_registrys():
    from benchmarks._fixtures import observer_kinds
    from hmpc_pin.compensation.observers import OBSERVER_KINDS
    from hmpc_pin.experiment import combos
    from hmpc_pin.experiment.config.controller import COMPENSATIONS, NATIVE_COMPENSATIONS

    observers = tuple(name for name, spec in REGISTRY.items() if spec.table == "observer")
    assert COMPENSATIONS == NAMES == compensation_names()
    assert tuple(n for n, s in REGISTRY.items() if s.compiled) == NATIVE_COMPENSATIONS
    assert combos.OBSERVERS == observers == OBSERVER_KINDS == observer_kinds()
    assert combos.ISM == compensation_names(table="ism") == ("ism", "ism-bl")
    assert compensation_names(table=None) == ("none",)


def test_an_entry_added_to_the_registry_is_read_by_the_config_and_the_builder(planar3, monkeypatch):
    """The config and the builder decode a name through the registry alone: an entry
    registered at run time loads, builds and runs in a controller."""
    from hmpc_pin.compensation.base import NoCompensation

    spec = replace(REGISTRY["none"], name="zero", summary="a second zero estimate")
    monkeypatch.setitem(REGISTRY, "zero", spec)
    cc = ControllerConfig(compensation="zero")
    assert (cc.observer, cc.ism, cc.label) == (None, None, "hmpc+zero")
    ctrl = make_controller(planar3, cc)
    assert isinstance(ctrl.compensation, NoCompensation)
    assert parse_combination("computed-torque+zero") == ("computed-torque", "zero")


def test_identify_reads_the_registrys_Y(planar3):
    """identify's observer model of Chen's NDO: L = c Y M⁻¹ with the registry's Y, the
    matrix the built observer runs with."""
    from hmpc_pin.identification import ObserverModel

    obs = make_compensation(planar3, _config("chen", observer={"gain": 50.0}))
    record = {"kind": "chen", "Ts": 0.01, "gain": 50.0}
    model = ObserverModel.from_record(record, planar3, planar3.nq)
    q = np.zeros((3, planar3.nq))
    phi = np.ones((3, planar3.nq, 1))
    oracle = ObserverModel("general", 1.0, 0.01, planar3, True, np.array(obs.cY))
    np.testing.assert_array_equal(model.filter(q, phi), oracle.filter(q, phi))
    assert isinstance(REGISTRY["chen"], CompensationSpec)
