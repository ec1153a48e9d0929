"""``[workspace]``: the plane the arm is mounted on, which no moving link may cross."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...exceptions import ConfigError
from ._fields import _array, _bool, _float, _set


@dataclass(frozen=True, eq=False)
class WorkspaceConfig:
    """The mounting plane and the clearance every moving link keeps above it
    (:class:`~hmpc_pin.model.workspace.Workspace`): ``hmpc-pin init`` chooses a reference
    inside it and ``hmpc-pin check`` flags a reference that leaves it or makes two links
    collide.

    Attributes:
        height: Height of the mounting plane along ``normal`` [m], in the URDF's root
            frame (0: the plane through the root link's origin, where an arm's base
            stands on its table).
        normal: The plane's normal [-] (3 numbers, made unit), pointing to the side the
            arm works in (``[0, 0, 1]``: the table is below).
        margin: Clearance [m] every moving link's collision geometry keeps above the plane.
        self_collision: Whether two links' collision geometries must not meet (pairs of
            adjacent links, and those the SRDF disables, are not checked).
        allowed_pairs: Pairs of links, by URDF name (``[["a", "b"], ...]``), that touch by
            design and are not checked either (``init`` lists those touching at the
            reference posture).
    """

    height: float = 0.0
    normal: np.ndarray = (0.0, 0.0, 1.0)  # type: ignore[assignment]
    margin: float = 0.02
    self_collision: bool = True
    allowed_pairs: list = field(default_factory=list)

    def __post_init__(self):
        _set(self, "height", _float("height", self.height))
        normal = _array("normal", self.normal)
        if normal.shape != (3,) or not np.any(normal):
            raise ConfigError(
                "normal",
                f"expected 3 numbers, not all 0 (the plane's normal), got {normal.tolist()}",
            )
        _set(self, "normal", normal / np.linalg.norm(normal))
        _set(self, "margin", _float("margin", self.margin, nonneg=True))
        _set(self, "self_collision", _bool("self_collision", self.self_collision))
        pairs = self.allowed_pairs
        if not isinstance(pairs, (list, tuple)) or not all(
            isinstance(p, (list, tuple)) and len(p) == 2 and all(isinstance(x, str) for x in p)
            for p in pairs
        ):
            raise ConfigError(
                "allowed_pairs",
                f'expected a list of pairs of link names, [["a", "b"], ...], got {pairs!r}',
            )
        _set(self, "allowed_pairs", [list(p) for p in pairs])
