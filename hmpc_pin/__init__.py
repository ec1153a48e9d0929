"""hmpc_pin: hierarchical multiloop MPC with a nonlinear disturbance observer on Pinocchio.

Li, Gu, Huang, Ji, Tang (2022), "Hierarchical multiloop MPC scheme for robot
manipulators with nonlinear disturbance observer": inverse dynamics decouples an
n-link arm into n double integrators (Eq 4), a box-constrained MPC per joint
chooses each joint's acceleration (Eq 25–26, solved by ProxSuite), and a
nonlinear disturbance observer (Eq 13) estimates and cancels friction and
external torques.

The package is layered; each layer imports only the layers below it (tested)::

    apps/          cli, run, compare, sweep, tune, identify, check, report, metrics, plots, viz,
                   ros (the nodes' commands)
      │
    ros/           ROS 2: the arm's topics as a PacedInterface · trajectory messages · arm node
      │
    experiment/    schema (TOML → dataclasses) · build (the one place names become objects)
      │
    realtime/      RobotInterface protocol · arm in another process · fixed-rate loop, safe stops
    identification/ friction (observer or inverse dynamics) and collision thresholds from a run
      │
    sim/           disturbances · plants (Plant protocol: RK4, Euler, MuJoCo) · sensing (the
      │            arm's interface: encoders, velocity estimate, latency) · simulate · Result
      │
    controllers/   Controller protocol · HierarchicalMPC · ComputedTorque · wrappers
      │      ╲
    tasks/    mpc/          Reference protocol: sine, quintic │ per-joint condensed QP (ProxSuite)
      │
    compensation/  Compensation protocol: NDO (Chen, general), momentum observer, ISM, none
      │
    model/         Robot (URDF → Pinocchio: M, C·q̇ + G, ABA), planar 3R IK
    native/        loads the compiled core _core (cpp/ + bindings/, built): dynamics,
      │            NDO, RK4 period, the fused MPC step
    data/, exceptions.py

Data flows one way: a reference and the measured state enter a controller, which holds
one compensation and calls its MPC; the torque goes to a plant; ``simulate`` closes the
loop; ``experiment.build`` assembles all of it from a config.
"""

from . import _startup  # noqa: F401  (first: Ctrl-C while the command line starts, exit 130)
from .apps.compare import Comparison, run_comparison
from .apps.metrics import Metrics, compute_metrics, format_metrics
from .compensation import (
    Compensation,
    DisturbanceObserver,
    IntegralSlidingMode,
    MomentumObserver,
    NoCompensation,
)
from .controllers import (
    ComputedTorque,
    Controller,
    CTSettings,
    HierarchicalMPC,
    MeasuredController,
    MPCSettings,
)
from .exceptions import (
    ArmError,
    ConfigError,
    DimensionError,
    ExtraError,
    HmpcError,
    InterfaceError,
    KinematicsError,
    LimitError,
    NativeError,
    NonFiniteError,
    OutputError,
    PerformanceWarning,
    RunInterrupted,
    SimulationError,
    SolverError,
    TrajectoryError,
    URDFError,
    ValidityWarning,
    VizError,
)
from .experiment.build import Experiment, make_controller, run_experiment, with_controller
from .experiment.schema import (
    COMPENSATIONS,
    CONTROLLER_KINDS,
    CONTROLLERS,
    ControllerConfig,
    ExperimentConfig,
    ObserverConfig,
    load_config,
)
from .model.planar import planar_ik, solve_pose, tool_pose
from .model.robot import Robot, load_robot
from .mpc import CondensedMPC, JointQPs
from .sim import (
    CoulombViscousFriction,
    Disturbance,
    EulerPlant,
    GaussianPulse,
    MuJoCoPlant,
    Periodic,
    Plant,
    Result,
    RK4Plant,
    SumDisturbance,
    ZeroDisturbance,
    simulate,
)
from .tasks import (
    JointTrajectory,
    PoseReference,
    QuinticReference,
    Reference,
    SineReference,
    as_reference,
    load_trajectory,
    retime_waypoints,
)

__version__ = "0.3.0.dev0"  # the same as pyproject.toml (tested)

__all__ = [
    "COMPENSATIONS",
    "CONTROLLERS",
    "CONTROLLER_KINDS",
    "ArmError",
    "CTSettings",
    "Comparison",
    "Compensation",
    "ComputedTorque",
    "CondensedMPC",
    "ConfigError",
    "Controller",
    "ControllerConfig",
    "CoulombViscousFriction",
    "DimensionError",
    "Disturbance",
    "DisturbanceObserver",
    "EulerPlant",
    "Experiment",
    "ExperimentConfig",
    "ExtraError",
    "GaussianPulse",
    "HierarchicalMPC",
    "HmpcError",
    "IntegralSlidingMode",
    "InterfaceError",
    "JointQPs",
    "JointTrajectory",
    "KinematicsError",
    "LimitError",
    "MPCSettings",
    "MeasuredController",
    "Metrics",
    "MomentumObserver",
    "MuJoCoPlant",
    "NativeError",
    "NoCompensation",
    "NonFiniteError",
    "ObserverConfig",
    "OutputError",
    "PerformanceWarning",
    "Periodic",
    "Plant",
    "PoseReference",
    "QuinticReference",
    "RK4Plant",
    "Reference",
    "Result",
    "Robot",
    "RunInterrupted",
    "SimulationError",
    "SineReference",
    "SolverError",
    "SumDisturbance",
    "TrajectoryError",
    "URDFError",
    "ValidityWarning",
    "VizError",
    "ZeroDisturbance",
    "__version__",
    "as_reference",
    "compute_metrics",
    "format_metrics",
    "load_config",
    "load_robot",
    "load_trajectory",
    "make_controller",
    "planar_ik",
    "retime_waypoints",
    "run_comparison",
    "run_experiment",
    "simulate",
    "solve_pose",
    "tool_pose",
    "with_controller",
]
