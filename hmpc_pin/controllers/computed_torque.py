"""Computed-torque control, the classical reference (``computed-torque``, ``computed-torque-pid``).

Inverse dynamics with a PD (or PID) outer loop and no MPC, no observer:

.. math::

    v = \\mathrm{clip}\\big(\\ddot r + k_p e + k_d \\dot e + k_i {\\textstyle\\int} e\\,dt,\\;
        v_{\\min}, v_{\\max}\\big), \\qquad \\tau = M(q)\\,v + C\\dot q + G,
    \\qquad e = r - q,

run at the control period :math:`T_s` with the torque held over it, like the MPC.

Fair tuning (same bandwidth). By default :math:`k_p, k_d` are the MPC's own
unconstrained state-feedback gain: the first row of :math:`H^{-1}F` restricted to
:math:`x_0` (:mod:`hmpc_pin.mpc.condensed`), so the PD loop has exactly the closed-loop poles
of the unconstrained MPC, :math:`\\mathrm{eig}(A_d - B_d[k_p\\;k_d])`. For the paper's
settings (Nc = 1) that is :math:`k_p = 273.9\\,\\mathrm{s^{-2}}`,
:math:`k_d = 22.73\\,\\mathrm{s^{-1}}` (poles 0.879 ± 0.113j, ω_n ≈ 16.5 rad/s,
ζ ≈ 0.69). The PID keeps :math:`k_p, k_d` and adds the :math:`k_i` that minimises the
spectral radius of its discrete closed loop (:func:`fastest_integral_gain`: the fastest
decay of all three modes; 1.19·10³ s⁻³ for the paper's settings). Any gains are
checked to give a stable discrete closed loop. The same acceleration bounds as the MPC
(``v_min``, ``v_max``) apply, and the integral only accumulates while the joint is
not saturated (conditional-integration anti-windup).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..compensation.base import Compensation, NoCompensation, check_compensation
from ..exceptions import ConfigError, NonFiniteError
from ..model.robot import Robot
from ..mpc.condensed import CondensedMPC
from ..tasks.base import as_reference, check_reference_size
from .base import AppliedTorque, config_parts, not_reset
from .hierarchical import MPCSettings

__all__ = [
    "CTSettings",
    "ComputedTorque",
    "closed_loop_poles",
    "fastest_integral_gain",
    "mpc_feedback_gain",
]


def mpc_feedback_gain(mpc: CondensedMPC) -> tuple[float, float]:
    """The unconstrained MPC's feedback gain :math:`(k_p, k_d)` on the current state.

    The unconstrained minimiser is :math:`U^\\star = -H^{-1}F[x_0; \\bar r]`, so the applied
    input is :math:`v_0 = -k_p q_0 - k_d \\dot q_0 + (\\text{reference terms})`.
    """
    K = np.linalg.solve(mpc.H, mpc.F)[0, :2]
    return float(K[0]), float(K[1])


def closed_loop_poles(Ts: float, kp: float, kd: float, ki: float = 0.0) -> np.ndarray:
    """Poles of the discrete closed loop of one joint under the PD/PID law at period ``Ts``.

    State :math:`[e, \\dot e, I]` with ZOH double-integrator error dynamics and
    :math:`I_{k+1} = I_k + T_s e_k`; the integral state is dropped when ``ki == 0``.
    """
    A = np.array([[1.0, Ts, 0.0], [0.0, 1.0, 0.0], [Ts, 0.0, 1.0]])
    B = np.array([Ts * Ts / 2.0, Ts, 0.0])
    K = np.array([kp, kd, ki])
    Acl = A - np.outer(B, K)
    return np.linalg.eigvals(Acl if ki else Acl[:2, :2])


def fastest_integral_gain(Ts: float, kp: float, kd: float) -> float:
    """The :math:`k_i` minimising the spectral radius of :func:`closed_loop_poles`.

    Searched over :math:`k_i \\in [10^{-4}, 1]\\,k_p k_d` (Routh's bound of the continuous
    loop is :math:`k_p k_d`) on a log grid, then refined by golden-section search.
    """

    def radius(log_ki: float) -> float:
        return float(np.abs(closed_loop_poles(Ts, kp, kd, math.exp(log_ki))).max())

    grid = np.log(kp * kd) + np.linspace(math.log(1e-4), 0.0, 200)
    k = int(np.argmin([radius(x) for x in grid]))
    a, b = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
    g = (math.sqrt(5.0) - 1.0) / 2.0
    for _ in range(60):
        c, d = b - g * (b - a), a + g * (b - a)
        if radius(c) < radius(d):
            b = d
        else:
            a = c
    return math.exp(0.5 * (a + b))


@dataclass(frozen=True)
class CTSettings:
    """Settings of :class:`ComputedTorque`.

    Attributes:
        Ts: Control period [s].
        kp: Proportional gain [1/s²].
        kd: Derivative gain [1/s].
        ki: Integral gain [1/s³] (0 for the PD).
        v_min, v_max: Acceleration bounds [rad/s²], scalar or (n,).
    """

    Ts: float
    kp: float
    kd: float
    ki: float = 0.0
    v_min: np.ndarray | float = MPCSettings.v_min
    v_max: np.ndarray | float = MPCSettings.v_max

    @classmethod
    def matching(
        cls,
        mpc: MPCSettings,
        *,
        pid: bool = False,
        kp: float | None = None,
        kd: float | None = None,
        ki: float | None = None,
    ) -> CTSettings:
        """Gains of the same bandwidth as the MPC ``mpc`` (module docstring): ``kp``, ``kd``
        default to the MPC's unconstrained feedback gain; for ``pid``, ``ki`` defaults to
        :func:`fastest_integral_gain`; the PD has ``ki = 0``."""
        kp0, kd0 = mpc_feedback_gain(CondensedMPC(mpc.Ts, mpc.N, mpc.Nc, mpc.Q, mpc.R, mpc.P))
        kp = kp if kp is not None else kp0
        kd = kd if kd is not None else kd0
        if not pid:
            ki = 0.0
        elif ki is None:
            ki = fastest_integral_gain(mpc.Ts, kp, kd)
        return cls(mpc.Ts, kp, kd, ki, mpc.v_min, mpc.v_max)


class ComputedTorque(AppliedTorque):
    """Inverse dynamics + PD/PID outer loop, :math:`\\tau = M v + C\\dot q + G - \\hat d`.

    Args:
        robot: The controller's model.
        settings: :class:`CTSettings` (default: the PD matching the paper's MPC).
        compensation: The disturbance estimate cancelled in τ (default none).

    Attributes:
        kp, kd, ki: The gains in use [1/s², 1/s, 1/s³] (``ki = 0`` for the PD).
        disturbance_estimate: :math:`\\hat d_k` of the compensation [N·m] (zeros without).
        v, tau: Last commanded acceleration [rad/s²] and torque [N·m].

    Raises:
        ConfigError: The gains give an unstable discrete closed loop.
    """

    def __init__(
        self,
        robot: Robot,
        settings: CTSettings | None = None,
        compensation: Compensation | None = None,
    ):
        if settings is not None and not isinstance(settings, CTSettings):
            settings, compensation = config_parts(settings, robot, "ComputedTorque", "CTSettings")
        settings = settings if settings is not None else CTSettings.matching(MPCSettings())
        self.robot, self.settings, self.n = robot, settings, robot.nq
        n = robot.nq
        self.v_min = np.broadcast_to(np.asarray(settings.v_min, dtype=float), (n,)).astype(float)
        self.v_max = np.broadcast_to(np.asarray(settings.v_max, dtype=float), (n,)).astype(float)
        self.kp, self.kd, self.ki = float(settings.kp), float(settings.kd), float(settings.ki)
        poles = closed_loop_poles(settings.Ts, self.kp, self.kd, self.ki)
        if np.abs(poles).max() >= 1.0:
            raise ConfigError(
                "controller.computed_torque",
                f"gains kp={self.kp:g}, kd={self.kd:g}, ki={self.ki:g} give discrete poles "
                f"{np.round(poles, 4).tolist()} at Ts={settings.Ts:g}; expected all inside the "
                "unit circle: lower the gains",
            )
        self.compensation: Compensation = (
            compensation if compensation is not None else NoCompensation(n)
        )
        check_compensation(self.compensation, robot, settings.Ts, "ComputedTorque")
        self.disturbance_estimate = np.zeros(n)
        self.integral = np.zeros(n)
        self.v = np.zeros(n)
        self.tau = np.zeros(n)
        self._started = False
        self._reference: object = None
        self._ref: object = None

    @property
    def Ts(self) -> float:
        """Control period [s]."""
        return self.settings.Ts

    def reset(self, q0: np.ndarray, dq0: np.ndarray) -> None:
        """Start a new run (the integral restarts at zero)."""
        q0 = self.robot.check_vector("q0", q0)
        dq0 = self.robot.check_vector("dq0", dq0)
        self.compensation.reset(q0, dq0)
        self.disturbance_estimate = np.zeros(self.n)
        self._started = False
        self._was_reset = True
        self.integral = np.zeros(self.n)
        self.v = np.zeros(self.n)
        self.tau = np.zeros(self.n)

    def step(self, t: float, q: np.ndarray, dq: np.ndarray, reference) -> np.ndarray:
        """The torque for the measured state at ``t`` (reference needs ``acceleration(t)``).

        Args:
            t: Time [s].
            q, dq: Measured joint positions [rad] and velocities [rad/s], shape (n,).
            reference: Object with ``sample(t) -> (r, ṙ)`` and ``acceleration(t) -> r̈``.

        Returns:
            τ [N·m], shape (n,).
        """
        if not math.isfinite(t):
            raise NonFiniteError("t", t)
        q = self.robot.check_vector("q", q)
        dq = self.robot.check_vector("dq", dq)
        if reference is not self._reference:
            if not getattr(self, "_was_reset", False):
                raise not_reset(self)
            check_reference_size(reference, self.n, "ComputedTorque.step")
            self._ref = as_reference(reference)
            self._reference = reference
        r, dr = self._ref.sample(t)  # type: ignore[attr-defined]
        ddr = self._ref.acceleration(t)  # type: ignore[attr-defined]
        e = r - q
        v_free = ddr + self.kp * e + self.kd * (dr - dq) + self.ki * self.integral
        robot = self.robot
        M = robot.mass_matrix(q)
        nle = robot.nonlinear_effects(q, dq)
        if self._started:
            self.disturbance_estimate = self.compensation.update(
                M, nle, q, dq, self._applied(), self.v
            )
        else:
            self.disturbance_estimate = self.compensation.estimate.copy()
        self._started = True
        self.v = v = np.clip(v_free, self.v_min, self.v_max)
        if self.ki:
            self.integral += np.where(v == v_free, self.settings.Ts * e, 0.0)
        tau = M @ v + nle
        tau -= self.disturbance_estimate
        self.tau = tau
        return tau.copy()
