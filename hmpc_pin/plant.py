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

* One buffer row per stage, ``[q_j | q̇_j | q̈_j | 1]``, so that the stage state
  :math:`[q_j; \\dot q_j]` and the stage derivative :math:`k_j = [\\dot q_j; \\ddot q_j]`
  are contiguous views: each stage update is one multiply and one add, and the final
  combination one product with the weights ``h/6·(1, 2, 2, 1)``.
* The paper's disturbances are recognised and evaluated fused: the time-only terms
  (:class:`~hmpc_pin.disturbances.GaussianPulse`) at all 3·substeps stage times of
  the period in a few flat numpy calls, added to the held torque once per period; the
  state-dependent friction (:class:`~hmpc_pin.disturbances.CoulombViscousFriction`)
  inside one product per stage: with :math:`\\mathrm{sgn}(\\dot q_j)` written where
  :math:`\\ddot q_j` goes next, the row ends in
  :math:`e_j = [\\dot q_j; \\mathrm{sgn}(\\dot q_j); 1]` and the ABA torque is
  :math:`e_j^T W_j`, :math:`W_j = [-\\mathrm{diag}(a); -\\mathrm{diag}(b);
  (\\tau + d_\\mathrm{pulse}(t_j))^T]`. Any other disturbance (a user callable, a
  subclass, two friction terms) is called as ``d(t, q, dq)`` at every stage, as before.
* numpy outputs passed positionally (cheaper than ``out=``), loops over precomputed
  views: six numpy calls and one ``pin.aba`` per stage.

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
        # Stage rows [q_j | dq_j | ddq_j | 1]; row 0 holds the current state.
        self._B = B = np.zeros((4, 3 * n + 1))
        B[:, 3 * n] = 1.0
        self._x = B[0, : 2 * n]
        self._K = B[:, n : 3 * n]  # k_j = [dq_j | ddq_j], shape (4, 2n)
        self._rows = [
            (B[j, :n], B[j, n : 2 * n], B[j, 2 * n : 3 * n], B[j, n : 3 * n], B[j, n:])
            for j in range(4)
        ]
        self._next = [B[j, : 2 * n] for j in range(1, 4)]
        self._c = [np.full(2 * n, c) for c in (0.5 * h, 0.5 * h, h)]
        self._w = (h / 6.0) * np.array([1.0, 2.0, 2.0, 1.0])
        self._tmp = np.empty(2 * n)
        self._dx = np.empty(2 * n)
        self._u = np.empty(n)
        # The stage times of a period, t_s = t + s·h, t_s + h/2 and t_s + h for each step s,
        # as three blocks of one flat array (what the plain loop computes, the same way).
        S = substeps
        self._s_h = np.arange(S) * h
        self._half = 0.5 * h
        self._times = np.empty(3 * S)
        self._t0, self._tm, self._t1 = self._times[:S], self._times[S : 2 * S], self._times[2 * S :]
        # Per stage time (rows ordered as _times) the matrix W with [dq | sgn(dq) | 1] @ W =
        # tau + pulses(t) - (a·dq + b·sgn(dq)): rows -diag(a), -diag(b), and T = tau +
        # pulses(t), the held torque plus the time-only terms at that stage time.
        self._W = W = np.zeros((3 * S, 2 * n + 1, n))
        self._T = W[:, 2 * n, :]
        self._W_triples = [(W[s], W[S + s], W[2 * S + s]) for s in range(S)]
        self._T_triples = [(self._T[s], self._T[S + s], self._T[2 * S + s]) for s in range(S)]
        if self._split is not None:
            pulses, friction = self._split
            self._friction = friction
            # Each pulse's coefficients tiled over the 3·S stage times: the pulses of a
            # whole period in a few flat numpy calls.
            self._pulses = [
                tuple(
                    np.tile(np.broadcast_to(c, (n,)), 3 * S)
                    for c in (p.center, -0.5 / p.sigma**2, p.amplitude)  # as GaussianPulse
                )
                for p in pulses
            ]
            if friction is not None:
                W[:, :n, :] = -np.diag(np.broadcast_to(friction.viscous, (n,)))
                W[:, n : 2 * n, :] = -np.diag(np.broadcast_to(friction.coulomb, (n,)))

    def _stage_times(self, t: float) -> np.ndarray:
        """Stage times of the period starting at ``t``: blocks t_s, t_s + h/2, t_s + h."""
        t0 = self._t0
        np.add(t, self._s_h, t0)
        np.add(t0, self._half, self._tm)
        np.add(t0, self.h, self._t1)
        return self._times

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
        if self._pulses:
            # GaussianPulse: amplitude·exp(k·x·x), x = t − center (its own operations)
            tt = times.repeat(self.n)
            total = None
            for center, k, amplitude in self._pulses:
                x = tt - center
                y = k * x
                y *= x
                np.exp(y, y)
                y *= amplitude
                if total is None:
                    total = y
                else:
                    total += y
            np.add(tau, total.reshape(-1, self.n), self._T)
        else:
            self._T[:] = tau
        model, data, aba = self.model, self.data, pin.aba
        rows = self._rows
        (q0, v0, a0, k0, e0), (q1, v1, a1, k1, e1) = rows[0], rows[1]
        (q2, v2, a2, k2, e2), (q3, v3, a3, _, e3) = rows[2], rows[3]
        x1, x2, x3 = self._next
        c1, c2, c3 = self._c
        x, K, w, tmp, dx = self._x, self._K, self._w, self._tmp, self._dx
        add, mul, sign, dot = np.add, np.multiply, np.sign, np.dot
        # (outputs passed positionally: a little cheaper than out=, 40 times per period)
        if self._friction is None:
            for r0, r1, r2 in self._T_triples:
                a0[:] = aba(model, data, q0, v0, r0)
                mul(k0, c1, tmp)
                add(x, tmp, x1)
                a1[:] = aba(model, data, q1, v1, r1)
                mul(k1, c2, tmp)
                add(x, tmp, x2)
                a2[:] = aba(model, data, q2, v2, r1)
                mul(k2, c3, tmp)
                add(x, tmp, x3)
                a3[:] = aba(model, data, q3, v3, r2)
                dot(w, K, dx)
                add(x, dx, x)
            return
        for W0, W1, W2 in self._W_triples:
            # sgn(dq_j) is written where ddq_j goes next, so that the stage row ends in
            # e_j = [dq_j | sgn(dq_j) | 1] and the torque is one product e_j @ W.
            sign(v0, a0)
            a0[:] = aba(model, data, q0, v0, e0.dot(W0))
            mul(k0, c1, tmp)
            add(x, tmp, x1)
            sign(v1, a1)
            a1[:] = aba(model, data, q1, v1, e1.dot(W1))
            mul(k1, c2, tmp)
            add(x, tmp, x2)
            sign(v2, a2)
            a2[:] = aba(model, data, q2, v2, e2.dot(W1))
            mul(k2, c3, tmp)
            add(x, tmp, x3)
            sign(v3, a3)
            a3[:] = aba(model, data, q3, v3, e3.dot(W2))
            dot(w, K, dx)
            add(x, dx, x)

    def _advance_generic(self, times: np.ndarray, tau: np.ndarray) -> None:
        """RK4 calling ``d(t, q, dq)`` at every stage (with copies of the stage state)."""
        dist = self.disturbance
        model, data, aba = self.model, self.data, pin.aba
        rows = self._rows
        nxt = self._next
        c = self._c
        x, K, w, tmp, dx, u = self._x, self._K, self._w, self._tmp, self._dx, self._u
        stage_times = zip(self._t0.tolist(), self._tm.tolist(), self._t1.tolist(), strict=True)
        for t0, tm, t1 in stage_times:
            for j, ts in enumerate((t0, tm, tm, t1)):
                qj, vj, aj, kj, _ = rows[j]
                np.add(tau, dist(ts, qj.copy(), vj.copy()), out=u)
                aj[:] = aba(model, data, qj, vj, u)
                if j < 3:
                    np.multiply(kj, c[j], out=tmp)
                    np.add(x, tmp, out=nxt[j])
            np.dot(w, K, out=dx)
            np.add(x, dx, out=x)
