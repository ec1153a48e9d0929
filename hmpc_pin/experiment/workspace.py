"""A config's workspace: the :class:`~hmpc_pin.model.workspace.Workspace` of its arm with
its ``[workspace]`` plane (the defaults without the table), and its reference scanned
against it (``hmpc-pin check``)."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from ..exceptions import URDFError, ValidityWarning
from ..model.robot import Robot
from ..model.workspace import Workspace, WorkspaceScan, find_srdf
from .config.workspace import WorkspaceConfig

__all__ = ["SCAN_STEP", "make_workspace", "scan_reference"]

#: The reference is scanned every this many seconds, or every control period when shorter
#: [s]: a link 1 m from a joint moving at 1 rad/s travels 10 mm between samples, whose
#: lowest point then dips below the samples' by at most about 1 m · (0.01 rad)² / 8.
SCAN_STEP = 0.01


def make_workspace(
    robot: Robot, settings: WorkspaceConfig | None = None, name: str | None = None
) -> Workspace | None:
    """The arm's workspace with the plane of ``settings`` (the defaults when ``None``),
    honouring the SRDF of the example-robot-data model ``name`` or the one beside the
    URDF; ``None`` when the URDF has no collision geometry or Pinocchio cannot load it
    (warned: :class:`~hmpc_pin.exceptions.ValidityWarning`)."""
    s = settings if settings is not None else WorkspaceConfig()
    try:
        ws = Workspace(
            robot,
            height=s.height,
            normal=s.normal,
            margin=s.margin,
            srdf=find_srdf(Path(robot.source), name),
            self_collision=s.self_collision,
            allowed=s.allowed_pairs,
        )
    except URDFError as exc:
        warnings.warn(
            f"{exc}; the reference is not checked against the mounting plane and for "
            "self-collision",
            ValidityWarning,
            stacklevel=3,
        )
        return None
    return ws if ws.geometry.ngeoms else None


def scan_reference(experiment) -> WorkspaceScan | None:
    """The config's reference over the run (every :data:`SCAN_STEP` s or control period)
    against its workspace (:func:`make_workspace`); ``None`` without collision geometry."""
    config = experiment.config
    ws = make_workspace(experiment.robot, config.workspace, config.robot.model)
    if ws is None:
        return None
    step = min(SCAN_STEP, config.controller.Ts)
    t = np.arange(0.0, config.simulation.duration + step / 2, step)
    q, _ = experiment.reference.sample_many(t)
    return ws.scan(np.asarray(q, dtype=float), t)
