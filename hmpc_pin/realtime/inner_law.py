"""Two rates under a 1 kHz arm: the MPC every :math:`m = T_s / P` cycles, the inner law
(inverse dynamics and the disturbance observer) every cycle.

:class:`InnerLawEveryCycle` wraps a :class:`~hmpc_pin.controllers.hierarchical.HierarchicalMPC`
whose period :math:`T_s` is a multiple of the arm's period :math:`P`. Every cycle :math:`k`:

1. the observer, run at :math:`P`, takes the period that just ended:
   ``update(M(q_k), C q̇_k + G(q_k), q_k, q̇_k, τ_{k-1} − J_{k-1}, v)``
   (Eq 13; the torque as the arm applied it, within the effort limit, less the joint
   dynamics' own part :math:`J = B\\dot q + F\\,\\mathrm{sgn}\\,\\dot q`, as the compiled step
   feeds its observer);
2. at :math:`k = 0, m, 2m, \\dots` the MPC: the wrapped controller's whole step, of which
   the outer loop's acceleration :math:`v` is kept until the next (by the cycle's time:
   the first cycle at or after each instant :math:`t_0 + j\\,T_s` runs it, so that a
   cycle the loop skipped shifts nothing);
3. Eq (4) at the fresh state: :math:`\\tau_k = M(q_k)\\,v + C\\dot q_k + G(q_k) + J(\\dot q_k)
   - \\hat d_k`.

The wrapped controller's own observer still runs inside its step at :math:`T_s` (its
estimate is not used). This is the inner law in Python (a compiled split of the step
into an MPC part and an inner part would do the same at less cost); not for a
controller with a declared latency (its prediction and torque alignment are the
compiled step's). :class:`~hmpc_pin.realtime.threaded_law.InnerLawThreaded` is this law
with the MPC in a compiled thread, off the cycle.

The real-time loop runs a law as it runs any controller (its ``Ts`` is the arm's period:
one call per cycle); ``hmpc-pin realtime``, ``ros`` and ``franka`` choose it with
``--inner-law`` or ``[realtime] inner_law``
(:func:`~hmpc_pin.experiment.inner_law.inner_law_controller`). Each law says its own
name (:attr:`InnerLawEveryCycle.name`, as the option spells it) and what it ran
(:meth:`InnerLawEveryCycle.summary`, the run's record).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ..exceptions import ConfigError

__all__ = ["InnerLawEveryCycle"]

FloatArray = NDArray[np.float64]


class InnerLawEveryCycle:
    """The MPC every ``Ts/period`` cycles, Eq (4) and the observer every cycle (module doc).

    Args:
        controller: A :class:`~hmpc_pin.controllers.hierarchical.HierarchicalMPC` (its
            ``robot``, ``v``, ``joint_dynamics`` and ``Ts`` are used).
        compensation: The observer at the arm's period (a
            :class:`~hmpc_pin.compensation.base.Compensation` built for ``Ts = period``).
        period: The arm's period :math:`P` [s]; ``controller.Ts`` a multiple of it.
        effort_limit: Per-joint limit [N·m] the arm applies the torque within (the
            observer is fed the clipped torque), or ``None``.

    Attributes:
        Ts: The wrapper's period, ``period`` (the loop runs it every cycle).
        mpc_every: :math:`m`.
        name: The law as ``--inner-law`` names it (a class attribute).
        label: The law in words (the run summaries).
    """

    name = "every-cycle"
    label = "every cycle"

    def __init__(self, controller, compensation, period: float, effort_limit=None):
        m = round(controller.Ts / period)
        if m < 1 or abs(m * period - controller.Ts) > 1e-9 * controller.Ts:
            raise ConfigError(
                "controller.Ts",
                f"{controller.Ts:g} s is not a multiple of the arm's period {period:g} s",
            )
        latency = getattr(controller, "latency", 0.0) or 0.0
        if latency > 0:
            raise ConfigError(
                "controller.latency",
                "the inner law every cycle does not apply with a declared latency "
                f"({latency:g} s): set Ts to the arm's period, or the latency to 0",
            )
        self.controller = controller
        self.compensation = compensation
        self.robot = controller.robot
        self.Ts = float(period)
        self.mpc_every = m
        n = self.robot.nq
        damping, friction = controller.joint_dynamics
        self._B = np.broadcast_to(np.asarray(damping, dtype=float), (n,)).copy()
        self._F = np.broadcast_to(np.asarray(friction, dtype=float), (n,)).copy()
        lim = np.full(n, math.inf) if effort_limit is None else effort_limit
        self._effort = np.broadcast_to(np.asarray(lim, dtype=float), (n,)).copy()
        self._v = np.zeros(n)
        self._fed = np.zeros(n)
        self._k = 0

    @property
    def disturbance_estimate(self) -> FloatArray:
        """The observer's estimate :math:`\\hat d` [N·m] (updated every cycle)."""
        return self.compensation.estimate

    def reset(self, q0: FloatArray, dq0: FloatArray) -> None:
        """Start a run at ``(q0, dq0)``: the MPC, the observer, the held acceleration."""
        self.controller.reset(q0, dq0)
        self.compensation.reset(q0, dq0)
        self._v[:] = 0.0
        self._fed[:] = 0.0
        self._k = 0
        self._t0 = math.nan  # the first MPC instant (the run's first cycle)
        self._next = -math.inf  # the next MPC instant [s]

    def _due(self, t: float) -> bool:
        """Whether cycle time ``t`` [s] reaches the next MPC instant ``t0 + j Ts`` (within
        half an arm period): by time, not by calls, so that a cycle the loop skipped (a
        missed deadline, a lost robot cycle) does not shift the MPC's instants."""
        return t >= self._next - 0.5 * self.Ts

    def _ran_mpc(self, t: float) -> None:
        """The MPC ran at ``t``: the next instant is the one after the instant ``t`` serves."""
        if math.isnan(self._t0):  # the run's first MPC instant
            self._t0 = t
        Tc = self.controller.Ts
        j = math.floor((t - self._t0) / Tc + 0.5 * self.Ts / Tc)
        self._next = self._t0 + (j + 1) * Tc

    def step(self, t: float, q: FloatArray, dq: FloatArray, reference) -> FloatArray:
        """The torque [N·m] of cycle ``k`` (module doc)."""
        M, nle = self._observe(q, dq)
        if self._due(t):
            self.controller.step(t, q, dq, reference)
            self._v[:] = np.ravel(self.controller.v)
            self._ran_mpc(t)
        return self._torque(M, nle, dq)

    def warm_up(self, t: float, q: FloatArray, dq: FloatArray, reference) -> None:
        """Before a cycle that runs the MPC, the wrapped controller's ``warm_up`` (its step
        run and undone: :meth:`~hmpc_pin.controllers.hierarchical.HierarchicalMPC.warm_up`);
        nothing before the other cycles (the real-time loop calls it before every cycle:
        this law's ``Ts`` is the arm's period)."""
        if self._due(t):
            self.controller.warm_up(t, q, dq, reference)

    def summary(self) -> dict:
        """What the law ran, for the run's record: ``name``, ``label``, ``mpc_every``
        (cycles per MPC step) and ``period`` [s]."""
        return {
            "name": self.name,
            "label": self.label,
            "mpc_every": int(self.mpc_every),
            "period": float(self.Ts),
        }

    def close(self) -> None:
        """Nothing to release (the threaded law joins its planner here)."""

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _observe(self, q: FloatArray, dq: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``(M(q), C q̇ + G)`` at the cycle's state, the observer advanced over the period
        that just ended (step 1 of the module doc)."""
        robot = self.robot
        M = robot.mass_matrix(q)
        nle = robot.nonlinear_effects(q, dq)
        if self._k > 0:
            self.compensation.update(M, nle, q, dq, self._fed, self._v)
        return M, nle

    def _torque(self, M: FloatArray, nle: FloatArray, dq: FloatArray) -> FloatArray:
        """Eq (4) with the held acceleration (step 3 of the module doc)."""
        J = self._B * dq + self._F * np.sign(dq)
        tau = M @ self._v + nle + J - self.compensation.estimate
        np.clip(tau, -self._effort, self._effort, out=self._fed)
        self._fed -= J
        self._k += 1
        return tau

    def __getattr__(self, name: str):
        # everything else (warm_up, settings, ...) is the wrapped controller's
        if name == "controller":
            raise AttributeError(name)
        return getattr(self.controller, name)
