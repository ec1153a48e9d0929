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

from ..exceptions import ConfigError
from .base import ControllerWrapper

__all__ = ["MeasuredController", "TimedController"]


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


class TimedController(ControllerWrapper):
    """Wrap a controller and time each ``step`` with ``perf_counter_ns``.

    It has the interface :func:`hmpc_pin.simulate.simulate` expects (``Ts``, ``reset``,
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
