"""Oracle of the RK4 plant's period (compiled: ``cpp/src/rk4.cpp``, ``RK4``).

Classical Runge–Kutta steps of :math:`h` over one control period with the torque
:math:`\\tau` held, Eq (1) :math:`M\\ddot q + C\\dot q + G = \\tau + d(t, q, \\dot q)`:

.. math::

    k_1 = f(t_s, x),\\ k_2 = f(t_s + \\tfrac h2, x + \\tfrac h2 k_1),\\
    k_3 = f(t_s + \\tfrac h2, x + \\tfrac h2 k_2),\\ k_4 = f(t_s + h, x + h k_3),\\
    x \\leftarrow x + \\tfrac h6 (k_1 + 2k_2 + 2k_3 + k_4),

with :math:`f(t, [q; \\dot q]) = [\\dot q; \\mathrm{ABA}(q, \\dot q, \\tau + d(t, q, \\dot q)
- B\\dot q - F\\,\\mathrm{sgn}\\,\\dot q)]` (``joint = (B, F)``, the joint damping and friction),
the disturbance called as a plain function at every stage and ABA from Pinocchio's
Python API -- the plain loop, with none of the compiled period's fusing.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin


def rk4_period(
    model, q, dq, tau, disturbance, t: float, h: float, substeps: int, aba=None, joint=None
):
    """``(q, q̇)`` after ``substeps`` RK4 steps of ``h`` from time ``t`` (new arrays).

    ``joint``: ``(B, F)`` per joint, the torque ``−B q̇ − F sgn q̇`` added at every stage.

    ``aba(q, v, u)``: the forward dynamics (default Pinocchio's ``pin.aba`` on ``model``;
    a model with mimic joints needs the package's ``Robot.aba``)."""
    data = model.createData()
    if aba is None:

        def aba(q, v, u):
            return pin.aba(model, data, q, v, u)

    def f(ts, q, v):
        u = tau + disturbance(ts, q.copy(), v.copy())
        if joint is not None:
            u = u - joint[0] * v - joint[1] * np.sign(v)
        return v, aba(q, v, u)

    q, v = np.array(q, dtype=float), np.array(dq, dtype=float)
    for s in range(substeps):
        ts = t + s * h
        k1q, k1v = f(ts, q, v)
        k2q, k2v = f(ts + h / 2, q + h / 2 * k1q, v + h / 2 * k1v)
        k3q, k3v = f(ts + h / 2, q + h / 2 * k2q, v + h / 2 * k2v)
        k4q, k4v = f(ts + h, q + h * k3q, v + h * k3v)
        q = q + h / 6 * (k1q + 2 * k2q + 2 * k3q + k4q)
        v = v + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
    return q, v
