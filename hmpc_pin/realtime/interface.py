"""The robot-interface protocol: what a real-time loop needs from an arm, simulated or real.

A torque-controlled arm (libfranka for the Panda, UR's direct torque mode) runs its own
clock: every interface period it publishes the measured state with its time stamp and
applies the last torque it received. :class:`RobotInterface` is that contract, seen from
the controller's side: :meth:`~RobotInterface.read` the newest measurement,
:meth:`~RobotInterface.write` a torque, :meth:`~RobotInterface.close`. A stamp that does
not advance between two reads means no new state arrived (the loop's watchdog counts it).

An arm that pushes its states (a ROS 2 topic, a fieldbus frame) rather than being
polled is a :class:`PacedInterface`: the loop then waits for each state and answers it,
instead of keeping its own deadlines.

Implementations: :class:`PlantArm` (a :class:`~hmpc_pin.sim.base.Plant` in this process,
stepped to a clock you give it: deterministic tests),
:class:`~hmpc_pin.realtime.process_arm.ProcessArm` (a plant in a separate process stepping in
wall-clock time, state and torque exchanged through shared memory, as a driver would), and
the template in
:mod:`~hmpc_pin.realtime.driver_template` (not run on hardware).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..exceptions import DimensionError
from ..sim.base import Plant

__all__ = ["PacedInterface", "PlantArm", "RobotInterface"]

FloatArray = NDArray[np.float64]


@runtime_checkable
class RobotInterface(Protocol):
    """A torque-controlled arm as a real-time loop sees it.

    Attributes:
        nq: Number of joints n.
        period: The arm's own period [s] (1 ms for libfranka): how often it publishes a
            state and samples the torque.

    Optional: a method ``stamp_clock() -> float``, now [s] on the clock of the stamps,
    lets the loop measure the latency from measurement to torque written (an arm that
    paces the loop has it as :meth:`PacedInterface.clock`). A method ``start()`` for an
    arm whose clock starts with it (Franka's torque control; a ROS arm's first state
    taken): :meth:`~hmpc_pin.realtime.loop.RealtimeLoop.run` with ``start=True`` calls
    it after its own set-up (the heap collected and frozen, the controller reset and
    warmed), so that none of the set-up costs the arm a cycle; :meth:`read` then returns
    the first state.
    """

    nq: int
    period: float

    def read(self) -> tuple[float, FloatArray, FloatArray]:
        """The newest measurement ``(stamp [s], q [rad], dq [rad/s])``, each (n,).

        ``stamp`` is the arm's time of the measurement; it does not advance while no new
        state arrives. The arrays may be reused by the next call: copy them to keep them.
        """
        ...

    def write(self, tau: FloatArray) -> None:
        """Command the torque ``tau`` [N·m], (n,), held by the arm until the next write."""
        ...

    def close(self) -> None:
        """Release the arm (stop the process, disconnect); idempotent."""
        ...


@runtime_checkable
class PacedInterface(RobotInterface, Protocol):
    """An arm that paces the loop: it publishes a state every period on its own clock and
    the loop answers each state with a torque (a ROS 2 ``/joint_states`` topic).

    The loop's deadline for a state is its stamp: latency is stamp → torque written, on
    :meth:`clock`, which must be the clock of the stamps.

    Optional attributes, set by :meth:`wait`: ``arrival`` (when the state taken arrived,
    on :meth:`clock`; the loop's deadline is then the arrival, and the stamp-to-torque
    latency is measured apart, so a constant transport delay is no miss) and
    ``overdue`` (how many of the periods :meth:`wait` reports arrived more than a period
    before it returned: the states the loop failed to answer; without it every period
    beyond the first is a miss).
    """

    def clock(self) -> float:
        """Now [s], on the clock of the stamps :meth:`read` returns."""
        ...

    def wait(self, timeout: float) -> int:
        """Block until a state newer than the last one taken arrives, or ``timeout`` [s].

        Takes the newest state (what :meth:`read` returns next) and returns how many
        states arrived since the previous call: 0 when none came within ``timeout``,
        more than 1 when the loop fell behind (the extra ones are periods not answered).
        """
        ...


class PlantArm:
    """A :class:`~hmpc_pin.sim.base.Plant` in this process, stepped to a clock.

    Every :meth:`read` first advances the plant, with the last torque written held, by
    every whole period :math:`T_a` that has elapsed on ``clock`` since the first write
    (before it the arm holds still, as an arm on its brakes): the plant's time follows
    the clock as a driver's follows the wall, and with an injected clock the run is
    deterministic.

    Args:
        plant: The arm's dynamics; its ``Ts`` is the interface period :math:`T_a` [s].
        q0, dq0: Initial state [rad, rad/s].
        clock: Seconds, monotonic (default :func:`time.perf_counter`).
        effort_limit: Per-joint torque limit [N·m] applied to the written torque
            (``None``: as written).

    Attributes:
        tau: The torque the arm currently holds [N·m] (after the effort limit).
        writes: Number of :meth:`write` calls.
    """

    def __init__(
        self,
        plant: Plant,
        q0: ArrayLike,
        dq0: ArrayLike | None = None,
        *,
        clock: Callable[[], float] = time.perf_counter,
        effort_limit: ArrayLike | None = None,
    ) -> None:
        self.plant = plant
        self.nq = n = plant.nq
        self.period = float(plant.Ts)
        q0 = np.array(q0, dtype=float)
        dq0 = np.zeros(n) if dq0 is None else np.array(dq0, dtype=float)
        if q0.shape != (n,) or dq0.shape != (n,):
            raise DimensionError(
                f"initial state of shapes {q0.shape}, {dq0.shape}; expected ({n},) each"
            )
        self._clock = clock
        self._limit: FloatArray | None = None
        if effort_limit is not None:
            self._limit = np.broadcast_to(np.asarray(effort_limit, dtype=float), (n,)).copy()
        plant.reset(q0, dq0, 0.0)
        self.q, self.dq = q0.copy(), dq0.copy()
        self.tau = np.zeros(n)
        self.writes = 0
        self._start: float | None = None
        self._steps = 0
        self.closed = False

    def read(self) -> tuple[float, FloatArray, FloatArray]:
        """Advance to the clock and return ``(plant time, q, dq)``."""
        if self._start is not None:
            due = int((self._clock() - self._start) / self.period + 1e-9)
            while self._steps < due:
                self.q, self.dq = self.plant.advance(self.tau)
                self._steps += 1
        return self._steps * self.period, self.q, self.dq

    def write(self, tau: FloatArray) -> None:
        """Hold ``tau`` [N·m] from now on (the first write releases the brakes)."""
        tau = np.asarray(tau, dtype=float)
        if tau.shape != (self.nq,):
            raise DimensionError(f"torque of shape {tau.shape}; expected ({self.nq},)")
        if self._limit is not None:
            np.clip(tau, -self._limit, self._limit, out=self.tau)
        else:
            self.tau[:] = tau
        if self._start is None:
            self._start = self._clock()
        self.writes += 1

    def close(self) -> None:
        """Nothing to release; marks the arm closed."""
        self.closed = True
