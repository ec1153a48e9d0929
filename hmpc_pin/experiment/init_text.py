"""The TOML text ``hmpc-pin init`` writes for an arm (:mod:`hmpc_pin.experiment.init`):
the decisions of an :class:`~hmpc_pin.experiment.init.InitPlan`, table by table, each
with the comment that says why.

Every function takes the plan ``p`` (an :class:`~hmpc_pin.experiment.init.InitPlan`, whose
attributes it reads) and returns the lines of its part of the file.
"""

from __future__ import annotations

import json
import re
import textwrap

import numpy as np

from ..compensation.observers import DEFAULT_GAIN
from .init_choices import (
    LATENCY,
    MODEL_AT_LINES,
    PERIODS,
    PLANT_STEPS,
    PULSE_CENTER,
    PULSE_SIGMA,
    ZOH_GAIN_MAX,
    ZOH_X_MAX,
)
from .posture import PATH_SAMPLES
from .posture import path as sine_path

__all__ = ["render", "vec"]


def _wrapped(text: str) -> list[str]:
    """``text`` as comment lines of at most 88 characters, continued lines indented."""
    return textwrap.wrap(text, 88, initial_indent="# ", subsequent_indent="#   ")


def _header_lines(p) -> list[str]:
    """The file's opening comment: what the experiment does and which joints it controls
    (continuous and mimic joints named)."""
    robot = p.robot
    lines = [
        f"# {p.name}: written by `hmpc-pin init` (hmpc_pin.experiment.init). Every joint",
        f"# tracks a sine around the reference posture ({p.posture_source})",
        "# under inertia-scaled friction and torque pulses; the URDF limits are soft state",
        "# constraints of every joint's MPC, the URDF effort limits saturate the plant.",
    ]
    lines += _wrapped(f"Controlled ({robot.nq}): {', '.join(robot.joint_names)}")
    if robot.continuous_joints:
        lines += _wrapped(
            "Continuous joints (revolute, no position limit, the angle does not wrap): "
            + ", ".join(robot.continuous_joints)
        )
    if robot.mimic_joints:
        lines += _wrapped(
            "Mimic joints (follow their leader, not controlled on their own): "
            + ", ".join(f"{f} = {m:g}*{j} + {o:g}" for f, (j, m, o) in robot.mimic_joints.items())
        )
    return lines


def _robot_lines(p, stem: str) -> list[str]:
    """The name, the description and the ``[robot]`` table (with the locked joints)."""
    n = p.robot.nq
    key, value = p.source
    lines = [
        f'name = "{stem}_init"',
        f'description = "{p.name}, {n} joints: sine around the reference posture (hmpc-pin init)"',
        "",
        "[robot]",
        f'{key} = "{value}"',
        "gravity = 9.81",
    ]
    if p.locked:
        lines += [
            "",
            "# Gripper, finger, hand and wheel joints are locked at the reference posture",
            "# (not controlled; their mass still loads the arm). Delete a line to control",
            "# that joint (a mimic follower goes with its leader).",
            "[robot.locked_joints]",
            *(f'"{j}" = {round(v, 6):g}' for j, v in p.locked.items()),
        ]
    return lines


def _period_lines(p) -> list[str]:
    """Why the control period is what it is (the URDF's damping, or a trial at 10 ms that
    tracked too coarsely), then ``Ts``, ``N`` and ``Nc``."""
    lines = []
    if p.periods() != PERIODS:  # the URDF's damping rules out the longer periods
        x = p.Ts / p.damping_tau
        lines += [
            f"# The URDF damping of {p.damped_joint!r} (time constant {1e3 * p.damping_tau:.3g} "
            "ms): periods up to",
            f"# {1e3 * ZOH_X_MAX * p.damping_tau:.3g} ms keep its zero-order-hold gain "
            f"x/(1 - e^-x), x = Ts/T, within {ZOH_GAIN_MAX:g}",
            f"# (here x = {x:.3g}); "
            + (
                "the shortest period offered."
                if p.Ts == PERIODS[-1] and x > ZOH_X_MAX
                else "the longest such period that tracks."
            ),
        ]
    elif p.Ts != 0.01:
        lines += [
            "# 10 ms (the paper's) tracks worse than 2.5e-3 rad on this arm in a 2 s trial:",
            "# the torque is held over a period while M(q) changes (error ~ Ts^3).",
        ]
    return [*lines, f"Ts = {p.Ts:g}", "N = 10", "Nc = 1"]


def _observer_lines(p) -> list[str]:
    """The compensation and the ``[controller.observer]`` table: Chen's NDO on a planar
    serial chain, else the general NDO with its bandwidth and the declared latency."""
    if p.compensation == "chen":
        return [
            'compensation = "chen"              # planar serial chain: the paper\'s NDO',
            "",
            "[controller.observer]",
            f"gain = {DEFAULT_GAIN}",
            *MODEL_AT_LINES,
        ]
    return [
        'compensation = "general"           # valid on any arm (Chen\'s Y only on planar',
        "                                   # chains)",
        f"latency = {LATENCY:g}                    # [s] age of the measurements: one 1 kHz cycle;",
        "                                   # set your driver's (guide: Sensing and latency)",
        "",
        "[controller.observer]",
        f"bandwidth = {p.bandwidth:g}                 # [1/s] per joint: Ts x bandwidth = "
        f"{p.Ts * p.bandwidth:.3g}",
        *MODEL_AT_LINES,
    ]


def _controller_lines(p) -> list[str]:
    """The ``[controller]`` table: the period, the URDF's joint dynamics, the acceleration
    bounds the effort limits pay for, the observer and, without usable position limits,
    ``[controller.constraints]``."""
    lines = ["", "[controller]", *_period_lines(p)]
    if not p.joint_dynamics:
        lines += [
            "# The URDF's joint damping is too stiff to simulate (see [plant]); on the real",
            "# arm, which applies it, set this to true (the default) to compensate it.",
            "joint_dynamics = false",
        ]
    if np.any(p.v_max < 100.0):
        lines += [
            "# Acceleration bounds [rad/s² or m/s²] the URDF effort limits can pay for at the",
            "# offset posture (sum_k |M_jk| v_k + |G_j| <= 0.9 effort_j; at most the paper's 100)",
            f"v_min = {vec(-p.v_max, 2)}",
            f"v_max = {vec(p.v_max, 2)}",
        ]
    lines += _observer_lines(p)
    if not p.position_limits:
        lines += [
            "",
            "[controller.constraints]",
            f"# The URDF gives {', '.join(p.bad_ranges)} a zero or inverted position range,",
            "# i.e. no usable limits: none are imposed.",
            "position = false",
        ]
    return lines


def _task_lines(p, duration: float) -> list[str]:
    """The ``[reference]`` sine, the ``[disturbance]`` tables (inertia-scaled friction and
    pulses) and ``[simulation]`` (with how to identify the friction from the run)."""
    n = p.robot.nq
    kinds = sorted(set(p.robot.joint_kinds))
    unit = " / ".join({"revolute": "rad", "prismatic": "m"}[k] for k in kinds)
    return [
        "[reference]",
        'kind = "sine"',
        f"amplitude = {vec(p.amplitude)}     # [{unit}]",
        f"frequency = {p.frequency:.4g}                  # [Hz], peak speed <= half the URDF "
        "velocity limits",
        f"offset = {vec(p.offset)}",
        "",
        "[disturbance]",
        'scale = "inertia"                  # coefficients x M_ii(q0)',
        "",
        "[disturbance.friction]",
        "viscous = 2.0",
        "coulomb = 0.5",
        "",
        "[disturbance.pulse]",
        "amplitude = 1.0",
        f"center = {vec([PULSE_CENTER + (j % 9) for j in range(n)])}",
        f"sigma = {PULSE_SIGMA:g}",
        "",
        "[simulation]",
        *_identify_lines(p, duration),
        f"duration = {duration:g}",
        "# Start on the reference: position r(0) (the default) and velocity dr/dt(0).",
        f"dq0 = {vec(2 * np.pi * p.frequency * p.amplitude, 6)}",
        "",
    ]


def render(p, duration: float) -> str:
    """The config's text for the plan ``p``, ``duration`` [s] long.

    Args:
        p: The :class:`~hmpc_pin.experiment.init.InitPlan` (its trial run done).
        duration: The run's length [s].
    """
    stem = re.sub(r"[^A-Za-z0-9_]+", "_", p.name)
    lines = [
        *_header_lines(p),
        *_robot_lines(p, stem),
        *_controller_lines(p),
        "",
        *_plant_lines(p),
        *_workspace_lines(p),
        *_task_lines(p, duration),
    ]
    return "\n".join(lines)


def _identify_lines(p, duration: float) -> list[str]:
    """What a run needs for ``hmpc-pin identify`` to fit the friction, as comments."""
    need, after = p.identify_duration, p.identify_after
    stem = re.sub(r"[^A-Za-z0-9_]+", "_", p.name)
    longer = f" --duration {need:g}" if duration < need else ""
    return [
        f"# Friction identification (hmpc-pin identify) needs {need:g} s"
        + (f", longer than this run's {duration:g} s" if longer else "")
        + ": the pulses",
        f"# are over at {after:.3g} s, then a period of the sine moves every joint both ways:",
        f"#   hmpc-pin run FILE{longer} --out out; hmpc-pin identify out/{stem}_init.npz "
        f"--after {after:.3g}",
    ]


def _workspace_lines(p) -> list[str]:
    """The ``[workspace]`` table init placed the sine in (nothing without collision
    geometry)."""
    ws = p.workspace
    if ws is None:
        return []
    scan = ws.scan(sine_path(p.offset, p.amplitude, 4 * PATH_SAMPLES - 3))
    low = min(scan.clearance.items(), key=lambda kv: kv[1], default=None)
    s = p.workspace_settings
    lines = [
        "[workspace]",
        "# The plane the arm is mounted on (its table), in the URDF's root frame: along the",
        "# whole sine every moving link's collision geometry keeps `margin` above it and",
        "# clear of the other links"
        + (" (pairs the SRDF disables excepted)" if ws.srdf is not None else "")
        + "; `hmpc-pin check` flags a reference that does not.",
    ]
    if p.plane_note:
        note = p.plane_note[0].upper() + p.plane_note[1:] + "."
        lines += textwrap.wrap(note, 86, initial_indent="# ", subsequent_indent="# ")
    if low is not None:
        lines.append(f"# Lowest along the sine: {low[0]} at {low[1]:.3g} m above the plane.")
    pairs = []
    if s.allowed_pairs:
        listed = ", ".join(f"[{json.dumps(a)}, {json.dumps(b)}]" for a, b in s.allowed_pairs)
        pairs = [
            "# Links touching at the reference posture: taken as touching by design (as",
            "# MoveIt's setup assistant disables them), not checked.",
            f"allowed_pairs = [{listed}]",
        ]
    return [
        *lines,
        f"height = {s.height:g}                       # [m]",
        f"normal = {vec(s.normal)}",
        f"margin = {s.margin:g}                    # [m]",
        *([] if s.self_collision else ["self_collision = false"]),
        *pairs,
        "",
    ]


def _plant_lines(p) -> list[str]:
    """The ``[plant]`` table when the URDF's joint damping needs it (else nothing)."""
    if p.joint_dynamics and p.plant_dt == PLANT_STEPS[0]:
        return []
    tau = 1.0 / p.damping_rate
    if p.joint_dynamics:
        return [
            "[plant]",
            f"# The URDF's joint damping (time constant down to {tau:.3g} s) needs a short",
            "# step of the RK4 plant.",
            f"dt = {p.plant_dt:g}",
            "",
        ]
    return [
        "[plant]",
        f"# The URDF's joint damping (time constant down to {tau:.3g} s) is too stiff for",
        f"# the RK4 plant even at dt = {PLANT_STEPS[-1]:g} s: the simulated arm leaves it out.",
        "joint_dynamics = false",
        "",
    ]


def vec(values, digits: int = 4) -> str:
    """``values`` as a TOML array, each rounded to ``digits`` decimals."""
    return "[" + ", ".join(f"{round(float(v), digits):g}" for v in values) + "]"
