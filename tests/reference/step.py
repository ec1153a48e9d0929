"""Oracle of the hierarchical MPC's step, paper Figure 1 (compiled: ``cpp/src/step.cpp``).

At every control instant, written from the equations with Pinocchio's Python API and the
other oracles of this folder:

1. :math:`M(q_k)` (CRBA) and :math:`C\\dot q_k + G` (RNEA) at the measured state;
2. the NDO of Eq 13 over the period that just ended, with the torque applied over it
   (:class:`~tests.reference.observers.NumpyNDO`), or :math:`\\hat d = 0`;
3. each joint's condensed QP (Eq 25–26) for the gradient
   :math:`g_i = 2\\Gamma^T\\bar Q(\\Phi x_{0,i} - \\bar r_i)` (scaled), with the reference
   sampled at :math:`t_k + jT_s,\\ j = 1..N`
   (:class:`~tests.reference.joint_qps.NumpyJointQPs`);
4. :math:`\\tau = M v + C\\dot q + G - \\hat d` with :math:`v` the first input (Eq 4).

With joint damping and friction ``(B, F)`` compensated, :math:`C\\dot q + G` carries
:math:`+B\\dot q + F\\,\\mathrm{sgn}\\,\\dot q` in step 4 (the observer of step 2 is given
:math:`C\\dot q + G` alone and the applied torque minus the last step's joint-dynamics
torque :math:`J = B\\dot q + F\\sigma + (g - 1)v/(M^{-1})_{jj}`), and joint j's torque gets
:math:`(g_j - 1) v_j / (M^{-1})_{jj}`, :math:`g_j = x/(1 - e^{-x})`,
:math:`x = b_j (M^{-1})_{jj} T_s` (``numpy.linalg.inv``), and the Coulomb term
:math:`f_j\\,\\mathrm{sgn}\\,\\dot q_j` is replaced by :math:`f_j\\sigma_j`, the sign of the
velocity's path over the period averaged by quadrature (:meth:`OracleHMPC._mean_sign`).

With ``model_at = "start"`` step 2 takes :math:`M` and :math:`C\\dot q + G` of the
previous step's measured state (the state the held torque was computed from) instead of
this step's.

Any other compensation law is given as ``law``: an object with ``reset(q0, dq0)`` and
``update(M, nle, q, dq, tau, v) -> d̂`` written from its own equations, called in step 2 with
the same model, the applied torque beyond :math:`J` and the oracle's previous :math:`v`.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from hmpc_pin.compensation.observers import DisturbanceObserver

from .joint_qps import NumpyJointQPs
from .observers import NumpyNDO


class OracleHMPC:
    """The step of a :class:`hmpc_pin.HierarchicalMPC` ``ctrl``, from the equations.

    Args:
        ctrl: The compiled controller whose settings, model, MPC data, limits and observer
            gain are reproduced (nothing of its state is used).
    """

    def __init__(self, ctrl, law=None):
        self.robot = ctrl.robot
        self.mpc = ctrl.mpc
        s = ctrl.settings
        self.Ts, self.N = s.Ts, s.N
        v_min, v_max = s.bounds(ctrl.n)
        self.qps = NumpyJointQPs(ctrl.mpc, v_min, v_max, ctrl.limits, eps_abs=s.eps_abs)
        comp = ctrl.compensation
        self.ndo = law
        if law is None and isinstance(comp, DisturbanceObserver):
            self.ndo = _NDOLaw(NumpyNDO(comp.cY, comp.Ts, comp.discretization == "implicit"))
        self.data = self.robot.model.createData()
        self.joint = ctrl.joint_dynamics  # (B, F) compensated (zeros: none)
        self.at_start = s.model_at == "start"

    def reset(self, dq0: np.ndarray, q0: np.ndarray | None = None) -> None:
        if self.ndo is not None:
            self.ndo.reset(q0, dq0)
        self.d_hat = np.zeros(self.robot.nq)
        self.J = np.zeros(self.robot.nq)  # the joint-dynamics torque of the last step
        self.prev = None  # M, C q̇ + G of the last step's measured state
        self.v = np.zeros(self.robot.nq)  # the last step's commanded acceleration

    def step(self, t, q, dq, reference, tau_applied_prev=None) -> tuple[np.ndarray, np.ndarray]:
        """Returns ``(τ, d̂)``; ``tau_applied_prev`` is None at the first step."""
        model, data = self.robot.model, self.data
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        nle0 = pin.rnea(model, data, q, dq, np.zeros_like(dq))
        B, F = self.joint
        if self.ndo is not None and tau_applied_prev is not None:
            # the rigid body's model; the torque beyond the last step's joint torque J
            Mo, no = self.prev if self.at_start else (M, nle0)
            self.d_hat = np.array(
                self.ndo.update(Mo, no, q, dq, tau_applied_prev - self.J, self.v), dtype=float
            )
        self.prev = (M, nle0)
        times = t + self.Ts * np.arange(1, self.N + 1)
        q_ref, dq_ref = reference.sample_many(times)
        ref = np.empty((2 * self.N, q.size))
        ref[0::2], ref[1::2] = q_ref, dq_ref
        x0 = np.vstack([q, dq])
        G = self.mpc.gradient(x0, ref)
        U, _slack, _soft = self.qps.solve(G, x0)
        v = U[0]
        minv = np.diag(np.linalg.inv(M))
        x = B * minv * self.Ts
        with np.errstate(invalid="ignore", divide="ignore"):
            g = np.where(x > 0, x / (1.0 - np.exp(-x)), 1.0)
        sigma = np.sign(dq)
        for j in np.flatnonzero(F):
            sigma[j] = self._mean_sign(dq[j], dq[j] + v[j] * self.Ts, x[j])
        J = B * dq + F * sigma + (g - 1.0) / minv * v
        tau = M @ v + nle0 + J - self.d_hat
        self.J = J
        self.v = v
        return tau, self.d_hat.copy()

    @staticmethod
    def _mean_sign(a: float, c: float, x: float) -> float:
        """The mean of sgn w(t) over the period weighted by e^{-x(1 - s)}, w the path
        a + (c - a)(1 - e^{-xs})/(1 - e^{-x}) (linear for x = 0), s = t/Ts: the crossing
        found by bisection, each side integrated by Simpson's rule."""
        if a == 0.0 or np.sign(a) == np.sign(c):
            return float(np.sign(c))

        def w(s):
            phi = s if x < 1e-8 else np.expm1(-x * s) / np.expm1(-x)
            return a + (c - a) * phi

        lo, hi = 0.0, 1.0
        for _ in range(100):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if np.sign(w(mid)) == np.sign(a) else (lo, mid)

        def integral(s0, s1, m=2001):
            s = np.linspace(s0, s1, m)
            f = np.exp(-x * (1.0 - s))
            h = (s1 - s0) / (m - 1)
            return h / 3 * (f[0] + f[-1] + 4 * f[1:-1:2].sum() + 2 * f[2:-1:2].sum())

        before, after = integral(0.0, lo), integral(lo, 1.0)
        return float((np.sign(a) * before + np.sign(c) * after) / (before + after))


class _NDOLaw:
    """:class:`~tests.reference.observers.NumpyNDO` as a compensation law."""

    def __init__(self, ndo: NumpyNDO):
        self.ndo = ndo

    def reset(self, q0, dq0) -> None:
        self.ndo.reset(dq0)

    def update(self, M, nle, q, dq, tau, v):
        return self.ndo.update(M, nle, dq, tau)


def assert_run_matches(oracle: OracleHMPC, result, reference, atol: float) -> None:
    """Replay a closed-loop ``result`` through ``oracle`` (reset at its first velocity) and
    check, at every recorded instant, the estimate d̂ and the torque τ to ``atol`` [N·m]
    times max(1, max |τ|): the oracle is given the measured state and the torque applied
    over the period before, as the compiled step was."""
    oracle.reset(result.dq[0], result.q[0])
    scale = max(1.0, float(np.abs(result.tau).max()))
    for k in range(len(result.t)):
        prev = None if k == 0 else result.tau_applied[k - 1]
        tau, d_hat = oracle.step(result.t[k], result.q[k], result.dq[k], reference, prev)
        np.testing.assert_allclose(result.d_hat[k], d_hat, rtol=0, atol=atol * scale)
        np.testing.assert_allclose(result.tau[k], tau, rtol=0, atol=atol * scale)
