"""The MPC in a compiled thread, the inner law every cycle (``InnerLawThreaded``).

As :class:`~hmpc_pin.realtime.inner_law.InnerLawEveryCycle` (the observer, Eq 13, and
the inverse dynamics, Eq 4, every cycle of the arm's period :math:`P`), but the MPC -- the
gradients and the joint QPs over the horizon (Eq 25–26) -- runs in a compiled planner
thread (``hmpc_pin._core.PlanThread``, ``cpp/include/hmpc/plan_thread.hpp``) with its own
copy of the joint QPs; it never takes the GIL. Every cycle :math:`k`:

1. the observer over the period that just ended (as the synchronous law);
2. at :math:`k = 0, m, 2m, \\dots` (by time, as the synchronous law) the state
   :math:`(t_k, q_k, \\dot q_k)` is handed to the planner (a request; it does not wait,
   the first after :meth:`InnerLawThreaded.reset` neither -- the cycles before the first
   plan brake, which holds an arm at rest -- except every time with ``wait=True``);
3. the acceleration of the latest plan for the cycle's time :math:`t`: the plan's row
   :math:`\\lfloor (t - t_\\text{plan}) / T_s \\rfloor` (past the control horizon its last
   row), if the plan is not older than ``max_age``; else the **brake** fallback
   :math:`v = \\operatorname{clip}(-\\dot q / T_s, v_\\min, v_\\max)` (the joints' velocity
   brought to zero over one MPC period within the acceleration bounds), counted in
   :attr:`InnerLawThreaded.fallbacks`;
4. Eq (4) with it at the fresh state (as the synchronous law).

With ``wait=True`` (deterministic: each request waits for its plan) the torques are, bit
for bit, those of :class:`~hmpc_pin.realtime.inner_law.InnerLawEveryCycle` on the same
controller. Without it the request's own cycle uses the previous plan (its row 1, or its
last with :math:`N_c = 1`). The default staleness bound is the plan's control horizon,
``max_age = max(N_c, 2) T_s``: a plan late by any number of periods is used shifted (each
row is the input the MPC chose for that time, along a prediction that kept the limits)
while the cycle's time lies within its control horizon, and the cycle brakes only beyond
it (with :math:`N_c = 1`, one MPC period late).

**The planner's scheduling** (applied at each run's first cycle, from the policy of the
thread that runs the cycles, :attr:`InnerLawThreaded.planner_scheduling` ``"auto"``): when
the torque loop runs under a real-time policy (``SCHED_FIFO``/``RR``: no normal thread can
preempt it) the planner keeps the loop's niceness -- it then competes only with the
machine's other normal work, and a lower share made plans late and cycles brake; when the
loop runs under the normal policy the planner is niced 10 above it, so that a woken
planner does not take the core from the cycle that woke it. ``summary()`` records what
was applied (``planner_nice``, ``planner_policy``).

The thread is stopped and joined by :meth:`InnerLawThreaded.close` (also ``with`` and the
object's end).
A failure of the planner (a QP not solved, a non-finite state) is raised by the next cycle.
"""

from __future__ import annotations

import contextlib
import math
import os

import numpy as np

from ..exceptions import ConfigError
from ..mpc.condensed import JointQPs
from ..native import load as load_native
from ..tasks.base import Reference, as_reference, reference_port
from .inner_law import FloatArray, InnerLawEveryCycle
from .pacing import realtime_policy

__all__ = ["PLANNER_NICE", "InnerLawThreaded", "checked_planner_scheduling"]

#: The planner's niceness above the torque loop's when the loop runs under the normal policy.
PLANNER_NICE = 10


def checked_planner_scheduling(value, key: str = "planner_scheduling") -> int | str:
    """``value`` as a planner scheduling: ``"auto"``, ``"fifo"`` or a niceness −20..19
    (a whole number; the module doc's rule).

    Raises:
        ConfigError: Anything else, named ``key``.
    """
    if value in ("auto", "fifo"):
        return value
    if isinstance(value, int) and not isinstance(value, bool) and -20 <= value <= 19:
        return int(value)
    raise ConfigError(key, f'expected "auto", "fifo" or a niceness -20..19, got {value!r}')


_KNOBS = (
    "max_iter",
    "shortcut",
    "active_set_iter",
    "soft_active_set_iter",
    "soft_step_exchanges",
    "soft_step_work",
    "shift",
)


def planner_qps(controller) -> JointQPs:
    """A copy of ``controller.qps`` (the same problem and knobs, its own solvers)."""
    s = controller.settings
    v_min, v_max = s.bounds(controller.n)
    qps = JointQPs(
        controller.mpc,
        v_min,
        v_max,
        controller.robot.joint_names,
        eps_abs=s.eps_abs,
        max_iter=s.max_iter,
        limits=controller.limits,
        layout=s.qp_layout,
    )
    for knob in _KNOBS:
        setattr(qps, knob, getattr(controller.qps, knob))
    return qps


class InnerLawThreaded(InnerLawEveryCycle):
    """The MPC in a compiled thread, Eq (4) and the observer every cycle (module doc).

    Args:
        controller: A :class:`~hmpc_pin.controllers.hierarchical.HierarchicalMPC` (its
            problem, settings and limits are copied into the planner; its own step is not
            run).
        compensation: The observer at the arm's period.
        period: The arm's period :math:`P` [s]; ``controller.Ts`` a multiple of it.
        effort_limit: Per-joint limit [N·m] or ``None`` (as the synchronous law).
        max_age: The staleness bound [s]: a plan older than this is never used (default
            its control horizon, ``max(Nc, 2) * controller.Ts``).
        wait: Each request waits for its plan (deterministic; the MPC's cost is then in the
            cycle, as the synchronous law's).

    Attributes:
        planner: The ``hmpc_pin._core.PlanThread`` (its thread's id: ``planner.tid``).
        planner_scheduling: The planner's scheduling, applied at each run's first cycle:
            ``"auto"`` (the module doc's rule), a niceness (−20..19), or ``"fifo"``
            (``SCHED_FIFO`` one priority below a real-time loop's; under a normal loop as
            ``"auto"``). A class attribute; an instance may set its own.
        fallbacks: Cycles that braked (no plan within ``max_age``) since :meth:`reset`.
        name: ``"threaded"`` (as ``--inner-law`` names it).
        label: The law in words (the run summaries).

    Its ``warm_up`` is ``None``: the MPC's memory is the planner thread's own, nothing to
    warm in the cycle (the real-time loop then runs no warm-up).
    """

    name = "threaded"
    label = "every cycle, the MPC threaded"
    planner_scheduling: int | str = "auto"
    warm_up = None  # type: ignore[assignment]  #: (no warm-up: class doc)

    def __init__(
        self,
        controller,
        compensation,
        period: float,
        effort_limit=None,
        max_age: float | None = None,
        wait: bool = False,
    ):
        super().__init__(controller, compensation, period, effort_limit)
        Ts = controller.Ts
        Nc = controller.settings.Nc
        age = max(Nc, 2) * Ts if max_age is None else float(max_age)
        if not (math.isfinite(age) and age > 0):
            raise ConfigError("max_age", f"expected a staleness bound [s] > 0, got {max_age!r}")
        self.wait = bool(wait)
        self._qps = planner_qps(controller)
        N = controller.settings.N
        self._offsets = Ts * np.arange(1, N + 1)
        # started at the caller's niceness: the rule is applied at the first cycle (raising a
        # niceness needs no right, lowering it one)
        self.planner = load_native().PlanThread(
            controller.mpc.FT, N, self._qps._core, self._offsets, Ts, age, nice=0
        )
        self._scheduled = False
        self._planner_policy = "normal"
        self._vmin, self._vmax = controller.settings.bounds(self.robot.nq)
        self._stack = np.zeros((2 + 2 * N, self.robot.nq))
        self._times = np.empty(N)
        self._reference: object = None
        self._ref: Reference | None = None
        self._compiled = False
        self.fallbacks = 0

    @property
    def max_age(self) -> float:
        """The staleness bound [s]."""
        return float(self.planner.max_age)

    def reset(self, q0: FloatArray, dq0: FloatArray) -> None:
        """Start a run (as the synchronous law); the planner's plan and QPs restart."""
        super().reset(q0, dq0)
        self.planner.reset()
        self.fallbacks = 0
        self._scheduled = False

    def schedule_planner(self) -> None:
        """Apply :attr:`planner_scheduling` from the calling thread's policy (module doc);
        done by the run's first cycle. A change the system refuses (a niceness lowered
        without the right) leaves the planner as it was (``summary()`` tells)."""
        self._scheduled = True
        mode = checked_planner_scheduling(self.planner_scheduling)
        tid = int(self.planner.tid)
        if not tid:  # not Linux, or stopped: nothing to schedule
            return
        rt = realtime_policy()
        try:
            base = os.getpriority(os.PRIO_PROCESS, 0)  # this thread's niceness (Linux)
            if os.sched_getscheduler(tid) != os.SCHED_OTHER:
                os.sched_setscheduler(tid, os.SCHED_OTHER, os.sched_param(0))
            if mode == "fifo" and rt:
                prio = max(1, os.sched_getparam(0).sched_priority - 1)
                os.sched_setscheduler(tid, os.SCHED_FIFO, os.sched_param(prio))
                self._planner_policy = f"SCHED_FIFO {prio}"
                return
        except (OSError, AttributeError):
            return
        nice = mode if isinstance(mode, int) else (base if rt else min(base + PLANNER_NICE, 19))
        with contextlib.suppress(RuntimeError):
            self.planner.set_nice(nice)
        self._planner_policy = "normal"

    def step(self, t: float, q: FloatArray, dq: FloatArray, reference) -> FloatArray:
        """The torque [N·m] of cycle ``k`` (module doc)."""
        M, nle = self._observe(q, dq)
        if not self._scheduled:
            self.schedule_planner()
        if self._due(t):
            self._request(t, q, dq, reference)
            if self.wait:
                self.planner.wait()
            self._ran_mpc(t)
        if not self.planner.input(t, self._v):
            self.fallbacks += 1
            np.clip(
                -np.asarray(dq, dtype=float) / self.controller.Ts,
                self._vmin,
                self._vmax,
                out=self._v,
            )
        return self._torque(M, nle, dq)

    def _request(self, t: float, q: FloatArray, dq: FloatArray, reference) -> None:
        """Hand ``(t, q, q̇)`` to the planner: it samples a compiled reference itself; any
        other is sampled here into the stack handed over."""
        if reference is not self._reference:
            self._reference = reference
            self._ref = as_reference(reference)
            port = reference_port(self._ref)
            self._compiled = port is not None
            self.planner.set_reference(port)
        if self._compiled:
            self.planner.request(t, q, dq)
            return
        N = len(self._offsets)
        S = self._stack
        S[0] = q
        S[1] = dq
        out = (S[2 : 2 + N], S[2 + N :])
        times = np.add(self._offsets, t, self._times)
        q_ref, dq_ref = self._ref.sample_many(times, out)  # type: ignore[union-attr]
        if q_ref is not out[0]:
            out[0][:] = q_ref
            out[1][:] = dq_ref
        self.planner.request_stack(t, S)

    def summary(self) -> dict:
        """As the synchronous law's, with the planner's counts: ``requests``,
        ``published``, ``dropped``, ``refused`` (plans past ``max_age``), ``fallbacks``
        (cycles that braked), ``max_age`` [s], ``wait``, and the planner thread's
        ``planner_nice`` and ``planner_policy`` (``"normal"`` or ``"SCHED_FIFO <prio>"``), and
        its longest solve ``max_solve`` [s] by its clock and ``max_solve_cpu`` [s] by its CPU
        time (their ratio: how long the planner waited for a core)."""
        p = self.planner
        return {
            **super().summary(),
            "requests": int(p.requests),
            "published": int(p.published),
            "dropped": int(p.dropped),
            "refused": int(p.stale),
            "fallbacks": int(self.fallbacks),
            "max_age": float(p.max_age),
            "wait": self.wait,
            "max_solve": float(p.max_solve),
            "max_solve_cpu": float(p.max_solve_cpu),
            "planner_nice": int(p.nice),
            "planner_policy": self._planner_policy,
        }

    def close(self) -> None:
        """Stop the planner thread and join it (idempotent)."""
        self.planner.stop()
