"""``hmpc-pin replay``: write a self-contained Meshcat HTML replay of a saved run. Its
arguments (``add_arguments``) and its entry point (``main``).
"""

from __future__ import annotations

from pathlib import Path

from ..common import EXIT_OK, write_replay

__all__ = ["add_arguments", "main"]


def add_arguments(rpl) -> None:
    """``hmpc-pin replay``."""
    rpl.description = (
        "Turn a result .npz written by `run` into one HTML file that plays the "
        "run as a Meshcat animation (play/pause/scrub), with no server and no network."
    )
    rpl.add_argument("result", type=Path, help="result .npz")
    rpl.add_argument("--out", type=Path, default=Path("replay.html"), help="HTML file to write")
    rpl.add_argument("--urdf", help="URDF of the arm (default: the one named in the result)")


def main(args) -> int:
    from ..runfile import load_run, run_robot

    result = load_run(args.result, "RESULT")
    robot = run_robot(result, str(args.urdf) if args.urdf else None, "RESULT")
    path = write_replay(robot, result, args.out, "--out")
    print(f"wrote {path} ({path.stat().st_size / 1e6:.1f} MB)")
    return EXIT_OK
