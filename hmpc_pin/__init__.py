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
    experiment/    config (TOML → dataclasses) · build (the one place names become objects)
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
      │            NDO, RK4 period, the compiled MPC step
    data/, exceptions.py

Data flows one way: a reference and the measured state enter a controller, which holds
one compensation and calls its MPC; the torque goes to a plant; ``simulate`` closes the
loop; ``experiment.build`` assembles all of it from a config.

``import hmpc_pin`` loads the exceptions only; every other public name (``hmpc_pin.X``,
``from hmpc_pin import X``) imports its module on first use, so that a script pays for the
parts it uses and never for the applications (``apps/``) or matplotlib.
"""

from . import _startup  # noqa: F401  (first: Ctrl-C while the command line starts, exit 130)
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
    RealtimeWarning,
    RunInterrupted,
    SimulationError,
    SolverError,
    TrajectoryError,
    URDFError,
    ValidityWarning,
    VizError,
)

TYPE_CHECKING = False  # True for type checkers (no import of typing: the guard comes first)
if TYPE_CHECKING:  # what the lazy names below are (for type checkers and editors)
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
    from .experiment.build import Experiment, make_controller, run_experiment, with_controller
    from .experiment.config import (
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

#: Public name → the module that defines it. Imported on first use (PEP 562): ``import
#: hmpc_pin`` loads the exceptions only, so that ``hmpc-pin --help`` and a library user who
#: needs one part do not pay for Pinocchio, ProxSuite, the applications or matplotlib.
_LAZY: dict[str, str] = {
    **dict.fromkeys(("Comparison", "run_comparison"), ".apps.compare"),
    **dict.fromkeys(("Metrics", "compute_metrics", "format_metrics"), ".apps.metrics"),
    **dict.fromkeys(
        (
            "Compensation",
            "DisturbanceObserver",
            "IntegralSlidingMode",
            "MomentumObserver",
            "NoCompensation",
        ),
        ".compensation",
    ),
    **dict.fromkeys(
        (
            "ComputedTorque",
            "Controller",
            "CTSettings",
            "HierarchicalMPC",
            "MeasuredController",
            "MPCSettings",
        ),
        ".controllers",
    ),
    **dict.fromkeys(
        ("Experiment", "make_controller", "run_experiment", "with_controller"), ".experiment.build"
    ),
    **dict.fromkeys(
        (
            "COMPENSATIONS",
            "CONTROLLER_KINDS",
            "CONTROLLERS",
            "ControllerConfig",
            "ExperimentConfig",
            "ObserverConfig",
            "load_config",
        ),
        ".experiment.config",
    ),
    **dict.fromkeys(("planar_ik", "solve_pose", "tool_pose"), ".model.planar"),
    **dict.fromkeys(("Robot", "load_robot"), ".model.robot"),
    **dict.fromkeys(("CondensedMPC", "JointQPs"), ".mpc"),
    **dict.fromkeys(
        (
            "CoulombViscousFriction",
            "Disturbance",
            "EulerPlant",
            "GaussianPulse",
            "MuJoCoPlant",
            "Periodic",
            "Plant",
            "Result",
            "RK4Plant",
            "SumDisturbance",
            "ZeroDisturbance",
            "simulate",
        ),
        ".sim",
    ),
    **dict.fromkeys(
        (
            "JointTrajectory",
            "PoseReference",
            "QuinticReference",
            "Reference",
            "SineReference",
            "as_reference",
            "load_trajectory",
            "retime_waypoints",
        ),
        ".tasks",
    ),
}


def __getattr__(name: str):
    """``hmpc_pin.X`` for a name of :data:`__all__` (imported on first use, then cached)
    or a subpackage (``hmpc_pin.sim``)."""
    import importlib

    module = _LAZY.get(name)
    if module is not None:
        value = getattr(importlib.import_module(module, __name__), name)
        globals()[name] = value
        return value
    if not name.startswith("_"):
        try:
            return importlib.import_module(f"{__name__}.{name}")
        except ModuleNotFoundError as exc:
            if exc.name != f"{__name__}.{name}":
                raise
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


from ._version import __version__  # noqa: E402  (the ground floor: imports nothing)

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
    "RealtimeWarning",
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
