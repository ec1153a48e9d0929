"""The real-time loop's stop sequence: the safe torque at the stop, the brake on the fresh
states, the held-safe torque left on the arm (the rules and the torques:
:mod:`hmpc_pin.realtime.safety`; when the loop stops: :mod:`hmpc_pin.realtime.loop`).

No path writes a non-finite torque: the safe torques are computed from copies of the last
finite state, and a non-finite one is replaced by the held-safe torque, then by zero.
"""

from __future__ import annotations

import time

import numpy as np

__all__ = ["StopSequence"]


class StopSequence:
    """The stop sequence of :class:`~hmpc_pin.realtime.loop.RealtimeLoop` (a part of it:
    the attributes are the loop's)."""

    def _stop_sequence(
        self, stop, k: int, K: int, q_last, dq_last, stamp: float, deadline: float, wrote: bool
    ) -> tuple[dict | None, dict]:
        """The stop sequence (the loop's module doc, "Safe stop"; with no fresh state to
        brake on, the held-safe torque; before the first command, nothing).

        Returns:
            ``(stop record or None, brake record)``.
        """
        clock, P = self.clock, self.settings.period
        stop_record = None
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
        return stop_record, brake

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
