"""Compensation: the disturbance estimate :math:`\\hat d` cancelled in Eq 4 (one protocol).

The compensations by name: :mod:`hmpc_pin.compensation.registry`."""

from .base import Compensation, NoCompensation
from .gate import FeedbackGate
from .ism import IntegralSlidingMode
from .observers import DisturbanceObserver, MomentumObserver, general_gain_bound
from .registry import (
    REGISTRY,
    CompensationSpec,
    build_compensation,
    compensation_names,
    compensation_spec,
)

__all__ = [
    "REGISTRY",
    "Compensation",
    "CompensationSpec",
    "DisturbanceObserver",
    "FeedbackGate",
    "IntegralSlidingMode",
    "MomentumObserver",
    "NoCompensation",
    "build_compensation",
    "compensation_names",
    "compensation_spec",
    "general_gain_bound",
]
