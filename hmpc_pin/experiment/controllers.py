"""The controller of a ``[controller]`` table: its settings, compensation and soft limits.

The part of the builder that turns a validated ``ControllerConfig`` into the arguments of a
controller class. It registers :func:`controller_parts` with the controllers
(:func:`~hmpc_pin.controllers.base.register_config_builder`) for the deprecated call of
version 0.1, ``HierarchicalMPC(robot, ControllerConfig)``: the controllers and the config
import nothing of the builder.
"""

from __future__ import annotations

import numpy as np

from ..compensation.bandwidth import bandwidth_posture, implied_bandwidth
from ..compensation.base import Compensation
from ..compensation.registry import build_compensation, compensation_spec
from ..controllers.base import register_config_builder
from ..controllers.computed_torque import CTSettings
from ..controllers.hierarchical import MPCSettings, state_limits
from ..controllers.registry import MPC_KEYS, controller_spec
from ..exceptions import ConfigError, URDFError
from ..model.robot import Robot
from ..mpc.condensed import StateLimits
from .combos import OBSERVERS
from .config.controller import ControllerConfig

__all__ = [
    "bandwidth_posture",
    "controller_limits",
    "controller_parts",
    "make_compensation",
    "mpc_settings",
    "observer_bandwidth",
    "uses_observer",
]


def mpc_settings(cc, n: int) -> MPCSettings:
    """:class:`~hmpc_pin.controllers.mpc_settings.MPCSettings` of ``[controller]``: the
    table's values, MPCSettings' own defaults for those that do not apply (the settings
    of ``hmpc`` for ``computed-torque*``, ``model_at`` without an observer)."""
    v_min, v_max = cc.bounds(n)
    given = {name: getattr(cc, name) for name in MPC_KEYS}
    if cc.observer is not None:
        given["model_at"] = cc.observer.model_at
    return MPCSettings(
        Ts=cc.Ts,
        N=cc.N,
        Nc=cc.Nc,
        Q=cc.Q,
        R=cc.R,
        P=cc.P,
        v_min=v_min,
        v_max=v_max,
        **{name: value for name, value in given.items() if value is not None},
    )


def controller_limits(cc, robot: Robot) -> StateLimits | None:
    """The soft state limits of ``[controller.constraints]`` for ``robot``: ``None`` if
    off or if the controller takes none
    (:attr:`~hmpc_pin.controllers.registry.ControllerSpec.limits`)."""
    if not controller_spec(cc.kind).limits:
        return None
    con = cc.constraints
    if con is None or not con.enabled:
        return None
    over = con.overrides(robot.nq)
    lower = over["lower"] if over["lower"] is not None else robot.lower
    upper = over["upper"] if over["upper"] is not None else robot.upper
    bad = np.flatnonzero(np.asarray(lower) >= np.asarray(upper))
    if bad.size and con.position:
        i = int(bad[0])
        if over["lower"] is not None or over["upper"] is not None:
            key = "lower" if over["lower"] is not None else "upper"
            raise ConfigError(
                f"controller.constraints.{key}",
                f"joint {robot.joint_names[i]!r}: lower={lower[i]:g} >= upper={upper[i]:g}; "
                "expected lower < upper",
            )
        what = "a zero" if lower[i] == upper[i] else "an inverted"
        raise URDFError(
            robot.source,
            f"joint {robot.joint_names[i]!r} has {what} position range <limit lower="
            f'"{lower[i]:g}" upper="{upper[i]:g}">; expected lower < upper. Fix the URDF, '
            "override the range in [controller.constraints] lower/upper, or set "
            "controller.constraints.position = false (no position limits)",
        )
    return state_limits(
        robot,
        lower=over["lower"],
        upper=over["upper"],
        velocity=over["velocity_limit"],
        position_on=con.position,
        velocity_on=con.velocity,
        slack_weight=con.slack_weight,
        slack_linear_weight=con.slack_linear_weight,
    )


def observer_bandwidth(robot: Robot, cc, posture: np.ndarray | None = None) -> np.ndarray | None:
    """Per joint, the bandwidth [1/s] the config ``cc`` asks of its observer (configured,
    or implied by its gain at ``posture``, default :func:`bandwidth_posture`); ``None``
    without an observer. Read from the config, before anything is built; the bandwidth of
    a built observer is :func:`~hmpc_pin.compensation.bandwidth.compensation_bandwidth`."""
    obs = cc.observer
    if obs is None:
        return None
    n = robot.nq
    if obs.bandwidth is not None:
        return np.broadcast_to(obs.bandwidth, (n,)).astype(float)
    Y = compensation_spec(cc.compensation).Y
    if Y is None:  # the momentum observer: its gain is its bandwidth
        return np.full(n, obs.gain)
    M0 = robot.mass_matrix(bandwidth_posture(robot) if posture is None else posture)
    return implied_bandwidth(obs.gain * Y(n), M0)


def make_compensation(robot: Robot, cc, posture: np.ndarray | None = None) -> Compensation:
    """The compensation ``cc.compensation`` names, with its table's settings (a
    bandwidth made exact at ``posture`` [rad], default :func:`bandwidth_posture`), as the
    registry builds it (:func:`~hmpc_pin.compensation.registry.build_compensation`)."""
    spec = compensation_spec(cc.compensation)
    table = getattr(cc, spec.table) if spec.table is not None else None
    return build_compensation(spec.name, robot, cc.Ts, table, posture)


def controller_parts(robot: Robot, cc, posture: np.ndarray | None = None) -> tuple:
    """The arguments after ``robot`` of the controller class of ``cc``: for ``hmpc``
    ``(MPCSettings, compensation, limits)``, for ``computed-torque*``
    ``(CTSettings, compensation)``."""
    compensation = make_compensation(robot, cc, posture)
    settings = mpc_settings(cc, robot.nq)
    spec = controller_spec(cc.kind)
    if spec.mpc:
        return settings, compensation, controller_limits(cc, robot)
    ct = cc.computed_torque
    gains = CTSettings.matching(settings, pid=spec.pid, kp=ct.kp, kd=ct.kd, ki=ct.ki)
    return gains, compensation


register_config_builder(ControllerConfig, controller_parts)

#: The name of :func:`controller_limits` before version 0.3 (imported by callers).
_limits = controller_limits


def uses_observer(cc: ControllerConfig) -> bool:
    """Whether the compensation of ``cc`` is an observer (chen, general, momentum)."""
    return cc.compensation in OBSERVERS
