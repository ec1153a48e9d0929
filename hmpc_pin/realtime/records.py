"""The run's records: the preallocated trajectories and per-cycle timing a run fills,
the latency statistics, and :class:`RealtimeRun`, what a real-time run returns."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..sim.result import Result
from .machine import steal_time

__all__ = ["RealtimeRun", "Records", "latency_stats"]


def latency_stats(latency: np.ndarray) -> dict:
    """Median, p99, p99.9, max [µs] and count of the finite entries of ``latency`` [s]."""
    x = latency[np.isfinite(latency)] * 1e6
    if x.size == 0:
        return {
            "median_us": math.nan,
            "p99_us": math.nan,
            "p999_us": math.nan,
            "max_us": math.nan,
            "count": 0,
        }
    p50, p99, p999 = np.percentile(x, [50.0, 99.0, 99.9])
    return {
        "median_us": float(p50),
        "p99_us": float(p99),
        "p999_us": float(p999),
        "max_us": float(x.max()),
        "count": int(x.size),
    }


@dataclass
class RealtimeRun:
    """A real-time run: the trajectories and every cycle's timing.

    Attributes:
        result: Trajectories at the controller steps (``t`` is the loop time
            :math:`kP`; ``d`` is NaN: an arm does not report its disturbance), with
            ``meta["realtime"]`` holding :attr:`stats` and ``meta["stop"]`` the stop.
        timing: Per interface cycle (K+1 entries, NaN where skipped): ``wake`` and
            ``latency`` [s] after the deadline, ``compute`` [s] from wake to write,
            ``stamp`` [s] of the state read, ``missed`` (bool), ``mpc`` (bool), ``gc``
            [s] spent collecting.
        stats: The summary (:meth:`summary` prints it).
        stop: ``None`` for a complete run, else the stop record: ``cause`` (one of
            :data:`~hmpc_pin.realtime.safety.STOP_CAUSES`), ``reason`` (one line),
            ``cycle``, ``t`` [s], ``safe_tau`` [N·m], ``q``, ``dq`` used, and
            ``safe_after_deadline`` and ``safe_after_detection`` [s], the time from
            the detecting cycle's deadline, and from the detection, to the safe torque
            written. Stopped by Ctrl-C or a deactivate before the first command:
            ``safe_tau`` is ``None`` and nothing was sent (``brake["ended"]`` is
            ``"nothing sent"``).
    """

    result: Result
    timing: dict[str, np.ndarray]
    stats: dict
    stop: dict | None = None

    @property
    def complete(self) -> bool:
        """Whether the run went to the end (with a state for every period of an arm
        that paces it, up to ``max_misses`` lost: ``result.message`` says otherwise)."""
        return self.stop is None and bool(self.result.complete)

    def summary(self) -> str:
        """The latency statistics in a few lines."""
        s = self.stats
        lat, wake = s["latency"], s["wake"]
        lines = [
            f"real-time loop: {s['rate']:g} Hz interface, controller every {s['decimation']} "
            f"cycles ({1.0 / s['controller_Ts']:g} Hz), {s['cycles_run']} of "
            f"{s['cycles']} cycles run, GC handling {'on' if s['gc_handling'] else 'off'}",
            f"  latency deadline->torque [us]: median {lat['median_us']:.0f}, p99 "
            f"{lat['p99_us']:.0f}, p99.9 {lat['p999_us']:.0f}, max {lat['max_us']:.0f}",
            f"  wake-up jitter [us]:           median {wake['median_us']:.0f}, p99 "
            f"{wake['p99_us']:.0f}, p99.9 {wake['p999_us']:.0f}, max {wake['max_us']:.0f}",
            f"  missed deadlines: {s['misses']} ({100 * s['miss_fraction']:.3f} %; "
            f"{s['skipped']} skipped), longest run of misses {s['max_consecutive_misses']}",
        ]
        if s.get("host_steal_s", 0.0) > 0:
            lines.append(
                f"  host steal during the run: {1e3 * s['host_steal_s']:.0f} ms (the "
                "hypervisor did not run this machine's CPUs while they had work)"
            )
        if s.get("arm_gaps"):
            lines.append(f"  periods with no state from the arm: {s['arm_gaps']}")
        age, declared = s.get("measured_latency"), s.get("declared_latency")
        if age is not None:
            lines.append(
                f"  measurement->torque [us]:      median {age['median_us']:.0f}, p99 "
                f"{age['p99_us']:.0f}, max {age['max_us']:.0f}"
                + ("" if declared is None else f" (declared latency {1e6 * declared:.0f})")
            )
        if s["gc_handling"]:
            lines.append(
                f"  GC in the slack: {s['gc_collections']} collections (max "
                f"{1e6 * s['gc_max_s']:.0f} us), {s['gc_deferred']} deferred"
            )
        else:
            lines.append(
                f"  automatic GC during the run: {s['gc_all_collections']} collections "
                f"(max {1e6 * s['gc_all_max_s']:.0f} us)"
            )
        return "\n".join(lines)

    def save_timing(self, path: str | Path) -> Path:
        """Write :attr:`timing` to ``path`` (``.npz``)."""
        path = Path(path)
        np.savez(path, **self.timing)
        return path if path.suffix == ".npz" else path.with_name(path.name + ".npz")


class Records:
    """The run's preallocated records: trajectories at the controller steps (``J``
    rows), timing per interface cycle (``C`` entries, NaN where skipped)."""

    __slots__ = ("age", "done", "gc", "j", "missed", "mpc", "stamp", "steal0", "t", "traj", "wake")

    def __init__(self, J: int, C: int, n: int):
        self.traj = {
            name: np.full((J, n), np.nan)
            for name in ("q", "dq", "tau", "d", "d_hat", "q_ref", "dq_ref")
        }
        self.t = np.full(J, np.nan)
        self.wake, self.done, self.stamp, self.gc, self.age = (np.full(C, np.nan) for _ in range(5))
        self.missed = np.zeros(C, dtype=bool)
        self.mpc = np.zeros(C, dtype=bool)
        self.j = 0  # controller steps recorded
        self.steal0 = steal_time()  # the host's steal time, counted from the set-up on

    def cycle(self, k: int, wake: float, done: float, stamp: float, is_mpc: bool) -> None:
        """Cycle ``k``'s wake and write times after its deadline [s], stamp, kind."""
        self.wake[k] = wake
        self.done[k] = done
        self.stamp[k] = stamp
        self.mpc[k] = is_mpc

    def step(self, j: int, t: float, q, dq, tau, d_hat, reference) -> None:
        """Controller step ``j`` at loop time ``t`` [s]."""
        traj = self.traj
        self.t[j] = t
        traj["q"][j] = q
        traj["dq"][j] = dq
        traj["tau"][j] = tau
        traj["d_hat"][j] = d_hat
        q_ref, dq_ref = reference.sample(t)
        traj["q_ref"][j] = q_ref
        traj["dq_ref"][j] = dq_ref

    def timing_stats(self) -> dict:
        """The cycles run and the latency statistics (:func:`latency_stats`) of the
        deadline → torque latency, the wake-up, the compute time (wake → torque) and the
        latency of the cycles that ran the controller; and ``host_steal_s``, the host's
        steal time [s] since the records were made (:func:`.machine.steal_time`)."""
        done, wake = self.done, self.wake
        return {
            "host_steal_s": steal_time() - self.steal0,
            "cycles_run": int(np.count_nonzero(np.isfinite(done))),
            "latency": latency_stats(done),
            "wake": latency_stats(wake),
            "compute": latency_stats(done - wake),
            "latency_mpc": latency_stats(np.where(self.mpc, done, np.nan)),
        }

    def timing(self) -> dict[str, np.ndarray]:
        """Every cycle's timing (:attr:`RealtimeRun.timing`)."""
        return {
            "wake": self.wake,
            "latency": self.done,
            "compute": self.done - self.wake,
            "stamp": self.stamp,
            "missed": self.missed,
            "mpc": self.mpc,
            "gc": self.gc,
            "age": self.age,
        }
