"""The spellings of earlier versions of ``[controller]``, in one place.

Version 0.1 named a controller × compensation in one ``kind`` (:data:`KIND_ALIASES`, e.g.
``"hmpc-momentum"``) and chose the observer of ``kind = "hmpc"`` with
``[controller.observer] enabled`` and ``kind``; version 0.2 writes ``kind`` and
``compensation``. Both load; this module turns the old spellings into the pair.
"""

from __future__ import annotations

from ...compensation.observers import DEFAULT_DESIGN
from ...controllers.registry import KIND_ALIASES as _KIND_ALIASES
from ...controllers.registry import REGISTRY, controller_kinds, controller_spec
from ...exceptions import ConfigError

__all__ = ["CONTROLLER_KINDS", "KIND_ALIASES", "resolve_compensation"]

#: Controller names of version 0.1, each one controller × one compensation (the
#: controller registry's :attr:`~hmpc_pin.controllers.registry.ControllerSpec.aliases`).
KIND_ALIASES = _KIND_ALIASES
#: Every name accepted by ``[controller] kind``, with those of version 0.1 (the registry's).
CONTROLLER_KINDS = controller_kinds()
#: The compensation a controller has when ``compensation`` is not given (the registry's
#: :attr:`~hmpc_pin.controllers.registry.ControllerSpec.default_compensation`; kept for
#: callers of version 0.2).
DEFAULT_COMPENSATION = {name: spec.default_compensation for name, spec in REGISTRY.items()}


def resolve_compensation(
    kind: str, controller: str, alias_comp: str | None, compensation: str | None, observer
) -> tuple[str, object]:
    """The compensation of ``[controller]`` and its observer table, from the spellings of
    version 0.1 and 0.2.

    ``kind`` may be a 0.1 alias (:data:`KIND_ALIASES`: the compensation is in the name,
    ``alias_comp``); without ``compensation``, ``kind = "hmpc"`` takes it from the 0.1 keys
    ``[controller.observer] enabled`` and ``kind`` (default Chen's NDO); every other
    controller its registered
    :attr:`~hmpc_pin.controllers.registry.ControllerSpec.default_compensation`. A 0.1 key
    beside the 0.2 spelling that supersedes it, or a contradiction between the two, is one
    :class:`ConfigError`.

    Returns:
        ``(compensation, observer table or None)``.
    """
    obs = observer
    legacy_keys = [
        k for k in ("enabled", "kind") if obs is not None and getattr(obs, k) is not None
    ]
    if alias_comp is not None:  # a 0.1 name: the compensation is in the name
        if compensation is not None and compensation != alias_comp:
            raise ConfigError(
                "compensation",
                f"{compensation!r} contradicts kind = {kind!r} (which is "
                f"hmpc × {alias_comp}); write kind = 'hmpc' with the compensation",
            )
        comp = alias_comp
        if obs is not None and comp == "momentum":
            if obs.enabled is False:
                raise ConfigError(
                    "observer.enabled",
                    "false, but kind = 'hmpc-momentum' is hmpc × momentum observer; for "
                    "no compensation write compensation = 'none'",
                )
            if obs.kind not in (None, "momentum"):
                raise ConfigError(
                    "observer.kind",
                    f"{obs.kind!r}, but kind = 'hmpc-momentum' uses the momentum "
                    "observer; write kind = 'hmpc', compensation = "
                    f"{obs.kind!r} instead",
                )
    elif compensation is not None:
        if legacy_keys:
            raise ConfigError(
                f"observer.{legacy_keys[0]}",
                "superseded by [controller] compensation; remove it (compensation = "
                f"{compensation!r} already chooses)",
            )
        comp = compensation
    elif controller_spec(controller).observer_v01:  # 0.1 spelling: the observer table decides
        enabled = True if obs is None or obs.enabled is None else obs.enabled
        comp = ((obs.kind if obs is not None else None) or DEFAULT_DESIGN) if enabled else "none"
        if not enabled:
            obs = None  # a table switched off by its own enabled = false
    else:
        comp = controller_spec(controller).default_compensation
        if legacy_keys:
            raise ConfigError(
                f"observer.{legacy_keys[0]}",
                f"does not apply to kind = {controller!r}; choose the compensation "
                "with [controller] compensation",
            )
    return comp, obs
