"""The closed loop in compiled chunks: :func:`~hmpc_pin.sim.simulate.simulate`'s per-step
loop, :data:`~hmpc_pin.sim.compiled_loop.LOOP_CHUNK` control periods per call into the
compiled core (``cpp/src/loop.cpp``, ``ClosedLoop``), for every setup. The loop calls each
part through its port (``cpp/include/hmpc/interfaces.hpp``), and each part hands its port
over itself, with ``loop_port`` (``None``: the part has no compiled port, and the loop calls
the Python object through the port's trampoline):

- the controller (``controller.loop_port(reference)``): the compiled step of
  :class:`~hmpc_pin.controllers.hierarchical.HierarchicalMPC` (its compensation and its
  reference behind the step's own ports), alone or behind the measurement port of a
  :class:`~hmpc_pin.controllers.wrappers.MeasuredController` (or
  :class:`~hmpc_pin.sim.sensing.SensedController`); any other controller (computed torque,
  any other wrapper, a controller whose ``step`` is replaced) is called as a whole,
  ``step(t, q, dq, reference)`` and ``disturbance_estimate``;
- the reference: the step's Reference port, compiled for a sine or a piecewise polynomial
  (:func:`~hmpc_pin.tasks.base.reference_port`), else sampled in Python;
- the plant (``plant.loop_port()``): :class:`~hmpc_pin.sim.plants.RK4Plant`'s compiled plant,
  its disturbance behind the Disturbance port (compiled pulses and friction evaluated in its
  period); any other plant (semi-implicit Euler, MuJoCo, an RK4 plant whose methods are
  replaced) is called as a whole, ``advance(tau)`` and ``disturbance_now()`` (and, after
  ``advance``, ``applied_disturbance(d)`` where the plant has it: the recorded ``d`` made
  the disturbance applied at the period's start);
- an ``on_step`` callback, if any, is called from the compiled loop once a step is recorded
  (with the reference sampled at that instant, as the per-step loop does).

Per step a chunk does what the per-step loop does, in the same order and with the same
floating-point operations (the controller's step, the records, the torque check, the effort
clip and its counts, the plant's period, the state check), so both loops give the same
arrays. Around a chunk the compiled loop calls the controller's chunk hooks (a measurement
that draws noise draws the chunk's at once and gives the unused draws back, also when a
fault stops the chunk). A fault stops the chunk at its step, and the same exception as the
per-step loop's is raised from here; Ctrl-C is checked before every step (the run keeps the
steps recorded so far). Afterwards the controller, the measurement (its state lives in the
port; its generator is where a draw per measurement leaves it) and the plant are in the
state the per-step loop leaves them in.

The per-step loop in Python, this loop's oracle, lives in the tests
(``tests/reference/loop.py``).
"""

from __future__ import annotations

import sys

import numpy as np

from .._deprecated import deprecated
from ..native import load as load_native
from ..native import loop_port

__all__ = ["LOOP_CHUNK", "CompiledLoop"]

#: Control periods per call into the compiled loop: between two calls
#: :attr:`CompiledLoop.progress` is told, and a measurement draws a chunk's noise at once.
LOOP_CHUNK = 64


def __getattr__(name: str):
    """``LOOPS`` and ``why_not_compiled`` of earlier versions (:mod:`hmpc_pin._deprecated`),
    with a :class:`DeprecationWarning`."""
    return deprecated(__name__, name)


class CompiledLoop:
    """One run's compiled loop over the recording arrays of
    :func:`~hmpc_pin.sim.simulate.simulate` (which builds it after ``reset``).

    Attributes:
        k: The step being run (where a fault or interrupt stopped the run).
        last: The last recorded step (-1: none).
    """

    #: What ``result.loop`` says of a run through this loop.
    name = "compiled"

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
        self.t_arr, self.records = t_arr, records
        n = records["q"].shape[1]
        self.n, self.K = n, len(t_arr) - 1
        plant_port = loop_port(plant)
        self._loop = load_native().ClosedLoop(
            plant if plant_port is None else plant_port,  # compiled, or through Python
            n,
            t_arr,
            [records[name] for name in ("q", "dq", "tau", "d", "d_hat", "tau_applied")],
            step_ns,
            sat_steps,
            sat_excess,
            np.full(n, np.inf) if limit is None else limit,
            limit is not None,
            min(state_bound, sys.float_info.max),
            float(controller.Ts),
        )
        if on_step is not None:
            self._loop.set_recorded(self._on_step(on_step))
        q0, dq0 = state if state is not None else (plant.q, plant.dq)
        self._x = np.concatenate([q0, dq0])
        self.k, self.last = 0, -1
        #: ``progress(k, K)`` after each chunk of periods (``None``: none); it sees the
        #: step count only, so the run is the same with or without it.
        self.progress = None

    def _on_step(self, on_step):
        """The callback after step k is recorded: the reference sampled at t_k into the
        records, then ``on_step(t_k, q_k, q_ref)``, as the per-step loop does."""
        t_arr, reference, rec = self.t_arr, self.reference, self.records
        rec_q, rec_q_ref, rec_dq_ref = rec["q"], rec["q_ref"], rec["dq_ref"]

        def recorded(k: int) -> None:
            t = t_arr[k]
            q_ref, dq_ref = reference.sample(t)
            rec_q_ref[k] = q_ref
            rec_dq_ref[k] = dq_ref
            on_step(t, rec_q[k].copy(), q_ref)

        return recorded

    def run(self) -> None:
        """Run every step, chunk by chunk; a fault raises the compiled core's exception
        (the per-step loop's, translated from C++ in one place) with :attr:`k`,
        :attr:`last` kept up to date for the caller's partial result."""
        controller, reference = self.controller, self.reference
        port = loop_port(controller, reference)  # built after reset, for this run's reference
        if port is None:  # the controller as a whole, from Python
            self._loop.set_controller(controller, reference)
        else:
            self._loop.set_controller(port)
        loop, n, K, x = self._loop, self.n, self.K, self._x
        k0 = 0
        while True:
            self.k = k0
            try:
                k = loop.run(x[:n], x[n:], k0, min(K + 1, k0 + LOOP_CHUNK))
            finally:
                self.k, self.last = loop.k, loop.last
            self.k = k
            if self.progress is not None:
                self.progress(k, K)
            if k == K:
                return
            k0 = k
