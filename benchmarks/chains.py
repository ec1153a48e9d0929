"""Planar n-link arms like ``robots/planar3.urdf``, built and written with yourdfpy.

Each link is a uniform slender rod of linear density 1 kg/m (planar3's), all of the
same length, so that every chain has planar3's total reach of 3.7 m. Centre of mass at
l/2, inertia m·l²/12 about the two axes perpendicular to the rod (1e-6 about its own).
Joint axes (0, −1, 0), limits ±π/2, effort 1e4 N·m, velocity 100 rad/s.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import yourdfpy

__all__ = ["planar_chain", "write_planar_chain"]

#: Total reach of the chain [m] (planar3: 1.5 + 1.2 + 1.0).
REACH = 3.7
#: Linear density of the rods [kg/m] (planar3's links: 1 kg per metre).
DENSITY = 1.0


def _translation(x: float) -> np.ndarray:
    """Homogeneous transform (4×4) of a translation by ``x`` [m] along the x axis."""
    T = np.eye(4)
    T[0, 3] = x
    return T


def planar_chain(n: int, reach: float = REACH, density: float = DENSITY) -> yourdfpy.URDF:
    """A planar arm of ``n`` uniform rods as a yourdfpy URDF object model.

    Args:
        n: Number of links and revolute joints (>= 1).
        reach: Total length of the arm [m].
        density: Linear density of each rod [kg/m].

    Returns:
        The URDF (``base_link``, ``link1 .. linkn``, ``joint1 .. jointn`` and a fixed
        ``tool`` frame at the tip).
    """
    if n < 1:
        raise ValueError(f"n={n}; a chain needs at least one link")
    length = reach / n
    mass = density * length
    inertia = np.diag([1e-6, mass * length**2 / 12.0, mass * length**2 / 12.0])
    links = [yourdfpy.Link(name="base_link")]
    joints = []
    for i in range(1, n + 1):
        links.append(
            yourdfpy.Link(
                name=f"link{i}",
                inertial=yourdfpy.Inertial(
                    origin=_translation(length / 2.0), mass=mass, inertia=inertia
                ),
            )
        )
        joints.append(
            yourdfpy.Joint(
                name=f"joint{i}",
                type="revolute",
                parent="base_link" if i == 1 else f"link{i - 1}",
                child=f"link{i}",
                origin=_translation(0.0 if i == 1 else length),
                axis=np.array([0.0, -1.0, 0.0]),
                limit=yourdfpy.Limit(
                    effort=1e4, velocity=100.0, lower=-math.pi / 2, upper=math.pi / 2
                ),
            )
        )
    links.append(yourdfpy.Link(name="tool"))
    joints.append(
        yourdfpy.Joint(
            name="tool_joint",
            type="fixed",
            parent=f"link{n}",
            child="tool",
            origin=_translation(length),
        )
    )
    robot = yourdfpy.Robot(name=f"planar{n}", links=links, joints=joints)
    return yourdfpy.URDF(robot=robot, build_scene_graph=False, load_meshes=False)


def write_planar_chain(n: int, directory: str | Path) -> Path:
    """Write :func:`planar_chain` ``(n)`` to ``directory/planar<n>.urdf`` and return the path."""
    path = Path(directory) / f"planar{n}.urdf"
    planar_chain(n).write_xml_file(str(path))
    return path
