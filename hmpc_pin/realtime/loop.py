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
from .interface import PacedInterface, RobotInterface
from .pacing import GCWatch, Tally, fifo_priority, sleep_until
from .records import RealtimeRun, Records, latency_stats
from .safety import SafetySettings

#: The names of the parts before they had modules of their own (kept for callers).
_GCWatch, _Tally, _Records = GCWatch, Tally, Records

__all__ = [
    "LoopSettings",
    "RealtimeLoop",
    "RealtimeRun",
    "fifo_priority",
    "latency_stats",
    "sleep_until",
]


#: Appended to a stop's reason: the setting to relax when the machine, not the arm, was
#: late (the config key and the command line's override).
RELAX_MISSES = (
    "; if the machine was loaded rather than the arm faulty, relax realtime.max_misses "
    "(--max-misses K)"
)
RELAX_WATCHDOG = (
    "; if the machine was loaded rather than the arm gone, relax realtime.watchdog (--watchdog S)"
)

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
        spin: Busy-wait this long [s] before each deadline instead of sleeping
            (:func:`sleep_until`); 0 sleeps the whole wait. Less than the period.
        warm_up: Wake this long [s] before each MPC cycle's deadline and call the
            controller's ``warm_up(t, q, dq, reference)`` (if it has one, e.g.
            :meth:`~hmpc_pin.controllers.hierarchical.HierarchicalMPC.warm_up`: a step on the
            last measured state, undone) so that the cycle's step finds its memory in the
            caches, then busy-wait to the deadline (with the default sleep); 0 disables it. Not
            with an arm that paces the loop (it waits for the state, not a deadline).
            Less than the period. Measured (``benchmarks/realtime.py --steps-only``): the
            step after a 10 ms sleep 1.5× the step back to back with 2e-4, 10–15× without.
    """

    rate: float = 1000.0
    duration: float = 10.0
    gc_handling: bool = True
    gc_slack: float = 3e-4
    spin: float = 0.0
    warm_up: float = 2e-4

    def __post_init__(self):
        for name in ("rate", "duration", "gc_slack"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ConfigError(f"realtime.{name}", f"expected a number > 0, got {value!r}")
        spin = self.spin
        if not (isinstance(spin, (int, float)) and 0 <= spin < 1.0 / self.rate):
            raise ConfigError(
                "realtime.spin",
                f"expected a time [s] >= 0 and below the period 1/rate = {1.0 / self.rate:g} s,"
                f" got {spin!r}",
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


class RealtimeLoop:
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
            (default: :func:`sleep_until` on ``clock``).
        joint_names: Stored in the result.
        meta: Stored in the result's ``meta``.
        on_step: ``on_step(t)``, called after the torque of each controller step is
            written (in the cycle's slack), with the loop time t [s]: publish estimates.

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
    ):
        self.interface, self.controller = interface, controller
        self.reference = as_reference(reference)
        self.safe_torque, self.settings, self.safety = safe_torque, settings, safety
        self.paced = isinstance(interface, PacedInterface)
        if self.paced:
            for name, given in (
                ("spin", settings.spin > 0),
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
        if self.paced:
            wait = interface.wait  # type: ignore[union-attr]
            self.sleep = lambda d: wait(max(0.0, d - clock()))
        elif sleep is not None and settings.spin > 0:
            raise ConfigError(
                "realtime.spin",
                f"spin={settings.spin:g} s does not apply with a sleep function given to the "
                "loop (it spins in the default sleep only); set spin = 0 or drop sleep=",
            )
        else:
            self.sleep = (
                sleep if sleep is not None else (lambda d: sleep_until(d, clock, settings.spin))
            )
        # After warm_up the default sleep busy-waits to the deadline (the core stays awake and
        # the caches stay this process's); a given sleep function is called instead.
        self._spin_after_warm_up = sleep is None and not self.paced
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
        done = rec.done
        ran = np.flatnonzero(np.isfinite(done))
        if ran.size == 0:
            return None
        last = int(ran[-1]) + 1
        window = done[self._seen : last]
        window = window[np.isfinite(window)]
        self._seen = last
        steps = np.flatnonzero(np.isfinite(rec.t))
        error = math.nan
        for j in steps[-2:][::-1]:  # (the newest row may be half written)
            e = rec.traj["q"][j] - rec.traj["q_ref"][j]
            if np.isfinite(e).all():
                error = float(np.abs(e).max())
                t = float(rec.t[j])
                break
        else:
            t = last * self.settings.period
        return {
            "t": t,
            "cycles": int(ran.size),
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
    def run(self, q0=None, dq0=None) -> RealtimeRun:
        """Run until the end or a safe stop.

        Args:
            q0, dq0: The state to reset the controller to (default: the first reading).
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
            return self._run(q0, dq0)
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

    def _run(self, q0, dq0) -> RealtimeRun:
        st, iface, ctrl = self.settings, self.interface, self.controller
        K = round(st.duration * st.rate)
        stamp, q, dq = iface.read()
        q_last, dq_last = np.array(q, dtype=float), np.array(dq, dtype=float)
        refused = self._start_fault(q_last, dq_last)
        if refused is not None:  # before any command: nothing is sent, the arm keeps its own
            raise ArmError(
                f"the first state from the arm ({type(iface).__name__}) is refused: {refused}; "
                "nothing was sent to the arm. Check its driver (or the limits in "
                "[realtime]) and start again"
            )
        self._last_state = (q_last, dq_last)
        ctrl.reset(q_last if q0 is None else q0, dq_last if dq0 is None else dq0)
        rec = Records(K // self.decimation + 2, K + 1, iface.nq)
        tally = Tally()
        self._rec, self._tally, self._seen = rec, tally, 0  # (read by progress())
        if st.gc_handling:
            gc.collect()
            gc.freeze()
            gc.disable()
        watch = self._gc_watch
        watch.count, watch.longest = 0, 0.0  # from the first cycle on
        stop, k, stamp, deadline, wrote = self._cycles(K, rec, tally, q_last, dq_last, stamp)
        return self._finish(stop, k, K, rec, tally, q_last, dq_last, stamp, deadline, wrote)

    def _cycles(self, K: int, rec: Records, tally: Tally, q_last, dq_last, stamp: float):
        """The cycles 0..K: wait, read, step every ``decimation`` cycles, write, record.

        Returns:
            ``(stop, k, stamp, deadline, wrote)``: the stop (``(cause, reason)`` or
            ``None``), the cycle it came at, the last stamp, that cycle's deadline and
            whether any command was written.
        """
        st, sf = self.settings, self.safety
        iface, ctrl, ref = self.interface, self.controller, self.reference
        clock, sleep = self.clock, self.sleep
        P, m = st.period, self.decimation
        # The measurement's age when its torque is written, on the stamps' clock: the
        # loop's own against an arm that paces it, else the interface's stamp_clock() if
        # it offers one (stamps on another clock cannot be compared).
        stamp_clock = clock if self.paced else getattr(iface, "stamp_clock", None)
        lower, upper, vmax = sf.lower, sf.upper, sf.velocity
        watchdog, max_misses = sf.watchdog, sf.max_misses
        tau = np.zeros(iface.nq)
        wrote = False
        j = 0
        handle_gc = st.gc_handling
        stop: tuple[str, str] | None = None
        next_mpc = 0
        paced, on_step = self.paced, self.on_step
        has_overdue = paced and hasattr(iface, "overdue")
        has_arrival = paced and hasattr(iface, "arrival")
        warm_lead = st.warm_up
        warm_up = getattr(ctrl, "warm_up", None) if warm_lead > 0 and not paced else None
        t0 = clock() + P
        self._fresh = (stamp, t0)  # the last stamp and when it was fresh (the watchdog)
        k = 0
        deadline = t0
        while k <= K:
            if paced:
                arrived, wake, stop = self._await_state(watchdog)
                if stop is not None:
                    break
                behind = arrived - 1  # states not answered: periods skipped
                # of which missed: those the arm reports overdue (a burst after its own
                # stall is not the loop's miss), else all
                late = min(behind, iface.overdue) if has_overdue else behind  # type: ignore[attr-defined]
                skipped_why = "states not answered"
            else:
                # Deadlines already passed are skipped (the arm holds the torque through them).
                behind = late = int((clock() - t0) / P) - k
                skipped_why = "periods skipped behind the clock"
            if behind > 0 and k > 0:
                skip = min(behind, K + 1 - k)
                late = min(late, skip)
                rec.missed[k : k + late] = True
                k += skip
                if tally.skip(skip, late, max_misses):
                    stop = (
                        "misses",
                        f"{tally.consecutive} consecutive missed deadlines "
                        f"(limit {max_misses}), {skip} {skipped_why}{RELAX_MISSES}",
                    )
                    break
                if k > K:
                    break
            if paced:
                stamp, q, dq = iface.read()
                self._fresh = (stamp, wake)
                # the deadline follows the arrival (a constant transport delay is no miss)
                deadline = iface.arrival if has_arrival else stamp  # type: ignore[attr-defined]
            else:
                deadline = t0 + k * P
                if warm_up is not None and k >= next_mpc and k > 0:
                    # in the slack before an MPC cycle: the step on the last state, undone
                    sleep(deadline - warm_lead)
                    warm_up(k * P, q_last, dq_last, ref)
                    if self._spin_after_warm_up:
                        while clock() < deadline:
                            pass
                sleep(deadline)
                wake = clock()
                stop = self._requested_stop()
                if stop is not None:
                    break
                stamp, q, dq = iface.read()
                stop = self._watch(stamp, wake, watchdog)
                if stop is not None:
                    break
            # One comparison each in the common case; NaN fails every one of them.
            if not ((q >= lower).all() and (q <= upper).all() and (np.abs(dq) <= vmax).all()):
                stop = ("fault", self._state_fault(q, dq))
                break
            q_last[:] = q
            dq_last[:] = dq
            is_mpc = k >= next_mpc
            if is_mpc:
                if self._pending_reference is not None:
                    ref = self._swap_reference(k * P, ref)
                try:
                    # copies: the interface may reuse its arrays, a controller may keep them
                    tau = ctrl.step(k * P, q.copy(), dq.copy(), ref)
                except HmpcError as exc:
                    stop = ("fault", f"controller: {exc}")
                    break
                if not np.isfinite(tau).all():
                    stop = ("fault", f"non-finite torque from the controller: {tau.tolist()}")
                    break
                next_mpc += m
                while next_mpc <= k:
                    next_mpc += m
            iface.write(tau)
            done = clock()
            wrote = True
            if is_mpc and stamp_clock is not None:
                rec.age[k] = (done if self.paced else stamp_clock()) - stamp
            # ---- bookkeeping, in the slack
            rec.cycle(k, wake - deadline, done - deadline, stamp, is_mpc)
            if is_mpc:
                rec.step(j, k * P, q, dq, tau, ctrl.disturbance_estimate, ref)
                j += 1
                self.time = k * P
                if on_step is not None:
                    on_step(k * P)
            if done > deadline + P:
                rec.missed[k] = True
                if tally.miss(max_misses):
                    stop = (
                        "misses",
                        f"{tally.consecutive} consecutive missed deadlines "
                        f"(limit {max_misses}); last latency {1e6 * (done - deadline):.0f} us "
                        f"for a {1e6 * P:.0f} us period{RELAX_MISSES}",
                    )
                    k += 1
                    break
            else:
                tally.consecutive = 0
            if handle_gc:
                tally.collect(k, deadline + P, clock, st.gc_slack, rec.gc)
            k += 1
        rec.j = j
        return stop, k, stamp, deadline, wrote

    def _await_state(self, watchdog: float) -> tuple[int, float, tuple[str, str] | None]:
        """Against an arm that paces the loop: wait for its next state (at most the
        watchdog). Returns ``(states arrived, wake time, stop or None)``."""
        arrived = self.interface.wait(watchdog)  # type: ignore[attr-defined]
        wake = self.clock()
        stop = self._requested_stop()
        if stop is None and not arrived:
            received = getattr(self.interface, "received", None)
            streamed = (
                "" if received is None else f"the arm stopped streaming after {received} states: "
            )
            stop = (
                "watchdog",
                f"{streamed}no new state from the arm for "
                f"{1e3 * watchdog:g} ms (watchdog), last stamp "
                f"{self._fresh[0]:.6g} s{RELAX_WATCHDOG}",
            )
        return arrived, wake, stop

    def _requested_stop(self) -> tuple[str, str] | None:
        """Ctrl-C or a stop asked by the program (a lifecycle deactivate), else ``None``."""
        if self._interrupt:
            return ("interrupted", "interrupted (Ctrl-C)")
        if self._requested is not None:
            return (self._requested, f"stop requested ({self._requested})")
        return None

    def _watch(self, stamp: float, wake: float, watchdog: float) -> tuple[str, str] | None:
        """The watchdog of a polled arm: a stamp that has not advanced for longer than
        ``watchdog`` [s] is a stop."""
        last, fresh_at = self._fresh
        if stamp != last:
            self._fresh = (stamp, wake)
            return None
        if wake - fresh_at <= watchdog:
            return None
        return (
            "watchdog",
            f"no new state from the arm for {1e3 * (wake - fresh_at):.1f} ms "
            f"(watchdog {1e3 * watchdog:g} ms), last stamp {stamp:.6g} s{RELAX_WATCHDOG}",
        )

    def _swap_reference(self, t: float, ref):
        """The pending reference if its time ``at`` has come (under the lock that
        :meth:`set_reference` takes), else ``ref``."""
        with self._reference_lock:
            pending = self._pending_reference
            if pending is not None and t >= pending[1] - 1e-9:
                ref, self._pending_reference = pending[0], None
                self.reference = ref
        return ref

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
        """The stop sequence (module doc, "Safe stop"; with no fresh state to brake on, the
        held-safe torque; before the first command, nothing), then the statistics and
        the run."""
        st, ctrl, clock = self.settings, self.controller, self.clock
        P, m = st.period, self.decimation
        stop_record = None
        # periods the arm's stamps passed with no state for them (before the brake's)
        gaps = int(getattr(self.interface, "gaps", 0)) if self.paced else 0
        fresh = stop is None or stop[0] != "watchdog"
        # stopped by its operator (Ctrl-C, a lifecycle deactivate) before its first command:
        # the arm never had one from this loop, so none is sent now either
        unsent = stop is not None and stop[0] in ("interrupted", "deactivated") and not wrote
        if unsent:
            cause, reason = stop  # type: ignore[misc]
            cycle = min(k, K)
            stop_record = {
                "cause": cause,
                "reason": f"stopped at t={cycle * P:.4f} s (cycle {cycle}) before the first "
                f"command: {reason}; nothing was sent to the arm",
                "cycle": int(cycle),
                "t": cycle * P,
                "safe_tau": None,
                "q": q_last.tolist(),
                "dq": dq_last.tolist(),
            }
        elif stop is not None:
            cause, reason = stop
            detected = clock()
            tau_safe = self._safe_write(q_last, dq_last) if fresh else self._held_write(q_last)
            written = clock()
            cycle = min(k, K)
            stop_record = {
                "cause": cause,
                "reason": f"safe stop at t={cycle * P:.4f} s (cycle {cycle}): {reason}; "
                + self._safe_words(),
                "cycle": int(cycle),
                "t": cycle * P,
                "safe_tau": tau_safe.tolist(),
                "q": q_last.tolist(),
                "dq": dq_last.tolist(),
                "safe_after_deadline": written - deadline,
                "safe_after_detection": written - detected,
            }
        elif fresh:
            self._safe_write(q_last, dq_last)
        if unsent:
            brake = {
                "ended": "nothing sent",
                "duration": 0.0,
                "states": 0,
                "speed": float(np.max(np.abs(dq_last), initial=0.0)),
                "q": q_last.tolist(),
                "held_tau": None,
            }
        else:
            last = self._fresh[0] if not self.paced else stamp
            brake = self._brake(P, q_last, dq_last, last, fresh, resume=not fresh)
        if stop_record is not None:
            stop_record["brake"] = brake
        done_a, wake_a = rec.done, rec.wake
        cycles_run = int(np.count_nonzero(np.isfinite(done_a)))
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
            "latency": latency_stats(done_a),
            "wake": latency_stats(wake_a),
            "compute": latency_stats(done_a - wake_a),
            "latency_mpc": latency_stats(np.where(rec.mpc, done_a, np.nan)),
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
        timing = {
            "wake": wake_a,
            "latency": done_a,
            "compute": done_a - wake_a,
            "stamp": rec.stamp,
            "missed": rec.missed,
            "mpc": rec.mpc,
            "gc": rec.gc,
            "age": rec.age,
        }
        return RealtimeRun(result, timing, stats, stop_record)

    def _stamp_clocked(self) -> bool:
        """Whether the measurement's age can be measured (module doc of :meth:`_cycles`)."""
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

    def _safe_write(self, q, dq) -> np.ndarray:
        """Write the safe torque at ``(q, dq)``; a non-finite one (a model or a state gone
        wrong) is replaced by the held-safe torque at the last finite position, then by
        zero: a non-finite command is never written."""
        tau = np.asarray(self.safe_torque(q, dq), dtype=float)
        if not np.isfinite(tau).all():
            return self._held_write(q)
        self.interface.write(tau)
        return tau

    def _held(self, q) -> np.ndarray:
        """The held-safe torque at ``q`` (:meth:`~.safety.SafeTorque.held`; for another
        safe-torque function, itself at zero velocity)."""
        held = getattr(self.safe_torque, "held", None)
        if callable(held):
            return np.asarray(held(q), dtype=float)
        return np.asarray(self.safe_torque(q, np.zeros_like(q)), dtype=float)

    def _held_write(self, q) -> np.ndarray:
        """Write the held-safe torque at ``q`` (zero if it is not finite)."""
        tau = self._held(q) if np.isfinite(q).all() else np.full(len(q), np.nan)
        if not np.isfinite(tau).all():
            tau = np.zeros(len(q))
        self.interface.write(tau)
        self._held_tau = tau
        return tau

    def _safe_words(self) -> str:
        describe = getattr(self.safe_torque, "describe", None)
        held = getattr(self.safe_torque, "describe_held", None)
        return (
            "safe torque "
            + (describe() if callable(describe) else "commanded")
            + " commanded, then the brake; "
            + (held() if callable(held) else "the safe torque at rest")
            + " at the last position left on the arm"
        )

    def _brake(
        self, P: float, q_last, dq_last, stamp: float, fresh: bool, resume: bool = False
    ) -> dict:
        """The stop sequence (:mod:`.safety`): while fresh finite states arrive, the safe
        torque at each, until every joint is slower than ``safety.brake_speed`` or
        ``safety.hold`` has passed; then the held-safe torque at the last finite position,
        the last command written. Works on copies: the interface may reuse its arrays.

        With ``resume`` (after a watchdog stop: the held-safe torque is on the arm
        already, its speed unknown) it waits up to ``hold`` for the states to resume and
        brakes on them if they do (a loaded machine's stall, not an arm gone): the arm is
        then left still, not coasting under G(q).

        Returns:
            ``ended`` (``"still"``, ``"time bound"``, ``"no fresh state"``), ``duration``
            [s], ``states`` (fresh states braked on), ``speed`` (max |q̇| [rad/s] at the
            last finite state), ``held_tau`` [N·m] (the last command).
        """
        sf, iface, clock = self.safety, self.interface, self.clock
        q_keep, dq_keep = np.array(q_last, dtype=float), np.array(dq_last, dtype=float)
        self._last_state = (q_keep, dq_keep)  # an error inside the brake holds G at q_keep
        start = clock()
        end = start + sf.hold
        # (a bound on the wall too: the clock of a paced arm, a simulator's, may stop)
        wall_end = time.monotonic() + max(2.0 * sf.hold, sf.hold + 1.0)
        fresh_at = start
        states = 0
        ended = "no fresh state"
        wait = getattr(iface, "wait", None) if self.paced else None
        awaiting = resume  # no fresh state yet since the watchdog: the speed is unknown
        patience = sf.hold if resume else sf.watchdog  # how long a fresh state is awaited
        while fresh or resume:
            now = clock()
            if not awaiting and float(np.max(np.abs(dq_keep), initial=0.0)) < sf.brake_speed:
                ended = "still"
                break
            if now >= end or time.monotonic() >= wall_end:
                ended = "no fresh state" if awaiting else "time bound"
                break
            if wait is not None:
                if not wait(min(sf.watchdog, end - now)):
                    if awaiting or clock() >= end:
                        continue
                    break
            else:
                self.sleep(min(now + P, end))
            new_stamp, q, dq = iface.read()
            if new_stamp == stamp:
                if clock() - fresh_at > patience:
                    break
                continue
            stamp, fresh_at = new_stamp, clock()
            awaiting, patience = False, sf.watchdog
            if not (np.isfinite(q).all() and np.isfinite(dq).all()):
                # not a state to brake on: the damping on the last finite velocity would be
                # a stale torque, so the held-safe one replaces it until a finite state comes
                self._held_write(q_keep)
                continue
            q_keep[:] = q
            dq_keep[:] = dq
            states += 1
            if float(np.max(np.abs(dq_keep), initial=0.0)) >= sf.brake_speed:
                self._safe_write(q_keep, dq_keep)
        # (after a watchdog stop with no state since, it is on the arm already: written once)
        held = self._held_write(q_keep) if fresh or states else self._held_tau
        self._last_state = (q_keep, np.zeros_like(dq_keep))
        return {
            "ended": ended,
            "duration": clock() - start,
            "states": states,
            "speed": float(np.max(np.abs(dq_keep), initial=0.0)),
            "q": q_keep.tolist(),
            "held_tau": held.tolist(),
        }

    def _start_fault(self, q, dq) -> str | None:
        """Why the first state cannot start the loop (non-finite, beyond the bounds), or
        ``None``."""
        sf = self.safety
        if (q >= sf.lower).all() and (q <= sf.upper).all() and (np.abs(dq) <= sf.velocity).all():
            return None
        return self._state_fault(q, dq)

    def _state_fault(self, q, dq) -> str:
        sf = self.safety
        names = self.joint_names or tuple(f"joint{i + 1}" for i in range(len(q)))
        if not (np.isfinite(q).all() and np.isfinite(dq).all()):
            return f"non-finite state from the arm: q={q.tolist()}, dq={dq.tolist()}"
        for i in range(len(q)):
            if not sf.lower[i] <= q[i] <= sf.upper[i]:
                return (
                    f"joint {names[i]!r} at q={q[i]:.4g} rad, beyond its bounds "
                    f"[{sf.lower[i]:.4g}, {sf.upper[i]:.4g}]"
                )
            if abs(dq[i]) > sf.velocity[i]:
                return (
                    f"joint {names[i]!r} at |dq|={abs(dq[i]):.4g} rad/s, beyond its bound "
                    f"{sf.velocity[i]:.4g}"
                )
        return "state beyond limits"
