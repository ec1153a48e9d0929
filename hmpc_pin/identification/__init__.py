"""Identification from a run of the controller: joint friction (fed forward by
``[controller.friction]``) and collision thresholds (``[collision]``).

:mod:`.friction` fits viscous and Coulomb friction per joint, from the observer's estimate
or from the rigid-body model's inverse dynamics, with confidence intervals, through
the model of the observer that ran (:mod:`.observer_model`), into a
:class:`.FrictionFit` (:mod:`.friction_fit`);
:mod:`.thresholds` learns a threshold per joint on the observer's estimate of a
contact-free run at a stated false-alarm probability. ``hmpc-pin identify`` is their
command line.
"""

from .friction import SOURCES, applied_torque, fit_friction, fit_joint
from .friction_fit import FrictionFit, JointFriction
from .observer_model import ObserverModel
from .thresholds import CollisionThresholds, learn_thresholds

__all__ = [
    "SOURCES",
    "CollisionThresholds",
    "FrictionFit",
    "JointFriction",
    "ObserverModel",
    "applied_torque",
    "fit_friction",
    "fit_joint",
    "learn_thresholds",
]
