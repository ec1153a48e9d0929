"""Tasks: the references the controllers track (one protocol, :mod:`.base`)."""

from .base import Reference, as_reference, check_limits, sample_horizon
from .quintic import QuinticReference
from .sine import SineReference

__all__ = [
    "QuinticReference",
    "Reference",
    "SineReference",
    "as_reference",
    "check_limits",
    "sample_horizon",
]
