"""The robot catalogue: the arms :func:`~hmpc_pin.model.robot.load_robot` accepts by name
from ``example-robot-data`` (its URDF and SRDF files), with the closest names suggested
for a typo."""

from __future__ import annotations

import difflib
from pathlib import Path

from ..exceptions import URDFError

__all__ = ["MOUNTED_ARMS", "example_robot_names", "example_robot_srdf", "example_robot_urdf"]


#: Arms example-robot-data mounts on a floating base although their URDF is a fixed-base
#: arm (the loader's ``free_flyer`` says how it mounts a model, not what the URDF is).
MOUNTED_ARMS = ("so100", "so101")


def example_robot_names() -> tuple[str, ...]:
    """Names accepted by :func:`~hmpc_pin.model.robot.load_robot` from
    ``example-robot-data`` (fixed-base URDF arms and all other fixed-base URDF models the
    loader package lists, and the arms of :data:`MOUNTED_ARMS`)."""
    from example_robot_data import robots_loader

    return tuple(
        sorted(
            name
            for name, loader in robots_loader.ROBOTS.items()
            if loader.urdf_filename and (not loader.free_flyer or name in MOUNTED_ARMS)
        )
    )


def example_robot_urdf(name: str) -> Path:
    """Path of the URDF of the ``example-robot-data`` model ``name`` (e.g. ``"panda"``).

    Raises:
        URDFError: Unknown name (the message lists the closest known names), a
            floating-base model, or a model shipped only as SDF.
    """
    from os.path import join

    from example_robot_data import robots_loader

    loader = robots_loader.ROBOTS.get(name)
    if loader is None:
        arms = ["planar3", *example_robot_names()]  # suggest arms only (not drones, legs)
        close = difflib.get_close_matches(name, arms, n=5, cutoff=0.5)
        hint = f"did you mean {', '.join(map(repr, close))}? " if close else ""
        raise URDFError(
            name,
            "is neither a URDF file nor an example-robot-data model name; "
            f"{hint}known arms include 'ur5', 'ur10', 'panda', 'z1' "
            "(`hmpc-pin init --list` or hmpc_pin.model.robot.example_robot_names() lists all)",
        )
    # The loader's free_flyer flag is not read: it says how example-robot-data mounts the
    # model, not what the URDF is (so100/so101 are flagged but are fixed-base arms). A
    # floating joint in the URDF itself is refused by load_robot.
    if not loader.urdf_filename:
        raise URDFError(name, "is shipped as SDF only; hmpc_pin loads URDF models")
    rel = join(loader.path, loader.urdf_subpath, loader.urdf_filename)
    model_path = loader.model_path or robots_loader.getModelPath(rel)
    return Path(model_path, rel).resolve()


def example_robot_srdf(name: str) -> tuple[Path | None, str | None]:
    """The SRDF of the ``example-robot-data`` model ``name`` and the name of its reference
    posture (``"default"``, ``"half_sitting"``, ``"ready"``, ...), or ``None`` for what the
    package does not ship."""
    from os.path import join

    from example_robot_data import robots_loader

    loader = robots_loader.ROBOTS.get(name)
    if loader is None or not loader.srdf_filename:
        return None, None
    rel = join(loader.path, loader.srdf_subpath, loader.srdf_filename)
    model_path = loader.model_path or robots_loader.getModelPath(rel)
    path = Path(model_path, rel).resolve()
    return (path if path.is_file() else None), (loader.ref_posture or None)
