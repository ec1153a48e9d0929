"""hmpc_pin: hierarchical multiloop MPC with a nonlinear disturbance observer on Pinocchio.

Li, Gu, Huang, Ji, Tang (2022), "Hierarchical multiloop MPC scheme for robot
manipulators with nonlinear disturbance observer": inverse dynamics decouples an
n-link arm into n double integrators (Eq 4), a box-constrained MPC per joint
chooses each joint's acceleration (Eq 25–26, solved by ProxSuite), and a
nonlinear disturbance observer (Eq 13) estimates and cancels friction and
external torques.
"""

from .config import ControllerConfig, ExperimentConfig, ObserverConfig, load_config
from .controller import HierarchicalMPC
from .disturbances import (
    CoulombViscousFriction,
    Disturbance,
    GaussianPulse,
    Periodic,
    SumDisturbance,
    ZeroDisturbance,
)
from .exceptions import (
    ConfigError,
    DimensionError,
    HmpcError,
    LimitError,
    NonFiniteError,
    OutputError,
    SimulationError,
    SolverError,
    URDFError,
)
from .experiment import Experiment, run_experiment
from .joint_mpc import CondensedMPC, JointQPs
from .kinematics import KinematicsError, planar_ik, solve_pose, tool_pose
from .measurement import MeasuredController
from .metrics import Metrics, compute_metrics, format_metrics
from .observers import DisturbanceObserver
from .references import QuinticReference, Reference, SineReference
from .robot import Robot, load_robot
from .simulate import Result, simulate

__version__ = "0.1.0"

__all__ = [
    "CondensedMPC",
    "ConfigError",
    "ControllerConfig",
    "CoulombViscousFriction",
    "DimensionError",
    "Disturbance",
    "DisturbanceObserver",
    "Experiment",
    "ExperimentConfig",
    "GaussianPulse",
    "HierarchicalMPC",
    "HmpcError",
    "JointQPs",
    "KinematicsError",
    "LimitError",
    "MeasuredController",
    "Metrics",
    "NonFiniteError",
    "ObserverConfig",
    "OutputError",
    "Periodic",
    "QuinticReference",
    "Reference",
    "Result",
    "Robot",
    "SimulationError",
    "SineReference",
    "SolverError",
    "SumDisturbance",
    "URDFError",
    "ZeroDisturbance",
    "__version__",
    "compute_metrics",
    "format_metrics",
    "load_config",
    "load_robot",
    "planar_ik",
    "run_experiment",
    "simulate",
    "solve_pose",
    "tool_pose",
]
