"""Controller wrappers: measurement (noise and delay) and timing.

:class:`MeasuredController` wraps any :class:`~hmpc_pin.controllers.base.Controller`
and hands it, at :math:`t_k`, the state measured at :math:`t_{k-\\mathrm{delay}}` plus
white Gaussian noise. The plant loop (:func:`~hmpc_pin.sim.simulate.simulate`) is
unchanged: it sees an ordinary controller. :class:`TimedController` times each step.
"""

from __future__ import annotations

import time
from collections import deque

import numpy as np

from ..compensation.gate import FeedbackGate
from ..exceptions import ConfigError
from .base import ControllerWrapper

__all__ = ["CollisionReaction", "FrictionFeedforward", "MeasuredController", "TimedController"]


class MeasuredController(ControllerWrapper):
    """A controller that sees noisy, delayed measurements of the plant state.

    At each control instant the true state is measured with noise
    :math:`\\tilde q = q + \\sigma_q\\,\\mathcal N(0, I)`,
    :math:`\\tilde{\\dot q} = \\dot q + \\sigma_{\\dot q}\\,\\mathcal N(0, I)`, and the
    wrapped controller receives the measurement taken ``delay`` periods earlier (before
    enough measurements exist, the first one). The time and the reference passed on are
    the current ones: the controller does not know about the delay.

    Args:
        controller: The wrapped controller (e.g. :class:`~hmpc_pin.HierarchicalMPC`).
        q_noise: Standard deviation of the joint-angle noise [rad].
        dq_noise: Standard deviation of the joint-velocity noise [rad/s].
        delay: Delay in control periods (0: none).
        rng: The noise source; seed it for reproducible runs.

    Attributes:
        controller: The wrapped controller.
    """

    def __init__(
        self,
        controller,
        *,
        q_noise: float = 0.0,
        dq_noise: float = 0.0,
        delay: int = 0,
        rng: np.random.Generator | None = None,
    ):
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
        self.rng = rng if rng is not None else np.random.default_rng()
        self._buffer: deque = deque(maxlen=self.delay + 1)
        self._started = False

    def _measure(self, q: np.ndarray, dq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n = len(q)
        noise = self.rng.standard_normal(2 * n)  # one draw per step: fixed stream per seed
        return q + self.q_noise * noise[:n], dq + self.dq_noise * noise[n:]

    def reset(self, q0: np.ndarray, dq0: np.ndarray) -> None:
        """Start a run: the controller starts from a measurement of ``(q0, dq0)``."""
        self._buffer.clear()
        self._started = False
        self._buffer.append(self._measure(np.asarray(q0, float), np.asarray(dq0, float)))
        self.controller.reset(*self._buffer[0])

    def step(self, t: float, q: np.ndarray, dq: np.ndarray, reference) -> np.ndarray:
        """Measure ``(q, dq)``, and call the controller with the measurement ``delay`` old."""
        if self._started:
            self._buffer.append(self._measure(q, dq))
        self._started = True
        q_m, dq_m = self._buffer[0]
        return self.controller.step(t, q_m, dq_m, reference)

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
                "controller.friction", f"expected finite per-joint viscous and coulomb of one "
                f"length, got {a.tolist()} and {b.tolist()}",
            )  # fmt: skip
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

    @property
    def compensation(self):
        """The wrapped controller's compensation (a collision watch may replace it)."""
        return self.controller.compensation

    @compensation.setter
    def compensation(self, value) -> None:
        self.controller.compensation = value

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
            raise ConfigError("collision.reaction", f"expected one of {self.REACTIONS}, got "
                              f"{reaction!r}")  # fmt: skip
        comp = getattr(controller, "compensation", None)
        if comp is None:
            raise ConfigError(
                "collision", f"{type(controller).__name__} has no compensation to watch; use "
                "a controller with a disturbance observer",
            )  # fmt: skip
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
