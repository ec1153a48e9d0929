"""``hmpc-pin configs``: the command's arguments and its entry point."""

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
