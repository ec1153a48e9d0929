"""``hmpc-pin examples``: list the packaged example scripts, or write a copy of one. Its
arguments (``add_arguments``) and its entry point (``main``).
"""

from __future__ import annotations

__all__ = ["add_arguments", "main"]


def add_arguments(exa) -> None:
    """``hmpc-pin examples`` (:mod:`hmpc_pin.apps.packaged`)."""
    from ..packaged import examples_arguments

    examples_arguments(exa)


def main(args) -> int:
    """``hmpc-pin examples`` (:func:`hmpc_pin.apps.packaged.cmd_examples`)."""
    from ..packaged import cmd_examples

    return cmd_examples(args)
