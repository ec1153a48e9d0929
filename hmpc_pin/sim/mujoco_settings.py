"""The MuJoCo plant's settings (``[plant.mujoco]``): what it adds to the URDF (joint
friction, damping, armature), its integrator, the geometry it collides with and an
obstacle."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..exceptions import ConfigError

__all__ = ["GEOMETRY_SOURCES", "MUJOCO_INTEGRATORS", "MuJoCoSettings", "Obstacle"]


#: ``[plant.mujoco] integrator`` names → MuJoCo's ``mjtIntegrator`` member names.
MUJOCO_INTEGRATORS = {
    "euler": "mjINT_EULER",
    "rk4": "mjINT_RK4",
    "implicit": "mjINT_IMPLICIT",
    "implicitfast": "mjINT_IMPLICITFAST",
}
#: ``[plant.mujoco] geometry``: which URDF geometry becomes MuJoCo's collision geometry.
GEOMETRY_SOURCES = ("collision", "visual", "none")


@dataclass(frozen=True)
class Obstacle:
    """A fixed box in the world the arm can touch (a wall or a table).

    Attributes:
        position: Centre of the box in the world frame [m], (3,).
        size: Half-lengths of the box along the world x, y, z axes [m], (3,) (MuJoCo's
            box ``size``).
        friction: Sliding friction coefficient of the contact [-].
        solref: MuJoCo's contact ``solref`` (time constant [s], damping ratio [-]): the
            softness of the surface (MuJoCo's default 0.02, 1; larger is softer, e.g. a
            padded surface). The obstacle's values are the contact's (geom priority).
    """

    position: tuple[float, float, float]
    size: tuple[float, float, float]
    friction: float = 0.5
    solref: tuple[float, float] = (0.02, 1.0)

    def __post_init__(self):
        for name in ("position", "size"):
            value = np.asarray(getattr(self, name), dtype=float)
            if value.shape != (3,) or not np.all(np.isfinite(value)):
                raise ConfigError(name, f"expected 3 finite numbers [x, y, z], got {value!r}")
            if name == "size" and np.any(value <= 0):
                raise ConfigError(name, f"expected half-lengths > 0, got {value.tolist()}")
            object.__setattr__(self, name, tuple(float(x) for x in value))
        if not (math.isfinite(self.friction) and self.friction >= 0):
            raise ConfigError("friction", f"expected a number >= 0, got {self.friction!r}")
        sr = np.asarray(self.solref, dtype=float)
        if sr.shape != (2,) or not np.all(np.isfinite(sr)) or np.any(sr <= 0):
            raise ConfigError(
                "solref", f"expected [time constant > 0, damping ratio > 0], got {sr!r}"
            )
        object.__setattr__(self, "solref", (float(sr[0]), float(sr[1])))


@dataclass(frozen=True)
class MuJoCoSettings:
    """What the MuJoCo plant adds to the URDF (everything defaults to the bare arm).

    Attributes:
        integrator: One of :data:`MUJOCO_INTEGRATORS` (default ``"implicitfast"``).
        frictionloss: Dry joint friction [N·m], one value or one per joint (controller
            order), MuJoCo's ``dof_frictionloss``.
        damping: Viscous joint damping [N·m·s/rad], ``dof_damping``.
        armature: Rotor inertia added to the joint [kg·m²], ``dof_armature``.
        friction_timeconst: Time constant [s] of the joints' dry-friction constraint (the
            controlled dofs' ``dof_solref``, damping ratio 1); ``None`` (default) keeps
            MuJoCo's 0.02 s. MuJoCo's ``frictionloss`` is a soft constraint: on a joint of
            small inertia or fast damping its force stays far below ``f`` at the speeds of a
            run unless this is short (2 timesteps is MuJoCo's shortest advisable value).
        import_urdf_dynamics: Keep the URDF's ``<dynamics damping friction>`` (added to
            the values above; default ``True``, as the Pinocchio plants apply them);
            ``False`` drops them.
        geometry: ``"collision"`` (the URDF's collision geometry, default), ``"visual"``
            (its visual geometry used for collisions, e.g. for an arm without collision
            tags) or ``"none"`` (no geometry: dynamics only).
        obstacle: An :class:`Obstacle`, or ``None`` (then contacts are switched off).
        package_dirs: Extra directories searched for ``package://`` names.
    """

    integrator: str = "implicitfast"
    frictionloss: float | tuple[float, ...] = 0.0
    damping: float | tuple[float, ...] = 0.0
    armature: float | tuple[float, ...] = 0.0
    friction_timeconst: float | None = None
    import_urdf_dynamics: bool = True
    geometry: str = "collision"
    obstacle: Obstacle | None = None
    package_dirs: tuple[str, ...] = field(default_factory=tuple)

    def __post_init__(self):
        if self.integrator not in MUJOCO_INTEGRATORS:
            raise ConfigError(
                "integrator",
                f"expected one of {tuple(MUJOCO_INTEGRATORS)}, got {self.integrator!r}",
            )
        if self.geometry not in GEOMETRY_SOURCES:
            raise ConfigError(
                "geometry", f"expected one of {GEOMETRY_SOURCES}, got {self.geometry!r}"
            )
        if self.obstacle is not None and self.geometry == "none":
            raise ConfigError(
                "geometry",
                "'none' leaves the arm without geometry, so it cannot touch the obstacle; "
                "use 'collision' or 'visual'",
            )
        tc = self.friction_timeconst
        if tc is not None and not (isinstance(tc, (int, float)) and math.isfinite(tc) and tc > 0):
            raise ConfigError("friction_timeconst", f"expected a time [s] > 0, got {tc!r}")
        for name in ("frictionloss", "damping", "armature"):
            value = np.asarray(getattr(self, name), dtype=float)
            if value.ndim > 1 or not np.all(np.isfinite(value)) or np.any(value < 0):
                raise ConfigError(
                    name, f"expected numbers >= 0 (one or one per joint), got {value!r}"
                )

    def per_joint(self, name: str, n: int) -> np.ndarray:
        """``frictionloss``, ``damping`` or ``armature`` broadcast to ``n`` joints."""
        value = np.asarray(getattr(self, name), dtype=float)
        if value.ndim == 1 and value.shape != (n,):
            raise ConfigError(
                name,
                f"has {value.shape[0]} entries but the robot has {n} joints; give {n} "
                "values or one value for all joints",
            )
        return np.broadcast_to(value, (n,)).astype(float)
