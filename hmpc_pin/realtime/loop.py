"""The fixed-rate loop: read the arm, step the controller, write the torque, every period.

Timing (interface period :math:`P = 1/f`, start :math:`t_0`):

* cycle :math:`k` has the absolute deadline :math:`D_k = t_0 + kP` (no drift: a late
  cycle does not move the later ones); the loop sleeps until :math:`D_k`, reads the
  newest state, and writes a torque;
* its **latency** is :math:`e_k - D_k`, from the deadline to the torque written, and its
  wake-up **jitter** :math:`w_k - D_k`; the cycle **misses** when :math:`e_k > D_k + P`
  (the arm's next period began without the new torque). A deadline that has already
  passed when the previous cycle ends is skipped and counted as missed (the arm holds
  the last torque through it);
* the controller runs every :math:`m = T_s / P` cycles (e.g. MPC at 100 Hz under a 1 kHz
  interface) at loop time :math:`kP`; the torque is held in between.

Paced by the arm (a :class:`~hmpc_pin.realtime.interface.PacedInterface`, e.g. a ROS 2
``/joint_states`` topic): cycle :math:`k` waits for the arm's next state and its deadline
is that state's stamp :math:`s_k` (on the interface's clock), so the latency
:math:`e_k - s_k` runs from the measurement to the torque written and the cycle misses
when :math:`e_k > s_k + P`; states that arrived while the loop was busy are periods not
answered (skipped, counted as missed); no state within ``watchdog`` stops the loop.

**Measured latency.** Where the stamps are on a clock the loop can read (an arm that paces
the loop; a polled interface with a ``stamp_clock()`` method, now on the stamps' clock),
every controller step records the
measurement's age when its torque is written, :math:`e_k - s_k` (``timing["age"]``;
``stats["measured_latency"]``, median/p99/max). That is the latency L the controller
compensates (``[controller] latency``, the guide "Sensing and latency"): the loop compares
its median with the declared one and warns (:class:`~hmpc_pin.exceptions.ValidityWarning`,
naming both) when they differ by more than
:func:`~hmpc_pin.compensation.bandwidth.latency_tolerance` (the bandwidth rule for the
controller's observer, at least half an interface period), once at least
:data:`MIN_LATENCY_SAMPLES` steps were measured. It is not fed to the controller
during the run: the latency changes the observer's torque alignment and the prediction,
which take effect at a reset, and a per-step value would carry the loop's jitter into the
model. Set the measured median in the config instead.

**Set-up** (:meth:`RealtimeLoop.run`), before the arm's clock: under a real-time policy
(``lock_memory="auto"``) the process's memory locked in RAM (``mlockall(MCL_CURRENT |
MCL_FUTURE)`` where permitted, unlocked after the run:
:func:`~.pacing.memory_locked`; ``stats["memory_lock"]`` records the outcome), so that no
page of the interpreter, the libraries or the records is faulted in or paged out during
the cycles; the whole heap collected and frozen (``gc_handling``); the controller reset
and, if it has ``warm_up``, its first step run once on the reset state and undone by a
second reset (the first step's one-time costs, not its torque); the records allocated;
what the set-up made collected; then, for an arm whose clock starts with its ``start()``
(``run(start=True)``: Franka's torque control, a ROS arm's first state), the start. None
of it costs the arm a cycle.

**Waiting** (:class:`~.pacing.Waker`, the loop's own sleep): the thread's timer slack is
1 ns during the run (and, if asked, ``cpu_latency``, the CPUs' idle-exit latency limited:
:func:`~.pacing.cpu_latency_limit`; not by default: on the virtual machine measured,
idle cores polling instead of halting brought stalls of about 100 ms to every real-time
thread); with ``spin = "auto"`` under a real-time policy it sleeps until a
stretch before the deadline, measured from its wake-ups, and busy-waits the rest. The
watchdog of a polled arm does not charge the loop's own late wake-up (more than a period)
to the arm (``stats["loop_stalls"]``). The cycles: :mod:`.cycles`; the stop sequence:
:mod:`.stop`.

Garbage collection (``gc_handling``): after start-up everything alive is moved out of
the collector's reach (:func:`gc.freeze`) and automatic collection is switched off; the
generation CPython would collect next (its counts against its thresholds) is collected
only in a cycle's slack, when at least ``gc_slack`` remains before the next deadline,
and deferred otherwise. Collector state is restored at the end.

Safe stop (:mod:`.safety`): on Ctrl-C (SIGINT sets a flag read at every cycle; a second
one raises :class:`KeyboardInterrupt`), a fault (non-finite state or torque, a
controller error such as a QP not solved, a measured state beyond the bounds),
``max_misses`` consecutive misses, or a stamp that stops advancing for ``watchdog``
seconds, the loop writes the safe torque at the last finite state in the same cycle,
runs the stop sequence of :mod:`.safety` (brake on the fresh states, at most ``hold``
seconds, then the held-safe torque :math:`g\\,G(q)`; after a watchdog stop the held-safe
torque at once, then the brake if the states resume within ``hold``), and returns the run
up to that point with ``complete = False`` and one line saying why, naming the setting
to relax after a watchdog or misses stop (``stop["brake"]``: how the brake ended). A
complete run ends with the same sequence. No path writes a non-finite torque: the
controller's is checked before it is written, the safe torques are computed from copies
of the last finite state.
"""

from __future__ import annotations

import contextlib
import gc
import math
import signal
import threading
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .._startup import was_interrupted
from ..compensation.bandwidth import compensation_bandwidth, latency_tolerance
from ..controllers.base import Controller
from ..exceptions import ArmError, ConfigError, HmpcError, ValidityWarning
from ..sim.result import Result
from ..tasks.base import as_reference
from .cycles import RELAX_MISSES, RELAX_WATCHDOG, Cycles
from .interface import PacedInterface, RobotInterface
from .pacing import (
    GCWatch,
    Tally,
    Waker,
    cpu_latency_limit,
    fifo_priority,
    memory_locked,
    realtime_policy,
    sleep_until,
    timer_slack,
)
from .records import RealtimeRun, Records, latency_stats
from .safety import SafetySettings
from .stop import StopSequence

#: The names of the parts before they had modules of their own (kept for callers).
_GCWatch, _Tally, _Records = GCWatch, Tally, Records

__all__ = [
    "RELAX_MISSES",
    "RELAX_WATCHDOG",
    "LoopSettings",
    "RealtimeLoop",
    "RealtimeRun",
    "fifo_priority",
    "latency_stats",
    "sleep_until",
]


#: The latency advice (``[controller] latency``) needs at least this many measured
#: controller steps (a failed start's single sample says nothing).
MIN_LATENCY_SAMPLES = 50


@dataclass(frozen=True)
class LoopSettings:
    """Rate and handling of the real-time loop.

    Attributes:
        rate: Interface rate f [Hz] (1000 for libfranka); ``1/rate`` must divide the
            controller's period.
        duration: Run length [s]; the loop runs cycles 0..round(duration·rate).
        gc_handling: Freeze the heap after start-up and collect only in the slack
            (module doc); ``False`` leaves Python's collector as it is.
        gc_slack: A collection runs only if at least this much [s] remains before the
            next deadline.
        spin: How the loop waits for a deadline (:class:`~.pacing.Waker`): ``"auto"``
            sleeps, then, when the loop's thread runs under a real-time policy
            (``SCHED_FIFO``: ``[realtime] priority``), busy-waits the last stretch, chosen
            from the wake-ups measured in the run (their 99th percentile, at most half a
            period); under normal scheduling it sleeps the whole wait (a thread that spins
            there is preempted more, not less: measured in the guide); a number [s] busy-waits
            that long before each deadline (below the period); 0 sleeps the whole wait.
            Applies to the loop's own sleep only (not with ``sleep=`` or an arm that paces
            the loop).
        warm_up: Wake early before each MPC cycle's deadline and call the controller's
            ``warm_up(t, q, dq, reference)`` (if it has one, e.g.
            :meth:`~hmpc_pin.controllers.hierarchical.HierarchicalMPC.warm_up`: a step on the
            last measured state, undone) so that the cycle's step finds its memory in the
            caches, then busy-wait to the deadline; 0 disables it. With the loop's own
            sleep, this [s] is the time first reserved for it, then the warm-up's measured
            99th percentile (a warm-up that would end after the deadline is skipped and
            counted); with ``sleep=``, the loop wakes this long before the deadline. Not
            with an arm that paces the loop (it waits for the state, not a deadline).
            Less than the period. Measured (``benchmarks/studies/realtime.py --steps-only``): the
            step after a 10 ms sleep 1.5× the step back to back with 2e-4, 10–15× without.
    """

    rate: float = 1000.0
    duration: float = 10.0
    gc_handling: bool = True
    gc_slack: float = 3e-4
    spin: float | str = "auto"
    warm_up: float = 2e-4

    def __post_init__(self):
        for name in ("rate", "duration", "gc_slack"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ConfigError(f"realtime.{name}", f"expected a number > 0, got {value!r}")
        spin = self.spin
        if spin != "auto" and not (
            isinstance(spin, (int, float))
            and not isinstance(spin, bool)
            and 0 <= spin < 1.0 / self.rate
        ):
            raise ConfigError(
                "realtime.spin",
                f'expected "auto" or a time [s] >= 0 and below the period 1/rate = '
                f"{1.0 / self.rate:g} s, got {spin!r}",
            )
        warm = self.warm_up
        if not (isinstance(warm, (int, float)) and 0 <= warm < 1.0 / self.rate):
            raise ConfigError(
                "realtime.warm_up",
                f"expected a time [s] >= 0 and below the period 1/rate = {1.0 / self.rate:g} s,"
                f" got {warm!r}",
            )

    @property
    def period(self) -> float:
        """Interface period P = 1 / rate [s]."""
        return 1.0 / self.rate

    def decimation(self, Ts: float) -> int:
        """Cycles per controller step, m = Ts · rate (a whole number >= 1)."""
        m = round(Ts * self.rate)
        if m < 1 or abs(m / self.rate - Ts) > 1e-9 * Ts:
            raise ConfigError(
                "realtime.rate",
                f"rate={self.rate:g} Hz does not divide the controller period Ts={Ts:g} s; "
                "expected Ts·rate to be a whole number >= 1 (e.g. 1000 Hz for Ts = 0.01 s)",
            )
        return m


def _inner(controller):
    """The controller inside any wrappers (the one with the settings)."""
    c = controller
    while not hasattr(c, "latency") and hasattr(c, "controller"):
        c = c.controller
    return c


def _declared_latency(controller) -> float | None:
    """The latency [s] the controller compensates (``None``: it has no such setting)."""
    latency = getattr(_inner(controller), "latency", None)
    return None if latency is None else float(latency)


class RealtimeLoop(Cycles, StopSequence):
    """Run a controller against a :class:`~hmpc_pin.realtime.interface.RobotInterface`
    at a fixed rate (module doc).

    Args:
        interface: The arm.
        controller: Any :class:`~hmpc_pin.controllers.base.Controller`; its ``Ts`` is a
            whole number of interface periods.
        reference: A :class:`~hmpc_pin.tasks.base.Reference` (or what
            :func:`~hmpc_pin.tasks.base.as_reference` adapts).
        safe_torque: :class:`~hmpc_pin.realtime.safety.SafeTorque` (or any
            ``f(q, dq) -> tau``).
        settings: Rate, duration, garbage-collection handling.
        safety: Bounds, k, watchdog, hold.
        clock: Monotonic seconds (default :func:`time.perf_counter`).
        sleep: ``sleep(deadline)``: return when ``clock()`` has reached ``deadline``
            (default: the loop's :class:`~.pacing.Waker` on ``clock``, as ``settings.spin``
            says).
        joint_names: Stored in the result.
        meta: Stored in the result's ``meta``.
        on_step: ``on_step(t)``, called after the torque of each controller step is
            written (in the cycle's slack), with the loop time t [s]: publish estimates.
        lock_memory: Lock the process's memory in RAM for the run (module doc,
            "Set-up"; ``stats["memory_lock"]`` says how it went); ``"auto"``: when the
            loop's thread runs under a real-time policy (where its latency is the point).
        cpu_latency: The CPUs' idle-exit latency limit [µs] to hold during the run (module
            doc, "Waiting"; ``stats["cpu_latency"]`` says how it went); ``None`` (default):
            none; ``"auto"``: 0 under a real-time policy, else none.

    Against a :class:`~hmpc_pin.realtime.interface.PacedInterface` the loop is paced by
    the arm's states and keeps time on the interface's clock (``clock``, ``sleep`` and
    ``spin`` do not apply).
    """

    def __init__(
        self,
        interface: RobotInterface,
        controller: Controller,
        reference,
        safe_torque: Callable,
        settings: LoopSettings,
        safety: SafetySettings,
        *,
        clock: Callable[[], float] = time.perf_counter,
        sleep: Callable[[float], None] | None = None,
        joint_names: tuple[str, ...] = (),
        meta: dict | None = None,
        on_step: Callable[[float], None] | None = None,
        lock_memory: bool | str = "auto",
        cpu_latency: int | str | None = None,
    ):
        self.interface, self.controller = interface, controller
        self.lock_memory, self.cpu_latency = lock_memory, cpu_latency
        self._memory_lock = self._cpu_latency = "off"  # the last run's outcomes
        self.reference = as_reference(reference)
        self.safe_torque, self.settings, self.safety = safe_torque, settings, safety
        self.paced = isinstance(interface, PacedInterface)
        fixed_spin = settings.spin != "auto" and settings.spin > 0
        if self.paced:
            for name, given in (
                ("spin", fixed_spin),
                ("sleep=", sleep is not None),
                ("clock=", clock is not time.perf_counter),
            ):
                if given:
                    raise ConfigError(
                        "realtime.spin" if name == "spin" else name,
                        f"{name} does not apply to an arm that paces the loop "
                        f"({type(interface).__name__}: the loop waits for its states, on "
                        "its clock); drop it",
                    )
            clock = interface.clock  # type: ignore[union-attr]
        self.clock = clock
        self.on_step = on_step
        self._pending_reference = None
        self.superseded = None  # the pending reference the last set_reference replaced
        self._reference_lock = threading.Lock()  # the swap against set_reference
        self.time = 0.0
        #: Whether the loop waits with its own :class:`~.pacing.Waker` (not paced by the
        #: arm, no sleep function given).
        self.sleep_is_default = sleep is None and not self.paced
        self._waker: Waker | None = None
        if self.paced:
            wait = interface.wait  # type: ignore[union-attr]
            self.sleep = lambda d: wait(max(0.0, d - clock()))
        elif sleep is not None:
            if fixed_spin:
                raise ConfigError(
                    "realtime.spin",
                    f"spin={settings.spin:g} s does not apply with a sleep function given to "
                    "the loop (it spins in the default sleep only); set spin = 0 or drop sleep=",
                )
            self.sleep = sleep
        else:
            spin = None if settings.spin == "auto" else float(settings.spin)
            self._waker = Waker(clock, settings.period, spin, warm=settings.warm_up)
            self.sleep = self._waker.until
        self._warm_up = (
            getattr(controller, "warm_up", None)
            if settings.warm_up > 0 and not self.paced
            else None
        )
        self._has_overdue = self.paced and hasattr(interface, "overdue")
        self._has_arrival = self.paced and hasattr(interface, "arrival")
        self._t0 = 0.0  # the first cycle's deadline (set when the cycles begin)
        self._stalls = 0  # the loop's own late wake-ups not charged to the arm (watchdog)
        self.joint_names = tuple(joint_names)
        self.meta = dict(meta or {})
        self.decimation = settings.decimation(controller.Ts)
        self._interrupt = 0
        self._requested: str | None = None
        self._started = False
        self._finished = threading.Event()
        self._last_state: tuple[np.ndarray, np.ndarray] | None = None
        self._held_tau = np.zeros(interface.nq)
        self._fresh = (0.0, 0.0)  # the last stamp and when it came (the watchdog's)
        self._rec: Records | None = None
        self._tally: Tally | None = None
        self._seen = 0  # the cycles progress() has reported
        self._ran = 0  # of which run (not skipped)
        self._cycles_done = self._steps_done = 0  # cycles and steps recorded (progress())

    def set_reference(self, reference, at: float = 0.0, base=None) -> bool:
        """Replace the reference from the first controller step at or after loop time
        ``at`` [s] (default: the next step) on; callable from another thread (the loop
        swaps it in at a step). A reference still pending is superseded (as a new
        trajectory replaces the last in ros2_control's trajectory controller). The caller
        checks it (limits, continuity at that time).

        Args:
            base: The reference the caller made ``reference`` continuous with: if the loop
                has swapped in another since, ``reference`` is not taken.

        Returns:
            Whether it was taken (False only when ``base`` is no longer the reference).
            ``self.superseded`` is then the pending reference it replaced (``None``: none).
        """
        with self._reference_lock:
            if base is not None and self.reference is not base:
                return False
            previous = self._pending_reference
            self.superseded = None if previous is None else previous[0]
            self._pending_reference = (as_reference(reference), float(at))
            return True

    @property
    def pending_reference(self):
        """The reference set but not yet swapped in (``None``: none)."""
        pending = self._pending_reference
        return None if pending is None else pending[0]

    def progress(self) -> dict | None:
        """Where the run is, for a status line printed by another thread while it runs
        (read from the run's records: the cycle does no work for it). ``None`` before the
        first cycle.

        Returns:
            ``t`` (loop time of the last controller step [s]), ``cycles`` (run so far),
            ``of`` (the run's cycles), ``misses``, ``longest`` (longest run of misses),
            ``worst_us`` (the worst latency [µs] since the previous call),
            ``error`` (max |q − q_ref| [rad] over the joints at the last step).
        """
        rec, tally = self._rec, self._tally
        if rec is None or tally is None:
            return None
        # only the cycles since the last call: the caller holds the GIL the loop needs
        done, last = rec.done, self._cycles_done
        window = done[self._seen : last]
        window = window[np.isfinite(window)]
        self._ran += window.size
        if self._ran == 0:
            return None
        self._seen = last
        error = math.nan
        j0 = self._steps_done
        for j in range(j0 - 1, max(j0 - 3, -1), -1):  # (the newest row may be half written)
            e = rec.traj["q"][j] - rec.traj["q_ref"][j]
            if np.isfinite(e).all():
                error = float(np.abs(e).max())
                t = float(rec.t[j])
                break
        else:
            t = last * self.settings.period
        return {
            "t": t,
            "cycles": self._ran,
            "of": int(done.size),
            "misses": tally.misses,
            "longest": tally.worst_run,
            "worst_us": float(1e6 * window.max()) if window.size else math.nan,
            "error": error,
        }

    # ------------------------------------------------------------------ stopping
    def request_stop(self) -> None:
        """Ask the loop to stop safely at its next cycle (what SIGINT does)."""
        self._interrupt += 1

    def request_stop_by(self, cause: str = "deactivated", timeout: float | None = None) -> bool:
        """Stop at the next cycle with ``cause`` (e.g. a ROS lifecycle node deactivated;
        callable from another thread) and wait until the stop sequence has run (at most
        ``timeout`` [s], default ``safety.hold`` + 1 s). Returns whether it has."""
        self._requested = cause
        wait = self.safety.hold + 1.0 if timeout is None else timeout
        return self._finished.wait(wait) if self._started else True

    def _on_sigint(self, signum, frame) -> None:
        self._interrupt += 1
        if self._interrupt > 1:
            raise KeyboardInterrupt

    # ---------------------------------------------------------------------- run
    def run(self, q0=None, dq0=None, *, start: bool = False) -> RealtimeRun:
        """Run until the end or a safe stop.

        Args:
            q0, dq0: The state to reset the controller to (default: the first reading).
            start: Call the interface's ``start()`` (its clock starts with it: Franka's
                torque control; a ROS arm's first state) after the set-up (module doc,
                "Set-up"), so that none of it costs the arm a cycle. Give ``q0`` (and
                ``dq0``) with it: the controller is then reset before the start, else
                after it, at the first state.
        """
        main = threading.current_thread() is threading.main_thread()
        old_handler = signal.signal(signal.SIGINT, self._on_sigint) if main else None
        if was_interrupted():  # a Ctrl-C swallowed while the run was set up: stop safely
            self._on_sigint(signal.SIGINT, None)
        gc_was_enabled = gc.isenabled()
        self._gc_watch = GCWatch(self.clock)
        gc.callbacks.append(self._gc_watch)
        self._started = True
        try:
            with contextlib.ExitStack() as stack:
                realtime = realtime_policy()  # (what the "auto" settings follow)
                lock = realtime if self.lock_memory == "auto" else bool(self.lock_memory)
                limit = self.cpu_latency
                limit = (0 if realtime else None) if limit == "auto" else limit
                self._memory_lock = stack.enter_context(memory_locked(lock))
                self._cpu_latency = stack.enter_context(cpu_latency_limit(limit))  # type: ignore[arg-type]
                if self._waker is not None:
                    stack.enter_context(timer_slack(1))
                    if self.settings.spin == "auto":  # spinning pays under a real-time policy
                        self._waker.adapt(realtime)
                return self._run(q0, dq0, start)
        except BaseException:
            # Whatever went wrong (a bug, a second Ctrl-C): the arm gets the held-safe
            # torque at the last finite position before the error propagates (nothing
            # refreshes it after this: no velocity term).
            if self._last_state is not None:
                self._held_write(self._last_state[0])
            raise
        finally:
            self._finished.set()
            gc.callbacks.remove(self._gc_watch)
            if self.settings.gc_handling:
                gc.unfreeze()
                if gc_was_enabled:
                    gc.enable()
            if main:
                signal.signal(signal.SIGINT, old_handler)

    def _first_state(self):
        """The arm's first state, copied; refused (nothing sent) if the loop cannot start
        from it."""
        iface = self.interface
        stamp, q, dq = iface.read()
        q_last, dq_last = np.array(q, dtype=float), np.array(dq, dtype=float)
        refused = self._start_fault(q_last, dq_last)
        if refused is not None:  # before any command: nothing is sent, the arm keeps its own
            raise ArmError(
                f"the first state from the arm ({type(iface).__name__}) is refused: {refused}; "
                "nothing was sent to the arm. Check its driver (or the limits in "
                "[realtime]) and start again"
            )
        return stamp, q_last, dq_last

    def _prepare(self, q0, dq0) -> None:
        """Reset the controller at ``(q0, dq0)``; if it can warm up (it has ``warm_up``), run
        its first step on that state and reset it again: the first step's one-time costs
        (memory, the solver's first factorisation, the Python path; ~150 µs for the Panda's
        MPC in a fresh process) are paid here, not in the first cycle."""
        ctrl = self.controller
        q0, dq0 = np.array(q0, dtype=float), np.array(dq0, dtype=float)
        ctrl.reset(q0, dq0)
        if getattr(ctrl, "warm_up", None) is None:
            return
        with contextlib.suppress(HmpcError):  # the real step reports it
            _inner(ctrl).step(0.0, q0.copy(), dq0.copy(), self.reference)
        ctrl.reset(q0, dq0)

    def _run(self, q0, dq0, start: bool) -> RealtimeRun:
        st, iface = self.settings, self.interface
        K = round(st.duration * st.rate)
        if st.gc_handling:  # the whole heap, before the arm's clock runs
            gc.collect()
            gc.freeze()
        first = None if start else self._first_state()
        if first is not None or q0 is not None:  # the controller ready before the start
            if dq0 is None:
                dq0 = np.zeros(iface.nq) if first is None else first[2]
            self._prepare(first[1] if q0 is None else q0, dq0)  # type: ignore[index]
        rec = Records(K // self.decimation + 2, K + 1, iface.nq)
        tally = Tally()
        self._rec, self._tally, self._seen = rec, tally, 0  # (read by progress())
        self._ran = self._cycles_done = self._steps_done = 0
        if st.gc_handling:  # what the set-up made (the heap is frozen: little to walk)
            gc.collect()
            gc.freeze()
            gc.disable()
        if start:
            iface.start()  # type: ignore[attr-defined]
            first = self._first_state()
            if q0 is None:  # no state known before the start: reset at the first one
                self._prepare(first[1], first[2] if dq0 is None else dq0)
        stamp, q_last, dq_last = first  # type: ignore[misc]
        self._last_state = (q_last, dq_last)
        watch = self._gc_watch
        watch.count, watch.longest = 0, 0.0  # from the first cycle on
        stop, k, stamp, deadline, wrote = self._cycles(K, rec, tally, q_last, dq_last, stamp)
        return self._finish(stop, k, K, rec, tally, q_last, dq_last, stamp, deadline, wrote)

    def _finish(
        self,
        stop,
        k: int,
        K: int,
        rec: Records,
        tally: Tally,
        q_last,
        dq_last,
        stamp: float,
        deadline: float,
        wrote: bool,
    ) -> RealtimeRun:
        """The stop sequence (:mod:`.stop`), then the statistics and the run."""
        st, ctrl = self.settings, self.controller
        P, m = st.period, self.decimation
        # periods the arm's stamps passed with no state for them (before the brake's)
        gaps = int(getattr(self.interface, "gaps", 0)) if self.paced else 0
        stop_record, brake = self._stop_sequence(
            stop, k, K, q_last, dq_last, stamp, deadline, wrote
        )
        timing = rec.timing_stats()
        cycles_run = timing.pop("cycles_run")
        watch = self._gc_watch
        stats = {
            "rate": st.rate,
            "controller_Ts": float(ctrl.Ts),
            "decimation": m,
            "cycles": K + 1,
            "cycles_run": cycles_run,
            "misses": tally.misses,
            "skipped": tally.skipped,
            "miss_fraction": tally.misses / max(1, cycles_run + tally.skipped),
            "max_consecutive_misses": tally.worst_run,
            **timing,
            # measurement -> torque written, at the controller's steps (None: the stamps
            # are on the arm's own clock) against the declared [controller] latency
            "measured_latency": latency_stats(rec.age) if self._stamp_clocked() else None,
            "declared_latency": _declared_latency(ctrl),
            "gc_handling": st.gc_handling,
            "gc_collections": tally.gc_runs,
            "gc_deferred": tally.gc_deferred,
            "gc_max_s": tally.gc_max,
            "gc_all_collections": watch.count,
            "gc_all_max_s": watch.longest,
            "period_us": 1e6 * P,
            "wait": self._wait_stats(),
            "loop_stalls": self._stalls,
            "memory_lock": self._memory_lock,
            "cpu_latency": self._cpu_latency,
            "brake": brake,
            "arm_gaps": gaps,
        }
        self._check_latency(stats)
        meta = {**self.meta, "realtime": stats, "stop": stop_record}
        j = rec.j
        message = "" if stop_record is None else stop_record["reason"]
        gapped = stop is None and gaps > self.safety.max_misses
        if gapped:
            message = (
                f"the arm's stamps passed {gaps} periods of {1e3 * P:g} ms with no state for "
                f"them (more than realtime.max_misses = {self.safety.max_misses}): the run "
                "is not complete. An arm publishing slower than the rate, or states on "
                "another clock than the controller's (a simulator's: run it with "
                "use_sim_time)"
            )
        result = Result(
            t=rec.t[:j].copy(),
            **{name: arr[:j].copy() for name, arr in rec.traj.items()},
            joint_names=self.joint_names,
            complete=stop is None and not gapped,
            message=message,
            meta=meta,
        )
        return RealtimeRun(result, rec.timing(), stats, stop_record)

    def _wait_stats(self) -> dict | None:
        """How the loop waited (``None``: paced by the arm, or a sleep function given):
        ``spin`` (the setting), ``lead_us`` (the busy-wait stretch at the end [µs]),
        ``spun_s`` (time spent busy-waiting [s]), ``warm_late`` and ``warm_skipped``
        (warm-ups that ended after their deadline, and skipped for want of time)."""
        w = self._waker
        if w is None:
            return None
        return {
            "spin": self.settings.spin,
            "adaptive": w.adaptive,
            "lead_us": 1e6 * w.lead,
            "spun_s": w.spun,
            "warm_late": w.late_work,
            "warm_skipped": w.skipped_work,
        }

    def _stamp_clocked(self) -> bool:
        """Whether the measurement's age can be measured (the module doc, "Measured latency")."""
        return self.paced or getattr(self.interface, "stamp_clock", None) is not None

    def _check_latency(self, stats: dict) -> None:
        """Warn when the measured latency (median) lies farther from the declared
        ``[controller] latency`` than :func:`~hmpc_pin.compensation.bandwidth.latency_tolerance`
        allows for the controller's observer; record the tolerance in ``stats``."""
        measured, declared = stats["measured_latency"], stats["declared_latency"]
        stats["latency_tolerance"] = None
        if measured is None or declared is None or not np.isfinite(measured["median_us"]):
            return
        if measured.get("count", 0) < MIN_LATENCY_SAMPLES:  # no advice from a few samples
            return
        inner = _inner(self.controller)
        bandwidth = None
        comp, robot = getattr(inner, "compensation", None), getattr(inner, "robot", None)
        if comp is not None and robot is not None and self._last_state is not None:
            bandwidth = compensation_bandwidth(comp, robot.mass_matrix(self._last_state[0]))
        median, p99 = 1e-6 * measured["median_us"], 1e-6 * measured["p99_us"]
        tol = latency_tolerance(
            bandwidth, float(self.controller.Ts), self.settings.period, over=median < declared
        )
        stats["latency_tolerance"] = tol
        if abs(median - declared) <= tol:
            return
        what = (
            "older than declared: the observer and the prediction pair the measurement "
            "with the wrong torques"
            if median > declared
            else "younger than declared: the controller predicts further ahead than the "
            "measurement is old"
        )
        warnings.warn(
            f"measured latency (measurement -> torque written) median {1e3 * median:.3g} ms, "
            f"p99 {1e3 * p99:.3g} ms against the declared [controller] latency = "
            f"{declared:g} s: {what}; beyond the tolerance {1e3 * tol:.3g} ms (the bandwidth "
            "rule for this observer, at least half an interface period); set "
            f"[controller] latency = {median:.3g}",
            ValidityWarning,
            stacklevel=3,
        )

    def _start_fault(self, q, dq) -> str | None:
        """Why the first state cannot start the loop (non-finite, beyond the bounds), or
        ``None``."""
        sf = self.safety
        if (q >= sf.lower).all() and (q <= sf.upper).all() and (np.abs(dq) <= sf.velocity).all():
            return None
        return self._state_fault(q, dq)

    def _state_fault(self, q, dq) -> str:
        return self.safety.state_fault(q, dq, self.joint_names)
