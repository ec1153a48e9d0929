"""``hmpc-pin plot``: draw the figures of a saved run, timing, sweep table or identification.
Its arguments (``add_arguments``) and its entry point (``main``).
"""

from __future__ import annotations

from ..common import EXIT_OK, out_dir

__all__ = ["add_arguments", "main"]


def add_arguments(plt) -> None:
    """``hmpc-pin plot`` (:mod:`hmpc_pin.apps.plot`)."""
    from ..plot import plot_arguments

    plot_arguments(plt)


def main(args) -> int:
    from ..plot import figures, save

    _, figs = figures(args.file, args.run)  # bad input stops here: nothing written
    out = out_dir(args.out if args.out is not None else args.file.parent)
    for path in save(args.file, figs, out):
        print(f"wrote {path}")
    if not figs:
        print(f"{args.file}: nothing to draw (no finite arrays)")
    return EXIT_OK
