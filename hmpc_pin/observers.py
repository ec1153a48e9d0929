"""Nonlinear disturbance observer (NDO), Eq (6)–(18) and (28)–(30).

Continuous form (Eq 13), with the auxiliary state :math:`z = \\hat d - p`:

.. math::

    \\dot z = -L z + L\\,(C\\dot q + G - \\tau - p), \\qquad \\hat d = z + p,

where :math:`p(q,\\dot q) = c\\,Y\\dot q` and :math:`L(q) = c\\,Y M(q)^{-1}` so that
:math:`\\dot p = L M \\ddot q` (Eq 9). The estimation error :math:`w = d - \\hat d`
then obeys :math:`\\dot w = -L w` for a constant disturbance (Eq 18).

Two choices of :math:`Y` are offered:

* ``"chen"``: :math:`Y` is the lower-triangular matrix of ones (Eq 28–30), the
  paper's design, proven for planar serial arms.
* ``"diagonal"``: :math:`Y = I` (:math:`p = c\\dot q`, :math:`L = cM^{-1}`), the
  general design; :math:`L` is then similar to the positive-definite
  :math:`M^{-1/2}\\,c\\,M^{-1/2}`, so the frozen-time error dynamics are stable on any arm.

Discretisation (SPEC §2). At the control period :math:`T_s` the observer is
integrated with backward Euler, which is unconditionally stable for any gain:

.. math::

    (I + T_s L_k)\\,z_k = z_{k-1} + T_s L_k\\,(n_k - \\tau_{k-1} - p_k),

with :math:`n_k = C\\dot q + G` at the measured state and :math:`\\tau_{k-1}` the
torque held over the last period. Explicit (forward) Euler is available for
comparison only: it diverges once :math:`T_s c\\,\\lambda_{\\max}(Y M^{-1}) > 2`.
"""

from __future__ import annotations

import numpy as np

__all__ = ["DisturbanceObserver", "observer_matrix"]

OBSERVER_KINDS = ("chen", "diagonal")
DISCRETIZATIONS = ("implicit", "explicit")


def observer_matrix(kind: str, n: int) -> np.ndarray:
    """Return the constant matrix :math:`Y` of the observer design ``kind``.

    Args:
        kind: ``"chen"`` (lower-triangular ones, Eq 28) or ``"diagonal"`` (identity).
        n: Number of joints.
    """
    if kind == "chen":
        return np.tril(np.ones((n, n)))
    if kind == "diagonal":
        return np.eye(n)
    raise ValueError(f"observer kind {kind!r} is not one of {OBSERVER_KINDS}")


class DisturbanceObserver:
    """Discrete-time NDO of Eq (13) with gain :math:`c` and design matrix :math:`Y`.

    Args:
        n: Number of joints.
        Ts: Sampling period [s].
        gain: Observer gain :math:`c` [1/s·(kg·m²)]; larger is faster.
        kind: ``"chen"`` or ``"diagonal"`` (see module docstring).
        discretization: ``"implicit"`` (backward Euler, default) or ``"explicit"``.

    Attributes:
        estimate: The current disturbance estimate :math:`\\hat d` [N·m], shape (n,).
    """

    def __init__(
        self,
        n: int,
        Ts: float,
        gain: float,
        kind: str = "chen",
        discretization: str = "implicit",
    ):
        if discretization not in DISCRETIZATIONS:
            raise ValueError(f"discretization {discretization!r} is not one of {DISCRETIZATIONS}")
        self.n = n
        self.Ts = float(Ts)
        self.gain = float(gain)
        self.kind = kind
        self.discretization = discretization
        self.cY = self.gain * observer_matrix(kind, n)
        self._eye = np.eye(n)
        self.z = np.zeros(n)
        self.estimate = np.zeros(n)

    def p(self, dq: np.ndarray) -> np.ndarray:
        """Auxiliary function :math:`p(\\dot q) = c Y \\dot q` (Eq 28)."""
        return self.cY @ dq

    def gain_matrix(self, M: np.ndarray) -> np.ndarray:
        """Observer gain :math:`L(q) = c Y M(q)^{-1}` (Eq 30)."""
        # L M = cY  <=>  M^T L^T = (cY)^T
        return np.linalg.solve(M.T, self.cY.T).T

    def reset(self, dq0: np.ndarray) -> None:
        """Start with :math:`z_0 = -p(\\dot q_0)`, so that :math:`\\hat d(0) = 0`."""
        self.z = -self.p(dq0)
        self.estimate = np.zeros(self.n)

    def update(
        self, M: np.ndarray, nle: np.ndarray, dq: np.ndarray, tau_prev: np.ndarray
    ) -> np.ndarray:
        """Advance one sampling period and return the new estimate :math:`\\hat d_k`.

        Args:
            M: Inertia matrix at the measured state [kg·m²].
            nle: :math:`C\\dot q + G` at the measured state [N·m].
            dq: Measured joint velocity [rad/s].
            tau_prev: Torque applied over the period that just ended [N·m].
        """
        p = self.cY @ dq
        TL = self.Ts * self.gain_matrix(M)
        rhs = TL @ (nle - tau_prev - p)
        if self.discretization == "implicit":
            self.z = np.linalg.solve(self._eye + TL, self.z + rhs)
        else:
            self.z = self.z - TL @ self.z + rhs
        self.estimate = self.z + p
        return self.estimate
