"""Sphinx configuration of the hmpc_pin documentation.

Built strictly by ``make docs``: ``sphinx-build -W --keep-going -n``: every warning is an
error and every cross-reference must resolve (``-n``, nitpicky). No intersphinx: the
build reads nothing from the network.
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))

from hmpc_docs import _shadowed_modules as hmpc_docs_shadowed  # noqa: E402

import hmpc_pin  # noqa: E402  (the installed package: `make docs` uses the project's .venv)

project = "hmpc_pin"
author = "hmpc_pin developers"
copyright = "hmpc_pin developers"
release = hmpc_pin.__version__
version = release

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinxarg.ext",
    "hmpc_docs",  # docs/_ext/hmpc_docs.py: the configuration reference, import-following refs
]

source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = ["_build", "_templates", "Thumbs.db", ".DS_Store"]
templates_path = ["_templates"]

# MyST: Markdown pages (the README's content is Markdown), with heading anchors so that
# pages can link to sections, and $...$ maths.
myst_enable_extensions = ["colon_fence", "dollarmath", "deflist"]
myst_heading_anchors = 3

# API pages: autosummary writes one page per public module (docs/api/generated, not
# committed); napoleon reads the Google-style docstrings.
autosummary_generate = True
autosummary_imported_members = False
# hmpc_pin.sim.simulate is a module and the function hmpc_pin.sim exports under the same
# name; the page of such a module is the module's (docs/_templates/autosummary/function.rst).
autosummary_context = {"shadowed": hmpc_docs_shadowed()}
autodoc_default_options = {"members": True, "show-inheritance": True}
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_typehints_description_target = "documented"
napoleon_google_docstring = True
napoleon_numpy_docstring = False
napoleon_use_rtype = False
napoleon_attr_annotations = True
# "Attributes:" sections become attribute entries (targets of :attr: references); a
# property listed there is not documented a second time (docs/_ext/hmpc_docs.py).
napoleon_use_ivar = False
add_module_names = False

# Nitpicky: every reference must resolve. Types of other libraries have no inventory
# here (intersphinx would fetch theirs over the network, and the build must work
# offline), so references to them are accepted unresolved. Nothing of hmpc_pin is.
nitpicky = True
_THIRD_PARTY = (
    r"(numpy|np|numpy\.typing|npt|pinocchio|pin|proxsuite|mujoco|scipy|matplotlib|"
    r"meshcat|dask|distributed|toppra|pink|qpsolvers|yourdfpy|tqdm|trimesh|"
    # the standard library: no inventory offline either
    r"pathlib|os|typing|collections|collections\.abc|abc|enum|dataclasses|argparse|"
    r"concurrent\.futures|multiprocessing|threading|io|types|contextlib|time|signal|json|"
    r"builtins|re|logging|warnings|subprocess|functools|numbers|gc)\..+"
)
_BUILTINS = (
    r"(int|float|str|bool|bytes|dict|list|tuple|set|frozenset|object|type|callable|"
    r"Callable|Path|Sequence|Iterable|Iterator|Mapping|Any|Optional|Union|Protocol|"
    r"ndarray|array_like|ArrayLike|NDArray|None|Exception|ValueError|RuntimeError|"
    r"TypeError|KeyError|OSError|KeyboardInterrupt|Warning|UserWarning|DeprecationWarning|"
    r"RuntimeWarning|NotImplementedError|TimeoutError|FileNotFoundError|IndexError|"
    r"ArithmeticError|optional|np\.ndarray|pin\.Model|pin\.Data|"
    # hmpc_pin's alias of numpy.typing.NDArray[numpy.float64], in signatures
    r"FloatArray)"
)
nitpick_ignore_regex = [
    (r"py:.*", _THIRD_PARTY),
    (r"py:.*", _BUILTINS),
]

html_theme = "furo"
html_title = f"hmpc_pin {release}"
html_static_path = ["_static"]
html_show_sourcelink = False
