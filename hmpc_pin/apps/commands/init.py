"""``hmpc-pin init``: write a commented config for any arm (URDF path or example-robot-data
name). Its arguments (``add_arguments``) and its entry point (``main``).
"""

from __future__ import annotations

import sys
from pathlib import Path

from ...exceptions import ConfigError
from ..common import EXIT_OK, checked_duration

__all__ = ["add_arguments", "main"]


def add_arguments(ini) -> None:
    """``hmpc-pin init`` (docs, "Your own arm")."""
    ini.description = (
        "Write a TOML experiment that runs as written: a sine per joint around "
        "the reference posture (SRDF, else mid-range) inside the position and velocity "
        "limits, moved where the whole sine keeps every link above the mounting plane and "
        "clear of the others (the URDF's collision geometry), inertia-scaled disturbances, "
        "an observer valid for the arm, gripper/finger "
        "joints locked. Exit 2 with one line when the URDF cannot be controlled."
    )
    ini.add_argument(
        "robot", nargs="?", help="URDF path or robot name (planar3, ur5, panda, ...; --list)"
    )
    ini.add_argument(
        "--list", action="store_true", help="list the robot names init accepts and exit"
    )
    ini.add_argument("--out", type=Path, default=None, help="TOML file to write [<name>.toml]")
    ini.add_argument(
        "--duration",
        type=float,
        help="simulated time [s] [long enough for `identify`: the pulses, then a period]",
    )
    ini.add_argument("--force", action="store_true", help="overwrite an existing --out file")
    ini.add_argument(
        "--plane-height",
        type=float,
        default=None,
        metavar="M",
        help="height of the mounting plane (the table) in the URDF's root frame, which no "
        "moving link's collision geometry may cross [m] [0]",
    )
    ini.add_argument(
        "--margin",
        type=float,
        default=None,
        metavar="M",
        help="clearance every moving link keeps above the plane [m] [0.02]",
    )


def main(args) -> int:
    """``hmpc-pin init ROBOT``: write a commented config that runs as written."""
    from ...experiment.config import WorkspaceConfig
    from ...experiment.init import plant_step_hint, write_config

    if args.list:
        _print_init_names()
        return EXIT_OK
    if args.robot is None:
        raise ConfigError("ROBOT", "give a URDF path or a robot name (--list lists the names)")
    duration = checked_duration(args.duration)  # None: long enough to identify friction
    try:
        workspace = WorkspaceConfig(
            height=0.0 if args.plane_height is None else args.plane_height,
            margin=0.02 if args.margin is None else args.margin,
        )
    except ConfigError as exc:
        flag = {"height": "--plane-height", "margin": "--margin"}[exc.key]
        raise ConfigError(flag, exc.message) from None
    path = write_config(
        args.robot,
        args.out,
        duration,
        overwrite=args.force,
        workspace=workspace,
        plane_given=args.plane_height is not None,
    )
    print(f"wrote {path}; run it with: hmpc-pin run {path}")
    lines = path.read_text(encoding="utf-8").splitlines()
    start = next((k for k, ln in enumerate(lines) if ln.startswith("# Friction identif")), None)
    if start is not None:  # what a run needs for `identify` (the file's comment)
        block = []
        for ln in lines[start:]:
            if not ln.startswith("#"):
                break
            block.append(ln[2:].strip())
        print(" ".join(block).replace("FILE", str(path)))
    hint = plant_step_hint("\n".join(lines))
    if hint is not None:
        print(hint, file=sys.stderr)
    return EXIT_OK


def _print_init_names() -> None:
    """``init --list``: the shipped arms and example-robot-data's arms (with so100/so101,
    which it mounts on a floating base: :data:`~hmpc_pin.model.robot.MOUNTED_ARMS`)."""
    from ...data import robot_names
    from ...model.robot import example_robot_names

    about = {"planar3": "the paper's arm", "fr3": "Franka Research 3, franka_description"}
    for name in sorted(robot_names(), key=lambda x: x != "planar3"):
        print(f"{name}  ({about.get(name, 'a packaged arm')}, shipped with hmpc_pin)")
    for name in example_robot_names():
        print(f"{name}  (example-robot-data)")
    print("or the path of any fixed-base arm's .urdf file")
