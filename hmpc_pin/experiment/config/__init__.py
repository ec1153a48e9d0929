"""The configuration, one module per TOML table (do-mpc style: one settings class per
component), assembled by :func:`~hmpc_pin.experiment.config.experiment.load_config`.

``[robot]`` :mod:`.robot` · ``[controller]`` (and its tables) :mod:`.controller`
(``[controller.friction]`` :mod:`~hmpc_pin.experiment.config.friction`) ·
``[plant]`` :mod:`.plant` · ``[reference]`` :mod:`.reference` · ``[disturbance]``
:mod:`.disturbance` · ``[simulation]`` :mod:`.simulation` · ``[sweep]`` :mod:`.sweep` ·
``[sweep.sensing]`` :mod:`.sensing` · ``[collision]`` :mod:`.collision` ·
``[realtime]`` :mod:`.realtime` · ``[ros]`` :mod:`.ros` · ``[workspace]``
:mod:`.workspace` · the whole file
:mod:`.experiment`; the value converters shared by all of them ``_fields``; the
spellings of earlier versions :mod:`.legacy`. Which ``[controller]`` keys apply to which
controller × compensation is :mod:`hmpc_pin.experiment.combos`.
"""

from .collision import (
    CollisionConfig,
)
from .controller import (
    COMPENSATIONS,
    CONTROLLERS,
    NATIVE_COMPENSATIONS,
    ComputedTorqueConfig,
    ConstraintConfig,
    ControllerConfig,
    ISMConfig,
    ObserverConfig,
    parse_combination,
)
from .disturbance import (
    FRICTION_SIGNS,
    DisturbanceConfig,
    FrictionConfig,
    PulseConfig,
)
from .experiment import (
    ExperimentConfig,
    load_config,
)
from .friction import (
    FrictionModelConfig,
)
from .legacy import CONTROLLER_KINDS, DEFAULT_COMPENSATION, KIND_ALIASES
from .plant import (
    ENGINES,
    PINOCCHIO_INTEGRATORS,
    MuJoCoConfig,
    ObstacleConfig,
    PlantConfig,
)
from .realtime import (
    RealtimeConfig,
)
from .reference import (
    POSE_PATHS,
    REFERENCE_TABLES,
    SINE_DEFAULTS,
    SINE_KEYS,
    CartesianConfig,
    PoseConfig,
    ReferenceConfig,
    TrajectoryConfig,
    WaypointsConfig,
)
from .robot import (
    RobotConfig,
)
from .ros import DISCOVERY_RANGES, RosConfig
from .sensing import (
    SensingConfig,
)
from .simulation import (
    SimulationConfig,
)
from .sweep import (
    CONDITIONS,
    SweepConfig,
)
from .workspace import WorkspaceConfig

__all__ = [
    "COMPENSATIONS",
    "CONDITIONS",
    "CONTROLLERS",
    "CONTROLLER_KINDS",
    "DEFAULT_COMPENSATION",
    "DISCOVERY_RANGES",
    "ENGINES",
    "FRICTION_SIGNS",
    "KIND_ALIASES",
    "NATIVE_COMPENSATIONS",
    "PINOCCHIO_INTEGRATORS",
    "POSE_PATHS",
    "REFERENCE_TABLES",
    "SINE_DEFAULTS",
    "SINE_KEYS",
    "CartesianConfig",
    "CollisionConfig",
    "ComputedTorqueConfig",
    "ConstraintConfig",
    "ControllerConfig",
    "DisturbanceConfig",
    "ExperimentConfig",
    "FrictionConfig",
    "FrictionModelConfig",
    "ISMConfig",
    "MuJoCoConfig",
    "ObserverConfig",
    "ObstacleConfig",
    "PlantConfig",
    "PoseConfig",
    "PulseConfig",
    "RealtimeConfig",
    "ReferenceConfig",
    "RobotConfig",
    "RosConfig",
    "SensingConfig",
    "SimulationConfig",
    "SweepConfig",
    "TrajectoryConfig",
    "WaypointsConfig",
    "WorkspaceConfig",
    "load_config",
    "parse_combination",
]
