"""The plant's physics engines by name: the one registry of ``[plant] engine``.

Each entry (:class:`EngineSpec`) says what the name is: whether this package integrates the
arm's dynamics itself (Pinocchio's ABA, :mod:`hmpc_pin.sim.plants`: then ``[plant] dt``,
``integrator``, ``tolerance``, ``coulomb`` and ``backend`` apply) or another engine steps it
(MuJoCo, :mod:`hmpc_pin.sim.mujoco`, configured by its own ``[plant.mujoco]`` table, whose
keys replace some of ``[plant]``). The configuration, the builder and ``hmpc-pin check``
read the engines here, so that an engine name is decoded once.

Example:
    >>> from hmpc_pin.sim.engines import ENGINES, engine_spec
    >>> tuple(ENGINES)
    ('pinocchio', 'mujoco')
    >>> engine_spec("mujoco").replaces
    {'dt': 'timestep', 'integrator': 'integrator'}
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..exceptions import ConfigError

__all__ = ["DEFAULT_ENGINE", "ENGINES", "EngineSpec", "engine_spec"]


@dataclass(frozen=True)
class EngineSpec:
    """What a ``[plant] engine`` name stands for.

    Attributes:
        name: The name ``[plant] engine`` takes.
        summary: One line for messages and the docs.
        integrated: This package integrates the dynamics (Pinocchio's ABA with the
            integrator of ``[plant] integrator``, at ``[plant] dt``); ``False`` for an engine
            that steps the arm itself.
        table: The ``[plant]`` sub-table that configures it (``"mujoco"``), or ``None``.
        replaces: The ``[plant]`` keys that do not apply to it, each with the key of
            :attr:`table` to set instead.
    """

    name: str
    summary: str
    integrated: bool
    table: str | None = None
    replaces: dict[str, str] = field(default_factory=dict)


#: Every engine, by the name ``[plant] engine`` takes.
ENGINES: dict[str, EngineSpec] = {
    spec.name: spec
    for spec in (
        EngineSpec("pinocchio", "Pinocchio's ABA on the plant model, integrated here", True),
        EngineSpec(
            "mujoco",
            "MuJoCo on the same URDF (the ``mujoco`` extra)",
            False,
            table="mujoco",
            replaces={"dt": "timestep", "integrator": "integrator"},
        ),
    )
}
#: The engine when ``[plant] engine`` is not given.
DEFAULT_ENGINE = "pinocchio"


def engine_spec(name: str, key: str = "plant.engine") -> EngineSpec:
    """The entry of the engine ``name``.

    Raises:
        ConfigError: ``name`` is not registered, naming ``key`` and every name.
    """
    try:
        return ENGINES[name]
    except (KeyError, TypeError):
        raise ConfigError(
            key, f"unknown engine {name!r}; expected one of {tuple(ENGINES)}"
        ) from None
