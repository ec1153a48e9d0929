"""Numpy oracle of the NDO of Eq (13) (compiled: ``cpp/src/observer.cpp``).

Continuous form, with :math:`p = cY\\dot q` (Eq 28) and :math:`L = cY M^{-1}` (Eq 30):

.. math::

    \\dot z = -L z + L\\,(C\\dot q + G - \\tau - p), \\qquad \\hat d = z + p.

Discretised at :math:`T_s` with :math:`n_k = C\\dot q_k + G_k` and the torque
:math:`\\tau_{k-1}` held over the period that just ended:

* backward Euler: :math:`(I + T_s L_k)\\,z_k = z_{k-1} + T_s L_k (n_k - \\tau_{k-1} - p_k)`;
* forward Euler: :math:`z_k = z_{k-1} + T_s L_k (n_k - \\tau_{k-1} - p_k - z_{k-1})`.

Written here literally, with :math:`L_k` formed and :math:`(I + T_s L_k)` solved by LAPACK
(``np.linalg.solve``) -- a different factorisation and a different order of operations from
the compiled one, which solves :math:`(M + T_s cY)` once.
"""

from __future__ import annotations

import numpy as np


class NumpyNDO:
    """The NDO of Eq (13), literally (module docstring).

    Args:
        cY: :math:`cY` (n, n).
        Ts: Period [s].
        implicit: Backward (``True``) or forward Euler.
    """

    def __init__(self, cY: np.ndarray, Ts: float, implicit: bool = True):
        self.cY = np.array(cY, dtype=float)
        self.Ts = float(Ts)
        self.implicit = implicit
        self.n = self.cY.shape[0]
        self.z = np.zeros(self.n)
        self.estimate = np.zeros(self.n)

    def reset(self, dq0: np.ndarray) -> None:
        """:math:`z_0 = -p(\\dot q_0)`, so :math:`\\hat d_0 = 0`."""
        self.z = -self.cY @ dq0
        self.estimate = np.zeros(self.n)

    def update(self, M, nle, dq, tau_prev) -> np.ndarray:
        """One period; returns :math:`\\hat d_k`."""
        L = self.cY @ np.linalg.inv(M)  # Eq (30)
        p = self.cY @ dq  # Eq (28)
        b = nle - tau_prev - p
        if self.implicit:
            A = np.eye(self.n) + self.Ts * L
            self.z = np.linalg.solve(A, self.z + self.Ts * L @ b)
        else:
            self.z = self.z + self.Ts * L @ (b - self.z)
        self.estimate = self.z + p
        return self.estimate.copy()
