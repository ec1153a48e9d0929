"""Sphinx extension of the hmpc_pin docs.

- ``config-reference`` directive: the configuration reference, generated at build time
  from the schema (the dataclasses of :mod:`hmpc_pin.experiment.config`, their Google
  docstrings' ``Attributes:`` and :mod:`hmpc_pin.experiment.combos`). A key without a
  docstring entry stops the build (:func:`config_rows` raises), so a new key cannot go
  undocumented.
- ``missing-reference`` hook: a short name in a docstring (``:class:`ConfigError```) is
  resolved the way Python resolves it, through the imports of the module the docstring is
  in, to the object's documented location. Names that Python cannot resolve stay
  unresolved (and fail the strict build).
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import re
import typing
from dataclasses import MISSING, dataclass

import numpy as np

TOP = "hmpc_pin.experiment.config.experiment.ExperimentConfig"

# TOML types as a user writes them, from the fields' annotations.
_TYPES = {
    "float": "number",
    "int": "integer",
    "bool": "boolean",
    "str": "string",
    "Path": "path (string)",
    "np.ndarray": "number or list",
    "list": "list of lists",
    "dict": "table name = number",
}
_UNIT = re.compile(r"\[([^\[\],]*[A-Za-z°%][^\[\],]*)\]")


@dataclass(frozen=True)
class Row:
    """One key of the configuration reference."""

    table: str  #: the TOML table, e.g. ``controller.observer``
    key: str  #: the key inside it
    type: str  #: the TOML type
    unit: str  #: unit from the docstring's ``[...]``, or ``""``
    default: str  #: the default as TOML, or ``"unset"``
    applies: str  #: controller × compensation pairs it applies to
    text: str  #: the docstring's description

    @property
    def dotted(self) -> str:
        return f"{self.table}.{self.key}" if self.table else self.key


def _cls(path: str):
    module, _, name = path.rpartition(".")
    return getattr(importlib.import_module(module), name)


def attribute_docs(cls) -> dict[str, str]:
    """The ``Attributes:`` section of a Google docstring: name → description
    (``lower, upper: ...`` documents both names)."""
    doc = inspect.getdoc(cls) or ""
    lines = doc.splitlines()
    out: dict[str, str] = {}
    try:
        start = next(i for i, ln in enumerate(lines) if ln.strip() == "Attributes:")
    except StopIteration:
        return out
    base = len(lines[start]) - len(lines[start].lstrip())
    names: list[str] = []
    for ln in lines[start + 1 :]:
        if not ln.strip():
            continue
        indent = len(ln) - len(ln.lstrip())
        if indent <= base:
            break
        m = re.match(r"^\s*([A-Za-z_][\w, ]*?)\s*(?:\(.*?\))?:\s*(.*)$", ln)
        if indent == base + 4 and m:
            names = [n.strip() for n in m.group(1).split(",")]
            for n in names:
                out[n] = m.group(2).strip()
        elif names:
            for n in names:
                out[n] += " " + ln.strip()
    return out


def _annotation(cls, name: str) -> str:
    ann = cls.__annotations__.get(name, "")
    return ann if isinstance(ann, str) else getattr(ann, "__name__", str(ann))


def _subtable(cls, name: str):
    """The config dataclass a field holds (a sub-table), or ``None``."""
    hints = typing.get_type_hints(cls, globalns=vars(importlib.import_module(cls.__module__)))
    hint = hints.get(name)
    for arg in (*typing.get_args(hint), hint):
        if dataclasses.is_dataclass(arg):
            return arg
    return None


def _toml(value) -> str:
    if value is None:
        return "unset"
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, dict):
        return "{}" if not value else str(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    return repr(value)


def _default(field) -> str:
    if field.default is not MISSING:
        return _toml(field.default)
    if field.default_factory is not MISSING:
        return _toml(field.default_factory())
    return "required"


def _type(annotation: str) -> str:
    parts = [p.strip() for p in annotation.split("|") if p.strip() != "None"]
    return " or ".join(_TYPES.get(p, p) for p in parts)


def applies_to(table: str, key: str) -> str:
    """The controller × compensation pairs a ``[controller]`` key or table applies to
    (:func:`hmpc_pin.experiment.combos.applies`); ``"all"`` elsewhere."""
    from hmpc_pin.experiment import combos
    from hmpc_pin.experiment.config import COMPENSATIONS, CONTROLLERS

    parts = table.split(".")
    if parts[0] != "controller":
        return "all"
    name = parts[1] if len(parts) > 1 else key
    if name not in combos.HMPC_ONLY + combos.TABLES:
        return "all"
    per = {c: [p for p in COMPENSATIONS if combos.applies(name, c, p)] for c in CONTROLLERS}
    first = per[CONTROLLERS[0]]
    if all(v == first for v in per.values()) and len(first) < len(COMPENSATIONS):
        return f"any controller × {', '.join(first)}"
    out = []
    for ctrl in CONTROLLERS:
        comps = per[ctrl]
        if len(comps) == len(COMPENSATIONS):
            out.append(f"{ctrl} × any")
        elif comps:
            out.append(f"{ctrl} × {', '.join(comps)}")
    if len(out) == len(CONTROLLERS) and all(s.endswith("× any") for s in out):
        return "all"
    return "; ".join(out)


def config_rows(cls=None, table: str = "") -> list[Row]:
    """Every key the configuration accepts, table by table, depth first.

    Raises:
        ValueError: A key has no entry in its class's ``Attributes:`` docstring.
    """
    cls = _cls(TOP) if cls is None else cls
    docs = attribute_docs(cls)
    rows: list[Row] = []
    subs = []
    for f in dataclasses.fields(cls):
        if f.name == "source":  # set by the loader, not a key
            continue
        sub = _subtable(cls, f.name)
        dotted = f"{table}.{f.name}" if table else f.name
        if sub is not None:
            subs.append((sub, dotted))
            continue
        text = docs.get(f.name)
        if not text:
            raise ValueError(
                f"configuration key {dotted!r} ({cls.__module__}.{cls.__qualname__}) has no "
                "description in the class docstring's 'Attributes:' section; document it "
                "(type, unit in [brackets], meaning) before it can be used"
            )
        unit = _UNIT.search(_ROLE.sub("", text))
        rows.append(
            Row(
                table=table,
                key=f.name,
                type=_type(_annotation(cls, f.name)),
                unit=unit.group(1) if unit else "",
                default=_default(f),
                applies=applies_to(table, f.name),
                text=text,
            )
        )
    for sub, dotted in subs:
        sub_rows = config_rows(sub, dotted)
        if not sub_rows:  # a table of free keys has no rows of its own
            continue
        rows.extend(sub_rows)
    return rows


def table_docs() -> dict[str, tuple[str, str]]:
    """Table → (class path, one-line summary) for every table of the schema."""
    out: dict[str, tuple[str, str]] = {}

    def walk(cls, table):
        doc = (inspect.getdoc(cls) or "").split("\n\n")[0].replace("\n", " ")
        out[table] = (f"{cls.__module__}.{cls.__qualname__}", doc)
        for f in dataclasses.fields(cls):
            sub = _subtable(cls, f.name)
            if sub is not None:
                walk(sub, f"{table}.{f.name}" if table else f.name)

    walk(_cls(TOP), "")
    return out


def _cell(text: str) -> str:
    return escape_bars(" ".join(text.split()))


def config_reference_rst() -> str:
    """The reference as reStructuredText: one section and one table per TOML table."""
    rows = config_rows()
    tables = table_docs()
    out: list[str] = []
    for table, (path, summary) in tables.items():
        mine = [r for r in rows if r.table == table]
        if not mine:
            continue
        title = f"[{table}]" if table else "Top level"
        module = path.rpartition(".")[0]
        out += [title, "-" * len(title), "", f".. py:currentmodule:: {module}", ""]
        out += [f"{summary} (:class:`~{path}`)", ""]
        out += [
            ".. list-table::",
            "   :header-rows: 1",
            "   :widths: 14 12 8 12 18 36",
            "",
            "   * - key",
            "     - type",
            "     - unit",
            "     - default",
            "     - applies to",
            "     - meaning",
        ]
        for r in mine:
            anchor = r.dotted
            out += [
                f"   * - ``{r.key}``",
                f"     - {_cell(r.type)}",
                f"     - {_cell(r.unit) or '—'}",
                f"     - ``{r.default}``",
                f"     - {_cell(r.applies)}",
                f"     - {_cell(r.text)}",
            ]
            del anchor
        out.append("")
    return "\n".join(out)


def _setup_directive(app):
    from docutils import nodes
    from docutils.statemachine import StringList
    from sphinx.util.docutils import SphinxDirective

    class ConfigReference(SphinxDirective):
        """``{config-reference}``: the generated configuration reference."""

        has_content = False

        def run(self):
            from sphinx.util.nodes import nested_parse_with_titles

            text = config_reference_rst()
            node = nodes.section()
            node.document = self.state.document
            lines = StringList(text.splitlines(), "<config-reference>")
            nested_parse_with_titles(self.state, lines, node)
            return node.children

    class Exports(SphinxDirective):
        """``hmpc-exports:: module``: the names of the module's ``__all__`` defined in
        another module, linked to where they are documented."""

        required_arguments = 1

        def run(self):
            text = exports_rst(self.arguments[0])
            if not text:
                return []
            node = nodes.section()
            node.document = self.state.document
            self.state.nested_parse(StringList(text.splitlines(), "<hmpc-exports>"), 0, node)
            return node.children

    app.add_directive("config-reference", ConfigReference)
    app.add_directive("hmpc-exports", Exports)


def exports_rst(modname: str) -> str:
    """A list of the names ``modname.__all__`` re-exports from its submodules."""
    module = importlib.import_module(modname)
    lines = []
    for name in getattr(module, "__all__", ()):
        obj = getattr(module, name)
        home = getattr(obj, "__module__", None)
        if home == modname or not isinstance(home, str) or not home.startswith("hmpc_pin"):
            continue
        if inspect.isclass(obj) or inspect.isfunction(obj):
            lines.append(f"* :py:obj:`{name} <{home}.{obj.__qualname__}>`")
        else:
            lines.append(f"* ``{name}``")
    if not lines:
        return ""
    head = [
        ".. rubric:: Re-exported here",
        "",
        f"Defined in a submodule, importable from ``{modname}``:",
        "",
    ]
    return "\n".join(head + lines) + "\n"


def _resolve_by_import(app, env, node, contnode):
    """Resolve ``:role:`Name``` through the imports of the docstring's module."""
    if node.get("refdomain") != "py":
        return None
    target = node.get("reftarget", "")
    if not target or target.startswith("."):
        target = target.lstrip(".")
    modname = node.get("py:module")
    clsname = node.get("py:class")
    domain = env.get_domain("py")
    objects = domain.objects
    candidates = []
    if modname:
        scopes = [modname]
        if clsname:
            scopes.insert(0, f"{modname}.{clsname}")
        for scope in scopes:
            candidates.append(f"{scope}.{target}")
    candidates.append(target)
    for cand in candidates:
        obj = _lookup(cand)
        if obj is _NOTHING:
            continue
        for name in _documented_names(obj, cand, objects):
            if name in objects:
                from sphinx.util.nodes import make_refnode

                entry = objects[name]
                return make_refnode(
                    app.builder, node["refdoc"], entry.docname, entry.node_id, contnode, name
                )
    return None


_NOTHING = object()


def _lookup(dotted: str):
    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except Exception:
            continue
        try:
            for p in parts[i:]:
                obj = getattr(obj, p)
        except AttributeError:
            return _NOTHING
        return obj
    return _NOTHING


def _documented_names(obj, dotted: str, objects) -> list[str]:
    names = []
    if inspect.ismodule(obj):
        names.append(obj.__name__)
    mod = getattr(obj, "__module__", None)
    qual = getattr(obj, "__qualname__", None)
    if isinstance(mod, str) and isinstance(qual, str):
        names.append(f"{mod}.{qual}")
        if isinstance(obj, property):
            pass
    # a constant or an alias: the documented name whose object is this one
    last = dotted.rpartition(".")[2]
    for name in objects:
        if name.rpartition(".")[2] == last and name not in names and _lookup(name) is obj:
            names.append(name)
    return names


_BARS = re.compile(r"(?<![\\|])\|(?=\S)([^|`\n]*?\S)\|(?![_|])")


def escape_bars(text: str) -> str:
    """``|x|`` (an absolute value or a norm, as the docstrings and the paper write it) is
    not a reStructuredText substitution: escape the bars outside inline literals and roles."""
    parts = re.split(r"(`[^`]*`)", text)
    return "".join(p if p.startswith("`") else _BARS.sub(r"\\|\1\\|", p) for p in parts)


def _prepare_docstring(app, what, name, obj, options, lines):
    """Before napoleon: escape ``|x|``; a one-line attribute docstring ``Prose: more`` is
    prose, not ``type: description`` (napoleon would take ``Prose`` for a type)."""
    for i, line in enumerate(lines):
        if line.lstrip().startswith("|") and line.rstrip().endswith("|"):
            continue  # a table row
        lines[i] = escape_bars(line)
    if what in ("attribute", "property", "data") and lines:
        i = _first_colon(lines[0])
        head = lines[0][:i] if i >= 0 else ""
        if " " in head.strip() and head[:1].isupper():
            lines[0] = f"{head} —{lines[0][i + 1 :]}"


_ROLE = re.compile(r"(:[\w:.+-]+:`[^`]*`|``[^`]*``|`[^`]*`)")


def _first_colon(line: str) -> int:
    """Index of the first ``:`` outside roles and literals (napoleon's split), or -1."""
    pos = 0
    for part in _ROLE.split(line):
        if not _ROLE.fullmatch(part) and ":" in part:
            return pos + part.index(":")
        pos += len(part)
    return -1


def _skip_member(app, what, name, obj, skip, options):
    """Skip a property its class's docstring documents under ``Attributes:`` (napoleon
    writes that entry; documenting the property too would describe it twice)."""
    if skip or what != "class" or not isinstance(obj, property) or obj.fget is None:
        return None
    import sys

    owner, _, _ = obj.fget.__qualname__.rpartition(".")
    cls = sys.modules.get(obj.fget.__module__)
    for part in owner.split(".") if owner else ():
        cls = getattr(cls, part, None)
    if inspect.isclass(cls) and name in attribute_docs(cls):
        return True
    return None


def _shadowed_modules(package: str = "hmpc_pin") -> list[str]:
    """Submodules hidden by a package attribute of the same name (``hmpc_pin.sim.simulate``
    is both a module and the function the package exports)."""
    import pkgutil
    import sys

    pkg = importlib.import_module(package)
    out = []
    for info in pkgutil.walk_packages(pkg.__path__, package + "."):
        if info.name.rpartition(".")[2].startswith("_"):
            continue
        try:
            importlib.import_module(info.name)
        except Exception:
            continue
        parent, _, leaf = info.name.rpartition(".")
        if getattr(sys.modules[parent], leaf, None) is not sys.modules[info.name]:
            out.append(info.name)
    return out


def cli_parser():
    """:func:`hmpc_pin.apps.cli.build_parser` with its help texts made safe for
    reStructuredText (sphinx-argparse parses them as such): ``|e|`` and ``*`` escaped."""
    import argparse

    from hmpc_pin.apps.cli import build_parser

    def fix(text):
        if not isinstance(text, str):
            return text
        text = escape_bars(text).replace("*", "\\*")
        return re.sub(r"(\w)_(?=\\|\W|$)", r"\1\\_", text)

    def walk(parser):
        parser.description = fix(parser.description)
        parser.epilog = fix(parser.epilog)
        for action in parser._actions:
            action.help = fix(action.help)
            if isinstance(action, argparse._SubParsersAction):
                for choice in action._choices_actions:
                    choice.help = fix(choice.help)
                for sub in action.choices.values():
                    walk(sub)

    parser = build_parser()
    walk(parser)
    return parser


def setup(app):
    _setup_directive(app)
    app.connect("autodoc-process-docstring", _prepare_docstring, priority=400)
    app.connect("autodoc-skip-member", _skip_member)
    app.connect("missing-reference", _resolve_by_import)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
