"""Which modules ``import hmpc_pin`` loads (structural, in a fresh interpreter; no timing):
the library's names load on first use (PEP 562), never the applications or matplotlib."""

from __future__ import annotations

import json
import subprocess
import sys

import hmpc_pin


def _loaded(code: str) -> set[str]:
    """The modules in ``sys.modules`` after running ``code`` in a fresh interpreter."""
    out = subprocess.run(
        [sys.executable, "-c", f"{code}\nimport json, sys; print(json.dumps(sorted(sys.modules)))"],
        capture_output=True, text=True, check=True, timeout=300,
    )  # fmt: skip
    return set(json.loads(out.stdout.strip().splitlines()[-1]))


def test_import_loads_no_application_and_no_heavy_dependency():
    loaded = _loaded("import hmpc_pin")
    ours = {m for m in loaded if m.startswith("hmpc_pin")}
    assert ours == {"hmpc_pin", "hmpc_pin._startup", "hmpc_pin.exceptions"}, ours
    for heavy in ("numpy", "pinocchio", "proxsuite", "matplotlib", "scipy", "yourdfpy"):
        assert heavy not in loaded, f"import hmpc_pin loaded {heavy}"


def test_a_library_name_loads_the_library_not_the_applications():
    loaded = _loaded("from hmpc_pin import Experiment, HierarchicalMPC, simulate")
    apps = sorted(m for m in loaded if m.startswith("hmpc_pin.apps"))
    assert not apps, f"the library loaded the applications: {apps}"
    assert "matplotlib" not in loaded
    assert "hmpc_pin.experiment.build" in loaded and "pinocchio" in loaded


def test_every_public_name_is_an_attribute_and_importable():
    for name in hmpc_pin.__all__:
        value = getattr(hmpc_pin, name)
        assert value is not None, name
    namespace: dict = {}
    exec(f"from hmpc_pin import {', '.join(hmpc_pin.__all__)}", namespace)
    assert set(hmpc_pin.__all__) <= set(namespace)
    assert set(hmpc_pin.__all__) <= set(dir(hmpc_pin))


def test_the_lazy_names_are_the_defining_modules_objects():
    from hmpc_pin.experiment.build import Experiment
    from hmpc_pin.sim import simulate

    assert hmpc_pin.Experiment is Experiment and hmpc_pin.simulate is simulate


def test_subpackages_are_attributes_and_unknown_names_an_attribute_error():
    import pytest

    assert hmpc_pin.sim.__name__ == "hmpc_pin.sim"
    with pytest.raises(AttributeError, match="no attribute 'no_such_name'"):
        _ = hmpc_pin.no_such_name


def test_help_loads_no_figure_engine_no_optional_extra_and_no_other_command():
    loaded = _loaded(
        "import contextlib, io\n"
        "from hmpc_pin.apps.cli import main\n"
        "with contextlib.redirect_stdout(io.StringIO()), contextlib.suppress(SystemExit):\n"
        "    main(['--help'])"
    )
    heavy = ("matplotlib", "scipy", "yourdfpy", "trimesh", "mujoco", "optuna", "dask",
             "rclpy", "meshcat")  # fmt: skip
    assert not [m for m in heavy if m in loaded], [m for m in heavy if m in loaded]
    commands = ("compare", "report", "viz", "check", "plots")
    assert not [c for c in commands if f"hmpc_pin.apps.{c}" in loaded]
