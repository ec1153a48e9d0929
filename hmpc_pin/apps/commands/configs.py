"""``hmpc-pin configs``: list the packaged configs, or write an editable copy of one. Its
arguments (``add_arguments``) and its entry point (``main``).
"""

from __future__ import annotations

__all__ = ["add_arguments", "main"]


def add_arguments(cfg) -> None:
    """``hmpc-pin configs`` (:mod:`hmpc_pin.apps.packaged`)."""
    from ..packaged import configs_arguments

    configs_arguments(cfg)


def main(args) -> int:
    """``hmpc-pin configs`` (:func:`hmpc_pin.apps.packaged.cmd_configs`)."""
    from ..packaged import cmd_configs

    return cmd_configs(args)
