"""Controller wrappers: measurement, friction feed-forward, collision reaction, timing.

:class:`MeasuredController` wraps any :class:`~hmpc_pin.controllers.base.Controller`
and hands it, at :math:`t_k`, what a measurement port makes of the plant's state (by
default the compiled plain model: the state measured at :math:`t_{k-\\mathrm{delay}}` plus
white Gaussian noise). The plant loop (:func:`~hmpc_pin.sim.simulate.simulate`) is
unchanged: it sees an ordinary controller. :class:`TimedController` times each step.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from ..compensation.gate import FeedbackGate
from ..exceptions import ConfigError
from ..native import load as load_native
from ..native import loop_port, replaced
from .base import ControllerWrapper

__all__ = ["CollisionReaction", "FrictionFeedforward", "MeasuredController", "TimedController"]


def _check_port(port) -> None:
    """A measurement port the loops can call: compiled, or a Python subclass of the port
    that defines ``reset`` and ``measure``.

    Raises:
        ConfigError: Anything else (named).
    """
    core = load_native()
    base = core.Measurement
    cls = type(port)
    if not isinstance(port, base):
        raise ConfigError(
            "measurement",
            f"expected a subclass of hmpc_pin.sim.sensing.Measurement, got {cls.__name__}",
        )
    if cls.__module__ == base.__module__:
        return  # compiled
    if isinstance(port, core.SensingMeasurement):
        raise ConfigError(
            "measurement",
            f"{cls.__name__} subclasses the compiled SensingMeasurement, whose loop calls "
            "the compiled model and not your overrides; subclass Measurement instead",
        )
    missing = [name for name in ("reset", "measure") if getattr(cls, name) is getattr(base, name)]
    if missing:
        raise ConfigError(
            "measurement",
            f"{cls.__name__} does not define {' and '.join(missing)}; a Measurement returns "
            "the measurement (q, dq) handed over from reset(q0, dq0) and measure(t, q, dq)",
        )


class MeasuredController(ControllerWrapper):
    """A controller that sees the plant through a measurement port.

    The port is :class:`hmpc_pin._core.Measurement <hmpc_pin.native>` (the abstract
    ``Measurement`` of ``cpp/include/hmpc/interfaces.hpp``): its ``reset(q0, dq0)`` gives the
    measurement handed over at :math:`t_0`, ``measure(t, q, dq)`` the one handed over at
    :math:`t_k` (k >= 1) from the plant's state, and ``command(tau)`` the torque the plant
    receives (the interface's torque filter; by default the torque as commanded). The same
    port serves both loops: the compiled loop calls it from C++ (a Python subclass through a
    trampoline), the per-step loop through this wrapper. The time and the reference passed
    on are the current ones: the controller does not know about the delay.

    Without ``measurement``, the port is the compiled plain model: white Gaussian noise
    :math:`\\tilde q = q + \\sigma_q\\,\\mathcal N(0, I)`,
    :math:`\\tilde{\\dot q} = \\dot q + \\sigma_{\\dot q}\\,\\mathcal N(0, I)` (2n draws
    of ``rng`` per measurement, the angles' first, also when both levels are 0), and the
    measurement taken ``delay`` periods earlier handed over (before enough measurements
    exist, the first one).

    Args:
        controller: The wrapped controller (e.g. :class:`~hmpc_pin.HierarchicalMPC`).
        q_noise: Standard deviation of the joint-angle noise [rad].
        dq_noise: Standard deviation of the joint-velocity noise [rad/s].
        delay: Delay in control periods (0: none).
        rng: The noise source; seed it for reproducible runs.
        measurement: A measurement port of your own (a subclass of
            ``hmpc_pin.native.load().Measurement``, also available as
            ``hmpc_pin.sim.sensing.Measurement``) instead of the plain model; then
            ``q_noise``, ``dq_noise``, ``delay`` and ``rng`` do not apply.

    Attributes:
        controller: The wrapped controller.
        measurement: The port.
    """

    def __init__(
        self,
        controller,
        *,
        q_noise: float = 0.0,
        dq_noise: float = 0.0,
        delay: int = 0,
        rng: np.random.Generator | None = None,
        measurement=None,
    ):
        if measurement is not None:
            if q_noise or dq_noise or delay or rng is not None:
                raise ConfigError(
                    "measurement",
                    "q_noise, dq_noise, delay and rng do not apply to a "
                    "measurement port of your own; give them to the port",
                )
            _check_port(measurement)
        if not (np.isfinite(q_noise) and q_noise >= 0 and np.isfinite(dq_noise) and dq_noise >= 0):
            raise ConfigError(
                "q_noise/dq_noise",
                f"got {q_noise=}, {dq_noise=}; expected finite noise levels >= 0",
            )
        if int(delay) != delay or delay < 0:
            raise ConfigError("delay", f"got {delay!r}; expected a whole number of periods >= 0")
        super().__init__(controller)
        self.q_noise = float(q_noise)
        self.dq_noise = float(dq_noise)
        self.delay = int(delay)
        self.rng = rng if rng is not None or measurement is not None else np.random.default_rng()
        if measurement is None:
            core = load_native()
            plain = core.SensingSettings()
            plain.exact = True
            plain.q_noise, plain.dq_noise, plain.delay = self.q_noise, self.dq_noise, self.delay
            measurement = core.SensingMeasurement(plain, self.rng)
        self.measurement = measurement

    @property
    def _started(self) -> bool:
        """Whether a step was handed a measurement since :meth:`reset` (the port's)."""
        return bool(self.measurement.started)

    def reset(self, q0: np.ndarray, dq0: np.ndarray) -> None:
        """Start a run: the controller starts from the port's measurement of ``(q0, dq0)``."""
        q_m, dq_m = self.measurement.call_reset(np.asarray(q0, float), np.asarray(dq0, float))
        self.controller.reset(q_m, dq_m)

    def step(self, t: float, q: np.ndarray, dq: np.ndarray, reference) -> np.ndarray:
        """Measure ``(q, dq)`` (from the second step on; the first uses the measurement at
        reset), call the controller with what the port hands over, pass its torque through
        the port's ``command``."""
        port = self.measurement
        q_m, dq_m = port.hand_over(t, q, dq)
        tau = self.controller.step(t, q_m, dq_m, reference)
        return port.call_command(np.asarray(tau, dtype=float))

    def loop_port(self, reference: object) -> Any:
        """The wrapped controller's compiled port (its ``loop_port``) behind this wrapper's
        measurement port, or ``None`` (no such port, or :meth:`step` or :meth:`reset`
        replaced: the loop then calls this object's ``step``)."""
        if replaced(self, MeasuredController, "step", "reset"):
            return None
        port = loop_port(self.controller, reference)
        if port is not None:
            port.set_measurement(self.measurement)
        return port

    def __getattr__(self, name):  # v, tau, observer, ... of the wrapped controller
        if name == "controller":
            raise AttributeError(name)
        return getattr(self.controller, name)


class FrictionFeedforward(ControllerWrapper):
    """Add a friction model's torque to a controller's, feed-forward.

    .. math::

        \\tau = \\tau_c + a \\odot \\dot q + b \\odot \\sigma(\\dot q), \\qquad
        \\sigma(\\dot q) = \\mathrm{sgn}\\,\\dot q \\ (v_s = 0) \\text{ or }
        \\tanh(\\dot q / v_s),

    at the measured velocity: the friction :math:`d = -(a\\dot q + b\\,\\mathrm{sgn}\\,
    \\dot q)` of the package's model (Eq 32, opposing) is cancelled before the observer
    sees it. The wrapped controller's compensation is fed its own torque
    :math:`\\tau_c`, so its estimate is what the model leaves (the model error plus any
    external torque). ``hmpc-pin identify`` fits :math:`a, b` from a run.

    Args:
        controller: Any controller.
        viscous: :math:`a` [N·m·s/rad], (n,). coulomb: :math:`b` [N·m], (n,).
        smoothing: :math:`v_s` [rad/s], >= 0.

    Attributes:
        torque: The feed-forward torque of the last step [N·m].
    """

    def __init__(self, controller, viscous, coulomb, smoothing: float = 0.0):
        a, b = np.array(viscous, dtype=float), np.array(coulomb, dtype=float)
        if a.shape != b.shape or a.ndim != 1 or not np.all(np.isfinite(np.r_[a, b])):
            raise ConfigError(
                "controller.friction",
                f"expected finite per-joint viscous and coulomb of one "
                f"length, got {a.tolist()} and {b.tolist()}",
            )
        if not (np.isfinite(smoothing) and smoothing >= 0):
            raise ConfigError("controller.friction.smoothing", f"expected >= 0, got {smoothing!r}")
        super().__init__(controller)
        self.viscous, self.coulomb, self.smoothing = a, b, float(smoothing)
        self.torque = np.zeros_like(a)

    def model(self, dq: np.ndarray) -> np.ndarray:
        """:math:`a \\odot \\dot q + b \\odot \\sigma(\\dot q)` [N·m]."""
        s = self.smoothing
        sign = np.tanh(dq / s) if s > 0 else np.sign(dq)
        return self.viscous * dq + self.coulomb * sign

    def step(self, t: float, q: np.ndarray, dq: np.ndarray, reference) -> np.ndarray:
        """The wrapped controller's torque plus the friction model's [N·m]."""
        tau = self.controller.step(t, q, dq, reference)
        self.torque = self.model(np.asarray(dq, dtype=float))
        return tau + self.torque

    def __getattr__(self, name):  # v, tau, observer, ... of the wrapped controller
        if name == "controller":
            raise AttributeError(name)
        return getattr(self.controller, name)


class TimedController(ControllerWrapper):
    """Wrap a controller and time each ``step`` with ``perf_counter_ns``.

    It has the interface :func:`hmpc_pin.sim.simulate.simulate` expects (``Ts``, ``reset``,
    ``step``, ``disturbance_estimate``), so a closed-loop run measures the step too.

    Attributes:
        samples_ns: Duration of every step since the last reset [ns].
    """

    def __init__(self, controller):
        super().__init__(controller)
        self.samples_ns: list[int] = []

    def reset(self, q0: np.ndarray, dq0: np.ndarray) -> None:
        """Reset the wrapped controller and forget the recorded durations."""
        self.samples_ns = []
        self.controller.reset(q0, dq0)

    def step(self, t: float, q: np.ndarray, dq: np.ndarray, reference) -> np.ndarray:
        """The wrapped controller's step [N·m], timed."""
        start = time.perf_counter_ns()
        tau = self.controller.step(t, q, dq, reference)
        self.samples_ns.append(time.perf_counter_ns() - start)
        return tau


class _Hold:
    """The constant reference :math:`r = q_\\mathrm{hold}`, :math:`\\dot r = 0`."""

    def __init__(self, q: np.ndarray):
        self.q = np.array(q, dtype=float)
        self._zero = np.zeros_like(self.q)

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        return self.q.copy(), self._zero.copy()

    def sample_many(self, times, out=None):
        m = len(times)
        q_ref = np.broadcast_to(self.q, (m, len(self.q)))
        dq_ref = np.zeros((m, len(self.q)))
        if out is not None:
            out[0][:] = q_ref
            out[1][:] = dq_ref
            return out
        return q_ref.copy(), dq_ref


class CollisionReaction(ControllerWrapper):
    """Flag a collision when the disturbance estimate exceeds a threshold, and react.

    The wrapped controller's compensation is put behind a
    :class:`~hmpc_pin.compensation.gate.FeedbackGate`. A collision is flagged at the first
    control instant :math:`t_c` at which :math:`|\\hat d_i| > \\bar d_i` on some joint i
    (the observer as a contact-torque estimator). Reactions:

    * ``"ignore"``: nothing changes (the paper's behaviour: the compensation cancels the
      contact torque, so the arm keeps pushing into the obstacle);
    * ``"stop"``: from the next instant on, the reference is the position measured at
      :math:`t_c` held still (:math:`r = q(t_c)`, :math:`\\dot r = 0`) and the estimate
      is no longer fed back (it is still computed and recorded).

    Args:
        controller: A controller with a ``compensation`` attribute
            (:class:`~hmpc_pin.controllers.hierarchical.HierarchicalMPC`,
            :class:`~hmpc_pin.controllers.computed_torque.ComputedTorque`).
        threshold: :math:`\\bar d` [N·m], one value or one per joint (> 0).
        reaction: ``"ignore"`` or ``"stop"``.

    Attributes:
        detected_at: :math:`t_c` [s], or ``None`` while no collision was flagged.
        joint: Index of the joint whose estimate crossed first (largest ratio), or ``None``.
        gate: The compensation gate.
    """

    REACTIONS = ("ignore", "stop")

    def __init__(self, controller, threshold, reaction: str = "ignore"):
        if reaction not in self.REACTIONS:
            raise ConfigError(
                "collision.reaction", f"expected one of {self.REACTIONS}, got {reaction!r}"
            )
        comp = getattr(controller, "compensation", None)
        if comp is None:
            raise ConfigError(
                "collision",
                f"{type(controller).__name__} has no compensation to watch; use "
                "a controller with a disturbance observer",
            )
        thr = np.asarray(threshold, dtype=float)
        if not (np.all(np.isfinite(thr)) and np.all(thr > 0)):
            raise ConfigError("collision.threshold", f"expected values > 0, got {thr!r}")
        super().__init__(controller)
        self.gate = comp if isinstance(comp, FeedbackGate) else FeedbackGate(comp)
        controller.compensation = self.gate
        self.threshold = thr
        self.reaction = reaction
        self.detected_at: float | None = None
        self.joint: int | None = None
        self._hold: _Hold | None = None

    @property
    def disturbance_estimate(self) -> np.ndarray:
        """The observer's estimate [N·m], fed back or not."""
        return np.array(self.gate.observed, dtype=float)

    def reset(self, q0: np.ndarray, dq0: np.ndarray) -> None:
        """Reset the controller; no collision flagged, feedback on."""
        self.controller.reset(q0, dq0)
        self.gate.feed_back = True
        self.detected_at, self.joint, self._hold = None, None, None

    def step(self, t: float, q: np.ndarray, dq: np.ndarray, reference) -> np.ndarray:
        """The wrapped step (with the held reference after a ``stop``); then the check."""
        tau = self.controller.step(t, q, dq, reference if self._hold is None else self._hold)
        if self.detected_at is None:
            ratio = np.abs(self.gate.observed) / self.threshold
            if ratio.max() > 1.0:
                self.detected_at, self.joint = float(t), int(np.argmax(ratio))
                if self.reaction == "stop":
                    self.gate.feed_back = False
                    self._hold = _Hold(q)
        return tau
