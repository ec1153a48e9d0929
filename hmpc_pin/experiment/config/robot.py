"""``[robot]``: the arm, from a URDF file or an example-robot-data name."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...checks import as_array
from ...exceptions import ConfigError
from ._fields import _float, _set


@dataclass(frozen=True, eq=False)
class RobotConfig:
    """The controller's robot model.

    Attributes:
        urdf: URDF path (relative paths are relative to the config file).
        model: Instead of ``urdf``, a robot name: ``"planar3"`` (shipped in the package)
            or an ``example-robot-data`` name (``"ur5"``, ``"panda"``, ``"z1"``, ...);
            give at most one of the two (neither: ``"planar3"``).
        gravity: Gravity magnitude [m/s²] along −z (paper: 9.8).
        locked_joints: Joints not controlled, by URDF name → locked position [rad or m]
            (e.g. Panda's fingers); removed with ``pin.buildReducedModel``.
        armature: Rotor inertia [kg·m²] added to each joint's diagonal of :math:`M(q)`
            (Pinocchio's ``model.armature``), one value or one per joint; not given: the
            URDF's (none). A URDF cannot carry it; a geared arm's motors add it (e.g. the
            FR3 that franky-sim simulates: 0.195 on joints 1–4, 0.074 on 5–7).
    """

    urdf: Path | None = None
    model: str | None = None
    gravity: float = 9.8
    locked_joints: dict = field(default_factory=dict)
    armature: np.ndarray | None = None

    def __post_init__(self):
        if self.urdf is not None and self.model is not None:
            raise ConfigError("model", "give either robot.urdf or robot.model, not both")
        if self.urdf is not None:
            if not isinstance(self.urdf, (str, Path)):
                raise ConfigError("urdf", f"expected a path string, got {self.urdf!r}")
            _set(self, "urdf", Path(self.urdf))
        if self.model is not None and not isinstance(self.model, str):
            raise ConfigError("model", f"expected a robot name string, got {self.model!r}")
        _set(self, "gravity", _float("gravity", self.gravity, nonneg=True))
        if not isinstance(self.locked_joints, dict):
            raise ConfigError(
                "locked_joints", f"expected a table name = position, got {self.locked_joints!r}"
            )
        _set(
            self,
            "locked_joints",
            {str(k): _float(f"locked_joints.{k}", v) for k, v in self.locked_joints.items()},
        )
        if self.armature is not None:
            _set(self, "armature", as_array("armature", self.armature, nonneg=True))

    @property
    def source(self) -> Path | str:
        """The URDF path or the robot name, as :func:`~hmpc_pin.model.robot.load_robot`
        takes it (neither given: ``"planar3"``, the paper's arm shipped in the package)."""
        if self.urdf is not None:
            return self.urdf
        return self.model if self.model is not None else "planar3"
