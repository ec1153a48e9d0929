"""``hmpc-pin native``: report the compiled core (built when the package was installed). Its
arguments (``add_arguments``) and its entry point (``main``).
"""

from __future__ import annotations

import sys

from ..common import EXIT_FAILED

__all__ = ["add_arguments", "main"]


def add_arguments(nat) -> None:
    """``hmpc-pin native``."""
    nat.description = (
        "Print where hmpc_pin's compiled core (the RK4 plant's period and the "
        "MPC step) is installed and what it was built against. It is built when the "
        "package is built (pip install); exit 1 if it cannot be loaded here."
    )
    nat.add_argument(
        "--build",
        action="store_true",
        help="deprecated since 0.3 (the core is built at install time): same as without it",
    )


def main(args) -> int:
    """``hmpc-pin native``: where the compiled core is and what it was built against."""
    from ... import native
    from ...exceptions import NativeError

    if args.build:
        print(
            "warning: `hmpc-pin native --build` is deprecated since 0.3: the compiled "
            "core is built when the package is installed",
            file=sys.stderr,
        )
    try:
        info = native.build_info()
    except NativeError as exc:
        print(f"native kernels: not available: {exc.reason}", file=sys.stderr)
        return EXIT_FAILED
    print(f"native kernels: {info['path']}")
    print(
        f"  built against pinocchio {info['pinocchio']}, proxsuite {info['proxsuite']} "
        f"({info['compiler']}, {info['build_type']})"
    )
    return 0
