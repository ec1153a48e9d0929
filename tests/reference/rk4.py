"""Oracle of the RK4 plant's period (compiled: ``cpp/src/rk4.cpp``, ``RK4``; its Coulomb
law by stick-slip events: ``cpp/src/stick_slip.cpp``, ``StickSlip``).

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


def stick_slip_period(model, q, dq, tau, Ts: float, friction, damping=None, rtol=1e-12):
    """``(q, q̇, events)`` after ``Ts`` [s] of :math:`M\\ddot q + C\\dot q + G = \\tau
    - B\\dot q - \\phi` with ``tau`` held and the Coulomb torque
    :math:`\\phi_i = F_i\\,\\mathrm{sgn}\\,\\dot q_i` while joint i moves, and at
    rest the value in :math:`[-F_i, F_i]` that keeps it at rest (the stick-slip law), by
    scipy's DOP853 at ``rtol`` with the sign changes and break-aways as events (an
    integration independent of the compiled one: its own mode logic, the constrained
    dynamics by :math:`M^{-1}` from Pinocchio's CRBA).

    Modes: +1/-1 sliding, 0 stuck. At rest a joint sticks when the torque that holds it,
    :math:`\\phi_S = ((M^{-1})_{SS})^{-1} (M^{-1}(\\tau - B\\dot q - C\\dot q - G))_S`
    (the sliding joints' Coulomb torque included), is within :math:`\\pm F`; else it slides
    against it, one joint at a time (largest :math:`|\\phi_i|/F_i` first).
    """
    from scipy.integrate import solve_ivp

    data = model.createData()
    n = model.nv
    F = np.asarray(friction, dtype=float)
    B = np.zeros(n) if damping is None else np.asarray(damping, dtype=float)

    def dynamics(q, v, mode):
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        Minv = np.linalg.inv(M)
        s = np.where(np.abs(mode) == 1, mode, 0.0)
        u = tau - B * v - F * s - pin.nonLinearEffects(model, data, q, v)
        a = Minv @ u
        S = np.flatnonzero(mode == 0)
        phi = np.zeros(n)
        if S.size:
            phi_s = np.linalg.solve(Minv[np.ix_(S, S)], a[S])  # the friction torque subtracted
            a = a - Minv[:, S] @ phi_s
            a[S] = 0.0
            phi[S] = phi_s
        return a, phi

    def modes(q, v):
        mode = np.where(F > 0, np.sign(v), 2.0)
        for _ in range(2 * n + 2):
            if not (mode == 0).any():
                break
            _, phi = dynamics(q, v, mode)
            ratio = np.where(mode == 0, np.abs(phi) / np.where(F > 0, F, 1.0), 0.0)
            j = int(np.argmax(ratio))
            if ratio[j] <= 1.0:
                break
            mode[j] = np.sign(phi[j])  # φ is subtracted: it slides along the force's push
        return mode

    q, v = np.array(q, dtype=float), np.array(dq, dtype=float)
    t, events = 0.0, 0
    while Ts - t > 1e-14:
        mode = modes(q, v)

        def rhs(_t, x, mode=mode):
            a, _ = dynamics(x[:n], x[n:], mode)
            return np.concatenate([np.where(mode == 0, 0.0, x[n:]), a])

        funcs = []
        for i in range(n):
            if abs(mode[i]) == 1 and v[i] != 0.0:

                def ev(_t, x, i=i, s=mode[i]):
                    return s * x[n + i]  # the velocity's sign change
            elif mode[i] == 0:

                def ev(_t, x, i=i, mode=mode):
                    return F[i] - abs(dynamics(x[:n], x[n:], mode)[1][i])  # the break-away
            else:
                continue
            ev.terminal, ev.direction = True, -1
            funcs.append((i, ev))
        sol = solve_ivp(rhs, (t, Ts), np.concatenate([q, v]), method="DOP853", rtol=rtol,
                        atol=rtol, events=[f for _, f in funcs] or None)  # fmt: skip
        x = sol.y[:, -1]
        q, v = x[:n].copy(), x[n:].copy()
        t = sol.t[-1]
        if sol.status == 1:  # an event: the crossing joint's velocity is 0 there
            events += 1
            for (i, _), te in zip(funcs, sol.t_events, strict=True):
                if te.size and abs(mode[i]) == 1:
                    v[i] = 0.0
    return q, v, events
