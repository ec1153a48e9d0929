"""The controllers by name: the one registry of ``[controller] kind``.

Each entry (:class:`ControllerSpec`) says what the name is: the class built, the parts it is
built from (the arguments after the robot), the compensation it has when none is given, the
``[controller]`` keys and tables that apply to it only, and the names version 0.1 gave it
combined with a compensation. Everything that needs to know the controllers reads them here
(the compensation registry's pattern, :mod:`hmpc_pin.compensation.registry`): the
configuration (the names ``kind`` accepts, which keys apply), the combinations
(``compare``, ``--no-ndo``), the builder, ``hmpc-pin check`` and ``hmpc-pin tune``.

Example:
    >>> from hmpc_pin.controllers.registry import REGISTRY, controller_spec
    >>> tuple(REGISTRY)
    ('hmpc', 'computed-torque', 'computed-torque-pid')
    >>> controller_spec("computed-torque").default_compensation
    'none'
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..compensation.observers import DEFAULT_DESIGN
from ..exceptions import ConfigError
from .computed_torque import ComputedTorque
from .hierarchical import HierarchicalMPC

__all__ = [
    "HMPC_ONLY",
    "KIND_ALIASES",
    "MPC_KEYS",
    "REGISTRY",
    "ControllerSpec",
    "controller_kinds",
    "controller_names",
    "controller_spec",
]

#: The keys of ``[controller]`` that are settings of the MPC only: unset (``None``) until
#: resolved, then :class:`~hmpc_pin.controllers.mpc_settings.MPCSettings`' default.
MPC_KEYS = ("eps_abs", "max_iter", "qp_layout", "backend", "latency", "joint_dynamics")
#: The keys and tables of ``[controller]`` of the hierarchical MPC only.
HMPC_ONLY = ("constraints", *MPC_KEYS)


@dataclass(frozen=True)
class ControllerSpec:
    """What a controller name stands for.

    Attributes:
        name: The name ``[controller] kind`` takes.
        cls: The class built (a :class:`~hmpc_pin.controllers.base.Controller`).
        summary: One line for messages and the docs.
        parts: The names of the arguments after the robot that :attr:`cls` is built
            from, in order: ``"settings"`` (its settings class), ``"compensation"``,
            ``"limits"`` (the joint limits of ``[controller.constraints]``).
        default_compensation: The compensation when ``[controller] compensation`` is not
            given (a name of :data:`~hmpc_pin.compensation.registry.REGISTRY`).
        keys: The ``[controller]`` keys and tables that apply to this controller only
            (beyond those of every controller and the compensation's table).
        pid: Its ``[controller.computed_torque]`` table accepts ``ki`` (the integral gain).
        aliases: The names version 0.1 gave this controller with a compensation
            (``{"hmpc-momentum": "momentum", ...}``); still accepted by ``kind``.
        observer_v01: In version 0.1 its compensation was chosen by ``[controller.observer]
            enabled`` and ``kind`` (default Chen's NDO).
    """

    name: str
    cls: type
    summary: str
    parts: tuple[str, ...]
    default_compensation: str
    keys: tuple[str, ...] = ()
    pid: bool = False
    aliases: dict[str, str] = field(default_factory=dict)
    observer_v01: bool = False

    @property
    def mpc(self) -> bool:
        """Whether it is the hierarchical MPC (it takes the MPC's keys, :data:`MPC_KEYS`)."""
        return "eps_abs" in self.keys

    @property
    def limits(self) -> bool:
        """Whether it is built with the joint limits of ``[controller.constraints]``."""
        return "limits" in self.parts


#: Every controller, by the name ``[controller] kind`` takes.
REGISTRY: dict[str, ControllerSpec] = {
    spec.name: spec
    for spec in (
        ControllerSpec(
            "hmpc",
            HierarchicalMPC,
            "the hierarchical multiloop MPC (Sections 2-3)",
            parts=("settings", "compensation", "limits"),
            default_compensation=DEFAULT_DESIGN,
            keys=HMPC_ONLY,
            aliases={
                "hmpc-none": "none",
                "hmpc-momentum": "momentum",
                "hmpc-ism": "ism",
                "hmpc-ism-bl": "ism-bl",
            },
            observer_v01=True,
        ),
        ControllerSpec(
            "computed-torque",
            ComputedTorque,
            "computed torque with PD gains (the classical reference)",
            parts=("settings", "compensation"),
            default_compensation="none",
            keys=("computed_torque",),
        ),
        ControllerSpec(
            "computed-torque-pid",
            ComputedTorque,
            "computed torque with PID gains",
            parts=("settings", "compensation"),
            default_compensation="none",
            keys=("computed_torque",),
            pid=True,
        ),
    )
}

#: The names version 0.1 gave a controller × compensation, each mapped to the pair
#: ``(controller, compensation)`` (from the registry's :attr:`ControllerSpec.aliases`).
KIND_ALIASES = {
    alias: (spec.name, comp) for spec in REGISTRY.values() for alias, comp in spec.aliases.items()
}


def controller_names() -> tuple[str, ...]:
    """The names ``[controller] kind`` takes (without the 0.1 aliases)."""
    return tuple(REGISTRY)


def controller_kinds() -> tuple[str, ...]:
    """Every name ``[controller] kind`` accepts: each controller followed by its 0.1
    aliases."""
    return tuple(name for spec in REGISTRY.values() for name in (spec.name, *spec.aliases))


def controller_spec(name: str, key: str = "controller.kind") -> ControllerSpec:
    """The entry of the controller ``name``.

    Raises:
        ConfigError: ``name`` is not registered, naming ``key`` and every name.
    """
    try:
        return REGISTRY[name]
    except (KeyError, TypeError):
        raise ConfigError(
            key, f"unknown controller {name!r}; expected one of {tuple(REGISTRY)}"
        ) from None
