"""Closed-loop simulation: any controller at period Ts against any plant.

The torque returned by the controller at :math:`t_k` is held over
:math:`[t_k, t_k + T_s)` (zero-order hold). The plant, which owns its own
``pin.Model``/``pin.Data`` (possibly a different URDF: model mismatch), is
integrated with a fixed step ``dt`` that divides :math:`T_s` (default 1 ms),

.. math::  \\ddot q = \\mathrm{ABA}(q, \\dot q, \\tau + d(t, q, \\dot q)),

with the disturbance evaluated at every plant step (and every RK4 stage).
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from .._deprecated import LOOPS
from .._startup import raise_if_interrupted
from ..checks import run_memory
from ..exceptions import (
    ConfigError,
    DimensionError,
    HmpcError,
    RunInterrupted,
    SimulationError,
)
from ..model.robot import Robot
from ..tasks.base import Reference, as_reference
from .compiled_loop import CompiledLoop
from .disturbances import ZeroDisturbance
from .plants import PLANTS, Plant
from .result import RESULT_ARRAYS, Result

__all__ = ["Result", "simulate"]


def _step_time(result: Result, step_ns: np.ndarray, Ts: float) -> None:
    """Attach the controller's step times to ``result`` as ``result.step_time`` [µs]
    (median, 99th percentile, max, Ts; not saved with the result, so that a run's files
    stay bit-identical) and, when the median exceeds Ts/2, a warning in
    ``result.meta["warnings"]``: such a controller cannot run in real time at this Ts."""
    if step_ns.size == 0:
        return
    us = step_ns / 1e3
    median = float(np.median(us))
    result.step_time = {  # type: ignore[attr-defined]
        "median_us": median,
        "p99_us": float(np.percentile(us, 99)),
        "max_us": float(us.max()),
        "Ts_us": Ts * 1e6,
    }
    if median > 0.5 * Ts * 1e6:
        result.meta.setdefault("warnings", []).append(
            f"the median controller step exceeds Ts/2 = {0.5 * Ts * 1e6:.0f} µs: too slow "
            "for real time at this Ts (shorten the horizon N or Nc, or raise Ts)"
        )


def _deprecated_loop(loop: str | None) -> None:
    """Warn that ``loop`` no longer chooses anything (every run goes through the compiled
    loop, whose oracle lives in the tests); refuse a value that never meant anything.

    Raises:
        ConfigError: ``loop`` is none of :data:`~hmpc_pin._deprecated.LOOPS`.
    """
    if loop is None:
        return
    if loop not in LOOPS:
        raise ConfigError("loop", f"loop={loop!r}; expected one of {LOOPS} (or leave it out)")
    warnings.warn(
        f"simulate(loop={loop!r}) is deprecated and has no effect: every run goes through the "
        "compiled loop (the same arrays the per-step loop gave); leave the keyword out",
        DeprecationWarning,
        stacklevel=3,
    )


def _plant(robot: Robot, plant, disturbance, dt: float, integrator: str, Ts: float) -> Plant:
    """The plant :func:`simulate` runs: ``plant`` itself when it is a
    :class:`~hmpc_pin.sim.plants.Plant` object (then ``disturbance``, ``dt`` and
    ``integrator`` do not apply), else the ``integrator``'s plant of ``plant`` (a ``Robot``)
    or of a copy of ``robot``.

    Raises:
        ConfigError: An option that does not apply, a plant at another period, an unknown
            integrator.
    """
    if hasattr(plant, "advance") and hasattr(plant, "reset"):
        for name, value, default in (
            ("disturbance", disturbance, None),
            ("dt", dt, 0.001),
            ("integrator", integrator, "rk4"),
        ):
            if value is not default and value != default:
                raise ConfigError(
                    name,
                    f"{value!r} does not apply to a Plant object ({type(plant).__name__}); "
                    "give it to the plant when you build it",
                )
        if abs(plant.Ts - Ts) > 1e-12 * Ts:
            raise ConfigError(
                "plant.Ts",
                f"the plant advances {plant.Ts:g} s per call but the controller "
                f"runs at Ts={Ts:g} s; build the plant with the controller's Ts",
            )
        return plant
    plant_robot = plant if plant is not None else robot.copy()
    if integrator not in PLANTS:
        raise ConfigError(
            "integrator", f"integrator={integrator!r}; expected one of {tuple(PLANTS)}"
        )
    dist = disturbance if disturbance is not None else ZeroDisturbance(robot.nq)
    return PLANTS[integrator](plant_robot, dist, Ts, dt)


def _complete(rec: dict, reference, times: np.ndarray, limit, sampled: bool) -> None:
    """The records of the ``m = len(times)`` steps run, completed in place: the reference
    at every instant in one vectorised call (unless ``sampled`` at each step already; the
    controller has sampled every one of these instants, so this cannot fail where the run
    did not), and the last torque as it would be applied when it was not (end of run,
    interrupt)."""
    m = len(times)
    if not sampled:
        rec["q_ref"][:m], rec["dq_ref"][:m] = reference.sample_many(times)
    tau, applied = rec["tau"][m - 1], rec["tau_applied"][m - 1]
    if np.isnan(applied).all() and np.isfinite(tau).all():
        applied[:] = tau if limit is None else np.clip(tau, -limit, limit)


def _raise_if_stopped(result: Result, cause, k: int, t_arr: np.ndarray, duration: float) -> None:
    """Raise what stopped the run, with its partial ``result``: ``RunInterrupted`` for
    Ctrl-C, ``SimulationError`` for a fault during step ``k`` (in the controller, in the
    torque check or in the plant's period over :math:`[t_k, t_k + T_s)`); nothing when
    ``cause`` is ``None``."""
    m, K = len(result.t), len(t_arr) - 1
    message = result.message
    if isinstance(cause, KeyboardInterrupt):
        result.meta["interrupted_at"] = float(result.t[-1]) if m else 0.0
        raise RunInterrupted(
            f"t={result.t[-1] if m else 0.0:.6g} s of {duration:g} s ({m} of {K + 1} samples kept)",
            result,
        ) from None
    if cause is not None:
        result.meta["failed_step"] = int(k)
        result.meta["failed_at"] = float(t_arr[k])
        raise SimulationError(
            f"simulation stopped in step {k} (t={t_arr[k]:.6g} s), {m} of {K + 1} samples "
            f"kept: {message}{observer_hint(result.d_hat, result.joint_names)}",
            result,
        ) from cause


def simulate(
    robot: Robot,
    controller,
    reference,
    disturbance=None,
    *,
    duration: float,
    q0,
    dq0=None,
    plant: Robot | Plant | None = None,
    dt: float = 0.001,
    integrator: str = "rk4",
    state_bound: float = 1e3,
    effort_limit=None,
    meta: dict | None = None,
    on_step=None,
    loop: str | None = None,
    progress=None,
) -> Result:
    """Run the closed loop and return the sampled trajectories.

    Args:
        robot: The controller's model (used only for dimensions here).
        controller: Object with ``Ts``, ``reset(q0, dq0)``, ``step(t, q, dq, reference)``
            and ``disturbance_estimate`` (e.g. :class:`~hmpc_pin.HierarchicalMPC`).
        reference: A :class:`~hmpc_pin.tasks.base.Reference` (or anything
            :func:`~hmpc_pin.tasks.base.as_reference` adapts).
        disturbance: Callable ``d(t, q, dq) -> (n,)`` [N·m]; ``None`` for no disturbance.
            Only with a plant built here (``plant`` a ``Robot`` or ``None``): a
            :class:`~hmpc_pin.sim.plants.Plant` object carries its own.
        duration: Simulated time [s].
        q0, dq0: Initial state [rad, rad/s] (``dq0`` defaults to zero).
        plant: A :class:`~hmpc_pin.sim.plants.Plant` (reset here to ``q0, dq0``), or the
            plant's ``Robot`` (integrated by the plant class ``integrator`` names), or
            ``None`` for a copy of ``robot`` (no mismatch).
        dt: Plant integration step [s]; must divide the control period (not with a
            ``Plant`` object, which has its own).
        integrator: ``"rk4"`` (classical Runge–Kutta) or ``"euler"`` (semi-implicit),
            :data:`~hmpc_pin.sim.plants.PLANTS` (not with a ``Plant`` object).
        state_bound: The run stops as diverged if any |q| or |q̇| exceeds it.
        effort_limit: Actuator limits [N·m], shape (n,) (inf: none). The plant applies
            :math:`\\mathrm{clip}(\\tau, -\\tau_{\\max}, \\tau_{\\max})`, recorded as the
            result's ``tau_applied`` beside the commanded ``tau``; ``None`` applies τ as is.
            The result's ``meta["saturation"]`` reports, per joint, the number of
            control periods saturated and the largest excess :math:`|\\tau| - \\tau_{\\max}`.
        meta: Metadata stored in the result.
        on_step: Optional callable ``on_step(t, q, q_ref)`` called at every control
            instant (e.g. :class:`~hmpc_pin.apps.viz.LiveView`).
        progress: Optional ``progress(k, K)`` after each chunk of control periods: ``k``
            of ``K`` done (a progress bar; the run is the same without it).
        loop: Deprecated, no effect (a ``DeprecationWarning``): every run goes through the
            compiled loop (:mod:`~hmpc_pin.sim.compiled_loop`: the parts written in Python
            called through its ports). Earlier versions chose here between it and a
            per-step loop in Python, which gave the same arrays.

    Returns:
        :class:`Result` with K+1 samples, K = round(duration / Ts).

    Raises:
        SimulationError: The state became non-finite or exceeded ``state_bound``, or
            the controller failed; ``exc.result`` holds the run up to that step
            (``complete=False``).
        RunInterrupted: Ctrl-C (SIGINT) during the run; ``exc.result`` holds the run up
            to the last whole control step (``complete=False``, ``message`` "interrupted
            at t=… s"). It is a ``KeyboardInterrupt``, so a loop of runs still stops.
    """
    _deprecated_loop(loop)
    q, dq, sim_plant, reference, limit = _checked_inputs(
        robot,
        controller,
        reference,
        disturbance,
        duration,
        q0,
        dq0,
        plant,
        dt,
        integrator,
        effort_limit,
    )
    loop_run = _LoopRun(robot.nq, float(controller.Ts), duration, limit)
    sim_plant.reset(q, dq, 0.0)
    controller.reset(q, dq)
    runner = CompiledLoop(
        controller,
        sim_plant,
        reference,
        loop_run.t,
        loop_run.rec,
        loop_run.step_ns,
        limit,
        state_bound,
        loop_run.sat_steps,
        loop_run.sat_excess,
        on_step,
        (q, dq),
    )
    runner.progress = progress
    k, last, message, cause = _run(runner, loop_run.t, duration)
    result = loop_run.result(
        robot, reference, last + 1, cause, message, meta, sampled=on_step is not None
    )
    result.loop = runner.name  # type: ignore[attr-defined]
    _raise_if_stopped(result, cause, k, loop_run.t, duration)
    return result


def _checked_inputs(
    robot: Robot,
    controller,
    reference,
    disturbance,
    duration: float,
    q0,
    dq0,
    plant,
    dt: float,
    integrator: str,
    effort_limit,
) -> tuple[np.ndarray, np.ndarray, Plant, Reference, np.ndarray | None]:
    """The boundary checks of :func:`simulate`, before anything runs.

    Returns:
        ``(q0, dq0, plant, reference, effort_limit)``: the initial state (copies), the
        plant built or taken, the reference adapted and the effort limits [N·m] (``None``:
        none).

    Raises:
        DimensionError: A vector of the wrong length, or a plant of another arm.
        ConfigError: The run's arrays would not fit in memory (``duration``).
    """
    n = robot.nq
    q = robot.check_vector("q0", q0).copy()
    dq = robot.check_vector("dq0", np.zeros(n) if dq0 is None else dq0).copy()
    Ts = float(controller.Ts)
    sim_plant = _plant(robot, plant, disturbance, dt, integrator, Ts)
    if sim_plant.nq != n:
        raise DimensionError(
            f"the plant has {sim_plant.nq} joints but the controller's robot has {n}; "
            "use the same arm"
        )
    reference = as_reference(reference)
    # Boundary check of the reference (once, before the loop): wrong shape or non-finite
    # at t = 0 is bad input, not a failure of the run.
    for name, value in zip(("q_ref", "dq_ref"), reference.sample(0.0), strict=True):
        robot.check_vector(f"reference.sample(0) {name}", value)
    run_memory("duration", duration, Ts, n)  # before the arrays: a clear message, no MemoryError
    limit = (
        None
        if effort_limit is None
        else robot.check_vector("effort_limit", effort_limit, finite=False)
    )
    return q, dq, sim_plant, reference, limit


class _LoopRun:
    """The arrays one run fills (the instants, the records, the step times and the
    saturation counts) and the :class:`Result` made of their filled part."""

    def __init__(self, n: int, Ts: float, duration: float, limit: np.ndarray | None):
        K = round(duration / Ts)
        self.Ts, self.limit = Ts, limit
        self.t = Ts * np.arange(K + 1)
        self.rec: dict[str, Any] = {
            name: np.full((K + 1, n), np.nan) for name in RESULT_ARRAYS if name != "t"
        }
        self.sat_steps = np.zeros(n, dtype=int)
        self.sat_excess = np.zeros(n)
        self.step_ns = np.zeros(K + 1, dtype=np.int64)

    def result(
        self,
        robot: Robot,
        reference: Reference,
        m: int,
        cause: BaseException | None,
        message: str,
        meta: dict | None,
        sampled: bool,
    ) -> Result:
        """The first ``m`` samples as a :class:`Result` (complete when ``cause`` is
        ``None``), with the step times and the saturation counts in its ``meta``."""
        if m:
            _complete(self.rec, reference, self.t[:m], self.limit, sampled=sampled)
        result = Result(
            t=self.t[:m],
            **{name: arr[:m] for name, arr in self.rec.items()},
            joint_names=tuple(robot.joint_names),
            complete=cause is None,
            message=message,
            meta=dict(meta or {}),
        )
        _step_time(result, self.step_ns[:m], self.Ts)
        _record_saturation(result, self.limit, self.sat_steps, self.sat_excess)
        return result


def _run(
    runner: CompiledLoop, t_arr: np.ndarray, duration: float
) -> tuple[int, int, str, BaseException | None]:
    """Run the loop to its end or its stop.

    Returns:
        ``(k, last, message, cause)``: the step reached, the last whole step, and for a
        stopped run its message and cause (an error of the package or Ctrl-C; ``None``:
        the run completed).
    """
    last = k = -1
    message = ""
    cause: BaseException | None
    try:
        raise_if_interrupted()  # a Ctrl-C swallowed while the run was set up
        try:
            runner.run()
        finally:
            k, last = runner.k, runner.last
    except HmpcError as exc:
        message = str(exc)
        cause = exc
    except KeyboardInterrupt as exc:  # Ctrl-C: keep the run up to the last whole step
        message = f"interrupted at t={t_arr[max(last, 0)]:.6g} s of {duration:g} s"
        cause = exc
    else:
        cause = None
    return k, last, message, cause


def _record_saturation(result: Result, limit, steps: np.ndarray, excess: np.ndarray) -> None:
    """``meta["saturation"]``: the effort limits, per joint the periods saturated and the
    largest excess (nothing without limits)."""
    if limit is not None:
        result.meta["saturation"] = {
            "effort_limit": [float(x) for x in limit],
            "steps": steps.tolist(),
            "max_excess": excess.tolist(),
        }


#: Samples over which :func:`observer_hint` looks for an estimate alternating in sign.
ALTERNATING = 6


def observer_hint(d_hat: np.ndarray, joint_names) -> str:
    """A clause naming an unstable observer for a failed run's message, or "".

    The observer loop that leaves the unit circle at :math:`z = -1` (a latency declared
    longer than the measurements' age, :mod:`hmpc_pin.compensation.bandwidth` case 4)
    shows as an estimate whose sign flips every period: flagged on a joint whose last
    :data:`ALTERNATING` estimates alternate in sign, each at least a tenth of its largest
    magnitude over the run (an oscillation that dominates it, not noise about zero).

    Args:
        d_hat: The recorded estimates [N·m], (m, n).
        joint_names: Names of the n joints.
    """
    d = np.asarray(d_hat, dtype=float)
    if d.ndim != 2 or len(d) < ALTERNATING or not np.all(np.isfinite(d[-ALTERNATING:])):
        return ""
    tail = d[-ALTERNATING:]
    flips = np.all(tail[1:] * tail[:-1] < 0, axis=0)
    peak = np.nanmax(np.abs(d), axis=0)
    big = np.all(np.abs(tail) >= 0.1 * peak, axis=0) & (peak > 0)
    bad = np.flatnonzero(flips & big)
    if not bad.size:
        return ""
    j = int(bad[np.argmax(peak[bad])])
    names = list(joint_names)
    return (
        f"; before it, the disturbance observer's estimate changed sign every period on "
        f"{bad.size} joint(s) (joint {names[j]!r}: |d̂| up to {peak[j]:.4g} N·m): its loop "
        "is unstable; the usual cause is a [controller] latency declared longer than the "
        "measurements' age, or a bandwidth above the rule (guide 'Sensing and latency')"
    )
