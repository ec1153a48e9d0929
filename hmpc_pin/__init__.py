"""hmpc_pin: hierarchical multiloop MPC with a nonlinear disturbance observer on Pinocchio.

Li, Gu, Huang, Ji, Tang (2022), "Hierarchical multiloop MPC scheme for robot
manipulators with nonlinear disturbance observer": inverse dynamics decouples an
n-link arm into n double integrators (Eq 4), a box-constrained MPC per joint
chooses each joint's acceleration (Eq 25–26, solved by ProxSuite), and a
nonlinear disturbance observer (Eq 13) estimates and cancels friction and
external torques.
"""

from .compare import Comparison, run_comparison
from .computed_torque import ComputedTorque
from .config import (
    CONTROLLER_KINDS,
    ControllerConfig,
    ExperimentConfig,
    ObserverConfig,
    load_config,
)
from .controller import HierarchicalMPC, make_controller
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
from .ism import IntegralSlidingMode
from .joint_mpc import CondensedMPC, JointQPs
from .kinematics import KinematicsError, planar_ik, solve_pose, tool_pose
from .measurement import MeasuredController
from .metrics import Metrics, compute_metrics, format_metrics
from .observers import DisturbanceObserver, MomentumObserver
from .references import QuinticReference, Reference, SineReference
from .robot import Robot, load_robot
from .simulate import Result, simulate

__version__ = "0.1.0"

__all__ = [
    "CONTROLLER_KINDS",
    "Comparison",
    "ComputedTorque",
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
    "IntegralSlidingMode",
    "JointQPs",
    "KinematicsError",
    "LimitError",
    "MeasuredController",
    "Metrics",
    "MomentumObserver",
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
    "make_controller",
    "planar_ik",
    "run_comparison",
    "run_experiment",
    "simulate",
    "solve_pose",
    "tool_pose",
]
