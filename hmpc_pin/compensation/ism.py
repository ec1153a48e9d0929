"""Integral sliding mode (ISM) loop per joint: the ``hmpc-ism`` baseline (Incremona et al. 2017).

After inverse dynamics every joint is a double integrator driven by the commanded
acceleration plus the matched disturbance :math:`\\tilde d = M^{-1} d`
[rad/s²]. The MPC's acceleration :math:`v` defines the *nominal* evolution of the
joint velocity; the sliding variable measures how far the real velocity has drifted
from it,

.. math::

    \\sigma(t) = \\dot q(t) - \\dot q(0) - \\int_0^t v(s)\\,ds
    \\quad\\Rightarrow\\quad \\dot\\sigma = u_{\\mathrm{ism}} + \\tilde d,

and the discontinuous term :math:`u_{\\mathrm{ism}} = -K\\,\\mathrm{sgn}(\\sigma)` with
:math:`K > \\sup|\\tilde d|` keeps :math:`\\sigma = 0` from the start (no reaching phase:
:math:`\\sigma(0) = 0`). The torque is :math:`\\tau = M(v + u_{\\mathrm{ism}}) + C\\dot q + G`.

Discrete time (the loop runs at the control period :math:`T_s`, like the MPC):
:math:`\\sigma_k = \\dot q_k - \\dot q_0 - T_s\\sum_{j<k} v_j` and the term is held over the
period, so :math:`\\sigma` chatters with an amplitude of about :math:`K T_s` and τ switches
by :math:`2 M_{ii} K` between periods — the chattering the NDO scheme avoids.

Boundary layer (``hmpc-ism-bl``): :math:`\\mathrm{sgn}(\\sigma)` is replaced by
:math:`\\mathrm{sat}(\\sigma/\\varphi)`, a linear loop of gain :math:`K/\\varphi` inside
:math:`|\\sigma| < \\varphi`; the default :math:`\\varphi = K T_s` (one period's
chattering amplitude) gives :math:`T_s K/\\varphi = 1`, inside the discrete stability
limit 2.
"""

from __future__ import annotations

import numpy as np

from ..exceptions import ConfigError

__all__ = ["IntegralSlidingMode"]


class IntegralSlidingMode:
    """Discrete-time integral sliding mode term, one per joint.

    Args:
        n: Number of joints.
        Ts: Control period [s].
        gain: Switching gain K [rad/s²], scalar or (n,).
        boundary_layer: Width φ [rad/s] of the saturation replacing sgn; ``None`` for
            the pure sign (discontinuous) law.

    Attributes:
        sigma: The sliding variable σ_k [rad/s], shape (n,).
        u: The last ISM acceleration :math:`u_{\\mathrm{ism}}` [rad/s²], shape (n,).
        estimate: The torque the term adds, written as a disturbance estimate
            :math:`\\hat d = -M u_{\\mathrm{ism}}` [N·m] so that
            :math:`\\tau = M v + C\\dot q + G - \\hat d` as for the observers.
    """

    def __init__(self, n: int, Ts: float, gain, boundary_layer: float | None = None):
        if boundary_layer is not None and not boundary_layer > 0:
            raise ConfigError(
                "boundary_layer", f"got {boundary_layer!r}; expected a width > 0 [rad/s] or None"
            )
        self.n = n
        self.Ts = float(Ts)
        self.K = np.broadcast_to(np.asarray(gain, dtype=float), (n,)).copy()
        self.boundary_layer = boundary_layer
        self.dq0 = np.zeros(n)
        self.nominal = np.zeros(n)  # T_s Σ_{j<k} v_j
        self.sigma = np.zeros(n)
        self.u = np.zeros(n)
        self.estimate = np.zeros(n)

    def reset(self, q0: np.ndarray, dq0: np.ndarray) -> None:
        """Start with σ = 0 at the initial velocity ``dq0`` (``q0`` unused)."""
        self.dq0 = np.array(dq0, dtype=float)
        self.nominal = np.zeros(self.n)
        self.sigma = np.zeros(self.n)
        self.u = np.zeros(self.n)
        self.estimate = np.zeros(self.n)

    def switching(self, sigma: np.ndarray) -> np.ndarray:
        """sgn(σ) (sgn 0 = 0), or sat(σ/φ) with a boundary layer."""
        if self.boundary_layer is None:
            return np.sign(sigma)
        return np.clip(sigma / self.boundary_layer, -1.0, 1.0)

    def update(
        self,
        M: np.ndarray,
        nle: np.ndarray,
        q: np.ndarray,
        dq: np.ndarray,
        tau_prev: np.ndarray,
        v_prev: np.ndarray,
    ) -> np.ndarray:
        """Advance one period and return :math:`\\hat d_k = -M u_k` [N·m] (the
        :class:`~hmpc_pin.compensation.base.Compensation` protocol; ``nle``, ``q`` and
        ``tau_prev`` unused).

        Args:
            M: Inertia matrix at the measured state [kg·m²].
            nle: :math:`C\\dot q + G` [N·m] (unused).
            q: Measured joint position [rad] (unused).
            dq: Measured joint velocity [rad/s].
            tau_prev: Torque of the period that just ended [N·m] (unused).
            v_prev: The MPC acceleration held over the period that just ended [rad/s²]
                (its nominal part only, without the ISM term).
        """
        self.nominal += self.Ts * v_prev
        self.sigma = dq - self.dq0 - self.nominal
        self.u = -self.K * self.switching(self.sigma)
        self.estimate = -(M @ self.u)
        return self.estimate
