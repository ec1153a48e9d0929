"""The real-time loop's cycles: wait for the cycle's deadline (the loop's clock, or the
arm's next state), read, step the controller every ``decimation`` cycles, write, record.

The two ways of pacing differ only in how a cycle begins (``Cycles._pace_clock``: the
loop's absolute deadlines, a warm-up and a busy-wait before them; ``Cycles._pace_arm``:
the arm's next state, its arrival the deadline); what follows the state is the same
(``Cycles._cycles``). Between the wake-up and the torque written the cycle does
nothing but the state's check, the controller's step and the write: the records, the
callback, the miss tally and the garbage collection come after the write, in the slack.
The timing rules and the stops are the loop's (:mod:`hmpc_pin.realtime.loop`).
"""

from __future__ import annotations

import numpy as np

from ..exceptions import HmpcError
from .records import Records

__all__ = ["RELAX_MISSES", "RELAX_WATCHDOG", "Cycles"]

#: Appended to a stop's reason: the setting to relax when the machine, not the arm, was
#: late (the config key and the command line's override).
RELAX_MISSES = (
    "; if the machine was loaded rather than the arm faulty, relax realtime.max_misses "
    "(--max-misses K)"
)
RELAX_WATCHDOG = (
    "; if the machine was loaded rather than the arm gone, relax realtime.watchdog (--watchdog S)"
)


class Cycles:
    """The cycles of :class:`~hmpc_pin.realtime.loop.RealtimeLoop` (a part of it: the
    attributes are the loop's)."""

    def _cycles(self, K: int, rec: Records, tally, q_last, dq_last, stamp: float):
        """The cycles 0..K: wait, read, step every ``decimation`` cycles, write, record.

        Returns:
            ``(stop, k, stamp, deadline, wrote)``: the stop (``(cause, reason)`` or
            ``None``), the cycle it came at, the last stamp, that cycle's deadline and
            whether any command was written.
        """
        st, sf = self.settings, self.safety
        iface, ctrl = self.interface, self.controller
        clock = self.clock
        P, m = st.period, self.decimation
        # The measurement's age when its torque is written, on the stamps' clock: the
        # loop's own against an arm that paces it, else the interface's stamp_clock() if
        # it offers one (stamps on another clock cannot be compared).
        stamp_clock = clock if self.paced else getattr(iface, "stamp_clock", None)
        lower, upper, vmax = sf.lower, sf.upper, sf.velocity
        max_misses = sf.max_misses
        tau = np.zeros(iface.nq)
        wrote = False
        j = 0
        handle_gc = st.gc_handling
        stop: tuple[str, str] | None = None
        next_mpc = 0
        paced, on_step = self.paced, self.on_step
        pace = self._pace_arm if paced else self._pace_clock
        t0 = clock() + P
        self._t0 = t0
        self._fresh = (stamp, t0)  # the last stamp and when it was fresh (the watchdog)
        k = 0
        deadline = t0
        while k <= K:
            stop, k, wake, at, taken, q, dq = pace(k, K, next_mpc, q_last, dq_last)
            if at is not None:
                deadline = at
            if taken is not None:
                stamp = taken
            if stop is not None or k > K:
                break
            # ---- the cycle's tail: check, step, write (nothing else before the write)
            # One comparison each in the common case; NaN fails every one of them.
            if not ((q >= lower).all() and (q <= upper).all() and (np.abs(dq) <= vmax).all()):
                stop = ("fault", self._state_fault(q, dq))
                break
            q_last[:] = q
            dq_last[:] = dq
            is_mpc = k >= next_mpc
            if is_mpc:
                ref = self.reference
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
            # ---- bookkeeping, in the slack
            if is_mpc and stamp_clock is not None:
                rec.age[k] = (done if paced else stamp_clock()) - stamp
            rec.cycle(k, wake - deadline, done - deadline, stamp, is_mpc)
            self._cycles_done = k + 1
            if is_mpc:
                rec.step(j, k * P, q, dq, tau, ctrl.disturbance_estimate, ref)
                j += 1
                self._steps_done = j
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

    # ------------------------------------------------------------------ how a cycle begins
    def _pace_clock(self, k: int, K: int, next_mpc: int, q_last, dq_last):
        """Paced by the loop's clock: skip the deadlines already passed, warm up before an
        MPC cycle, wait for the deadline, read the newest state.

        Returns:
            ``(stop, k, wake, deadline, stamp, q, dq)`` (``k`` past the skipped cycles;
            ``k > K``: the run's end came while skipping; ``deadline`` and ``stamp``
            ``None`` where the cycle did not get that far: the last ones stand).
        """
        clock, P, t0 = self.clock, self.settings.period, self._t0
        # Deadlines already passed are skipped (the arm holds the torque through them).
        behind = int((clock() - t0) / P) - k
        if behind > 0 and k > 0:
            k, stop = self._skip(k, K, behind, behind, "periods skipped behind the clock")
            if stop is not None or k > K:
                return stop, k, 0.0, None, None, q_last, dq_last
        deadline = t0 + k * P
        warm_up = self._warm_up
        if warm_up is not None and k >= next_mpc and k > 0:
            # in the slack before an MPC cycle: the step on the last state, undone
            ref, t = self.reference, k * P
            if self._waker is not None:
                self._waker.until(deadline, lambda: warm_up(t, q_last, dq_last, ref))
            else:
                self.sleep(deadline - self.settings.warm_up)
                warm_up(t, q_last, dq_last, ref)
                self.sleep(deadline)
        else:
            self.sleep(deadline)
        wake = clock()
        stop = self._requested_stop()
        if stop is not None:
            return stop, k, wake, deadline, None, q_last, dq_last
        stamp, q, dq = self.interface.read()
        stop = self._watch(stamp, wake, self.safety.watchdog, wake - deadline)
        return stop, k, wake, deadline, stamp, q, dq

    def _pace_arm(self, k: int, K: int, next_mpc: int, q_last, dq_last):
        """Paced by the arm: wait for its next state (at most the watchdog); the states
        that arrived while the loop was busy are periods skipped, missed if the arm
        reports them overdue. Returns as :meth:`_pace_clock`."""
        iface = self.interface
        arrived, wake, stop = self._await_state(self.safety.watchdog)
        if stop is not None:
            return stop, k, wake, None, None, q_last, dq_last
        behind = arrived - 1  # states not answered: periods skipped
        if behind > 0 and k > 0:
            # of which missed: those the arm reports overdue (a burst after its own stall is
            # not the loop's miss), else all
            late = min(behind, iface.overdue) if self._has_overdue else behind  # type: ignore[attr-defined]
            k, stop = self._skip(k, K, behind, late, "states not answered")
            if stop is not None or k > K:
                return stop, k, wake, None, None, q_last, dq_last
        stamp, q, dq = iface.read()
        self._fresh = (stamp, wake)
        # the deadline follows the arrival (a constant transport delay is no miss)
        deadline = iface.arrival if self._has_arrival else stamp  # type: ignore[attr-defined]
        return None, k, wake, deadline, stamp, q, dq

    def _skip(self, k: int, K: int, behind: int, late: int, why: str):
        """Skip ``behind`` periods, ``late`` of them missed. Returns ``(k, stop)``."""
        tally, rec, max_misses = self._tally, self._rec, self.safety.max_misses
        skip = min(behind, K + 1 - k)
        late = min(late, skip)
        rec.missed[k : k + late] = True  # type: ignore[union-attr]
        k += skip
        if tally.skip(skip, late, max_misses):  # type: ignore[union-attr]
            return k, (
                "misses",
                f"{tally.consecutive} consecutive missed deadlines "  # type: ignore[union-attr]
                f"(limit {max_misses}), {skip} {why}{RELAX_MISSES}",
            )
        return k, None

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

    def _watch(
        self, stamp: float, wake: float, watchdog: float, late: float = 0.0
    ) -> tuple[str, str] | None:
        """The watchdog of a polled arm: a stamp that has not advanced for longer than
        ``watchdog`` [s] of the loop's own time awake is a stop.

        ``late`` [s] is how late the loop woke after its deadline: a wake-up later than a
        period is the loop's own stall (the machine's, not the arm's), so that stretch is
        not charged to the arm (the stamp is judged again at the next cycles, on time).
        """
        last, fresh_at = self._fresh
        if stamp != last:
            self._fresh = (stamp, wake)
            return None
        if late > self.settings.period:
            fresh_at = min(wake, fresh_at + late)
            self._fresh = (last, fresh_at)
            self._stalls += 1
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
