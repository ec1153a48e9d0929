"""``hmpc-pin identify``: identify joint friction (or collision thresholds) from a saved run.
Its arguments (``add_arguments``) and its entry point (``main``).
"""

from __future__ import annotations

__all__ = ["add_arguments", "main"]


def add_arguments(idf) -> None:
    """``hmpc-pin identify`` (:mod:`hmpc_pin.apps.identify`)."""
    from ..identify import identify_arguments

    identify_arguments(idf)


def main(args) -> int:
    """``hmpc-pin identify RESULT`` (:func:`hmpc_pin.apps.identify.cmd_identify`)."""
    from ..identify import cmd_identify

    return cmd_identify(args)
