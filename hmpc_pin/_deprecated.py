"""The names earlier versions exported that no longer do anything, in one place.

A module that still answers one of them looks it up here (its module ``__getattr__``
calls :func:`deprecated`), so that a user's file importing it keeps working and is told,
once, what replaced it. This module imports nothing of the package.
"""

from __future__ import annotations

import importlib
import warnings
from typing import Any

__all__ = ["LOOPS", "deprecated", "why_not_compiled"]

#: The values ``simulate(loop=...)`` accepted (the keyword has no effect since 0.3: every
#: run goes through the compiled loop); was ``hmpc_pin.sim.compiled_loop.LOOPS``.
LOOPS = ("auto", "compiled", "python")


def why_not_compiled(controller: Any, plant: Any, reference: Any, on_step: Any = None) -> None:
    """``None`` for every setup: every part is called through a port of the compiled loop;
    was ``hmpc_pin.sim.compiled_loop.why_not_compiled``."""
    return None


class _Moved:
    """The value of a name that moved: ``module.name``, looked up when asked for (so that
    the value has one home and this module imports nothing of the package)."""

    def __init__(self, module: str, name: str):
        self.module, self.name = module, name

    def resolve(self) -> Any:
        return getattr(importlib.import_module(self.module), self.name)


#: ``{(module, name): (value, what to do instead)}`` of the names kept for earlier versions.
NAMES: dict[tuple[str, str], tuple[Any, str]] = {
    ("hmpc_pin.sim.compiled_loop", "LOOPS"): (
        LOOPS,
        "leave simulate's loop keyword out (every run goes through the compiled loop)",
    ),
    ("hmpc_pin.sim.compiled_loop", "why_not_compiled"): (
        why_not_compiled,
        "every setup runs compiled; remove the call (it always returned None)",
    ),
    ("hmpc_pin.sim.plants", "PULSE_CHUNK"): (
        _Moved("hmpc_pin.sim.compiled_loop", "LOOP_CHUNK"),
        "the compiled loop's chunk is hmpc_pin.sim.compiled_loop.LOOP_CHUNK (the plant "
        "tabulates nothing)",
    ),
    ("hmpc_pin.realtime.franka.rates", "InnerLawEveryCycle"): (
        _Moved("hmpc_pin.realtime.inner_law", "InnerLawEveryCycle"),
        "import it from hmpc_pin.realtime.inner_law (every real-time command runs it)",
    ),
    ("hmpc_pin.realtime.franka.threaded", "InnerLawThreaded"): (
        _Moved("hmpc_pin.realtime.threaded_law", "InnerLawThreaded"),
        "import it from hmpc_pin.realtime.threaded_law (every real-time command runs it)",
    ),
    ("hmpc_pin.realtime.franka.threaded", "planner_qps"): (
        _Moved("hmpc_pin.realtime.threaded_law", "planner_qps"),
        "import it from hmpc_pin.realtime.threaded_law",
    ),
}


def deprecated(module: str, name: str) -> Any:
    """The value of the deprecated ``module.name``, with a :class:`DeprecationWarning`
    naming what to do instead.

    Raises:
        AttributeError: ``module`` has no deprecated ``name`` (the usual error of a missing
            attribute).
    """
    try:
        value, instead = NAMES[(module, name)]
    except KeyError:
        raise AttributeError(f"module {module!r} has no attribute {name!r}") from None
    moved = isinstance(value, _Moved)
    warnings.warn(
        f"{module}.{name} is deprecated since 0.3"
        + ("; " if moved else " and does nothing; ")
        + instead,
        DeprecationWarning,
        stacklevel=3,
    )
    return value.resolve() if moved else value
