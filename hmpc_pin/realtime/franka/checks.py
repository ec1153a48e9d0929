"""What is checked before a Franka motion, on the robot's own state and model: nothing is
sent to the arm when one of them fails.

* the robot is in mode Idle (not Reflex, not a user stop, not guided);
* the config's arm has 7 joints named ``...joint1`` to ``...joint7`` in order (the FCI
  reports no names: the config's arm must be the robot's);
* the measured q lies inside the config arm's position limits;
* the config arm's :math:`M(q)` agrees with the robot's own model
  (``load_model().mass(state)``, the URDF it serves plus the end effector it reports):
  joint :math:`i` is refused when
  :math:`\\max_j |M_{ij} - M^\\mathrm{robot}_{ij}| > \\epsilon\\, M^\\mathrm{robot}_{ii}`
  (:data:`MASS_TOLERANCE`, 10 %: the observer takes a model error of that size, a wrong
  arm or a forgotten end effector is well beyond it).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ...exceptions import ArmError

__all__ = ["MASS_TOLERANCE", "check_joint_names", "check_mass", "check_mode", "check_position"]

FloatArray = NDArray[np.float64]

#: Relative tolerance of the mass-matrix check (module doc).
MASS_TOLERANCE = 0.10


def check_mode(mode_name: str) -> None:
    """Refuse a robot not in mode Idle (naming its mode and what to do)."""
    if mode_name == "Idle":
        return
    what = {
        "Reflex": "a reflex stopped its last motion: pass --recover (automatic error "
        "recovery) or recover it in Desk",
        "UserStopped": "the user stop is pressed: release it",
        "Guiding": "it is being guided by hand: release the guiding button",
        "Move": "another motion runs on it",
        "AutomaticErrorRecovery": "it is recovering from an error: wait and start again",
    }.get(mode_name, "open Desk, unlock the joints and activate FCI")
    raise ArmError(f"the robot is in mode {mode_name}, expected Idle: {what}. Nothing was sent")


def check_joint_names(names) -> None:
    """Refuse a config arm that is not a 7-joint Franka (``...joint1`` .. ``...joint7``)."""
    names = tuple(names)
    if len(names) != 7:
        raise ArmError(
            f"the config's arm has {len(names)} joints ({', '.join(names)}); a Franka arm "
            'has 7: use robot.model = "fr3" or "panda" (with its fingers locked)'
        )
    for i, name in enumerate(names):
        if not name.endswith(f"joint{i + 1}"):
            raise ArmError(
                f"the config's joint {i + 1} is {name!r}; expected the Franka's joint{i + 1} "
                "(e.g. fr3 'joint1'..'joint7', panda 'panda_joint1'..'panda_joint7')"
            )


def check_position(q: FloatArray, lower: FloatArray, upper: FloatArray, names) -> None:
    """Refuse a measured q outside ``[lower, upper]`` [rad] (naming the joint)."""
    for i in range(len(q)):
        if not lower[i] <= q[i] <= upper[i]:
            raise ArmError(
                f"joint {names[i]!r} stands at q={q[i]:.4f} rad, outside the config arm's "
                f"limits [{lower[i]:.4f}, {upper[i]:.4f}]; move it inside (Desk) first"
            )


def mass_errors(M_config: FloatArray, M_robot: FloatArray) -> FloatArray:
    """Per joint :math:`\\max_j |\\Delta M_{ij}| / M^\\mathrm{robot}_{ii}` (module doc)."""
    diff = np.abs(np.asarray(M_config) - np.asarray(M_robot)).max(axis=1)
    return diff / np.diag(M_robot)


def check_mass(
    M_config: FloatArray, M_robot: FloatArray, names, tolerance: float = MASS_TOLERANCE
) -> FloatArray:
    """Refuse when the config arm's M(q) differs from the robot's beyond ``tolerance``
    (naming the worst joint); returns the per-joint errors (:func:`mass_errors`)."""
    err = mass_errors(M_config, M_robot)
    i = int(np.argmax(err))
    if err[i] > tolerance:
        raise ArmError(
            f"the config's arm is not this robot: M(q) row of joint {names[i]!r} differs from "
            f"the robot's own model (load_model().mass) by {100 * err[i]:.1f} % of its M_ii "
            f"(tolerance {100 * tolerance:g} %); check robot.model (fr3 or panda) and the end "
            "effector the robot reports (Desk: end-effector settings). Nothing was sent"
        )
    return err
