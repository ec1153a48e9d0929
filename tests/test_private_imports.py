"""No module of the package imports another module's private name (``from .x import _y``):
a name shared between modules is public in the module it belongs to (structural, by AST)."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "hmpc_pin"


def kept(file: str, module: str) -> bool:
    """The imports kept: ``experiment/config/_fields.py`` is the config subpackage's own
    private module of field readers, shared by that subpackage's files alone by design."""
    return file.startswith("experiment/config/") and module == "_fields"


def private_imports(package: Path = PACKAGE) -> list[tuple[str, str, str]]:
    """(file relative to the package, module, name) of every import of a private name from
    another of the package's modules."""
    out = []
    for path in sorted(package.rglob("*.py")):
        rel = path.relative_to(package).as_posix()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not isinstance(node, ast.ImportFrom) or not node.module:
                continue
            ours = node.level > 0 or node.module.split(".")[0] == "hmpc_pin"
            for alias in node.names if ours else ():
                if alias.name.startswith("_") and not alias.name.startswith("__"):
                    out.append((rel, node.module.rsplit(".", 1)[-1], alias.name))
    return out


def test_no_module_imports_another_modules_private_name():
    found = [x for x in private_imports() if not kept(x[0], x[1])]
    assert found == [], found


def test_the_scan_sees_a_private_import(tmp_path):
    """The scan itself can fail: relative and absolute imports, one name of several (a
    private module of the package, ``from . import _startup``, is the package's own)."""
    (tmp_path / "sub").mkdir()
    (tmp_path / "a.py").write_text("from .b import _x\nfrom . import _startup\n")
    (tmp_path / "sub" / "c.py").write_text("from ..b import (\n    y,\n    _z,\n)\n")
    (tmp_path / "d.py").write_text("from hmpc_pin.b import _w, __version__\nimport os\n")
    assert private_imports(tmp_path) == [
        ("a.py", "b", "_x"),
        ("d.py", "b", "_w"),
        ("sub/c.py", "b", "_z"),
    ]
