"""A Franka FR3 or Panda over the vendor's ``pylibfranka`` (FCI), as the real-time
loop's :class:`~hmpc_pin.realtime.interface.PacedInterface`.

The robot runs the clock: every 1 ms ``readOnce()`` returns its state and the
``Duration`` since the last read, and ``writeOnce(Torques)`` answers it. So
:meth:`FrankaArm.wait` is ``readOnce`` (the loop is paced by the robot, never by a
sleep), a ``Duration`` of :math:`m` periods reports :math:`m - 1` lost cycles, and
:meth:`FrankaArm.write` answers the state taken, through the
:class:`~.filter.CommandFilter` (ramp-in, rate limit against ``tau_J_d``, torque limit).
A state the loop did not answer (it was busy with its stop) is answered at the next
:meth:`~FrankaArm.wait` with the last command requested, filtered: every state gets one
command.

The torque sent excludes gravity (the robot adds :math:`G(q)`). :meth:`FrankaArm.finish`
ends the motion: the command ramped to zero within the rate limit, then one zero command
with ``motion_finished``; the robot's own controller then holds the arm (mode Idle).

A reflex (``ControlException``) or a lost connection (``NetworkException``) ends the
motion on the robot's side: nothing can be sent. :meth:`~FrankaArm.wait` then reports no
state (the loop stops, its records kept) and :attr:`FrankaArm.fault` holds the cause
(``"reflex"`` or ``"network"``), the robot's mode, ``last_motion_errors`` and
``current_errors`` by name, and the last state.

``pylibfranka`` is imported when the arm is made (extra ``franka``).
"""

from __future__ import annotations

import contextlib
import os
import time
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ...exceptions import ArmError, ExtraError, NonFiniteError
from .filter import CommandFilter

__all__ = [
    "FrankaArm",
    "error_names",
    "import_franka",
    "restore_thread_policy",
    "thread_policy",
]

FloatArray = NDArray[np.float64]


def thread_policy() -> tuple[int, int] | None:
    """The calling thread's scheduling policy and priority (``None``: not readable)."""
    try:
        return os.sched_getscheduler(0), os.sched_getparam(0).sched_priority
    except (AttributeError, OSError):
        return None


def restore_thread_policy(policy: tuple[int, int] | None) -> None:
    """Put the calling thread back to ``policy`` (:func:`thread_policy`): libfranka's
    ``Robot()`` and its motions leave it at ``SCHED_FIFO`` 99 where they may, which would
    make everything the process runs afterwards real-time."""
    if policy is None:
        return
    with contextlib.suppress(OSError):
        os.sched_setscheduler(0, policy[0], os.sched_param(policy[1]))


#: The FCI's period [s].
PERIOD = 0.001


def import_franka():
    """``pylibfranka``, or :class:`~hmpc_pin.exceptions.ExtraError` naming the extra."""
    try:
        import pylibfranka  # type: ignore[import-not-found]
    except ImportError as exc:
        raise ExtraError("franka", f"hmpc-pin franka (pylibfranka: {exc})") from exc
    return pylibfranka


def error_names(errors) -> list[str]:
    """The names of the flags set in a pylibfranka ``Errors`` (e.g.
    ``["joint_position_limits_violation"]``)."""
    names = []
    for name in dir(type(errors)):
        if name.startswith("_"):
            continue
        value = getattr(errors, name, None)
        if value is True:
            names.append(name)
    return names


class _Cycles:
    """The driver's own record, one row per robot cycle (preallocated)."""

    FIELDS = ("q", "dq", "tau_J", "tau_J_d", "tau_ext_hat_filtered", "requested", "command")

    def __init__(self, capacity: int, n: int):
        self.capacity = capacity
        self.arrays = {name: np.full((capacity, n), np.nan) for name in self.FIELDS}
        self.robot_time = np.full(capacity, np.nan)
        self.duration = np.full(capacity, np.nan)
        self.success_rate = np.full(capacity, np.nan)
        self.compute = np.full(capacity, np.nan)
        self.arrival = np.full(capacity, np.nan)
        self.sent = np.zeros(capacity, dtype=bool)
        self.finished = np.zeros(capacity, dtype=bool)
        self.rows = 0

    def as_dict(self) -> dict[str, np.ndarray]:
        r = self.rows
        out = {name: a[:r].copy() for name, a in self.arrays.items()}
        out.update(
            robot_time=self.robot_time[:r].copy(),
            duration=self.duration[:r].copy(),
            success_rate=self.success_rate[:r].copy(),
            compute=self.compute[:r].copy(),
            arrival=self.arrival[:r].copy(),
            sent=self.sent[:r].copy(),
            motion_finished=self.finished[:r].copy(),
        )
        return out


class FrankaArm:
    """A Franka arm over pylibfranka in torque control (module doc).

    Args:
        address: The robot's FCI address (a simulator: ``127.0.0.1``).
        limit: Per-joint torque limit [N·m] of the command filter, (7,).
        ramp: Cycles of the ramp-in (the first command is zero).
        realtime: ``"enforce"`` (libfranka's ``kEnforce``: a real-time kernel) or
            ``"ignore"`` (``kIgnore``: a simulator, or a test without a real-time kernel).
        capacity: Cycles the driver's own record holds (later cycles are not recorded).

    Attributes:
        fault: ``None``, or the record of a reflex or a lost connection (module doc).
        lost: Cycles lost (the robot's ``Duration`` beyond one period, summed).
        overdue: Periods lost before the state :meth:`wait` took (the loop's misses).
        arrival: When the state taken arrived (:meth:`clock`).
    """

    nq = 7
    period = PERIOD

    def __init__(
        self,
        address: str,
        limit,
        *,
        ramp: int = 100,
        realtime: str = "enforce",
        capacity: int = 60_000,
    ):
        franka = import_franka()
        self._franka = franka
        if realtime not in ("enforce", "ignore"):
            raise ArmError(f"realtime={realtime!r}; expected 'enforce' or 'ignore'")
        modes = franka.RealtimeConfig
        config = modes.kEnforce if realtime == "enforce" else modes.kIgnore
        policy = thread_policy()  # libfranka's Robot() switches this thread to SCHED_FIFO 99
        try:
            self.robot = franka.Robot(address, config)
        except franka.RealtimeException as exc:
            raise ArmError(
                f"libfranka refuses real-time enforcement here ({exc}); run on a PREEMPT_RT "
                "kernel with an rtprio limit, or pass --realtime ignore (a simulator)"
            ) from None
        except (franka.NetworkException, franka.FrankaException, RuntimeError) as exc:
            raise ArmError(
                f"no Franka arm answers at {address!r} ({exc}); check the address, that "
                "FCI is enabled in Desk, and the network (or start the simulator: "
                "franky-sim -s mujoco)"
            ) from None
        finally:
            restore_thread_policy(policy)
        self.address = address
        self.filter = CommandFilter(limit, ramp=ramp)
        self._control: Any = None  # pylibfranka's ActiveControlBase during a motion
        self._state: Any = None
        self._answered = True
        self._q = np.zeros(self.nq)
        self._dq = np.zeros(self.nq)
        self._tau_J_d = np.zeros(self.nq)
        self._request = np.zeros(self.nq)
        self.stamp = 0.0
        self.arrival = 0.0
        self.overdue = 0
        self.lost = 0
        self.fault: dict | None = None
        self.nonfinite = 0  # non-finite commands requested (zero sent instead)
        self._cycle = -1  # the robot cycle of the state taken, since start()
        self._row = -1
        self._cycles = _Cycles(capacity, self.nq)
        self._closed = False

    # ------------------------------------------------------------------ before the motion
    def _errors(self) -> tuple:
        """pylibfranka's exception classes."""
        f = self._franka
        return (
            f.ControlException,
            f.NetworkException,
            f.CommandException,
            f.InvalidOperationException,
            f.RealtimeException,
            f.FrankaException,
        )

    def _call(self, what: str, fn, *args):
        """``fn(*args)``, a pylibfranka error as :class:`ArmError` naming ``what``."""
        try:
            return fn(*args)
        except self._errors() as exc:
            raise ArmError(f"{what} failed on the robot at {self.address!r}: {exc}") from None

    def read_state(self):
        """The robot's state, outside a motion (``Robot.read_once``)."""
        return self._call("reading the state", self.robot.read_once)

    def model_mass(self, state) -> FloatArray:
        """:math:`M(q)` [kg·m²], (7, 7), of the robot's own model (``load_model().mass``)."""
        model = self._call("loading the robot's model", self.robot.load_model)
        return np.array(model.mass(state), dtype=float).reshape(7, 7, order="F")

    def set_collision_behavior(self, lower, upper) -> None:
        """Send joint torque collision thresholds [N·m] (each (7,)); the Cartesian force
        thresholds are set to the robot's defaults' scale, 20 and 40 N (N·m)."""
        self._call(
            "set_collision_behavior",
            self.robot.set_collision_behavior,
            [float(x) for x in lower],
            [float(x) for x in upper],
            [20.0] * 6,
            [40.0] * 6,
        )

    def recover(self) -> None:
        """``automatic_error_recovery()``: leave Reflex for Idle."""
        self._call("automatic_error_recovery", self.robot.automatic_error_recovery)

    def move_to(self, q1, duration: float, on_interrupt=None) -> dict:
        """Move by the quintic of :mod:`.move` from where the arm stands to ``q1`` [rad]
        in ``duration`` [s], in the robot's joint position control (joint impedance).

        Args:
            on_interrupt: ``f() -> bool``, asked every cycle: ``True`` ends the move where
                it is (one command with ``motion_finished``).

        Returns:
            ``{"duration", "cycles", "error"}`` (the largest |q − q1| [rad] at the end).
        """
        from .move import quintic

        franka = self._franka
        control = self._call(
            "starting joint position control",
            self.robot.start_joint_position_control,
            franka.ControllerMode.JointImpedance,
        )
        t = 0.0
        q0 = None
        cycles = 0
        target = np.asarray(q1, dtype=float)
        try:
            while True:
                state, dt = control.readOnce()
                t += dt.to_sec()
                if q0 is None:
                    q0 = np.array(state.q_d if np.any(state.q_d) else state.q, dtype=float)
                stop = on_interrupt is not None and on_interrupt()
                q = quintic(q0, target, duration, t)
                cmd = franka.JointPositions(q.tolist())
                done = stop or t >= duration
                if done:
                    if stop:  # where the command is now: the robot holds it
                        cmd = franka.JointPositions(list(state.q_d))
                    cmd.motion_finished = True
                control.writeOnce(cmd)
                cycles += 1
                if done:
                    break
        except self._errors() as exc:
            raise ArmError(
                f"the move to the reference's start was aborted by the robot: {exc}"
            ) from None
        finally:
            del control
        state = self.read_state()
        return {
            "duration": t,
            "cycles": cycles,
            "error": float(np.max(np.abs(np.asarray(state.q) - target))),
            "interrupted": bool(on_interrupt is not None and on_interrupt()),
        }

    # ------------------------------------------------------------------ the motion
    def start(self) -> None:
        """Start torque control and take the first state (answered by a zero command)."""
        self._control = self._call("starting torque control", self.robot.start_torque_control)
        self.filter.reset()
        self._cycle = -1
        self._request[:] = 0.0
        self._read()

    @property
    def cycle(self) -> int:
        """The robot cycle of the state taken, counted from :meth:`start` (0: the first;
        lost cycles counted)."""
        return self._cycle

    def clock(self) -> float:
        """Now [s] (``time.perf_counter``): the clock of the stamps."""
        return time.perf_counter()

    def _read(self) -> int:
        """``readOnce``; the number of periods since the last state (0: none, a fault)."""
        got = self._guarded(self._control.readOnce)
        if got is None:
            return 0
        state, duration = got
        now = time.perf_counter()
        periods = max(1, round(duration.to_sec() / PERIOD)) if self._cycle >= 0 else 1
        self._cycle += periods
        self.overdue = periods - 1
        self.lost += periods - 1
        self._state = state
        self._q[:] = state.q
        self._dq[:] = state.dq
        self._tau_J_d[:] = state.tau_J_d
        self.stamp = self.arrival = now
        self._answered = False
        c = self._cycles
        row = self._row = min(self._cycle, c.capacity) if self._cycle < c.capacity else -1
        if row >= 0:
            a = c.arrays
            a["q"][row] = self._q
            a["dq"][row] = self._dq
            a["tau_J"][row] = state.tau_J
            a["tau_J_d"][row] = self._tau_J_d
            a["tau_ext_hat_filtered"][row] = state.tau_ext_hat_filtered
            c.robot_time[row] = state.time.to_sec()
            c.duration[row] = duration.to_sec()
            c.success_rate[row] = state.control_command_success_rate
            c.arrival[row] = now
            c.rows = max(c.rows, row + 1)
        return periods

    def wait(self, timeout: float) -> int:
        """Answer the state taken if the loop did not, then block for the robot's next
        state (``readOnce``); the periods it reports (0: a reflex or a lost connection,
        :attr:`fault`)."""
        if self._control is None or self.fault is not None:
            return 0
        if not self._answered:
            self._send(self._request)
            if self.fault is not None:
                return 0
        return self._read()

    def read(self) -> tuple[float, FloatArray, FloatArray]:
        """``(stamp [s], q [rad], dq [rad/s])`` of the state taken."""
        return self.stamp, self._q, self._dq

    def write(self, tau: FloatArray) -> None:
        """Answer the state taken with ``tau`` [N·m] (without gravity), filtered; a second
        write for the same state becomes the command requested for the next one."""
        tau = np.asarray(tau, dtype=float)
        if np.isfinite(tau).all():
            self._request[:] = tau
        else:
            self.nonfinite += 1
            self._request[:] = 0.0
        if self._answered or self._control is None or self.fault is not None:
            return
        self._send(self._request)

    def _send(self, tau: FloatArray, finished: bool = False) -> None:
        """Answer the state taken with ``tau`` [N·m] through the filter (a non-finite
        ``tau``: toward zero within the rate limit)."""
        try:
            cmd = self.filter(tau, self._tau_J_d)
        except NonFiniteError:
            cmd = self.filter.toward_zero(self._tau_J_d)
        self._write(tau, cmd, finished, timed=True)

    def finish(self, max_cycles: int = 2000) -> dict:
        """End the motion (module doc): ramp the command to zero within the rate limit,
        then one zero command with ``motion_finished``.

        Returns:
            ``{"cycles", "mode", "speed"}``: the ramp's cycles, the robot's mode after it
            and its largest joint speed [rad/s] then (``{}`` after a fault).
        """
        if self._control is None or self.fault is not None:
            return {}
        cycles = 0
        step = self.filter.max_step
        zero = np.zeros(self.nq)
        while self.fault is None and cycles < max_cycles:
            if self._answered and not self._read():
                break
            cycles += 1
            if np.max(np.abs(self._tau_J_d)) <= step:
                self._request[:] = 0.0
                self._send_raw(zero, finished=True)
                break
            self._send_raw(self.filter.toward_zero(self._tau_J_d).copy())
        self._control = None
        if self.fault is not None:
            return {}
        time.sleep(0.05)  # the robot leaves Move for Idle after the motion's end
        try:
            state = self.robot.read_once()
        except self._errors() as exc:  # the run is kept: say what could not be read
            return {"cycles": cycles, "mode": "unknown", "speed": float("nan"), "error": str(exc)}
        return {
            "cycles": cycles,
            "mode": state.robot_mode.name,
            "speed": float(np.max(np.abs(np.asarray(state.dq)))),
        }

    def _send_raw(self, cmd: FloatArray, finished: bool = False) -> None:
        """Send ``cmd`` as it is (already within the rate and torque limits)."""
        self._write(cmd, cmd, finished, timed=False)

    def _write(self, requested: FloatArray, cmd: FloatArray, finished: bool, timed: bool) -> None:
        """``writeOnce(cmd)`` for the state taken, recorded in the driver's own record
        (``requested`` beside it; ``timed``: its compute time too, the loop's cycles)."""
        torques = self._franka.Torques(cmd.tolist())
        if finished:
            torques.motion_finished = True
        row = self._row
        c = self._cycles
        if row >= 0:
            c.arrays["requested"][row] = requested
            c.arrays["command"][row] = cmd
            c.sent[row] = True
            c.finished[row] = finished
        self._guarded(self._control.writeOnce, torques)
        if timed and row >= 0:
            c.compute[row] = time.perf_counter() - self.arrival
        self._answered = True

    def _guarded(self, fn, *args):
        """``fn(*args)`` (``readOnce`` or ``writeOnce``); a reflex (``ControlException``)
        or a lost connection (``NetworkException``) is recorded (:meth:`_fail`) instead
        of raised, and gives ``None``."""
        franka = self._franka
        try:
            return fn(*args)
        except franka.ControlException as exc:
            self._fail("reflex", exc)
        except franka.NetworkException as exc:
            self._fail("network", exc)
        return None

    def _fail(self, cause: str, exc: BaseException) -> None:
        """Record a reflex or a lost connection (module doc); nothing is sent after it."""
        self._control = None
        record: dict = {
            "cause": cause,
            "message": str(exc),
            "cycle": int(self._cycle),
            "last_q": self._q.tolist(),
            "last_dq": self._dq.tolist(),
            "last_tau_J_d": self._tau_J_d.tolist(),
        }
        if cause == "reflex":
            try:
                state = self.robot.read_once()
                record.update(
                    robot_mode=state.robot_mode.name,
                    last_motion_errors=error_names(state.last_motion_errors),
                    current_errors=error_names(state.current_errors),
                    q=list(state.q),
                    dq=list(state.dq),
                    tau_J=list(state.tau_J),
                )
            except Exception as inner:  # the record says what could not be read
                record["state_error"] = str(inner)
        self.fault = record

    # ------------------------------------------------------------------ after
    @property
    def cycles(self) -> dict[str, np.ndarray]:
        """The driver's own record, one row per robot cycle since :meth:`start`:
        ``q``, ``dq``, ``tau_J``, ``tau_J_d`` (what the robot received before this state),
        ``tau_ext_hat_filtered``, ``requested`` and ``command`` (sent, filtered) [N·m],
        ``robot_time`` and ``duration`` [s], ``success_rate``, ``compute`` [s]
        (``readOnce`` returned → ``writeOnce``), ``arrival`` [s] (when ``readOnce``
        returned: the loop's stamp of that state), ``sent`` and ``motion_finished``."""
        return self._cycles.as_dict()

    def save_cycles(self, path: Path) -> Path:
        """Write :attr:`cycles` to ``path`` (``.npz``)."""
        np.savez(path, **self.cycles)  # type: ignore[arg-type]
        return path

    def close(self) -> None:
        """End a motion still running (:meth:`finish`); idempotent."""
        if self._closed:
            return
        self._closed = True
        if self._control is not None and self.fault is None:
            self.finish()
