"""Which ``[controller]`` keys and tables apply to which controller × compensation.

The one registry of it: the loader (:mod:`hmpc_pin.experiment.schema`) refuses a key that
does not apply to the chosen pair, and the builder
(:func:`~hmpc_pin.experiment.build.with_controller`) drops the keys that stop applying when a
run switches the pair
(``--compensation``, ``--no-ndo``, ``compare``).
"""

from __future__ import annotations

__all__ = ["HMPC_ONLY", "TABLES", "applies"]

#: Compensations that are observers (they use ``[controller.observer]``).
OBSERVERS = ("chen", "general", "momentum")
#: Compensations of integral sliding mode (``[controller.ism]``).
ISM = ("ism", "ism-bl")
#: Keys of the hierarchical MPC only (``kind = "hmpc"``).
HMPC_ONLY = (
    "constraints",
    "eps_abs",
    "max_iter",
    "qp_layout",
    "backend",
    "latency",
    "joint_dynamics",
)
#: The sub-tables of ``[controller]`` and the pairs they apply to.
TABLES = ("observer", "ism", "computed_torque")


def applies(name: str, controller: str, compensation: str) -> bool:
    """Whether the ``[controller]`` key or table ``name`` applies to the pair.

    Args:
        name: A key of :data:`HMPC_ONLY` or a table of :data:`TABLES`.
        controller: ``hmpc``, ``computed-torque`` or ``computed-torque-pid``.
        compensation: ``chen``, ``general``, ``momentum``, ``ism``, ``ism-bl`` or ``none``.
    """
    if name == "observer":
        return compensation in OBSERVERS
    if name == "ism":
        return compensation in ISM
    if name == "computed_torque":
        return controller.startswith("computed-torque")
    if name in HMPC_ONLY:
        return controller == "hmpc"
    raise KeyError(f"{name!r} is not a key of the registry (expected one of "
                   f"{HMPC_ONLY + TABLES})")  # fmt: skip
