"""Franka FR3 and Panda over ``pylibfranka`` (FCI): the arm interface of the real-time
loop, its command filter, the move to the start and the checks before a motion.

``pylibfranka`` (extra ``franka``) is imported only when a :class:`FrankaArm` is made.
"""

from .arm import FrankaArm, error_names, import_franka
from .checks import MASS_TOLERANCE, check_joint_names, check_mass, check_mode, check_position
from .filter import FRANKA_TORQUE_LIMIT, MAX_STEP, CommandFilter
from .move import check_move, quintic, quintic_duration

__all__ = [
    "FRANKA_TORQUE_LIMIT",
    "MASS_TOLERANCE",
    "MAX_STEP",
    "CommandFilter",
    "FrankaArm",
    "check_joint_names",
    "check_mass",
    "check_mode",
    "check_move",
    "check_position",
    "error_names",
    "import_franka",
    "quintic",
    "quintic_duration",
]
