"""The closed loop in compiled chunks: :func:`~hmpc_pin.sim.simulate.simulate`'s per-step
loop, many control periods per call into the compiled core (``cpp/src/loop.cpp``,
``ClosedLoop``), for every setup: the loop calls each part through a port
(``cpp/include/hmpc/interfaces.hpp``):

- the controller: :class:`~hmpc_pin.controllers.hierarchical.HierarchicalMPC` is stepped
  in C++ (its compensation behind the step's Compensation port: the compiled NDO of Eq 13,
  or a Python compensation called from the step; its model the compiled dynamics, or
  Pinocchio's Python API called from the step for mimic joints), alone or behind a
  :class:`~hmpc_pin.controllers.wrappers.MeasuredController` (or
  :class:`~hmpc_pin.sim.sensing.SensedController`), whose measurement port (compiled: the
  plain noise and delay, the interface model of :mod:`~hmpc_pin.sim.sensing`; or a Python
  subclass) is called by the loop; any other controller (computed torque, any other
  wrapper) is called as a whole,
  ``step(t, q, dq, reference)`` and ``disturbance_estimate``, through the Controller port;
- the reference: one with a compiled form (sine, piecewise polynomial) is sampled in C++;
  any other is sampled in Python (the controller's ``sample_many`` of the horizon, as its
  per-step ``step`` does), called from the compiled loop through its Reference port;
- the plant: :class:`~hmpc_pin.sim.plants.RK4Plant`'s compiled plant (its ``port``, whose
  state it is) is advanced by the loop itself, its disturbance compiled (time-only terms
  tabulated by the plant per :data:`~hmpc_pin.sim.plants.PULSE_CHUNK` periods, a chunk of
  the loop at a time; one Coulomb–viscous friction evaluated in C++) or a callable
  ``d(t, q, dq)`` called at every stage; any other plant (semi-implicit Euler, MuJoCo, an
  RK4 plant whose methods are replaced) is called as a whole, ``advance(tau)`` and
  ``disturbance_now()`` (and, after ``advance``, ``applied_disturbance(d)`` where the plant
  has it: the recorded ``d`` made the disturbance applied at the period's start), through
  the Plant port;
- an ``on_step`` callback, if any, is called from the compiled loop once a step is recorded
  (with the reference sampled at that instant, as the per-step loop does).

Each chunk is :data:`~hmpc_pin.sim.plants.PULSE_CHUNK` periods: per step it does what the
per-step loop does, in the same order and with the same floating-point operations (the
controller's step, the records, the torque check, the effort clip and its counts, the
plant's compiled period, the state check), so both loops give the same arrays. A fault
stops the chunk at its step, and the same exception as the per-step loop's is raised from
here; Ctrl-C is checked before every step (the run keeps the steps recorded so far).
Afterwards the controller, the measurement (its state lives in the port; its generator is
where a draw per measurement leaves it) and the plant are in the state the per-step loop
leaves them in.

The per-step loop in Python, this loop's oracle, lives in the tests
(``tests/reference/loop.py``).
"""

from __future__ import annotations

import sys
from typing import Any

import numpy as np

from .._deprecated import deprecated
from ..controllers.hierarchical import HierarchicalMPC
from ..controllers.wrappers import MeasuredController
from ..native import load as load_native
from .plants import PULSE_CHUNK, RK4Plant

__all__ = ["CompiledLoop"]


def __getattr__(name: str):
    """``LOOPS`` and ``why_not_compiled`` of earlier versions (:mod:`hmpc_pin._deprecated`),
    with a :class:`DeprecationWarning`."""
    return deprecated(__name__, name)


def _own(obj, cls, *names: str) -> bool:
    """Whether ``obj``'s methods ``names`` are ``cls``'s own (not overridden by a subclass
    or replaced on the instance, e.g. by a spy: then the loop must call them)."""
    return all(
        getattr(getattr(obj, name, None), "__func__", None) is getattr(cls, name) for name in names
    )


def _parts(controller):
    """``(HierarchicalMPC, MeasuredController or None)`` of ``controller`` when its step is
    the compiled one (then the loop calls the compiled step and the ports around it), or
    ``None`` (then the loop calls the controller as a whole through its Controller port)."""
    measured = None
    if isinstance(controller, MeasuredController) and _own(
        controller, MeasuredController, "step", "reset"
    ):
        measured, controller = controller, controller.controller
    if isinstance(controller, HierarchicalMPC) and _own(controller, HierarchicalMPC, "step"):
        return controller, measured
    return None


def _compiled_plant(plant) -> bool:
    """Whether ``plant`` is an :class:`~hmpc_pin.sim.plants.RK4Plant` whose period the loop
    runs itself (its methods not replaced, e.g. by a spy: then it is called as a plant)."""
    return isinstance(plant, RK4Plant) and _own(
        plant, RK4Plant, "advance", "disturbance_now", "applied_disturbance", "reset", "prepare"
    )


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
        ctrl, measured = _parts(controller) or (None, None)
        self.ctrl, self.measured, self.plant, self.reference = ctrl, measured, plant, reference
        self.t_arr, self.records = t_arr, records
        n = records["q"].shape[1]
        self.n, self.K = n, len(t_arr) - 1
        self._rk4 = rk4 = _compiled_plant(plant)
        self._loop = load_native().ClosedLoop(
            plant.port if rk4 else plant,  # the compiled plant, or the plant through Python
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
        if ctrl is None:  # the controller as a whole, from Python
            self._loop.set_controller(controller, reference)
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
        ctrl, K = self.ctrl, self.K
        port: Any = None if self.measured is None else self.measured.measurement
        if ctrl is not None:  # its compiled step, with its reference and measurement ports
            self._loop.set_controller(ctrl.compiled_controller(self.reference, port))
        ahead = isinstance(port, load_native().SensingMeasurement)
        if ahead:  # the noise of a chunk drawn at once, the unused draws given back
            port.ahead = PULSE_CHUNK
        try:
            self._chunks(K)
        finally:
            if ahead:
                port.give_back()
                port.ahead = 1

    def _chunks(self, K: int) -> None:
        plant = self.plant
        k0 = 0
        while k0 <= K:
            self.k = k0
            # A chunk: as far as the compiled plant's table of time-only terms goes.
            k1 = min(K + 1, plant.prepare(k0) if self._rk4 else k0 + PULSE_CHUNK)
            k = self._chunk(k0, k1)
            self.k = k
            if self.progress is not None:
                self.progress(k, K)
            if k == K:
                return
            k0 = k1

    def _chunk(self, k0: int, k1: int) -> int:
        """Steps ``k0 .. k1 - 1``; the measurement's Python flag brought up to date
        afterwards (also when a fault or Ctrl-C stops the chunk). Returns the step where it
        stopped."""
        loop, n = self._loop, self.n
        started = loop.started
        x = self._x
        try:
            return loop.run(x[:n], x[n:], k0, k1)
        finally:
            self.k, self.last = loop.k, loop.last
            if self.measured is not None and loop.started != started:
                self.measured._started = True
