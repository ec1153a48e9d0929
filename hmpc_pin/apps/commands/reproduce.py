"""``hmpc-pin reproduce``: run every paper experiment and write DIR/report.md. Its arguments
(``add_arguments``) and its entry point (``main``).
"""

from __future__ import annotations

from pathlib import Path

from ..common import EXIT_FAILED, EXIT_OK, out_dir

__all__ = ["add_arguments", "main"]


def add_arguments(rep) -> None:
    """``hmpc-pin reproduce``."""
    rep.description = (
        "Run every experiment of the paper's Section 5 (with and without the "
        "observer), draw Figures 3(b) and 4-10, and write a Markdown report comparing "
        "the numbers with the paper's claims."
    )
    rep.add_argument("--out", type=Path, default=Path("out/reproduce"), help="output directory")
    rep.add_argument(
        "--configs",
        type=Path,
        default=None,
        help="directory holding the paper_*.toml configs [the packaged ones]",
    )
    rep.add_argument("--quiet", action="store_true", help="no progress bar")


def main(args) -> int:
    from ..report import reproduce

    out = out_dir(args.out)
    ok = reproduce(out, configs_dir=args.configs, progress=not args.quiet)
    return EXIT_OK if ok else EXIT_FAILED
