"""``[realtime]``: the wall-clock loop and its safe stops."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...exceptions import ConfigError
from ._fields import _array, _bool, _float, _int, _set

#: The values of ``[realtime] inner_law`` (and ``--inner-law``): ``"auto"`` the command's
#: own choice, ``"whole-step"`` the controller's whole step every ``Ts``, its torque held
#: in between, ``"every-cycle"`` the MPC every ``Ts`` with the inverse dynamics and the
#: observer every cycle, ``"threaded"`` the same with the MPC in a compiled thread
#: (:mod:`hmpc_pin.experiment.inner_law`).
INNER_LAWS = ("auto", "whole-step", "every-cycle", "threaded")


@dataclass(frozen=True, eq=False)
class RealtimeConfig:
    """The real-time loop of ``hmpc-pin realtime`` (:mod:`hmpc_pin.realtime`).

    Attributes:
        rate: Interface rate [Hz]; ``1/rate`` must divide ``controller.Ts`` and be a whole
            number of ``plant.dt`` (the arm process integrates its plant at that period).
        gc: Garbage-collection handling (freeze after start-up, collect in the slack).
        gc_slack: Minimum slack [s] before the next deadline for a collection.
        damping: Joint damping of the safe torque [N·m·s/rad], one value or per joint
            (a diagonal brake: a joint of large inertia slows slowly; a warning says
            when the arm would still move when ``hold`` ends).
        brake_time: Brake with the inertia-scaled damping :math:`M(q)/T_b` [s] instead of
            ``damping``: every joint slows as :math:`e^{-t/T_b}` (with ``damping``: an
            error, one or the other). At least e·(d+1) interface periods, d the periods
            between a state and its command taking effect (1 + the declared latency):
            shorter overshoots (checked where the rate is known). Neither given:
            ``hold``/6 (at least that minimum): the arm is still when the brake ends.
        gravity: Gravity compensation in the safe torque (not given: on). Under
            ``hmpc-pin ros`` the choice is ``[ros] gravity``; this key, if given, must
            agree with it (``true`` with ``"controller"``, ``false`` with ``"arm"``).
        max_misses: Consecutive missed deadlines that stop the loop (k). Default 100
            (0.1 s at 1 kHz: runs of up to 91 misses were measured on a loaded 2-core
            machine, the tutorial "The real-time loop").
        watchdog: A state stamp that does not advance for this long [s] stops the loop.
            Default 0.1 (stalls of up to 46 ms measured on the same machine).
        hold: Bound in time [s] of the brake after a stop (and at the end of a run): the
            safe torque at each fresh state until every joint is slower than
            ``brake_speed``, at most this long; then the held-safe torque ``G(q)`` (no
            velocity term), the last command (:mod:`hmpc_pin.realtime.safety`). Default 2.
        brake_speed: The brake ends when every joint is slower than this [rad/s]; the
            arm then drifts at most about this fast under the held-safe torque. Default
            0.005.
        limits: Stop when the measured state leaves the URDF limits widened by
            ``position_margin`` and ``velocity_scale``.
        position_margin: Margin [rad] outside the URDF position limits (with ``limits``).
        velocity_scale: Factor on the URDF velocity limits (with ``limits``).
        priority: ``SCHED_FIFO`` priority (1–99) of the loop and the arm process (of the
            node, under ``hmpc-pin ros``); ``"auto"`` (default) takes 80 where this process
            may (root, ``CAP_SYS_NICE`` or an rtprio limit) and keeps normal scheduling
            elsewhere (the run's statistics say which: ``priority``); 0 keeps normal
            scheduling.
        cpus: Run the loop's thread on these CPUs only (indices, e.g. ``[1]``); empty
            (default): wherever the kernel puts it. On a machine whose other work is
            kept off those CPUs (``isolcpus``, a cpuset) the loop's caches stay its own;
            on a shared machine pinning can keep it waiting behind another thread on its
            CPU while another CPU idles.
        spin: How the loop waits for a deadline: ``"auto"`` (default) sleeps, then
            busy-waits the last stretch, chosen from the wake-ups measured during the run
            (their 99th percentile, at most half a period: the loop is awake at the
            deadline); a time [s] below ``1/rate`` busy-waits that long before each
            deadline; 0 sleeps the whole wait.
        inner_law: How the controller runs under a faster arm (``Ts`` a multiple of the
            interface period), one of :data:`INNER_LAWS`: ``"whole-step"`` the whole
            step every ``Ts``, its torque held in between; ``"every-cycle"`` the MPC every
            ``Ts``, the inverse dynamics (Eq 4) and the disturbance observer every cycle;
            ``"threaded"`` the same with the MPC in a compiled thread (its latest plan
            used within ``2 Ts``); ``"auto"`` (default): ``hmpc-pin franka``
            ``"every-cycle"`` where it applies, else ``"whole-step"``; ``hmpc-pin
            realtime`` and ``hmpc-pin ros`` ``"whole-step"``
            (:mod:`hmpc_pin.experiment.inner_law`).
        planner: The threaded inner law's planner thread (``inner_law = "threaded"`` only;
            with another law an error): ``"auto"`` (also when not given) keeps the loop's
            niceness under a real-time loop and sits 10 above it under a normal one;
            ``"fifo"`` runs it under ``SCHED_FIFO`` one priority below a real-time loop
            (under a normal loop as ``"auto"``); a whole number −20..19 is its niceness
            (:mod:`hmpc_pin.realtime.threaded_law`, checked with the law, before anything
            runs).
        warm_up: Wake this long [s] before each MPC cycle's deadline and run the
            controller's step on the last measured state, undone (its memory then warm in
            the caches for the cycle's step), then busy-wait to the deadline; below
            ``1/rate``; 0 disables it. Default 2e-4.
    """

    rate: float = 1000.0
    gc: bool = True
    gc_slack: float = 3e-4
    damping: np.ndarray | None = None
    brake_time: float | None = None
    gravity: bool | None = None
    max_misses: int = 100
    watchdog: float = 0.1
    hold: float = 2.0
    brake_speed: float = 0.005
    limits: bool = True
    position_margin: float | None = None
    velocity_scale: float | None = None
    priority: int | str = "auto"
    cpus: tuple[int, ...] = ()
    spin: float | str = "auto"
    warm_up: float = 2e-4
    inner_law: str = "auto"
    planner: int | str | None = None

    def __post_init__(self):
        _set(self, "rate", _float("rate", self.rate, positive=True))
        if self.inner_law not in INNER_LAWS:
            raise ConfigError(
                "inner_law", f"expected one of {', '.join(INNER_LAWS)}, got {self.inner_law!r}"
            )
        if self.spin != "auto":
            _set(self, "spin", _float("spin", self.spin, nonneg=True))
        if self.spin != "auto" and self.spin >= 1.0 / self.rate:  # type: ignore[operator]
            raise ConfigError(
                "spin",
                f"expected a time [s] below the period 1/rate = {1.0 / self.rate:g} s, "
                f'got {self.spin:g}; or "auto"',
            )
        _set(self, "warm_up", _float("warm_up", self.warm_up, nonneg=True))
        if self.warm_up >= 1.0 / self.rate:
            raise ConfigError(
                "warm_up",
                f"expected a time [s] below the period 1/rate = "
                f"{1.0 / self.rate:g} s, got {self.warm_up:g}",
            )
        if self.priority != "auto":
            _set(self, "priority", _int("priority", self.priority, minimum=0))
        if self.priority != "auto" and self.priority > 99:  # type: ignore[operator]
            raise ConfigError(
                "priority", f'expected 0 (off) or 1..99, or "auto", got {self.priority}'
            )
        cpus = self.cpus
        if not isinstance(cpus, (list, tuple)):
            raise ConfigError("cpus", f"expected a list of CPU indices, got {cpus!r}")
        _set(self, "cpus", tuple(_int("cpus", c, minimum=0) for c in cpus))
        _set(self, "gc", _bool("gc", self.gc))
        _set(self, "gc_slack", _float("gc_slack", self.gc_slack, positive=True))
        if self.brake_time is not None:
            if self.damping is not None:
                raise ConfigError(
                    "damping",
                    "does not apply with brake_time (the brake is "
                    "M(q)/brake_time); give one of them",
                )
            _set(self, "brake_time", _float("brake_time", self.brake_time, positive=True))
        elif self.damping is not None:
            _set(self, "damping", _array("damping", self.damping, nonneg=True))
        if self.gravity is not None:
            _set(self, "gravity", _bool("gravity", self.gravity))
        _set(self, "max_misses", _int("max_misses", self.max_misses, minimum=1))
        _set(self, "watchdog", _float("watchdog", self.watchdog, positive=True))
        _set(self, "hold", _float("hold", self.hold, nonneg=True))
        _set(self, "brake_speed", _float("brake_speed", self.brake_speed, positive=True))
        _set(self, "limits", _bool("limits", self.limits))
        for name in ("position_margin", "velocity_scale"):
            value = getattr(self, name)
            if value is None:
                continue
            if not self.limits:
                raise ConfigError(
                    name, "does not apply with limits = false; drop it or set limits = true"
                )
            _set(
                self,
                name,
                _float(
                    name, value, nonneg=name == "position_margin", positive=name == "velocity_scale"
                ),
            )

    @property
    def margin(self) -> float:
        """``position_margin`` [rad] (default 0.05)."""
        return 0.05 if self.position_margin is None else self.position_margin

    @property
    def scale(self) -> float:
        """``velocity_scale`` (default 1.5)."""
        return 1.5 if self.velocity_scale is None else self.velocity_scale
