"""Which ``[controller]`` keys and tables apply to which controller × compensation.

The table a compensation is configured by is the compensation registry's
(:mod:`hmpc_pin.compensation.registry`); the keys of each controller are the controller
registry's (:mod:`hmpc_pin.controllers.registry`). The loader
(:mod:`hmpc_pin.experiment.config`) refuses a key that does not apply to the chosen pair, and
the builder (:func:`~hmpc_pin.experiment.build.with_controller`) drops the keys that stop
applying when a run switches the pair
(``--compensation``, ``--no-ndo``, ``compare``).
"""

from __future__ import annotations

from ..compensation.registry import compensation_names, compensation_spec
from ..controllers.registry import HMPC_ONLY, controller_spec

__all__ = ["HMPC_ONLY", "TABLES", "applies"]

#: Compensations that are observers (they use ``[controller.observer]``; the registry's).
OBSERVERS = compensation_names(table="observer")
#: Compensations of integral sliding mode (``[controller.ism]``; the registry's).
ISM = compensation_names(table="ism")
#: The sub-tables of ``[controller]`` and the pairs they apply to.
TABLES = ("observer", "ism", "computed_torque")


def applies(name: str, controller: str, compensation: str) -> bool:
    """Whether the ``[controller]`` key or table ``name`` applies to the pair.

    Args:
        name: A key of :data:`HMPC_ONLY` or a table of :data:`TABLES`.
        controller: A name of the controller registry
            (:data:`~hmpc_pin.controllers.registry.REGISTRY`).
        compensation: A name of the compensation registry
            (:data:`~hmpc_pin.compensation.registry.REGISTRY`).
    """
    if name in ("observer", "ism"):
        return compensation_spec(compensation).table == name
    if name in HMPC_ONLY or name == "computed_torque":
        return name in controller_spec(controller).keys
    raise KeyError(f"{name!r} is not a key of the registry (expected one of {HMPC_ONLY + TABLES})")
