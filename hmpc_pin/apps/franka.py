"""``hmpc-pin franka``: the experiment's controller on a Franka FR3 or Panda over
``pylibfranka`` (FCI), in torque control at 1 kHz (:mod:`hmpc_pin.realtime.franka`).

The same real-time loop as ``hmpc-pin realtime`` and ``hmpc-pin ros``
(:class:`~hmpc_pin.realtime.loop.RealtimeLoop`: its safety, watchdog, records and
summary), paced by the robot's ``readOnce``. In order:

1. connect; check the robot (mode Idle, the config's arm is a 7-joint Franka, q inside
   the limits, the config arm's M(q) against the robot's own model); with ``--recover``
   a robot in Reflex is recovered first;
2. send the collision thresholds (``--thresholds``, from ``identify --thresholds``);
3. move from where the arm stands to the reference's start (a quintic within velocity and
   acceleration bounds, in the robot's joint position control), or refuse beyond
   ``--max-move``;
4. the torque motion: the controller's torque without G(q) (the robot adds it) through
   the command filter (ramp-in, rate limit against ``tau_J_d``, torque limits);
5. the end (normal, Ctrl-C, a fault, lost cycles): the loop's inertia brake (without
   gravity), the command ramped to zero within the rate limit, one zero command with
   ``motion_finished``: the robot holds the arm (Idle). A reflex or a lost connection
   ends the motion on the robot's side: its record is kept, exit 1.

Writes ``<stem>_franka.npz`` (the run, as ``run``/``realtime`` write it, with
``tau_J_d``, ``tau_ext_hat_filtered`` and the command sent at the controller steps in
its extra arrays), ``<stem>_franka_timing.npz`` (the loop's cycles),
``<stem>_franka_cycles.npz`` (the driver's own record, every robot cycle) and
``<stem>_franka.json`` (statistics, stop, the driver's summary, tracking).
"""

from __future__ import annotations

import contextlib
import signal
import sys
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..exceptions import ArmError, ConfigError, HmpcError, ValidityWarning
from ..experiment.build import Experiment
from ..experiment.config import ExperimentConfig
from ..experiment.inner_law import close_law, inner_law_controller, inner_law_summary
from ..experiment.realtime import realtime_parts
from ..realtime.franka import (
    FRANKA_TORQUE_LIMIT,
    FrankaArm,
    check_joint_names,
    check_mass,
    check_mode,
    check_move,
    check_position,
    quintic_duration,
)
from ..realtime.franka.arm import restore_thread_policy, thread_policy
from ..realtime.loop import RealtimeLoop, RealtimeRun
from ..realtime.safety import GravityByArm, SafeTorque, SafetySettings
from .common import add_inner_law_option, inner_law_value
from .realtime import save_run

__all__ = ["FrankaOptions", "franka_parts", "run_franka"]

#: Inside the URDF's position limits by this much [rad], the driver's own watch stops
#: before the robot's position reflex would.
POSITION_MARGIN = 0.02
#: The driver's own velocity watch at this fraction of the URDF's velocity limits.
VELOCITY_FRACTION = 0.9
#: The values of --inner-law (FrankaOptions.inner_law; "held", the name of earlier
#: versions, is "whole-step").
INNER_LAWS = ("auto", "whole-step", "every-cycle", "threaded", "held")
#: The move to the start: at most this joint speed [rad/s] and acceleration [rad/s²].
MOVE_VELOCITY = 0.5
MOVE_ACCELERATION = 1.0


class FrankaOptions:
    """The command line's choices for a Franka run.

    Attributes:
        address: The robot's FCI address.
        realtime: ``"enforce"`` or ``"ignore"`` (libfranka's ``RealtimeConfig``).
        recover: Recover a robot in Reflex before the motion, and after a reflex.
        max_move: Largest joint distance [rad] moved to the reference's start.
        model_tolerance: Relative tolerance of the mass-matrix check.
        thresholds: ``(lower, upper)`` joint torque collision thresholds [N·m] or ``None``.
        ramp: Cycles of the command's ramp-in.
        inner_law: ``None`` (``[realtime] inner_law``, by default ``"auto"``: every
            cycle where it applies), ``"every-cycle"`` (Eq 4 and the observer every cycle,
            the MPC every ``Ts``), ``"threaded"`` (the same with the MPC in a compiled
            thread, its latest plan used within a staleness bound) or ``"whole-step"``
            (the whole step every ``Ts``, its torque held; ``"held"`` is its earlier
            name) (:mod:`hmpc_pin.experiment.inner_law`).
    """

    def __init__(
        self,
        address: str,
        realtime: str = "enforce",
        recover: bool = False,
        max_move: float = 1.0,
        model_tolerance: float = 0.10,
        thresholds=None,
        ramp: int = 100,
        inner_law: str | None = None,
    ):
        self.address, self.realtime, self.recover = address, realtime, recover
        self.max_move, self.model_tolerance = float(max_move), float(model_tolerance)
        self.thresholds, self.ramp = thresholds, int(ramp)
        self.inner_law = None if inner_law is None else inner_law_value(inner_law)


def franka_parts(experiment: Experiment, inner_law: str | None = None):
    """The loop settings (1 kHz), the driver's own limits (inside the URDF's), the safe
    torque (the inertia brake without gravity) and the controller without G(q), run by the
    inner law of ``[realtime] inner_law`` (``inner_law``, ``--inner-law``, over it):
    by default (``"auto"``) the MPC every ``Ts`` with Eq 4 and the observer every cycle
    (:class:`~hmpc_pin.realtime.inner_law.InnerLawEveryCycle`) where it applies (the
    hierarchical MPC with an observer, no declared latency, ``Ts`` > 1 ms), else the whole
    step (:mod:`hmpc_pin.experiment.inner_law`).

    Raises:
        ConfigError: 1 kHz does not divide the controller period, the brake settings, an
            inner law that does not apply.
    """
    loop_settings, safety, safe = realtime_parts(experiment, 1000.0, plant=False)
    robot = experiment.robot
    lower = np.asarray(robot.model.lowerPositionLimit, dtype=float) + POSITION_MARGIN
    upper = np.asarray(robot.model.upperPositionLimit, dtype=float) - POSITION_MARGIN
    velocity = np.where(robot.velocity_limit > 0, VELOCITY_FRACTION * robot.velocity_limit, np.inf)
    safety = SafetySettings(
        lower,
        upper,
        velocity,
        max_misses=min(safety.max_misses, 19),
        watchdog=max(safety.watchdog, 0.01),
        hold=safety.hold,
        brake_speed=safety.brake_speed,
    )
    loop_settings = replace(loop_settings, warm_up=0.0, spin=0.0)
    safe = SafeTorque(
        robot,
        safe.damping,
        gravity=False,
        effort_limit=FRANKA_TORQUE_LIMIT,
        brake_time=safe.brake_time,
    )
    ctrl = inner_law_controller(
        experiment, loop_settings.period, "franka", FRANKA_TORQUE_LIMIT, choice=inner_law
    )
    return loop_settings, safety, safe, GravityByArm(ctrl, robot)


def _check_robot(arm: FrankaArm, experiment: Experiment, options: FrankaOptions) -> dict:
    """The checks before the motion (:mod:`hmpc_pin.realtime.franka.checks`)."""
    state = arm.read_state()
    mode = state.robot_mode.name
    recovered = False
    if mode == "Reflex" and options.recover:
        arm.recover()
        recovered = True
        state = arm.read_state()
        mode = state.robot_mode.name
    check_mode(mode)
    robot = experiment.robot
    names = tuple(robot.joint_names)
    check_joint_names(names)
    q = np.asarray(state.q, dtype=float)
    check_position(q, robot.model.lowerPositionLimit, robot.model.upperPositionLimit, names)
    # the robot's model has no rotor inertia: compare the rigid bodies' M(q)
    rigid = robot.mass_matrix(q) - np.diag(np.asarray(robot.model.armature, dtype=float))
    err = check_mass(rigid, arm.model_mass(state), names, tolerance=options.model_tolerance)
    return {
        "mode": mode,
        "recovered": recovered,
        "q": q.tolist(),
        "mass_error": err.tolist(),
        "mass_tolerance": options.model_tolerance,
        "end_effector_mass": float(state.m_ee),
    }


def run_franka(
    config: ExperimentConfig,
    options: FrankaOptions,
    out: Path,
    stem: str | None = None,
    experiment: Experiment | None = None,
    ready=None,
    controller_wrapper=None,
    started=None,
):
    """Run ``config`` on a Franka arm (module doc); write the files to ``out``.

    Args:
        config: The experiment.
        options: Address and choices (:class:`FrankaOptions`).
        out: Output directory (exists, writable).
        stem: File stem (default: the config's name).
        experiment: ``config`` already built (default: built here).
        ready: ``None`` or ``ready()``, called just before the torque motion starts.
        controller_wrapper: ``None`` or ``f(controller) -> controller`` applied to the
            controller without G(q) (tests inject faults with it).
        started: ``None`` or ``started(arm)``, called with the
            :class:`~hmpc_pin.realtime.franka.FrankaArm` once torque control runs (after
            ``ready``): a supervisor may end the motion from another thread with
            libfranka's ``arm.robot.stop()`` (the robot preempts it: a
            ``ControlException``, recorded as a reflex is).

    Returns:
        ``(run, files, arm_summary)``.
    """
    policy = thread_policy()  # libfranka's Robot() may switch this thread to SCHED_FIFO 99
    d = _Drive(config, options, out, stem, experiment, ready, controller_wrapper, started)
    try:
        return _drive(d)
    finally:
        restore_thread_policy(policy)


@dataclass
class _Drive:
    """A Franka run: :func:`run_franka`'s arguments, then the experiment built and
    :func:`franka_parts`' answer (``parts``)."""

    config: ExperimentConfig
    options: FrankaOptions
    out: Path
    stem: str | None
    experiment: Experiment | None
    ready: Callable[[], None] | None
    controller_wrapper: Callable | None
    started: Callable | None
    parts: tuple = ()


def _drive(d: _Drive):
    """:func:`run_franka`'s work (its return), the thread's scheduling policy put back by
    the caller on every way out; the inner law closed (the threaded law's planner thread
    joined) on every way out."""
    d.stem = (d.stem or d.config.name) + "_franka"
    if d.experiment is None:
        d.experiment = Experiment.from_config(d.config)
    d.parts = franka_parts(d.experiment, d.options.inner_law)
    try:
        return _drive_law(d)
    finally:
        close_law(d.parts[3])


def _drive_law(d: _Drive):
    """:func:`_drive`'s work once the controller is built; the caller closes the law."""
    options, out, stem, experiment = d.options, d.out, str(d.stem), d.experiment
    assert experiment is not None
    loop_settings, safety, safe, ctrl = d.parts
    law = inner_law_summary(ctrl, loop_settings.period)
    if d.controller_wrapper is not None:
        ctrl = d.controller_wrapper(ctrl)
    K = round(loop_settings.duration * loop_settings.rate)
    capacity = K + round(2.0 * safety.hold * 1000) + 3000
    arm = FrankaArm(
        options.address,
        FRANKA_TORQUE_LIMIT,
        ramp=options.ramp,
        realtime=options.realtime,
        capacity=capacity,
    )
    names = tuple(experiment.robot.joint_names)
    summary: dict = {
        "address": options.address,
        "realtime": options.realtime,
        "inner_law": law["label"],
    }
    summary["checks"] = _check_robot(arm, experiment, options)
    if law["name"] != "threaded" and hasattr(experiment.controller, "qps"):
        cpu = activation_step_cpu(experiment.controller, experiment.reference, experiment.q0)
        summary["activation_step_cpu_us"] = 1e6 * cpu
        advice = threaded_advice(cpu, loop_settings.period)
        if advice is not None:
            summary["advice"] = advice
            warnings.warn(advice, ValidityWarning, stacklevel=2)
    if options.thresholds is not None:
        lower, upper = options.thresholds
        arm.set_collision_behavior(lower, upper)
        summary["collision_thresholds"] = {"lower": list(lower), "upper": list(upper)}
    _move_to_start(arm, experiment, options, summary, names)
    loop = RealtimeLoop(
        arm,
        ctrl,
        experiment.reference,
        safe,
        loop_settings,
        safety,
        joint_names=names,
        meta=experiment.meta(),
    )
    switch = sys.getswitchinterval()
    state = arm.read_state()  # where the move left the arm: the controller's reset state
    try:
        if d.ready is not None:
            d.ready()
        if d.started is not None:
            d.started(arm)
        sys.setswitchinterval(1e-4)  # readOnce holds the GIL while it waits
        # the loop collects and freezes the heap and resets the controller, then starts
        # torque control (the robot's clock): none of its set-up costs the arm a cycle
        run = loop.run(np.array(state.q, dtype=float), np.array(state.dq, dtype=float), start=True)
    finally:
        sys.setswitchinterval(switch)
        with _SigintDeferred() as deferred:  # the ramp to zero is not cut short
            end = arm.finish() if arm.fault is None else {}
    _close_record(run, arm, options, summary, end, deferred["count"])
    law = inner_law_summary(d.parts[3], loop_settings.period)  # the counts at the end
    run.stats["inner_law"] = law
    if "requests" in law:  # the MPC's planner thread (the threaded law)
        summary["planner"] = {
            k: law[k] for k in ("requests", "published", "dropped", "refused", "fallbacks")
        }
        summary["planner"]["max_age"] = law["max_age"]
    files = save_run(run, out, stem, "franka")
    files.append(arm.save_cycles(out / f"{stem}_cycles.npz"))
    return run, files, summary


def activation_step_cpu(controller, reference, q0, offset: float = 0.2, steps: int = 3) -> float:
    """The MPC's step at an activation, by the thread's CPU time [s] (preemption mostly
    left out): the costliest of ``steps`` steps of ``controller`` (a hierarchical MPC) on
    the arm held at rest ``offset`` [rad] off ``reference``'s start on every joint (the
    bounds and soft limits of every joint active at once: the worst step of a closed loop
    that starts there, and every step of a stalled arm). The controller is reset before and
    after."""
    q_ref, _ = reference.sample(0.0)
    q = np.asarray(q_ref, dtype=float) + offset
    dq = np.zeros_like(q)
    controller.reset(q, dq)
    worst = 0.0
    try:
        for k in range(steps):
            start = time.thread_time()
            controller.step(k * controller.Ts, q, dq, reference)
            worst = max(worst, time.thread_time() - start)
    except HmpcError:  # the run reports it
        pass
    controller.reset(np.asarray(q0, dtype=float), np.zeros_like(q))
    return worst


def threaded_advice(step_cpu: float, period: float) -> str | None:
    """The threaded law recommended when the MPC's step at an activation
    (:func:`activation_step_cpu`, ``step_cpu`` [s]) does not fit the arm's ``period``
    [s] with the MPC in the cycle; ``None`` otherwise."""
    if not step_cpu > period:
        return None
    return (
        f"the MPC's step takes {1e6 * step_cpu:.0f} us of CPU where its limits activate "
        f"(measured 0.2 rad off the reference's start), beyond the arm's period of "
        f"{1e3 * period:g} ms: with the MPC in the cycle such cycles are late; run it in its "
        "compiled thread (--inner-law threaded), whose cycles use the last plan shifted "
        "instead of waiting"
    )


def _move_to_start(arm, experiment: Experiment, options: FrankaOptions, summary, names) -> None:
    """Move the arm from where it stands to the reference's start (a quintic within
    :data:`MOVE_VELOCITY` and :data:`MOVE_ACCELERATION`, refused beyond
    ``options.max_move``); ``summary["move"]`` records it. Ctrl-C stops the move where it
    is (the arm Idle) and raises :class:`KeyboardInterrupt`."""
    q_now = np.asarray(summary["checks"]["q"])
    q_start = np.asarray(experiment.reference.sample(0.0)[0], dtype=float)
    check_move(q_now, q_start, options.max_move, names)
    T = quintic_duration(q_start - q_now, np.full(7, MOVE_VELOCITY), np.full(7, MOVE_ACCELERATION))
    interrupted = {"flag": False}

    def on_sigint(signum, frame):
        interrupted["flag"] = True

    old = signal.signal(signal.SIGINT, on_sigint)
    try:
        summary["move"] = arm.move_to(q_start, T, lambda: interrupted["flag"])
    finally:
        signal.signal(signal.SIGINT, old)
    if interrupted["flag"]:
        raise KeyboardInterrupt(
            "interrupted during the move to the reference's start; the arm holds where "
            "the move stopped (Idle); nothing else was run or written"
        )


def _close_record(run, arm, options: FrankaOptions, summary, end, interrupts: int) -> None:
    """After the motion: a Ctrl-C during the final ramp recorded as the stop, the recovery
    (``--recover``) tried after a fault, the driver's summary, the fault and the robot's
    own signals added to ``run``'s record."""
    if interrupts and run.stop is None:
        run.stop = {"cause": "interrupted", "reason": "interrupted (Ctrl-C) at the end", "t": 0.0}
        run.stop["t"] = float(run.result.t[-1]) if len(run.result.t) else 0.0
        run.stop["safe_tau"] = None
        run.result.meta["stop"] = run.stop
    if arm.fault is not None and options.recover:
        try:
            arm.recover()
            arm.fault["recovered"] = True
        except ArmError as exc:  # the run is kept: the record says why not
            arm.fault["recovered"] = False
            arm.fault["recovery_error"] = str(exc)
    summary.update(_driver_summary(arm, end))
    _record_fault(run, arm)
    _add_extras(run, arm)
    run.result.meta["franka"] = summary
    # tau and tau_applied are the torque sent: the robot adds G(q) (Result.gravity_by_arm)
    run.result.meta["gravity_by_arm"] = True


class _SigintDeferred:
    """Within the block a Ctrl-C is counted, not raised (``deferred["count"]``); outside
    the main thread nothing changes."""

    def __enter__(self) -> dict:
        self.state = {"count": 0}
        self._old = None
        with contextlib.suppress(ValueError):  # not the main thread
            self._old = signal.signal(signal.SIGINT, self._count)
        return self.state

    def _count(self, signum, frame) -> None:
        self.state["count"] += 1

    def __exit__(self, *exc) -> None:
        if self._old is not None:
            signal.signal(signal.SIGINT, self._old)


def _driver_summary(arm: FrankaArm, end: dict) -> dict:
    c = arm.cycles
    sent = c["sent"]
    compute = c["compute"][np.isfinite(c["compute"])] * 1e6
    rate = c["success_rate"][np.isfinite(c["success_rate"])]
    out = {
        "cycles": len(sent),
        "commands_sent": int(sent.sum()),
        "lost_cycles": int(arm.lost),
        "success_rate_min": float(rate.min()) if rate.size else None,
        "success_rate_mean": float(rate.mean()) if rate.size else None,
        "compute_p50_us": float(np.percentile(compute, 50)) if compute.size else None,
        "compute_p99_us": float(np.percentile(compute, 99)) if compute.size else None,
        "compute_max_us": float(compute.max()) if compute.size else None,
        "nonfinite_requests": arm.nonfinite,
        "end": end,
        "fault": arm.fault,
        "tau": "the controller's torque without G(q) (the robot adds gravity)",
    }
    return out


def _record_fault(run: RealtimeRun, arm: FrankaArm) -> None:
    """A reflex or a lost connection as the run's stop (the loop saw only the states
    stop coming)."""
    fault = arm.fault
    if fault is None:
        return
    if run.stop is None:  # during the ramp to zero, after the loop's last cycle
        t = float(run.result.t[-1]) if len(run.result.t) else 0.0
        run.stop = {"cause": fault["cause"], "t": t, "safe_tau": None}
        run.result.meta["stop"] = run.stop
        run.result.complete = False
    if fault["cause"] == "reflex":
        reason = f"reflex: {describe_reflex(fault)}; nothing could be sent after it"
    else:
        reason = f"network: the connection to the robot was lost ({fault['message']})"
    run.stop["cause"] = fault["cause"]
    run.stop["reason"] = f"stopped at t={run.stop['t']:.4f} s: {reason}"
    run.stop["franka"] = fault
    run.result.message = run.stop["reason"]


def describe_reflex(fault: dict) -> str:
    """A reflex's record in words: libfranka's message, the robot's mode after it and the
    errors of the aborted motion by name (``last_motion_errors``), else the errors now."""
    errors = fault.get("last_motion_errors") or fault.get("current_errors") or []
    mode = fault.get("robot_mode", "unknown")
    return (
        f"the robot aborted the motion ({fault['message']}; robot mode {mode}, motion "
        f"errors: {', '.join(errors) or 'none reported'})"
    )


def _add_extras(run: RealtimeRun, arm: FrankaArm) -> None:
    """``tau_J_d``, ``tau_ext_hat_filtered``, ``command`` at the controller steps."""
    c = arm.cycles
    t = run.result.t
    # each controller step's state, found by its stamp (when readOnce returned)
    k = np.rint(t / arm.period).astype(int)
    stamps = run.timing["stamp"][np.minimum(k, len(run.timing["stamp"]) - 1)]
    # (rows of lost cycles hold the previous arrival: sorted, each found at its first row)
    arrival = np.maximum.accumulate(np.where(np.isfinite(c["arrival"]), c["arrival"], -np.inf))
    rows = np.searchsorted(arrival, stamps)
    found = (rows < len(arrival)) & (arrival[np.minimum(rows, len(arrival) - 1)] == stamps)
    for name in ("tau_J_d", "tau_ext_hat_filtered", "command"):
        arr = np.full((len(t), arm.nq), np.nan)
        arr[found] = c[name][rows[found]]
        run.result.extra[name] = arr


def format_driver(summary: dict) -> str:
    """The driver's line: cycles, lost, success rate, compute, the end."""
    end = summary.get("end") or {}
    p50, p99 = summary.get("compute_p50_us"), summary.get("compute_p99_us")
    rate = summary.get("success_rate_min")
    line = (
        f"franka: {summary['cycles']} robot cycles, {summary['commands_sent']} commands sent, "
        f"{summary['lost_cycles']} lost, success rate min "
        + ("n/a" if rate is None else f"{rate:.3f}")
        + ", compute readOnce->writeOnce [us] "
        + ("n/a" if p50 is None else f"p50 {p50:.0f}, p99 {p99:.0f}")
    )
    line += f"; inner law {summary.get('inner_law', 'n/a')}"
    if end:
        line += f"; ended in mode {end['mode']}, max |dq| {end['speed']:.2g} rad/s"
    return line


def franka_arguments(parser) -> None:
    """The arguments of ``hmpc-pin franka``."""
    parser.description = (
        "Run the experiment's controller on a Franka FR3 or Panda over pylibfranka (FCI) "
        "in torque control at 1 kHz, paced by the robot (extra: franka). Checks the robot "
        "first (mode Idle, 7 joints, q inside the limits, the config arm's M(q) against the "
        "robot's own model), moves it to the reference's start, then runs the real-time "
        "loop of `hmpc-pin realtime` with every command filtered (first command 0, ramp-in, "
        "|dtau| <= 0.999 N·m per cycle against tau_J_d, torque limits; gravity left to the "
        "robot). Ends (normal, Ctrl-C, a fault, lost cycles) with the brake, the command "
        "ramped to zero and motion_finished: the robot holds the arm. Exit 0, 130 "
        "(Ctrl-C), 1 (a stop: fault, reflex, network; data kept), 2 (bad input, a check "
        "refused). Dry run: franky-sim -s mujoco, then --robot-ip 127.0.0.1 --realtime ignore."
    )
    parser.add_argument("config", type=Path, help="experiment TOML file (e.g. fr3_sine)")
    parser.add_argument("--robot-ip", required=True, metavar="HOST", help="the robot's FCI address")
    parser.add_argument("--duration", type=float, help="run length [s] (overrides the config)")
    parser.add_argument("--out", type=Path, default=Path("out"), help="output directory [out]")
    parser.add_argument(
        "--recover",
        action="store_true",
        help="call automatic_error_recovery() on a robot in Reflex before the motion and "
        "after a reflex during it",
    )
    parser.add_argument(
        "--realtime",
        choices=("enforce", "ignore"),
        default="enforce",
        help="libfranka's real-time requirement: enforce (a PREEMPT_RT kernel, the robot) "
        "or ignore (a simulator) [enforce]",
    )
    parser.add_argument(
        "--max-move",
        type=float,
        default=1.0,
        metavar="RAD",
        help="refuse when a joint stands farther than RAD from the reference's start [1.0]",
    )
    parser.add_argument(
        "--model-tolerance",
        type=float,
        default=0.10,
        metavar="F",
        help="refuse when a row of the config arm's M(q) differs from the robot's own model "
        "by more than F times its diagonal entry [0.10]",
    )
    add_inner_law_option(parser, "every-cycle where it applies, else whole-step")
    parser.add_argument(
        "--thresholds",
        type=Path,
        metavar="JSON",
        help="collision thresholds to send with set_collision_behavior: the JSON written "
        "by `hmpc-pin identify --thresholds` (its robot_estimate, else its thresholds)",
    )


def load_thresholds(path: Path) -> tuple[list[float], list[float]]:
    """``(lower, upper)`` joint torque collision thresholds [N·m] from the JSON of
    ``hmpc-pin identify --thresholds``: its ``robot_estimate`` (fitted on the robot's own
    ``tau_ext_hat_filtered``) if present, else its thresholds; ``upper`` is twice ``lower``
    unless given.

    Raises:
        ConfigError: The file is missing, not JSON, or has no 7 positive thresholds.
    """
    import json

    try:
        data = json.loads(Path(path).read_text())
    except (OSError, ValueError) as exc:
        raise ConfigError("--thresholds", f"cannot read {path}: {exc}") from None
    block = data.get("robot_estimate") or data
    lower = block.get("lower", block.get("thresholds")) if isinstance(block, dict) else None
    try:
        low = [float(x) for x in lower]
    except (TypeError, ValueError):
        raise ConfigError(
            "--thresholds", f"{path}: expected 'thresholds' (7 values [N·m]), got {lower!r}"
        ) from None
    up = [float(x) for x in block.get("upper", [2.0 * x for x in low])]
    if (
        len(low) != 7
        or len(up) != 7
        or min(low) <= 0
        or any(u < lo for u, lo in zip(up, low, strict=False))
    ):
        raise ConfigError(
            "--thresholds", f"{path}: expected 7 thresholds > 0 with upper >= lower, got {low}"
        )
    return low, up
