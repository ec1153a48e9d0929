"""What the real-time loop does when it must stop: the safe torque and the limits it watches.

The safe torque holds the arm against gravity and brakes its motion,

.. math::  \\tau_\\mathrm{safe} = g\\,G(q) - D\\,\\dot q, \\qquad g \\in \\{0, 1\\},

with :math:`G(q)` from Pinocchio (the controller's model, ``rnea(q, 0, 0)``) and
:math:`D = \\mathrm{diag}(d_i)` [N·m·s/rad] the joint damping, or, with a brake time
:math:`T_b` [s], the inertia-scaled brake :math:`D = M(q)/T_b`: then
:math:`M\\ddot q = -M\\dot q/T_b` (gravity compensated, Coriolis aside) and every joint
slows as :math:`e^{-t/T_b}` whatever the arm's inertia. A diagonal :math:`D` slows the
arm's slowest mode with the time constant :math:`\\lambda_\\max(M, D)`, the largest
generalized eigenvalue of :math:`M v = \\lambda D v` (:func:`brake_time_constant`): 2
N·m·s/rad gives 1.0 s on ``panda_sine``'s Panda, 6.7 s on the paper's 3-link arm
(16 kg·m² about its first joint) at their start postures.

An effort interface holds the last command it received until it is told otherwise
(ros2_control's ``JointGroupEffortController`` has no timeout), so what is written last
must be safe to hold forever without new states. The **stop sequence** of the real-time
loop is therefore:

1. at the stop, :math:`\\tau_\\mathrm{safe}` at the last finite state (or, with no fresh
   state to brake on, step 3 at once);
2. while fresh states arrive, brake: :math:`\\tau_\\mathrm{safe}` at each *current*
   state, until every :math:`|\\dot q_i|` is below ``brake_speed`` or ``hold`` seconds
   have passed (or no fresh state comes within the watchdog);
3. the **held-safe** torque :math:`\\tau_\\mathrm{held} = g\\,G(q)` at the last finite
   position, with no velocity term (a damping term on a velocity that is no longer
   measured is a constant torque that accelerates the arm): zero when the arm
   compensates gravity itself (:math:`g = 0`).

After a watchdog stop (no fresh state: the velocity is unknown) step 3 comes first, at
once, since it is the only command safe to hold without a measurement; the loop then
waits up to ``hold`` for the states to resume and, if they do (a loaded machine's stall
rather than an arm gone), runs step 2 on them and ends on step 3 where the arm came to
rest. The inertia brake is what leaves the arm still: its torque needs the velocity, so
it can only act on fresh states.

Every safe torque is clipped to the joints' effort limits (``effort_limit``, the
plant's): a brake command beyond what the drive takes is clipped by the drive anyway. The
limit is on the total joint torque: with :math:`g = 0` (the arm adds its own
:math:`G(q)`) the command is clipped to :math:`[-L - G(q), L - G(q)]`, as the simulated
plant clips the total (the controller's torques are sent as computed: the arm's drive
clips them, and the controller's observer models that clip).

On an arm without friction the held-safe torque leaves it coasting at the speed it had
(at most ``brake_speed`` after a completed brake): the drift over a time :math:`T` is at
most :math:`T \\cdot` ``brake_speed`` plus the model's gravity error.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..controllers.base import ControllerWrapper
from ..exceptions import ConfigError
from ..model.robot import Robot

__all__ = ["STOP_CAUSES", "GravityByArm", "SafeTorque", "SafetySettings", "brake_time_constant"]

FloatArray = NDArray[np.float64]

#: Why a loop stops early: Ctrl-C, a fault (non-finite value, QP not solved, state beyond
#: limits, any controller error), k consecutive missed deadlines, no new state (watchdog),
#: a stop asked by the program (a ROS lifecycle node deactivated); on a Franka arm, a reflex
#: of the robot or the connection lost (:mod:`hmpc_pin.realtime.franka`).
STOP_CAUSES = ("interrupted", "fault", "misses", "watchdog", "deactivated", "reflex", "network")


class SafeTorque:
    """:math:`\\tau_\\mathrm{safe} = g\\,G(q) - D\\dot q` [N·m].

    Args:
        robot: The controller's model (its own ``pin.Data`` is used: call from one thread).
        damping: :math:`d_i` [N·m·s/rad], one value or (n,), each >= 0.
        gravity: Include the gravity compensation :math:`G(q)`.
        effort_limit: Per-joint torque limit [N·m], one value or (n,), each > 0 (``inf``
            or ``None``: none); every safe torque is clipped to it.
        brake_time: :math:`T_b` [s]: brake with :math:`M(q)\\dot q/T_b` instead of
            ``damping`` (module doc); ``None``: the diagonal damping.
    """

    def __init__(
        self,
        robot: Robot,
        damping=2.0,
        gravity: bool = True,
        effort_limit=None,
        brake_time: float | None = None,
    ):
        n = robot.nq
        d = np.broadcast_to(np.asarray(damping, dtype=float), (n,)).copy()
        if not np.all(np.isfinite(d)) or np.any(d < 0):
            raise ConfigError("realtime.damping", f"expected values >= 0, got {d.tolist()}")
        if brake_time is not None and not (np.isfinite(brake_time) and brake_time > 0):
            raise ConfigError("realtime.brake_time", f"expected a time > 0 [s], got {brake_time!r}")
        self.brake_time = None if brake_time is None else float(brake_time)
        self.robot, self.damping, self.gravity = robot, d, bool(gravity)
        limit = np.full(n, np.inf) if effort_limit is None else effort_limit
        lim = np.broadcast_to(np.asarray(limit, dtype=float), (n,)).copy()
        if np.any(np.isnan(lim)) or np.any(lim <= 0):
            raise ConfigError(
                "plant.effort_limit",
                f"expected values > 0 [N·m] (inf: no limit), got {lim.tolist()}",
            )
        self.effort_limit = lim
        self._limited = bool(np.isfinite(lim).any())

    def __call__(self, q: FloatArray, dq: FloatArray) -> FloatArray:
        """The safe torque [N·m], (n,), at the measured state, clipped to the limits."""
        if self.brake_time is None:
            tau = -self.damping * dq
        else:
            tau = self.robot.mass_matrix(q) @ dq
            tau *= -1.0 / self.brake_time
        lim = self.effort_limit
        if self.gravity:
            tau += self.robot.gravity_torque(q)
            return np.clip(tau, -lim, lim, out=tau)
        if self._limited:  # the arm adds G(q): the total joint torque is what is limited
            g = self.robot.gravity_torque(q)
            return np.clip(tau + g, -lim, lim) - g
        return tau

    def held(self, q: FloatArray) -> FloatArray:
        """The held-safe torque :math:`g\\,G(q)` [N·m], (n,): no velocity term (module
        doc), clipped to the limits."""
        if self.gravity:
            tau = np.array(self.robot.gravity_torque(q), dtype=float)
            return np.clip(tau, -self.effort_limit, self.effort_limit, out=tau)
        return np.zeros(self.robot.nq)

    def describe_held(self) -> str:
        """The held-safe torque in words: ``"G(q)"`` or ``"zero torque"``."""
        return "G(q)" if self.gravity else "zero torque"

    def describe(self) -> str:
        """In words, e.g. ``"gravity compensation + damping 2 N·m·s/rad"``."""
        grav = "gravity compensation + " if self.gravity else ""
        if self.brake_time is not None:
            return grav + f"inertia brake M(q) dq / {self.brake_time:g} s"
        d = self.damping
        damp = f"{d[0]:g}" if np.all(d == d[0]) else "[" + ", ".join(f"{x:g}" for x in d) + "]"
        return ("gravity compensation + " if self.gravity else "") + f"damping {damp} N·m·s/rad"


def brake_time_constant(M: FloatArray, damping: FloatArray) -> float:
    """The slowest time constant [s] of :math:`M\\ddot q = -D\\dot q`: the largest
    generalized eigenvalue of :math:`M v = \\lambda D v` (``inf`` when a joint has no
    damping).

    Args:
        M: The joint-space inertia [kg·m²], (n, n), symmetric positive definite.
        damping: :math:`d_i` [N·m·s/rad], (n,).
    """
    d = np.asarray(damping, dtype=float)
    if np.any(d <= 0):
        return float("inf")
    s = 1.0 / np.sqrt(d)
    return float(np.linalg.eigvalsh(s[:, None] * M * s[None, :]).max())


@dataclass(frozen=True)
class SafetySettings:
    """When the loop stops, and how long it holds the safe torque.

    Attributes:
        lower, upper: Joint position bounds [rad], (n,); a measured q outside is a fault.
        velocity: Joint speed bounds [rad/s], (n,); a measured |q̇| above is a fault.
        max_misses: This many consecutive periods without a torque written in time
            stop the loop (k; libfranka's reflex trips after a few).
        watchdog: A stamp that has not advanced for longer than this [s] stops the loop.
        hold: Bound in time [s] of the brake after a stop (module doc): the safe torque
            at each fresh state, at most this long, then the held-safe torque; 0 writes
            the held-safe torque right after the stop's first safe torque.
        brake_speed: The brake ends when every joint's measured speed is below this
            [rad/s] (the arm then drifts at most this fast under the held-safe torque).
    """

    lower: FloatArray
    upper: FloatArray
    velocity: FloatArray
    max_misses: int = 10
    watchdog: float = 0.01
    hold: float = 0.1
    brake_speed: float = 0.005

    def __post_init__(self):
        for name in ("watchdog", "hold", "brake_speed"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and np.isfinite(value) and value >= 0):
                raise ConfigError(f"realtime.{name}", f"expected a number >= 0, got {value!r}")

    def state_fault(self, q, dq, joint_names=()) -> str:
        """Why the measured ``(q, dq)`` is a fault (non-finite, or the first joint beyond
        its bounds), one line naming the joint (``joint_names``, else ``joint1``...)."""
        names = joint_names or tuple(f"joint{i + 1}" for i in range(len(q)))
        if not (np.isfinite(q).all() and np.isfinite(dq).all()):
            return f"non-finite state from the arm: q={q.tolist()}, dq={dq.tolist()}"
        for i in range(len(q)):
            if not self.lower[i] <= q[i] <= self.upper[i]:
                return (
                    f"joint {names[i]!r} at q={q[i]:.4g} rad, beyond its bounds "
                    f"[{self.lower[i]:.4g}, {self.upper[i]:.4g}]"
                )
            if abs(dq[i]) > self.velocity[i]:
                return (
                    f"joint {names[i]!r} at |dq|={abs(dq[i]):.4g} rad/s, beyond its bound "
                    f"{self.velocity[i]:.4g}"
                )
        return "state beyond limits"

    @classmethod
    def unlimited(cls, n: int, **kwargs) -> SafetySettings:
        """No position or velocity bound (tests, simulated arms without limits)."""
        inf = np.full(n, np.inf)
        return cls(-inf, inf.copy(), inf.copy(), **kwargs)


class GravityByArm(ControllerWrapper):
    """The wrapped controller's torque without gravity, for an arm that adds
    :math:`G(q)` itself (Franka's FCI, KUKA's FRI torque overlay):
    :math:`\\tau_\\mathrm{sent} = \\tau - G(q)` at the state of the step (pair it with a
    :class:`SafeTorque` with ``gravity=False``).

    Args:
        controller: The controller (its torque includes :math:`G(q)`).
        robot: The model :math:`G` is computed on (the controller's).
    """

    def __init__(self, controller, robot: Robot):
        super().__init__(controller)
        self.robot = robot

    def step(self, t: float, q: FloatArray, dq: FloatArray, reference: object) -> FloatArray:
        """The controller's torque minus :math:`G(q)` [N·m]."""
        tau = self.controller.step(t, q, dq, reference)
        return np.asarray(tau, dtype=float) - self.robot.gravity_torque(q)

    def __getattr__(self, name: str):
        # everything else (latency, detected_at, warm_up, ...) is the controller's
        if name == "controller":
            raise AttributeError(name)
        return getattr(self.controller, name)
