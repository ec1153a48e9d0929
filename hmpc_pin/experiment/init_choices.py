"""What ``hmpc-pin init`` chooses from (:mod:`hmpc_pin.experiment.init`): the control
periods and plant steps it tries, the sine's amplitude and frequency, the postures and the
joints it locks, the observer's bandwidth and declared latency, the disturbance's pulses
and the trial run's pass mark."""

from __future__ import annotations

import re

__all__ = [
    "AMPLITUDE",
    "AMPLITUDE_SCALES",
    "BANDWIDTH_PERIODS",
    "FREQUENCY",
    "LATENCY",
    "LOCK_PATTERN",
    "MODEL_AT_LINES",
    "PERIODS",
    "PLANT_STEPS",
    "POSTURES",
    "PULSE_CENTER",
    "PULSE_SIGMA",
    "TRIAL",
    "TRIAL_RMS",
    "ZOH_GAIN_MAX",
    "ZOH_X_MAX",
]

#: The RK4 plant steps ``init`` chooses from [s] (the first that suits the URDF damping).
PLANT_STEPS = (1e-3, 5e-4, 2e-4, 1e-4, 5e-5, 2e-5, 1e-5)
#: The general observer's bandwidth ``init`` writes, times Ts (Ts·ω = 10).
BANDWIDTH_PERIODS = 10.0
#: The observer's model at the start of the period (the state the held torque was computed
#: from): its estimate is then the correction Eq (4) needs for the next period.
MODEL_AT_LINES = [
    'model_at = "start"                 # M, C dq + G where the held torque was computed',
    "                                   # (guide: Joint dynamics, the observer's model)",
]

#: The measurement latency ``init`` declares [s]: one cycle of a 1 kHz interface.
LATENCY = 0.001

#: Joints locked by ``init`` (case-insensitive search in the joint name).
LOCK_PATTERN = re.compile(
    r"finger|gripper|hand|thumb|index|middle|ring|little|pinky|palm|jaw|claw|knuckle|wheel|caster"
    r"|suspension",
    re.IGNORECASE,
)
#: Reference postures looked for in an SRDF, in order, after the loader's own.
POSTURES = ("default", "half_sitting", "ready", "home", "standing", "arm_up", "neutral")
AMPLITUDE = {"revolute": 0.3, "prismatic": 0.05}  # [rad], [m]
#: The first torque pulse's centre [s] (joint j's at PULSE_CENTER + j mod 9) and the
#: pulses' standard deviation [s].
PULSE_CENTER, PULSE_SIGMA = 1.0, 0.3
FREQUENCY = 0.1  # [Hz]
#: Amplitude scales tried, in order, until gravity along the sine fits the effort limits.
AMPLITUDE_SCALES = (1.0, 0.5, 0.25)
#: Control periods tried, in order [s].
PERIODS = (0.01, 0.005, 0.002)
#: The largest zero-order-hold gain g = x/(1 − e^−x), x = Ts/T_j, a damped joint may need
#: at the chosen Ts (g = 2 at x = 1.594): the period's torque correction for the damping
#: is then at most the inertial torque itself (module docstring, "Control period").
ZOH_GAIN_MAX = 2.0
#: x at which g(x) = :data:`ZOH_GAIN_MAX` (by bisection; a test checks it).
ZOH_X_MAX = 1.5936242600400397
#: The trial run's pass mark, RMS error over its second half [rad or m].
TRIAL_RMS = 2.5e-3
#: The trial run's length [s].
TRIAL = 2.0
