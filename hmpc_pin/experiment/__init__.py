"""Experiments: the TOML configuration (:mod:`.config`) and the one place a config becomes
objects (:mod:`.build`)."""

from .build import Experiment, make_controller, run_experiment, with_controller
from .config import ControllerConfig, ExperimentConfig, load_config

__all__ = [
    "ControllerConfig",
    "Experiment",
    "ExperimentConfig",
    "load_config",
    "make_controller",
    "run_experiment",
    "with_controller",
]
