"""The deprecated module ``hmpc_pin.experiment.schema`` (the configuration's path in 0.2):
it still gives every name it gave, the very objects of :mod:`hmpc_pin.experiment.config`,
with a DeprecationWarning naming the replacement. The only file of the repository that
imports it (``tests/test_architecture.py`` checks the others)."""

from __future__ import annotations

import importlib
import sys

import pytest

from hmpc_pin.experiment import combos, config

from .conftest import CONFIGS

SHIM = "hmpc_pin.experiment.schema"


@pytest.fixture
def fresh_shim(monkeypatch):
    """Import the shim as a user's first import does (not the cached module)."""
    monkeypatch.delitem(sys.modules, SHIM, raising=False)

    def _import():
        return importlib.import_module("hmpc_pin.experiment.schema")

    return _import


def test_the_shim_warns_and_gives_the_configs_own_objects(fresh_shim):
    with pytest.warns(DeprecationWarning, match=r"hmpc_pin\.experiment\.config"):
        schema = fresh_shim()
    assert set(schema.__all__) == {*config.__all__, "OBSERVERS"}
    for name in config.__all__:
        assert getattr(schema, name) is getattr(config, name), name
    assert schema.OBSERVERS == combos.OBSERVERS == ("chen", "general", "momentum")
    loaded = schema.load_config(CONFIGS / "paper_combined.toml")
    assert isinstance(loaded, config.ExperimentConfig)
    assert loaded.controller.label == "hmpc+chen"


def test_from_the_shim_import_star_gives_every_name(fresh_shim):
    namespace: dict = {}
    with pytest.warns(DeprecationWarning, match="deprecated since 0.3"):
        exec(f"from {SHIM} import *", namespace)
    assert {*config.__all__, "OBSERVERS"} <= set(namespace)
