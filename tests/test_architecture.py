"""The package's layers (``hmpc_pin/__init__.py`` draws them): each module imports only
its own subpackage and the layers below; no import cycle; the data ships in the wheel."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parent.parent / "hmpc_pin"

#: Rank of each layer; a module may import its own subpackage and lower ranks only.
RANK = {
    "data": 0,
    "exceptions": 0,
    "_version": 0,
    "_deprecated": 0,
    "_startup": 0,
    "checks": 0.5,  # imports exceptions only
    "model": 1,
    "native": 1,
    "compensation": 2,
    "mpc": 2,
    "tasks": 2,
    "controllers": 3,
    "sim": 4,
    "realtime": 5,
    "identification": 5,
    "experiment": 6,
    "ros": 6.5,
    "apps": 7,
    "__init__": 8,
    "__main__": 9,
}


def _modules() -> dict[str, Path]:
    out = {}
    for path in PKG.rglob("*.py"):
        if path.parent == PKG / "examples":  # scripts shipped to be copied, not modules
            continue
        rel = path.relative_to(PKG.parent).with_suffix("")
        parts = list(rel.parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _imports(name: str, path: Path, top_only: bool = False) -> set[str]:
    """Every ``hmpc_pin`` module ``name`` imports (function-level imports included unless
    ``top_only``)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    if top_only:
        tree = ast.Module(
            body=[n for n in tree.body if not isinstance(n, (ast.FunctionDef, ast.ClassDef))],
            type_ignores=[],
        )
    is_pkg = path.name == "__init__.py"
    base = name.split(".") if is_pkg else name.split(".")[:-1]
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                anchor = base[: len(base) - node.level + 1]
                target = ".".join([*anchor, *(node.module.split(".") if node.module else [])])
            else:
                target = node.module or ""
            if target.startswith("hmpc_pin"):
                found.add(target)
                for alias in node.names:  # "from . import plots" imports a module
                    found.add(f"{target}.{alias.name}")
        elif isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.startswith("hmpc_pin"))
    mods = _modules()
    return {t for t in found if t in mods and t != name}


def _layer(module: str) -> str:
    parts = module.split(".")
    return "__init__" if len(parts) == 1 else parts[1]


GRAPH = {name: _imports(name, path) for name, path in _modules().items()}


def test_every_subpackage_has_a_rank():
    assert {_layer(m) for m in GRAPH} <= set(RANK)


@pytest.mark.parametrize("module", sorted(GRAPH))
def test_module_imports_only_its_layer_and_below(module):
    own = _layer(module)
    for target in GRAPH[module]:
        other = _layer(target)
        if other == own or target == "hmpc_pin":
            # the package root only through its own __init__ (e.g. _startup in apps)
            if target == "hmpc_pin":
                assert RANK[own] >= RANK["apps"], f"{module} imports the package root"
            continue
        assert RANK[other] < RANK[own], f"{module} ({own}) imports {target} ({other}): upward"


def test_no_import_cycle_between_modules():
    # Every import, function-level ones included: a function-level import does not fail
    # at import time, but it is still a dependency cycle.
    top = GRAPH
    state: dict[str, int] = {}

    def visit(node, stack):
        state[node] = 1
        for nxt in top[node]:
            if nxt.startswith(node + "."):
                continue  # a package's __init__ imports its own modules
            if state.get(nxt) == 1:
                pytest.fail("import cycle: " + " -> ".join([*stack, node, nxt]))
            if state.get(nxt) is None:
                visit(nxt, [*stack, node])
        state[node] = 2

    for name in sorted(top):
        if name not in state:
            visit(name, [])


def test_the_config_imports_nothing_of_the_builder():
    # The configuration validates; the builder (hmpc_pin.experiment's other modules) turns
    # a validated config into objects: the config may import its own package, the table of
    # which keys apply to which pair (combos) and the layers below the experiment only.
    allowed = ("hmpc_pin.experiment.config", "hmpc_pin.experiment.combos")
    for module in (m for m in GRAPH if m.startswith("hmpc_pin.experiment.config")):
        for target in GRAPH[module]:
            if _layer(target) == "experiment":
                assert target.startswith(allowed), f"{module} imports the builder's {target}"


#: The deprecated module of 0.2 (``hmpc_pin.experiment.schema``), and the one file that
#: imports it on purpose: the shim's own test.
SHIM = "hmpc_pin.experiment.schema"
SHIM_USERS = {"hmpc_pin/experiment/schema.py", "tests/test_schema_shim.py"}


def _imports_the_shim(path: Path) -> bool:
    """Whether ``path`` imports :data:`SHIM` (absolute, relative, or a string handed to
    importlib or to a subprocess)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    named: list[str] = []  # what each import (or string) names, relative ones resolved
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            module = node.module or ""
            if node.level:  # from .schema / from ..experiment.schema / from . import schema
                anchor = ".".join(
                    path.relative_to(PKG.parent).parent.parts[: 1 - node.level]
                    if node.level > 1
                    else path.relative_to(PKG.parent).parent.parts
                )
                base = f"{anchor}.{module}" if module else anchor
                named += [base, *(f"{base}.{a.name}" for a in node.names)]
            else:
                named += [module, *(f"{module}.{a.name}" for a in node.names)]
        elif isinstance(node, ast.Import):
            named += [a.name for a in node.names]
        elif isinstance(node, ast.Call) and getattr(node.func, "attr", None) == "import_module":
            named += [c.value for c in ast.walk(node) if isinstance(c, ast.Constant)]
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):  # code to run
            named += re.findall(r"(?:from|import)\s+([\w.]+)", node.value)
    return any(name == SHIM or name.endswith(".experiment.schema") for name in named)


def test_nothing_in_the_repository_imports_the_schema_shim():
    root = PKG.parent
    files = [p for d in ("hmpc_pin", "tests", "benchmarks", "examples", "docs")
             for p in (root / d).rglob("*.py")]  # fmt: skip
    users = {p.relative_to(root).as_posix() for p in files if _imports_the_shim(p)}
    assert users == SHIM_USERS
    pages = [p for p in (root / "docs").rglob("*.md") if "import" in p.read_text("utf-8")]
    for page in [*pages, root / "README.md"]:
        text = page.read_text(encoding="utf-8")
        assert f"from {SHIM} import" not in text and f"import {SHIM}" not in text, page


def test_every_command_is_one_module_with_the_same_two_entry_points():
    """``hmpc-pin``'s table registers one module of ``hmpc_pin.apps.commands`` per command,
    each exporting ``add_arguments(parser)`` and ``main(args)``, and no other module."""
    import importlib
    import inspect

    from hmpc_pin.apps.cli import COMMANDS

    folder = PKG / "apps" / "commands"
    modules = {p.stem for p in folder.glob("*.py")} - {"__init__"}
    assert sorted(m for _, m in COMMANDS.values()) == sorted(modules)
    for name in modules:
        module = importlib.import_module(f"hmpc_pin.apps.commands.{name}")
        assert module.__all__ == ["add_arguments", "main"], name
        for entry in (module.add_arguments, module.main):
            assert list(inspect.signature(entry).parameters)[1:] == [], (name, entry)


def test_report_does_not_import_the_command_line():
    assert "hmpc_pin.apps.cli" not in GRAPH["hmpc_pin.apps.report"]


def test_every_exception_is_defined_in_exceptions_py():
    for name, path in _modules().items():
        if name == "hmpc_pin.exceptions":
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, ast.ClassDef):
                bases = {getattr(b, "id", getattr(b, "attr", "")) for b in node.bases}
                assert not bases & {"Exception", "HmpcError", "ValueError", "RuntimeError"}, (
                    f"{name} defines exception {node.name}"
                )
            if isinstance(node, ast.Raise) and isinstance(node.exc, ast.Call):
                fn = getattr(node.exc.func, "id", "")
                assert fn not in ("ValueError", "TypeError"), f"{name}: bare {fn}"


# ------------------------------------------------------------------ benchmarks/
BENCH = PKG.parent / "benchmarks"


def _bench_imports(path: Path) -> tuple[set[str], list[str], list[str]]:
    """The ``benchmarks`` modules ``path`` imports (dotted below ``benchmarks``, e.g.
    ``studies.long_run``), the private names it takes from ``hmpc_pin``, and the modules of
    ``tests`` it imports (function-level imports included)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    mods, private, tests = set(), [], []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module:
            if node.module == "benchmarks" or node.module.startswith("benchmarks."):
                below = node.module.removeprefix("benchmarks").lstrip(".")
                for alias in node.names:  # a module, or a name of the module `below`
                    name = f"{below}.{alias.name}".lstrip(".")
                    mods.add(name if (BENCH / f"{name.replace('.', '/')}.py").exists() else below)
            elif node.module.startswith("hmpc_pin"):
                private += [f"{node.module}.{a.name}" for a in node.names
                            if a.name.startswith("_")]  # fmt: skip
                private += [node.module] if any(p.startswith("_") for p in
                                                node.module.split(".")) else []  # fmt: skip
            elif node.module == "tests" or node.module.startswith("tests."):
                tests.append(node.module)
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("benchmarks."):
                    mods.add(alias.name.removeprefix("benchmarks."))
                if alias.name.startswith("hmpc_pin") and any(
                    p.startswith("_") for p in alias.name.split(".")
                ):
                    private.append(alias.name)
                if alias.name == "tests" or alias.name.startswith("tests."):
                    tests.append(alias.name)
        elif isinstance(node, ast.Call) and getattr(node.func, "attr", None) == "import_module":
            tests += [c.value for c in node.args if isinstance(c, ast.Constant)
                      and str(c.value).startswith("tests")]  # fmt: skip
    return mods - {""}, private, tests


def _bench_modules() -> dict[str, Path]:
    """Every program of ``benchmarks/`` by its dotted name below it: the suite
    (``run``, ``steps``, ...), ``studies.*`` and ``tools.*``."""
    return {
        p.relative_to(BENCH).with_suffix("").as_posix().replace("/", "."): p
        for p in BENCH.rglob("*.py")
        if p.stem != "__init__"
    }


def test_benchmarks_form_no_import_cycle_and_use_only_public_names():
    graph, private, tests = {}, {}, {}
    for name, path in _bench_modules().items():
        graph[name], found, from_tests = _bench_imports(path)
        if found:
            private[name] = found
        if from_tests:
            tests[name] = from_tests
    assert not private, f"benchmarks importing private hmpc_pin names: {private}"
    assert not tests, f"benchmarks importing tests/ (load an oracle by its path): {tests}"
    assert "_fixtures" in graph and not graph["_fixtures"], "the fixtures import no benchmark"
    unknown = {n: sorted(d - set(graph)) for n, d in graph.items() if d - set(graph)}
    assert not unknown, f"benchmarks importing no benchmark module: {unknown}"
    state: dict[str, int] = {}

    def visit(name: str, stack: list[str]) -> None:
        state[name] = 1
        for dep in graph[name]:
            assert state.get(dep) != 1, f"import cycle: {' -> '.join([*stack, name, dep])}"
            if dep not in state:
                visit(dep, [*stack, name])
        state[name] = 2

    for name in graph:
        if name not in state:
            visit(name, [])


def test_benchmarks_are_the_suite_the_studies_and_the_tools():
    """``benchmarks/``: the suite ``run.py`` drives and its harness (no study in its imports),
    ``studies/`` the programs the pages cite (each cited by one at least), ``tools/`` the
    developer tools (no page's figure comes from one)."""
    graph = {n: _bench_imports(p)[0] for n, p in _bench_modules().items()}
    suite, stack = set(), ["run"]
    while stack:
        name = stack.pop()
        if name not in suite:
            suite.add(name)
            stack += graph[name]
    top = {n for n in graph if "." not in n}
    assert not [n for n in suite if n.startswith("studies.")], suite
    assert top - suite <= {"memory"}, f"not run by the suite: {sorted(top - suite - {'memory'})}"
    root = PKG.parent
    pages = [*(root / "docs").rglob("*.md"), root / "README.md", root / "BENCHMARKS.md"]
    cited = "\n".join(p.read_text(encoding="utf-8") for p in pages)
    studies = [n.split(".", 1)[1] for n in graph if n.startswith("studies.")]
    uncited = [s for s in studies if f"benchmarks/studies/{s}.py" not in cited
               and f"benchmarks.studies.{s}" not in cited]  # fmt: skip
    assert studies and not uncited, f"studies no page cites: {uncited}"


# ------------------------------------------------------------------ test tiers
def test_every_end_to_end_file_of_the_tiers_exists():
    from tests.conftest import E2E_FILES

    tests = PKG.parent / "tests"
    assert E2E_FILES and all((tests / name).is_file() for name in E2E_FILES)


#: The sizes a maintainer can hold: a Python file and function, a C++ file, a C++ function;
#: ``ruff format`` owns the formatting (``# fmt: skip`` only where a table is clearer).
MAX_FILE_LINES, MAX_FUNCTION_LINES = 700, 120
MAX_CPP_LINES, MAX_CPP_FUNCTION_LINES, MAX_FMT_SKIPS = 500, 100, 50

#: Files being split in parallel on other branches, and what of them is over the limits
#: today: ``None`` for the file's length, else a function's name. A temporary allowance,
#: removed (the test tightened) when those branches merge; a file or function not listed
#: here is held to the limits.
_PENDING = {}


def _python_files() -> list[tuple[str, Path]]:
    return sorted((path.relative_to(PKG).as_posix(), path) for path in PKG.rglob("*.py"))


def test_no_python_file_is_longer_than_a_maintainer_can_hold():
    long = [(rel, n) for rel, path in _python_files()
            if (n := len(path.read_text(encoding="utf-8").splitlines())) > MAX_FILE_LINES
            and None not in _PENDING.get(rel, ())]  # fmt: skip
    assert not long, f"Python files over {MAX_FILE_LINES} lines: {long}"


def test_no_python_function_is_longer_than_a_maintainer_can_hold():
    long = []
    for rel, path in _python_files():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                lines = node.end_lineno - node.lineno + 1
                if lines > MAX_FUNCTION_LINES and node.name not in _PENDING.get(rel, ()):
                    long.append((rel, node.name, lines))
    assert not long, f"functions over {MAX_FUNCTION_LINES} lines: {long}"


def test_the_pending_allowance_names_only_what_is_over_the_limits():
    """Each allowance is needed today: a file listed is over the limit, a function listed
    is over its limit (so the allowance shrinks as the parallel splits land)."""
    for rel, allowed in _PENDING.items():
        path = PKG / rel
        assert path.is_file(), rel
        tree = ast.parse(path.read_text(encoding="utf-8"))
        sizes = {node.name: node.end_lineno - node.lineno + 1 for node in ast.walk(tree)
                 if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)}  # fmt: skip
        for name in allowed:
            if name is None:
                assert len(path.read_text(encoding="utf-8").splitlines()) > MAX_FILE_LINES, rel
            else:
                assert sizes.get(name, 0) > MAX_FUNCTION_LINES, f"{rel}: {name}"


def _cpp_files() -> list[Path]:
    root = PKG.parent
    files = [p for d in ("cpp", "bindings") for p in (root / d).rglob("*.[ch]pp")]
    assert files, "the C++ sources are where the build finds them"
    return sorted(files)


def test_no_cpp_file_is_longer_than_a_maintainer_can_hold():
    root = PKG.parent
    long = [(str(p.relative_to(root)), n) for p in _cpp_files()
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_CPP_LINES]  # fmt: skip
    assert not long, f"C++ files over {MAX_CPP_LINES} lines: {long}"


#: A C++ block's header is a function's when it ends with ``)`` and, after it, only
#: qualifiers, a trailing return type or a constructor's initialiser list (``) : a(x), b(y)``).
_CPP_FUNCTION_HEADER = re.compile(
    r"\)\s*(?:const|noexcept|override|final|mutable|\s)*(?:->\s*[\w:<>,&*\s]+)?$"
    r"|\)\s*:\s*[\w:]+\s*\(.*\)$",
    re.S,
)
_CPP_CONTROL = re.compile(r"^(?:if|for|while|switch|catch|do|else)\b")


def _cpp_blank(text: str) -> str:
    """The C++ source with its comments and string/char literals blanked (newlines kept)."""
    pattern = r'//[^\n]*|/\*.*?\*/|"(?:\\.|[^"\\\n])*"|\'(?:\\.|[^\'\\\n])*\''
    return re.sub(pattern, lambda m: re.sub(r"[^\n]", " ", m.group()), text, flags=re.S)


def cpp_function_lengths(text: str) -> list[tuple[str, int]]:
    """Each C++ function of ``text`` (a definition at namespace or class scope) with its length.

    The rule, by brace matching over the source with its comments and literals blanked: a
    ``{`` opens a function when it is not inside another function and its header (the text
    since the last ``;``, ``{`` or ``}``) ends like a function's signature
    (:data:`_CPP_FUNCTION_HEADER`) and does not begin with a control keyword. Its length is
    the number of lines from the header's first line to the matching ``}``, both included
    (the signature counts: a long parameter list is part of what a reader holds). Lambdas,
    loops and other blocks inside a function count toward it.

    Returns:
        (header's last 60 characters, lines) per function, in source order.
    """
    code = _cpp_blank(text)
    out: list[tuple[str, int]] = []
    stack: list[tuple[bool, int, str]] = []  # (is a function, first line, header)
    last = 0  # index just past the last ; { or }
    for k, ch in enumerate(code):
        if ch == ";":
            last = k + 1
        elif ch == "{":
            header = code[last:k].strip()
            inside = any(f for f, _, _ in stack)
            is_fn = (
                not inside
                and bool(_CPP_FUNCTION_HEADER.search(header))
                and not _CPP_CONTROL.match(header)
                and not header.startswith("#")
            )
            start = last + (len(code[last:k]) - len(code[last:k].lstrip()))
            stack.append((is_fn, code.count("\n", 0, start) + 1, header))
            last = k + 1
        elif ch == "}":
            if stack:
                is_fn, first, header = stack.pop()
                if is_fn:
                    end = code.count("\n", 0, k) + 1
                    out.append((" ".join(header.split())[-60:], end - first + 1))
            last = k + 1
    return out


def test_the_cpp_function_length_counter_follows_its_rule():
    text = (
        "namespace a {\n"  # a namespace: not a function
        "// f() { not code }\n"
        "int f(int x) const {\n  if (x) {\n    return 1;\n  }\n  return 0;\n}\n"
        "struct S {\n  S(int a) : a_(a) {}\n  int a_;\n};\n"
        "auto g() -> int {\n  auto l = [](int y) { return y; };\n  return l(1);\n}\n"
        "}  // namespace a\n"
    )
    assert cpp_function_lengths(text) == [
        ("int f(int x) const", 6),
        ("S(int a) : a_(a)", 1),
        ("auto g() -> int", 4),
    ]


def test_no_cpp_function_is_longer_than_a_maintainer_can_hold():
    root = PKG.parent
    long = [
        (str(p.relative_to(root)), name, n)
        for p in _cpp_files()
        for name, n in cpp_function_lengths(p.read_text(encoding="utf-8"))
        if n > MAX_CPP_FUNCTION_LINES
    ]
    assert not long, f"C++ functions over {MAX_CPP_FUNCTION_LINES} lines: {long}"


def test_ruff_format_owns_the_formatting_of_the_package():
    skips = sum(p.read_text(encoding="utf-8").count("# fmt: skip") for p in PKG.rglob("*.py"))
    assert skips <= MAX_FMT_SKIPS, f"{skips} '# fmt: skip' in the package"


#: The names each registry owns: a literal listing two or more of them elsewhere in the
#: package is a second home for the decision the registry states once.
REGISTRIES = {
    "hmpc_pin/controllers/registry.py": ("hmpc", "computed-torque", "computed-torque-pid"),
    "hmpc_pin/sim/engines.py": ("pinocchio", "mujoco"),
}


def _literal_names(node: ast.AST) -> set[str]:
    """The string constants of a tuple, list or set literal, or of a dict literal's keys."""
    items = node.keys if isinstance(node, ast.Dict) else getattr(node, "elts", [])
    return {n.value for n in items if isinstance(n, ast.Constant) and isinstance(n.value, str)}


@pytest.mark.parametrize("home", sorted(REGISTRIES))
def test_each_registry_is_the_only_place_listing_its_names(home):
    """The controller kinds and the plant engines are listed in their registry only; every
    other module reads them there (``controller_spec``, ``engine_spec``)."""
    names = set(REGISTRIES[home])
    found = []
    for path in sorted(PKG.rglob("*.py")):
        rel = path.relative_to(PKG.parent).as_posix()
        if rel == home:
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.Tuple, ast.List, ast.Set, ast.Dict)):
                listed = _literal_names(node) & names
                if len(listed) >= 2:
                    found.append(f"{rel}:{node.lineno} lists {sorted(listed)}")
    assert not found, "a second list of the registry's names:\n" + "\n".join(found)


def test_the_registry_check_finds_a_second_list():
    """The check above fails on a module that lists two kinds (it can fail)."""
    tree = ast.parse('KINDS = ("hmpc", "computed-torque")\nD = {"mujoco": 1, "pinocchio": 2}')
    literals = [n for n in ast.walk(tree) if isinstance(n, (ast.Tuple, ast.Dict))]
    assert [
        len(_literal_names(n) & {"hmpc", "computed-torque", "mujoco", "pinocchio"})
        for n in literals
    ] == [2, 2]


def test_one_dask_cluster_factory_and_one_ctrl_c_deferral():
    """A local Dask cluster is made in one place (``apps/cluster.py``, used by the sweep and
    the tuner), and Ctrl-C is kept back in one class (``_startup.DeferredInterrupt``)."""
    makers, deferrals = [], []
    for rel, path in _python_files():
        text = path.read_text(encoding="utf-8")
        if "LocalCluster(" in text:
            makers.append(rel)
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.ClassDef) and node.name.endswith("Interrupt"):
                deferrals.append(f"{rel}:{node.name}")
    assert makers == ["apps/cluster.py"]
    assert deferrals == ["_startup.py:DeferredInterrupt"]
