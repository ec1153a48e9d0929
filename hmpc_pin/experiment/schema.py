"""Typed, validated configuration: frozen dataclasses loaded from TOML.

Every controller setting defaults to the paper's value (Section 4), so
``ControllerConfig()`` is the paper's controller. An experiment file
(``configs/*.toml``) has the sections ``[robot]``, ``[controller]``,
``[controller.observer]``, ``[plant]`` (with ``[plant.mujoco]`` and
``[plant.mujoco.obstacle]`` for ``engine = "mujoco"``), ``[reference]``, ``[disturbance]``
(with optional ``[disturbance.friction]`` and ``[disturbance.pulse]``),
``[simulation]``, ``[sweep]``, ``[collision]`` and ``[realtime]``; see
``configs/paper_combined.toml`` for every key (``configs/planar3_contact_mujoco.toml`` for the
MuJoCo and collision tables).

Validation happens at the boundary: unknown keys, wrong types, non-finite numbers, vectors
of the wrong length and out-of-range values raise one
:class:`~hmpc_pin.exceptions.ConfigError` naming the key.

Deprecated since 0.3: the tables live in :mod:`hmpc_pin.experiment.config`, one module each;
this module gathers them under the names of version 0.2 (``from hmpc_pin.experiment.schema
import ...`` keeps working, with a :class:`DeprecationWarning` when first imported; import
from :mod:`hmpc_pin.experiment.config` instead, ``OBSERVERS`` from
:mod:`hmpc_pin.experiment.combos`).
"""

from __future__ import annotations

import warnings

from . import config as _config
from .combos import OBSERVERS
from .config import *  # noqa: F403  (the 0.2 names, re-exported)

__all__ = [*_config.__all__, "OBSERVERS"]

warnings.warn(
    "hmpc_pin.experiment.schema is deprecated since 0.3; import from "
    "hmpc_pin.experiment.config (OBSERVERS from hmpc_pin.experiment.combos)",
    DeprecationWarning,
    stacklevel=2,
)
