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
    assert ours == {"hmpc_pin", "hmpc_pin._startup", "hmpc_pin.exceptions", "hmpc_pin._version"}, (
        ours
    )
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
    heavy = ("numpy", "pinocchio", "proxsuite", "matplotlib", "scipy", "yourdfpy", "trimesh",
             "mujoco", "optuna", "dask", "rclpy", "meshcat")  # fmt: skip
    assert not [m for m in heavy if m in loaded], [m for m in heavy if m in loaded]
    commands = ("compare", "report", "viz", "check", "plots", "run", "metrics", "tune", "ros")
    assert not [c for c in commands if f"hmpc_pin.apps.{c}" in loaded]
    library = ("experiment", "model", "controllers", "sim", "mpc", "compensation")
    assert not [m for m in library if f"hmpc_pin.{m}" in loaded]


def test_a_command_builds_its_own_arguments_only():
    """``hmpc-pin replay --help`` builds the parser of ``replay`` alone: the library behind the
    other commands' help texts (the compensations' registry, the metrics) is not loaded."""
    loaded = _loaded(
        "import contextlib, io\n"
        "from hmpc_pin.apps.cli import main\n"
        "with contextlib.redirect_stdout(io.StringIO()), contextlib.suppress(SystemExit):\n"
        "    main(['replay', '--help'])"
    )
    assert "hmpc_pin.compensation.registry" not in loaded and "numpy" not in loaded


def test_the_parser_of_one_command_is_the_full_parsers_command():
    """Built alone or with all the others, a command's parser is the same: its help and the
    defaults it parses."""
    from hmpc_pin.apps.cli import COMMANDS, build_parser

    def command_parser(parser, name):
        sub = next(a for a in parser._actions if isinstance(a.choices, dict))
        return sub.choices[name]

    full = build_parser()
    for name in COMMANDS:
        alone = command_parser(build_parser((name,)), name)
        both = command_parser(full, name)
        assert alone.format_help() == both.format_help(), name
        assert [a.dest for a in alone._actions] == [a.dest for a in both._actions], name
        assert alone.get_default("func") is both.get_default("func") is not None, name


def test_the_version_loads_nothing_heavy():
    """``__version__`` is on the ground floor: reading it loads no NumPy, no Pinocchio."""
    loaded = _loaded("from hmpc_pin._version import __version__")
    assert not {"numpy", "pinocchio", "hmpc_pin.apps"} & loaded
    assert hmpc_pin.__version__ == __import__("hmpc_pin._version").__version__


def test_the_dead_names_of_earlier_versions_still_import_with_a_warning():
    """``why_not_compiled`` and ``LOOPS`` of ``hmpc_pin.sim.compiled_loop`` (nothing reads
    them since every part runs behind a port) import for a user's file, each warning."""
    import warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        from hmpc_pin.sim.compiled_loop import LOOPS, why_not_compiled

    assert why_not_compiled(None, None, None) is None and "python" in LOOPS
    assert [w.category for w in caught] == [DeprecationWarning] * 2
    import hmpc_pin.sim.compiled_loop as loop

    try:
        loop.no_such_name
    except AttributeError as exc:
        assert "no_such_name" in str(exc)
    else:
        raise AssertionError("an unknown name must be an AttributeError")
