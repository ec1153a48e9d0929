"""The documentation: every Python example runs, the configuration reference lists every
key the loader accepts, and no page points outside the repository.

The strict build itself (``make docs``: warnings are errors, every cross-reference
resolved) runs in ``.ci/run`` after the tests.
"""

from __future__ import annotations

import dataclasses
import importlib
import re
import runpy
import sys
import tomllib
from pathlib import Path

import pytest

from hmpc_pin.exceptions import ConfigError, URDFError
from hmpc_pin.experiment.config import ExperimentConfig, load_config

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PAGES = sorted(
    [ROOT / "README.md"]
    + [p for p in DOCS.rglob("*.md") if "_build" not in p.parts and "_static" not in p.parts]
)
FENCE = re.compile(r"^```python[^\n]*\n(.*?)^```", re.S | re.M)


def python_blocks() -> list[tuple[str, str]]:
    out = []
    for page in PAGES:
        for i, m in enumerate(FENCE.finditer(page.read_text(encoding="utf-8"))):
            out.append((f"{page.relative_to(ROOT)}#{i + 1}", m.group(1)))
    return out


BLOCKS = python_blocks()


def test_the_docs_have_python_examples():
    pages = {name.split("#")[0] for name, _ in BLOCKS}
    assert "README.md" in pages
    assert len(BLOCKS) >= 15, BLOCKS


@pytest.mark.parametrize(("name", "code"), BLOCKS, ids=[n for n, _ in BLOCKS])
def test_python_example_runs(name, code, tmp_path, monkeypatch):
    """Each block runs as written, in a fresh namespace, from an empty folder (where it may
    write files); packaged configs and robots are found by name."""
    monkeypatch.chdir(tmp_path)
    script = tmp_path / "example.py"
    script.write_text(code, encoding="utf-8")
    monkeypatch.setattr(sys, "argv", [str(script)])
    import matplotlib

    matplotlib.use("Agg")
    runpy.run_path(str(script), run_name="__main__")


# -- the configuration reference ----------------------------------------------------------


def _ext():
    sys.path.insert(0, str(DOCS / "_ext"))
    try:
        return importlib.import_module("hmpc_docs")
    finally:
        sys.path.remove(str(DOCS / "_ext"))


def accepted_keys() -> set[str]:
    """Every dotted key the loader accepts, found by asking it: a key is accepted when a
    file holding only that key is not refused as an unknown key."""
    import typing

    keys = set()

    def walk(cls, prefix):
        module = sys.modules[cls.__module__]
        hints = typing.get_type_hints(cls, vars(module))
        for f in dataclasses.fields(cls):
            if f.name == "source":
                continue
            sub = next(
                (a for a in (*typing.get_args(hints[f.name]), hints[f.name])
                 if dataclasses.is_dataclass(a)),
                None,
            )  # fmt: skip
            dotted = f"{prefix}.{f.name}" if prefix else f.name
            if sub is not None:
                walk(sub, dotted)
            else:
                keys.add(dotted)

    walk(ExperimentConfig, "")
    return keys


def _refused_as_unknown(dotted: str, tmp_path: Path) -> bool:
    *tables, key = dotted.split(".")
    text = (f"[{'.'.join(tables)}]\n" if tables else "") + f"{key} = 12345\n"
    path = tmp_path / "probe.toml"
    path.write_text(text, encoding="utf-8")
    try:
        load_config(path)
    except ConfigError as exc:
        return "unknown key" in str(exc)
    return False


def test_the_loader_accepts_the_keys_the_schema_walk_finds_and_no_other(tmp_path):
    """The oracle of the reference test is the loader itself: each key found by walking
    the dataclasses is not an unknown key, and a key that is not there is."""
    keys = accepted_keys()
    assert len(keys) > 100
    for dotted in sorted(keys):
        assert not _refused_as_unknown(dotted, tmp_path), dotted
    for dotted in ("controller.horizon", "plant.mujoco.stepsize", "colour"):
        assert _refused_as_unknown(dotted, tmp_path), dotted


def test_configuration_reference_lists_every_key_with_type_default_and_meaning():
    ext = _ext()
    rows = {r.dotted: r for r in ext.config_rows()}
    missing = accepted_keys() - set(rows)
    assert not missing, f"keys the loader accepts but the reference does not list: {missing}"
    assert set(rows) <= accepted_keys()
    for dotted, row in rows.items():
        assert row.type and row.default and row.text.strip(), dotted
    text = ext.config_reference_rst()
    for dotted, row in rows.items():
        assert f"``{row.key}``" in text, dotted
    # the sections of the generated page: one per table
    for table in {r.table for r in rows.values() if r.table}:
        assert f"[{table}]" in text, table


def test_configuration_reference_units_defaults_and_pairs_match_the_schema():
    """A few entries against values written here by hand from the paper and combos.py."""
    rows = {r.dotted: r for r in _ext().config_rows()}
    assert rows["controller.Ts"].unit == "s" and rows["controller.Ts"].default == "0.01"
    assert rows["controller.N"].default == "10"
    assert rows["robot.gravity"].unit == "m/s²"
    assert rows["controller.observer.gain"].applies == "any controller × chen, general, momentum"
    assert rows["controller.qp_layout"].applies == "hmpc × any"
    assert rows["controller.ism.gain"].applies == "any controller × ism, ism-bl"
    assert rows["controller.computed_torque.kp"].applies == (
        "computed-torque × any; computed-torque-pid × any"
    )
    assert rows["controller.Q"].default == "[[50.0, 0.0], [0.0, 0.0]]"


def test_a_key_without_documentation_fails_the_reference():
    ext = _ext()

    @dataclasses.dataclass(frozen=True)
    class Table:
        """A table.

        Attributes:
            documented: A documented key [s].
        """

        documented: float = 1.0
        undocumented: float = 2.0

    with pytest.raises(ValueError, match="undocumented"):
        ext.config_rows(Table, "demo")


def test_every_packaged_config_uses_only_documented_keys():
    rows = {r.dotted for r in _ext().config_rows()}
    free = ("robot.locked_joints.",)  # a table of joint names

    def keys(table, prefix=""):
        for k, v in table.items():
            dotted = f"{prefix}.{k}" if prefix else k
            if isinstance(v, dict) and dotted not in rows:
                yield from keys(v, dotted)
            else:
                yield dotted

    for path in sorted((ROOT / "hmpc_pin" / "data" / "configs").glob("*.toml")):
        for dotted in keys(tomllib.loads(path.read_text(encoding="utf-8"))):
            assert dotted in rows or dotted.startswith(free), (path.name, dotted)


# -- what the pages say -------------------------------------------------------------------


def test_readme_is_a_front_page():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 250
    assert "make demo" in text and "make test" in text
    # the links are absolute (the README is the wheel's long description): an image is a
    # file of the repository (test_packaged maps every link back to a page or file)
    source = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"][
        "urls"
    ]["Source"]
    for image in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text):
        assert image.startswith(f"{source}/raw/main/"), image
        assert (ROOT / image.removeprefix(f"{source}/raw/main/")).is_file(), image
    for link in re.findall(r"\]\(([^)#]+\.md)\)", text):
        assert (ROOT / link.removeprefix(f"{source}/blob/main/")).is_file(), link


def test_no_page_points_outside_the_repository():
    for page in [*PAGES, ROOT / "BENCHMARKS.md"]:
        text = page.read_text(encoding="utf-8")
        assert "../shared" not in text and "/work/" not in text, page
        assert not re.search(r"\bissue \d+", text, re.I), page


def test_equation_map_names_modules_that_exist():
    text = (DOCS / "concepts" / "scheme.md").read_text(encoding="utf-8")
    targets = re.findall(r"\{(?:class|func|mod)\}`~?([\w.]+)`", text)
    assert len(targets) >= 10
    for target in targets:
        module, _, name = target.rpartition(".")
        try:
            importlib.import_module(target)
            continue
        except ImportError:
            pass
        assert hasattr(importlib.import_module(module), name), target
    for path in re.findall(r"`((?:cpp|bindings)/[\w./]+)`", text):
        assert (ROOT / path).is_file(), path


def test_unknown_robot_error_names_a_function_that_exists():
    from hmpc_pin.model.robot import load_robot

    with pytest.raises(URDFError) as info:
        load_robot("not_a_robot_anywhere")
    named = re.findall(r"(hmpc_pin(?:\.\w+)+)\(\)", str(info.value))
    assert named, str(info.value)
    for dotted in named:
        module, _, name = dotted.rpartition(".")
        names = getattr(importlib.import_module(module), name)()
        assert "panda" in names and "ur5" in names


def test_guide_index_collects_the_guide_pages():
    index = (DOCS / "guide" / "index.md").read_text(encoding="utf-8")
    assert ":glob:" in index
    assert [p for p in (DOCS / "guide").glob("*.md") if p.name != "index.md"]


def test_files_the_pages_name_exist():
    """A script, config or source file named in the pages is in the repository."""
    path = re.compile(
        r"(?<![\w/])((?:benchmarks|examples|tests|cpp|bindings|hmpc_pin|configs)/[\w/.-]+\.(?:py|toml|cpp|hpp|csv|urdf))"
    )
    named = set()
    for page in [*PAGES, ROOT / "BENCHMARKS.md"]:
        named |= set(path.findall(page.read_text(encoding="utf-8")))
    assert len(named) > 20
    missing = sorted(p for p in named if not (ROOT / p).exists())
    assert not missing, missing


# ------------------------------------------------------------ docs that work from a wheel
SHELL_FENCE = re.compile(r"^```(?:bash|console|sh)[^\n]*\n(.*?)^```", re.S | re.M)
INLINE = re.compile(r"`([^`\n]+)`")


def _commands(page: Path) -> list[str]:
    """Every command a page gives: the lines of its shell blocks and its inline code spans
    that start with ``hmpc-pin`` or ``python``."""
    text = page.read_text(encoding="utf-8")
    lines = [ln for m in SHELL_FENCE.finditer(text) for ln in m.group(1).splitlines()]
    spans = [s for s in INLINE.findall(text.replace("\n", " "))]
    return [c.strip() for c in lines + spans if c.strip().startswith(("hmpc-pin", "python "))]


PAGE_PARAMS = [pytest.param(p, id=str(p.relative_to(ROOT))) for p in PAGES]


@pytest.mark.parametrize("page", PAGE_PARAMS)
def test_commands_use_packaged_names_or_say_they_need_a_clone(page):
    """A wheel has no configs/, examples/ or benchmarks/ folder: a command names a packaged
    config by name, and a script of the repository is run where the page says it needs a
    clone."""
    bad = []
    text = page.read_text(encoding="utf-8")
    for cmd in _commands(page):
        if re.search(r"(^|\s)configs/", cmd):
            bad.append(f"{page.relative_to(ROOT)}: {cmd}")
        elif re.search(r"(examples|benchmarks)[/.]", cmd) and "clone" not in text:
            bad.append(f"{page.relative_to(ROOT)} (no word of a clone): {cmd}")
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("page", PAGE_PARAMS)
def test_no_page_installs_an_extra_from_an_index(page):
    """No bare `pip install "hmpc_pin[extra]"`: the package is on no index."""
    text = page.read_text(encoding="utf-8")
    assert not re.search(r"pip install [\"']hmpc_pin\[\w+\][\"']", text)


def test_install_hints_work_for_the_installation_they_run_from():
    """A missing extra's message gives the command of this installation, here an
    editable clone (the wheel's form is checked in test_wheel)."""
    from hmpc_pin.exceptions import ExtraError, install_command

    assert install_command("ros") == f'pip install -e "{ROOT}[ros]"'
    assert install_command("ros") in str(ExtraError("ros", "hmpc-pin ros"))


def test_the_reproduction_report_is_this_versions():
    """The report the reproduction page includes was written by the package it documents."""
    import hmpc_pin

    head = (DOCS / "_static" / "reproduce" / "report.md").read_text(encoding="utf-8")
    assert f"(hmpc_pin {hmpc_pin.__version__}," in head.splitlines()[2]


def test_make_demo_installs_only_what_the_demo_needs():
    """The demo runs examples/track_sine.py: the package and its dependencies, no extra
    (the dev extra alone pulls about 240 MB of ROS 2)."""
    make = (ROOT / "Makefile").read_text(encoding="utf-8")
    rule = re.search(r"^\$\(VENV\)/\.demo:.*?(?=^\S)", make, re.S | re.M).group(0)
    assert "pip install -e ." in rule and "[" not in rule.split("pip install", 1)[1]
    assert re.search(r"^demo: \$\(VENV\)/\.demo$", make, re.M)
    imports = re.findall(r"^(?:from|import) (\w+)", (ROOT / "examples" / "track_sine.py")
                         .read_text(encoding="utf-8"), re.M)  # fmt: skip
    core = {"argparse", "sys", "time", "pathlib", "__future__", "hmpc_pin"}
    assert set(imports) <= core, set(imports) - core


OWN_ARM_ROW = re.compile(r"^\| (\w+) \| (\d+) \((\d+)\)[^|]* \| ([^|]+) \| (\d+) \|", re.M)
OBSERVER_CELL = re.compile(
    r"(chen|general|momentum) \((?:ω ([\d.]+)(?:–([\d.]+))? 1/s|c ([\d.]+))"
    r"(?:, latency ([\d.]+) ms)?\)"
)
OWN_ARM_QUICK = ("ur5", "double_pendulum", "so101")


def _own_arm_rows() -> dict[str, tuple]:
    text = (DOCS / "tutorials" / "own-arm.md").read_text(encoding="utf-8")
    return {m.group(1): m.groups()[1:] for m in OWN_ARM_ROW.finditer(text)}


@pytest.mark.parametrize(
    "model",
    [
        pytest.param(m, marks=() if m in OWN_ARM_QUICK else pytest.mark.slow)
        for m in sorted(_own_arm_rows())
    ],
)
def test_the_own_arm_table_is_what_init_writes_today(model, tmp_path):
    """The tutorial's table (joints, observer, period) against `hmpc-pin init` now."""
    import numpy as np

    from hmpc_pin.experiment.build import load_robot_config
    from hmpc_pin.experiment.init import init_config

    joints, locked, observer, ts_ms = _own_arm_rows()[model]
    path = tmp_path / f"{model}.toml"
    path.write_text(init_config(model), encoding="utf-8")
    config = load_config(path)
    cc = config.controller
    robot = load_robot_config(config.robot)
    assert (robot.nq, len(robot.locked_joints)) == (int(joints), int(locked))
    assert cc.Ts == pytest.approx(float(ts_ms) / 1e3)
    m = OBSERVER_CELL.fullmatch(observer.strip())
    assert m, observer
    kind, w_lo, w_hi, gain, latency = m.groups()
    assert cc.compensation == kind
    if w_lo is not None:
        w = np.atleast_1d(cc.observer.bandwidth)
        assert (w.min(), w.max()) == pytest.approx((float(w_lo), float(w_hi or w_lo)))
    else:
        assert cc.observer.gain == pytest.approx(float(gain))
    assert (cc.latency or 0.0) == pytest.approx(float(latency or 0) / 1e3)


def test_the_own_arm_table_lists_every_model_init_offers():
    from hmpc_pin.model.catalogue import example_robot_names

    rows = _own_arm_rows()
    text = (DOCS / "tutorials" / "own-arm.md").read_text(encoding="utf-8")
    listed = set(rows) | set(re.findall(r"^\| (\w+) \| \|", text, re.M))
    assert set(example_robot_names()) <= listed, set(example_robot_names()) - listed
