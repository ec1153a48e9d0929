"""An arm simulated in a separate process, stepping in wall-clock time, as a driver would.

The child process builds a :class:`~hmpc_pin.sim.base.Plant` (any: the RK4 or Euler
Pinocchio plant, or another engine's) from a picklable factory and advances it by its
period :math:`T_a` at absolute wall-clock deadlines, catching up by several steps when
it wakes late, so that the arm's time follows the wall. Every period it samples the
newest torque and publishes ``(stamp, q, dq)``. Until the first torque arrives the arm
holds still (on its brakes) while its stamp advances.

State and torque are exchanged through one :class:`~multiprocessing.shared_memory.SharedMemory`
block, each direction guarded by a sequence counter (a seqlock: the
writer makes the counter odd, writes, makes it even; a reader retries when the counter
was odd or changed during its copy). Counters are 8-byte aligned int64 stores, atomic on
x86-64 and, under its total store order, seen in program order by the other process;
a port to a weaker memory model would need explicit fences.

Ctrl-C in the terminal reaches the whole process group: the arm ignores SIGINT, so that
the controller's safe stop still has an arm to command.

Scheduling beside the loop: under ``SCHED_FIFO`` the arm process runs one level below the
priority it is given (the loop's: ``priority - 1``, at least 1), so that where the arm's
step and the loop's wake-up meet on one core the loop preempts the arm (two FIFO tasks at
one priority do not preempt each other: the later waits for the earlier's step); the arm
catches up on its wall-clock deadlines after. Its garbage collector is frozen and
disabled once its plant is built (the step allocates every period: automatic collections
would land in its steps), and the generation due is collected after a step when at least
:data:`ARM_GC_SLACK` of the period remains (:class:`~hmpc_pin.realtime.pacing.Tally`);
the collector is restored when the loop ends (``counters["gc"]``).
"""

from __future__ import annotations

import contextlib
import gc
import multiprocessing as mp
import os
import signal
import time
import traceback
from collections.abc import Callable
from multiprocessing.shared_memory import SharedMemory

import numpy as np
from numpy.typing import NDArray

from ..exceptions import DimensionError, SimulationError
from .pacing import Tally, resolve_priority

__all__ = ["ARM_GC_SLACK", "READ_GIVE_UP", "READ_NAP", "READ_SPINS", "ProcessArm", "StateReader"]

FloatArray = NDArray[np.float64]

# int64 control slots
_STATE_SEQ, _CMD_SEQ, _STOP, _READY, _STALL, _MISSED_CMDS, _STEPS, _LATE, _GC, _GC_RUNS = range(10)
_NCTL = 10

#: The arm's collector state (``counters["gc"]``), from the ``_GC`` slot.
_GC_STATES = ("automatic", "frozen", "restored")

#: The fraction of the arm's period that must remain after a step for a collection there.
ARM_GC_SLACK = 0.5


def _views(buf, n: int):
    """``(ctl int64[8], period float64[1], state [stamp, q, dq] float64[1+2n], tau float64[n])``."""
    ctl = np.ndarray((_NCTL,), dtype=np.int64, buffer=buf)
    floats = np.ndarray((2 + 3 * n,), dtype=np.float64, buffer=buf, offset=8 * _NCTL)
    return ctl, floats[:1], floats[1 : 2 + 2 * n], floats[2 + 2 * n :]


def _size(n: int) -> int:
    return 8 * (_NCTL + 2 + 3 * n)


def start_child(proc) -> None:
    """Start the process ``proc`` with SIGINT blocked, so that a Ctrl-C to the process
    group while the child starts (before its own code sets SIGINT to ignored and unblocks
    it) neither kills it nor prints a traceback; the parent's mask is restored after."""
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        proc.start()
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def _arm_main(
    name, n, make_plant, q0, dq0, effort_limit, conn, priority=0, gc_frozen=True
) -> None:  # pragma: no cover
    """The child process: attach the shared block, run :func:`_arm_loop`, report a failure.

    (Covered by the tests through :class:`ProcessArm`, in another process.)
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})  # blocked by start_child
    # (spawned children share the parent's resource tracker: the parent's unlink
    # unregisters the block once for both)
    shm = SharedMemory(name=name)
    try:
        if priority:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
        _arm_loop(shm.buf, n, make_plant, q0, dq0, effort_limit, conn, gc_frozen)
    except BaseException:
        with contextlib.suppress(OSError):
            conn.send(traceback.format_exc())
    finally:
        shm.close()


def _arm_loop(
    buf, n, make_plant, q0, dq0, effort_limit, conn, gc_frozen=True
) -> None:  # pragma: no cover
    """Build the plant, then step it in wall-clock time until the stop flag is set (the
    collector frozen and disabled meanwhile with ``gc_frozen``, restored after)."""
    ctl = _views(buf, n)[0]
    was_enabled = gc.isenabled()
    try:
        _arm_steps(buf, n, make_plant, q0, dq0, effort_limit, conn, gc_frozen)
    finally:
        if ctl[_GC] == 1:
            gc.unfreeze()
            if was_enabled:
                gc.enable()
            ctl[_GC] = 2


def _arm_steps(
    buf, n, make_plant, q0, dq0, effort_limit, conn, gc_frozen
) -> None:  # pragma: no cover
    """:func:`_arm_loop`'s steps."""
    ctl, period_buf, state, tau_buf = _views(buf, n)
    plant = make_plant()
    if plant.nq != n:
        raise DimensionError(f"the arm's plant has {plant.nq} joints; expected {n}")
    plant.reset(q0, dq0, 0.0)
    P = float(plant.Ts)
    period_buf[0] = P
    q, dq = np.array(q0, dtype=float), np.array(dq0, dtype=float)
    tau, cmd = np.zeros(n), np.zeros(n)
    limit = None if effort_limit is None else np.asarray(effort_limit, dtype=float)

    def publish(stamp, q, dq):
        ctl[_STATE_SEQ] += 1
        state[0] = stamp
        state[1 : 1 + n] = q
        state[1 + n :] = dq
        ctl[_STATE_SEQ] += 1

    publish(0.0, q, dq)
    tally, spent = Tally(), np.zeros(1)
    if gc_frozen:  # what the set-up made, collected; the rest out of the collector's reach
        gc.collect()
        gc.freeze()
        gc.disable()
        ctl[_GC] = 1
    slack = ARM_GC_SLACK * P
    ctl[_READY] = 1
    conn.send(None)
    clock, sleep = time.perf_counter, time.sleep
    last_cmd, started, steps, k = 0, False, 0, 0
    t0 = clock()
    while not ctl[_STOP]:
        k += 1
        delay = t0 + k * P - clock()
        if delay > 0:
            sleep(delay)
        s1 = ctl[_CMD_SEQ]
        if s1 != last_cmd and not s1 & 1:
            cmd[:] = tau_buf
            if ctl[_CMD_SEQ] == s1:
                last_cmd, started = s1, True
                if limit is not None:
                    np.clip(cmd, -limit, limit, out=tau)
                else:
                    tau[:] = cmd
        elif started:
            ctl[_MISSED_CMDS] += 1
        due = int((clock() - t0) / P)
        if due > k:
            ctl[_LATE] += due - k
            k = due
        if started:
            # (when catching up, each step is published: a simulator that lags the wall
            # still delivers a state every step, as an arm would)
            while steps < k:
                q, dq = plant.advance(tau)
                steps += 1
                ctl[_STEPS] = steps
                if not ctl[_STALL]:
                    publish(steps * P, q, dq)
        else:
            steps = k
            ctl[_STEPS] = steps
            if not ctl[_STALL]:
                publish(steps * P, q, dq)
        if gc_frozen:  # the generation due, in the step's slack
            tally.collect(0, t0 + (k + 1) * P, clock, slack, spent)
            ctl[_GC_RUNS] = tally.gc_runs


#: How a reader waits for the arm caught in the middle of publishing: this many tries at
#: once, then a sleep of ``READ_NAP`` between tries, for at most ``READ_GIVE_UP`` in all.
READ_SPINS = 64
#: The sleep [s] between a reader's tries after ``READ_SPINS``.
READ_NAP = 2e-5
#: How long [s] a reader waits for a whole copy before keeping the last one.
READ_GIVE_UP = 2e-3


def _read_state(ctl, state, buf, scratch) -> bool:
    """Copy the published ``[stamp, q, dq]`` into ``buf`` under the seqlock (through
    ``scratch``: ``buf`` only ever holds a whole copy); whether a new copy was taken.

    A writer caught mid-write (its counter odd, or changed during the copy) is waited for:
    :data:`READ_SPINS` tries at once, then a sleep of ``READ_NAP`` between tries. The
    sleep is what lets it finish where the reader's thread preempted it on their core (the
    arm runs a priority level below the loop): a reader that only spins there keeps it from
    running (a 100 000-try spin cost the loop 9–12 ms each time). After
    ``READ_GIVE_UP`` ``buf`` keeps the last whole copy: its stamp, not advancing, is
    the watchdog's.
    """
    tries, end = 0, 0.0
    while True:
        s1 = ctl[_STATE_SEQ]
        if not s1 & 1:
            scratch[:] = state
            if ctl[_STATE_SEQ] == s1:
                buf[:] = scratch
                return True
        tries += 1
        if tries > READ_SPINS:
            now = time.perf_counter()
            if not end:
                end = now + READ_GIVE_UP
            elif now > end:
                return False
            time.sleep(READ_NAP)


class StateReader:
    """Read-only access to an arm process's published state from another process (a
    viewer, a logger): attaches to the block by name, never writes.

    Args:
        name: :attr:`ProcessArm.shm_name`.
        n: Number of joints.
    """

    def __init__(self, name: str, n: int):
        self._shm = SharedMemory(name=name)
        self._ctl, _, self._state, _ = _views(self._shm.buf, n)
        self._buf, self._scratch = np.full(1 + 2 * n, np.nan), np.empty(1 + 2 * n)

    def read(self) -> tuple[float, FloatArray, FloatArray]:
        """``(stamp, q, dq)``, copies."""
        _read_state(self._ctl, self._state, self._buf, self._scratch)
        n = (self._buf.size - 1) // 2
        return float(self._buf[0]), self._buf[1 : 1 + n].copy(), self._buf[1 + n :].copy()

    def close(self) -> None:
        """Detach (the arm process's owner frees the block)."""
        del self._ctl, self._state
        self._shm.close()


class ProcessArm:
    """An arm in a separate process, a :class:`~hmpc_pin.realtime.interface.RobotInterface`.

    Args:
        make_plant: A picklable callable (a module-level function or a
            :func:`functools.partial` of one) returning the arm's
            :class:`~hmpc_pin.sim.base.Plant`; it is called in the child process, and the
            plant's ``Ts`` is the arm's period.
        q0, dq0: Initial state [rad, rad/s].
        effort_limit: Per-joint torque limit [N·m] the arm applies (``None``: none).
        start_timeout: Seconds to wait for the child to build its plant.
        priority: ``SCHED_FIFO`` priority of the loop the arm serves (0: normal
            scheduling; ``"auto"``: 80 where permitted, else normal; see
            :func:`~hmpc_pin.realtime.loop.fifo_priority`): the arm process runs
            ``below`` levels under it (at least 1), as a robot's own controller runs
            beside the loop (module doc).
        below: Levels under ``priority`` the arm process runs (0: the loop's own).
        gc_frozen: Freeze and disable the arm process's garbage collector while it runs,
            collecting in its steps' slack (module doc); ``False`` leaves it automatic.

    Attributes:
        period: The arm's period [s] (its plant's ``Ts``).

    Raises:
        SimulationError: The child failed to start (its traceback in the message).
    """

    def __init__(
        self,
        make_plant: Callable,
        q0,
        dq0=None,
        *,
        effort_limit=None,
        start_timeout: float = 120.0,
        priority: int | str = 0,
        below: int = 1,
        gc_frozen: bool = True,
    ):
        q0 = np.array(q0, dtype=float)
        n = q0.size
        dq0 = np.zeros(n) if dq0 is None else np.array(dq0, dtype=float)
        if q0.shape != (n,) or dq0.shape != (n,):
            raise DimensionError(
                f"initial state of shapes {q0.shape}, {dq0.shape}; expected ({n},) each"
            )
        self.nq = n
        priority = resolve_priority(priority)  # "auto": 80 where permitted, else 0
        if priority:
            priority = max(1, priority - int(below))
        #: The arm process's ``SCHED_FIFO`` priority (0: normal scheduling).
        self.priority = priority
        self._shm = SharedMemory(create=True, size=_size(n))
        try:  # a Ctrl-C before the process exists: the block freed, nothing left
            self._ctl, self._period, self._state, self._tau = _views(self._shm.buf, n)
            self._ctl[:] = 0
            self._closed = False
            self._final: dict = {}
            child = self._prepare(n, make_plant, q0, dq0, effort_limit, priority, gc_frozen)
        except BaseException:
            with contextlib.suppress(Exception):
                self.__dict__.pop("_ctl", None)
                self.__dict__.pop("_period", None)
                self.__dict__.pop("_state", None)
                self.__dict__.pop("_tau", None)
                self._shm.close()
            self._shm.unlink()
            raise
        try:
            start_child(self._proc)
            child.close()
            self._wait_ready(start_timeout)
        except BaseException:  # Ctrl-C or a failure while starting: no process, no block left
            self.close(wait=0.0)
            raise
        self.period = float(self._period[0])
        self._buf, self._scratch = np.full(1 + 2 * n, np.nan), np.empty(1 + 2 * n)
        self._q, self._dq = self._buf[1 : 1 + n], self._buf[1 + n :]

    def _prepare(self, n, make_plant, q0, dq0, effort_limit, priority, gc_frozen):
        """The pipe and the (not yet started) arm process; the child's end of the pipe."""
        ctx = mp.get_context("spawn")
        self._conn, child = ctx.Pipe(duplex=False)
        self._proc = ctx.Process(
            target=_arm_main,
            args=(
                self._shm.name,
                n,
                make_plant,
                q0,
                dq0,
                effort_limit,
                child,
                priority,
                gc_frozen,
            ),
            name="hmpc-pin-arm",
            daemon=True,
        )
        return child

    def _wait_ready(self, start_timeout: float) -> None:
        end = time.monotonic() + start_timeout
        while not self._ctl[_READY]:
            if self._conn.poll(0.01):
                message = self._conn.recv()
                if message is not None:
                    raise SimulationError(f"the arm process failed to start:\n{message}")
            if not self._proc.is_alive() or time.monotonic() > end:
                raise SimulationError(
                    f"the arm process did not start within {start_timeout:g} s "
                    f"(exit code {self._proc.exitcode}); check the plant factory"
                )

    @property
    def shm_name(self) -> str:
        """Name of the shared-memory block (for a :class:`StateReader`)."""
        return self._shm.name

    def read(self) -> tuple[float, FloatArray, FloatArray]:
        """The newest published ``(stamp, q, dq)`` (arrays reused by the next call)."""
        _read_state(self._ctl, self._state, self._buf, self._scratch)
        return float(self._buf[0]), self._q, self._dq

    def write(self, tau: FloatArray) -> None:
        """Publish ``tau`` [N·m]; the arm applies it from its next period."""
        ctl = self._ctl
        ctl[_CMD_SEQ] += 1
        self._tau[:] = tau
        ctl[_CMD_SEQ] += 1

    def stall(self, on: bool = True) -> None:
        """Fault injection: the arm keeps moving but stops publishing its state."""
        self._ctl[_STALL] = int(on)

    @property
    def counters(self) -> dict:
        """Arm-side counts: ``steps`` integrated, ``missed_commands`` (periods without a
        new torque once started), ``late`` (periods the arm's own loop woke too late for),
        ``gc`` (its collector: ``"automatic"``, ``"frozen"`` while it runs with
        ``gc_frozen``, ``"restored"`` after), ``gc_collections`` (run in its slack),
        ``priority`` (its ``SCHED_FIFO`` priority, 0: normal)."""
        if self._closed:  # (as the arm process left them)
            return dict(self._final)
        c = self._ctl
        return {
            "steps": int(c[_STEPS]),
            "missed_commands": int(c[_MISSED_CMDS]),
            "late": int(c[_LATE]),
            "gc": _GC_STATES[int(c[_GC])],
            "gc_collections": int(c[_GC_RUNS]),
            "priority": self.priority,
        }

    @property
    def pid(self) -> int | None:
        """The arm process's id (``None`` before it started)."""
        return self._proc.pid

    @property
    def alive(self) -> bool:
        """Whether the arm process runs."""
        return self._proc.is_alive()

    def close(self, wait: float = 5.0) -> None:
        """Stop the arm process and free the shared memory (idempotent).

        Args:
            wait: Time [s] the arm is given to stop by itself before it is terminated.
        """
        if self._closed:
            return
        self._closed = True
        try:  # (a Ctrl-C while the arm stops still frees the block)
            self._ctl[_STOP] = 1
            if self._proc.pid is not None:
                self._proc.join(timeout=wait)
            if self._proc.is_alive():
                self._proc.terminate()
                self._proc.join(timeout=5.0)
            self._conn.close()
            self._closed = False
            self._final = self.counters
            self._closed = True
        finally:
            self._closed = True
            with contextlib.suppress(Exception):
                del self._ctl, self._period, self._state, self._tau
                self._shm.close()
            self._shm.unlink()

    def __enter__(self) -> ProcessArm:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
