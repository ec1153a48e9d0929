"""Compensation: the disturbance estimate :math:`\\hat d` cancelled in Eq 4 (one protocol)."""

from .base import Compensation, NoCompensation
from .gate import FeedbackGate
from .ism import IntegralSlidingMode
from .observers import DisturbanceObserver, MomentumObserver, general_gain_bound

__all__ = [
    "Compensation",
    "DisturbanceObserver",
    "FeedbackGate",
    "IntegralSlidingMode",
    "MomentumObserver",
    "NoCompensation",
    "general_gain_bound",
]
