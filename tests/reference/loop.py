"""Oracle of the closed loop (compiled: ``cpp/src/loop.cpp``, ``ClosedLoop``, glued by
:mod:`hmpc_pin.sim.compiled_loop`).

The zero-order-hold loop of the paper's Fig. 1, one control period at a time, each part called
through its public Python methods -- the plain loop, with none of the compiled loop's chunks,
ports or fused disturbances. Per step k, at :math:`t_k = k T_s`:

1. :math:`\\tau_k` = ``controller.step(t_k, q_k, q̇_k, reference)``;
2. the records: :math:`q_k, \\dot q_k, \\tau_k`, the plant's disturbance
   :math:`d(t_k, q_k, \\dot q_k)`, the controller's estimate :math:`\\hat d_k`
   (and, with ``on_step``, the reference at :math:`t_k`, then ``on_step(t_k, q_k, r_k)``);
3. (k < K) :math:`\\tau_k` finite, clipped to the effort limit
   :math:`\\mathrm{clip}(\\tau_k, -\\tau_{\\max}, \\tau_{\\max})` (the saturation counts),
   recorded as applied;
4. ``plant.advance(τ)``: the plant's period :math:`[t_k, t_k + T_s)` with the torque held;
   then, where the plant has it, the recorded :math:`d_k` becomes
   ``plant.applied_disturbance(d_k)``, the disturbance applied at the period's start (a
   joint at rest held by a Coulomb term: its holding torque, not :math:`\\mathrm{sgn}\\,0 = 0`);
5. every :math:`|q|, |\\dot q|` at :math:`t_{k+1}` finite and within the bound.

:class:`PerStepLoop` has :class:`~hmpc_pin.sim.compiled_loop.CompiledLoop`'s constructor,
``run()`` and ``k``/``last``, so that a test runs :func:`hmpc_pin.simulate` (its set-up, its
partial results and messages) on this loop with :func:`per_step`. Nothing in ``hmpc_pin``
imports this module.
"""

from __future__ import annotations

import contextlib
import importlib
import sys
import time

import numpy as np

from hmpc_pin.exceptions import NonFiniteError
from hmpc_pin.sim.base import state_error


class PerStepLoop:
    """The closed loop per step in Python (module docstring), over the recording arrays of
    :func:`hmpc_pin.simulate`.

    Attributes:
        k: The step being run (where a fault or interrupt stopped the run).
        last: The last recorded step (-1: none).
    """

    name = "per-step"

    def __init__(
        self,
        controller,
        plant,
        reference,
        t_arr,
        records,
        step_ns,
        limit,
        state_bound: float,
        sat_steps,
        sat_excess,
        on_step=None,
        state=None,
    ):
        self.controller, self.plant, self.reference = controller, plant, reference
        self.t_arr, self.rec, self.step_ns = t_arr, records, step_ns
        self.limit, self.bound = limit, state_bound
        self.sat_steps, self.sat_excess = sat_steps, sat_excess
        self.on_step = on_step
        self.q, self.dq = state if state is not None else (plant.q, plant.dq)
        self.k, self.last = 0, -1

    def run(self) -> None:
        """Every step of the run (module docstring); a fault raises the package's exception
        with :attr:`k` and :attr:`last` where the run stopped."""
        ctrl, plant, ref, rec = self.controller, self.plant, self.reference, self.rec
        limit, bound, t_arr = self.limit, self.bound, self.t_arr
        q, dq = self.q, self.dq
        cap = min(bound, sys.float_info.max)  # an infinite state fails an infinite bound
        K = len(t_arr) - 1
        for k in range(K + 1):
            self.k = k
            t = t_arr[k]
            start = time.perf_counter_ns()
            tau = ctrl.step(t, q, dq, ref)
            self.step_ns[k] = time.perf_counter_ns() - start
            rec["q"][k], rec["dq"][k], rec["tau"][k] = q, dq, tau
            rec["d"][k] = plant.disturbance_now()
            rec["d_hat"][k] = ctrl.disturbance_estimate
            self.last = k
            if self.on_step is not None:
                q_ref, dq_ref = ref.sample(t)
                rec["q_ref"][k], rec["dq_ref"][k] = q_ref, dq_ref
                self.on_step(t, q, q_ref)
            if k == K:
                return
            if not np.all(np.isfinite(tau)):
                raise NonFiniteError("tau", tau, f"at t={t:.6g}")
            if limit is not None:
                excess = np.abs(tau) - limit
                if (excess > 0).any():
                    self.sat_steps += excess > 0
                    np.maximum(self.sat_excess, excess, out=self.sat_excess)
                    tau = np.clip(tau, -limit, limit)
            rec["tau_applied"][k] = tau
            q, dq = plant.advance(tau)
            applied = getattr(plant, "applied_disturbance", None)
            if applied is not None:
                rec["d"][k] = applied(rec["d"][k].copy())
            if not (np.all(np.abs(q) <= cap) and np.all(np.abs(dq) <= cap)):
                raise state_error(q, dq, t + ctrl.Ts, bound)


@contextlib.contextmanager
def per_step():
    """Within the block, :func:`hmpc_pin.simulate` (and ``Experiment.run``) run the
    :class:`PerStepLoop` oracle instead of the compiled loop; ``result.loop`` says
    ``"per-step"``."""
    sim = importlib.import_module("hmpc_pin.sim.simulate")  # (the package's name is the function)
    saved = sim.CompiledLoop
    sim.CompiledLoop = PerStepLoop
    try:
        yield
    finally:
        sim.CompiledLoop = saved
