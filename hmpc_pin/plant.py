"""The plant of the closed loop: Pinocchio ABA integrated over one control period.

:class:`RK4Plant` advances :math:`M\\ddot q + C\\dot q + G = \\tau + d(t, q, \\dot q)`
(Eq 1) over one control period :math:`T_s` with the torque held, by classical
Runge–Kutta (RK4) steps of ``dt``, the disturbance evaluated at every stage:

.. math::

    k_1 = f(t_s, x), \\quad k_2 = f(t_s + h/2, x + \\tfrac h2 k_1), \\quad
    k_3 = f(t_s + h/2, x + \\tfrac h2 k_2), \\quad k_4 = f(t_s + h, x + h k_3),

    x \\leftarrow x + \\tfrac h6 (k_1 + 2k_2 + 2k_3 + k_4), \\qquad
    f(t, [q; \\dot q]) = [\\dot q;\\ \\mathrm{ABA}(q, \\dot q, \\tau + d(t, q, \\dot q))].

This is the simulation's hot loop (40 ABA calls per 10 ms control period at 1 ms),
written for few Python-level numpy calls, not for a different result:

* One buffer row per stage, ``[q_j | q̇_j | q̈_j]``, so that the stage state
  :math:`[q_j; \\dot q_j]` and the stage derivative :math:`k_j = [\\dot q_j; \\ddot q_j]`
  are contiguous views and each stage update is one multiply and one add.
* The paper's disturbances are recognised and evaluated fused: the time-only terms
  (:class:`~hmpc_pin.disturbances.GaussianPulse`) for every stage time of the period
  in one vectorised call, added to the held torque once per period; the
  state-dependent friction (:class:`~hmpc_pin.disturbances.CoulombViscousFriction`)
  at every stage with four in-place numpy calls. Any other disturbance (a user
  callable, a subclass) is called as ``d(t, q, dq)`` at every stage, as before.

The results equal the plain loop (``q2 = q + h/2·dq`` …, ``aba(q, dq, tau + d(t, q, dq))``
per stage) up to floating-point rounding (tested to 1e-12 on the paper scenario).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from .disturbances import (
    CoulombViscousFriction,
    GaussianPulse,
    SumDisturbance,
    ZeroDisturbance,
)

__all__ = ["RK4Plant", "split_disturbance"]


def split_disturbance(disturbance, n: int):
    """Split ``disturbance`` into fused parts, or return ``None`` if it has other terms.

    Returns:
        ``(pulses, friction)``: the :class:`GaussianPulse` terms (time-only) and the
        single :class:`CoulombViscousFriction` term (or ``None``); ``None`` instead of
        the pair when the disturbance has any other term (a user callable, a
        subclass, two friction terms), which is then evaluated term by term.
    """
    terms = disturbance.terms if type(disturbance) is SumDisturbance else (disturbance,)
    pulses, friction = [], []
    for term in terms:
        kind = type(term)
        if kind is GaussianPulse:
            pulses.append(term)
        elif kind is CoulombViscousFriction:
            friction.append(term)
        elif kind is not ZeroDisturbance:
            return None
    if len(friction) > 1:
        return None
    for term in (*pulses, *friction):
        for coef in vars(term).values():
            if isinstance(coef, np.ndarray) and coef.shape not in ((), (n,)):
                return None  # let the plain evaluation raise its own broadcasting error
    return pulses, (friction[0] if friction else None)


class RK4Plant:
    """Classical RK4 integration of a Pinocchio model over one control period.

    Args:
        plant: The plant's :class:`~hmpc_pin.robot.Robot` (its ``model`` and ``data``).
        disturbance: Callable ``d(t, q, dq) -> (n,)`` [N·m].
        Ts: Control period [s] (the torque is held over it).
        substeps: Number of RK4 steps of ``h = Ts / substeps`` per period.
    """

    def __init__(self, plant, disturbance, Ts: float, substeps: int):
        n = plant.nq
        self.n = n
        self.model, self.data = plant.model, plant.data
        self.disturbance = disturbance
        self.h = h = Ts / substeps
        self.substeps = substeps
        self._split = split_disturbance(disturbance, n)
        # Stage rows [q_j | dq_j | ddq_j]; row 0 holds the current state.
        self._B = B = np.zeros((4, 3 * n))
        self._x = B[0, : 2 * n]
        self._K = B[:, n:]  # k_j = [dq_j | ddq_j], shape (4, 2n)
        self._rows = [(B[j, :n], B[j, n : 2 * n], B[j, 2 * n :], B[j, n:]) for j in range(4)]
        self._next = [B[j, : 2 * n] for j in range(1, 4)]
        self._c = [np.full(2 * n, c) for c in (0.5 * h, 0.5 * h, h)]
        self._w = (h / 6.0) * np.array([1.0, 2.0, 2.0, 1.0])
        self._tmp = np.empty(2 * n)
        self._dx = np.empty(2 * n)
        self._u = np.empty(n)
        # Stage times of one period relative to its start: t_s, t_s + h/2, t_s + h per step.
        s_h = np.arange(substeps) * h
        self._s_h = s_h
        self._half = 0.5 * h
        self._times = np.empty((substeps, 3))
        # Held torque plus the time-only terms at the stage times, rows as _times.
        self._T = np.empty((substeps * 3, n))
        self._T_rows = list(self._T)
        if self._split is not None:
            pulses, friction = self._split
            self._pulses = pulses
            self._friction = friction
            if friction is not None:
                # a·dq + b·sgn(dq) = [dq | sgn(dq)] @ [diag(a); diag(b)]
                self._Wt = np.vstack(
                    [
                        np.diag(np.broadcast_to(friction.viscous, (n,))),
                        np.diag(np.broadcast_to(friction.coulomb, (n,))),
                    ]
                )

    def _stage_times(self, t: float) -> np.ndarray:
        """Stage times of the period starting at ``t``: rows (t_s, t_s + h/2, t_s + h)."""
        T = self._times
        ts = T[:, 0]
        np.add(t, self._s_h, out=ts)
        np.add(ts, self._half, out=T[:, 1])
        np.add(ts, self.h, out=T[:, 2])
        return T

    def advance(
        self, t: float, q: np.ndarray, dq: np.ndarray, tau: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Integrate from ``(q, dq)`` at ``t`` over one period with ``tau`` held.

        Returns:
            New arrays ``(q, dq)`` at ``t + Ts``.
        """
        n = self.n
        x = self._x
        x[:n] = q
        x[n:] = dq
        times = self._stage_times(t)
        if self._split is None:
            self._advance_generic(times, tau)
        else:
            self._advance_fused(times, tau)
        return x[:n].copy(), x[n:].copy()

    def _advance_fused(self, times: np.ndarray, tau: np.ndarray) -> None:
        """RK4 with the time-only terms tabulated and the friction fused (module doc)."""
        T = self._T
        T[:] = tau
        if self._pulses:
            tt = times.reshape(-1)
            for p in self._pulses:
                T += p.sample_many(tt)
        rows = self._T_rows
        model, data, aba = self.model, self.data, pin.aba
        (q0, v0, a0, k0), (q1, v1, a1, k1), (q2, v2, a2, k2), (q3, v3, a3, k3) = self._rows
        x1, x2, x3 = self._next
        c1, c2, c3 = self._c
        x, K, w, tmp, dx, u = self._x, self._K, self._w, self._tmp, self._dx, self._u
        add, mul, sub, sign, dot = np.add, np.multiply, np.subtract, np.sign, np.dot
        if self._friction is None:
            for s in range(self.substeps):
                r0, r1, r2 = rows[3 * s], rows[3 * s + 1], rows[3 * s + 2]
                a0[:] = aba(model, data, q0, v0, r0)
                mul(k0, c1, out=tmp)
                add(x, tmp, out=x1)
                a1[:] = aba(model, data, q1, v1, r1)
                mul(k1, c2, out=tmp)
                add(x, tmp, out=x2)
                a2[:] = aba(model, data, q2, v2, r1)
                mul(k2, c3, out=tmp)
                add(x, tmp, out=x3)
                a3[:] = aba(model, data, q3, v3, r2)
                dot(w, K, out=dx)
                add(x, dx, out=x)
            return
        Wt = self._Wt
        for s in range(self.substeps):
            r0, r1, r2 = rows[3 * s], rows[3 * s + 1], rows[3 * s + 2]
            # u = tau + pulses(t) - (a·dq + b·sgn(dq)): sgn(dq_j) is written where ddq_j
            # goes next, and [dq_j | sgn(dq_j)]·[diag a; diag b] is one product.
            sign(v0, out=a0)
            a0[:] = aba(model, data, q0, v0, sub(r0, k0.dot(Wt), out=u))
            mul(k0, c1, out=tmp)
            add(x, tmp, out=x1)
            sign(v1, out=a1)
            a1[:] = aba(model, data, q1, v1, sub(r1, k1.dot(Wt), out=u))
            mul(k1, c2, out=tmp)
            add(x, tmp, out=x2)
            sign(v2, out=a2)
            a2[:] = aba(model, data, q2, v2, sub(r1, k2.dot(Wt), out=u))
            mul(k2, c3, out=tmp)
            add(x, tmp, out=x3)
            sign(v3, out=a3)
            a3[:] = aba(model, data, q3, v3, sub(r2, k3.dot(Wt), out=u))
            dot(w, K, out=dx)
            add(x, dx, out=x)

    def _advance_generic(self, times: np.ndarray, tau: np.ndarray) -> None:
        """RK4 calling ``d(t, q, dq)`` at every stage (with copies of the stage state)."""
        dist = self.disturbance
        model, data, aba = self.model, self.data, pin.aba
        rows = self._rows
        nxt = self._next
        c = self._c
        x, K, w, tmp, dx, u = self._x, self._K, self._w, self._tmp, self._dx, self._u
        for t0, tm, t1 in times.tolist():
            for j, ts in enumerate((t0, tm, tm, t1)):
                qj, vj, aj, kj = rows[j]
                np.add(tau, dist(ts, qj.copy(), vj.copy()), out=u)
                aj[:] = aba(model, data, qj, vj, u)
                if j < 3:
                    np.multiply(kj, c[j], out=tmp)
                    np.add(x, tmp, out=nxt[j])
            np.dot(w, K, out=dx)
            np.add(x, dx, out=x)
