"""The controller step's benchmark: median and tail of ``HierarchicalMPC.step`` along a
recorded closed-loop trajectory, and the joint QPs alone by layout."""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import hmpc_pin  # noqa: E402
from benchmarks._fixtures import (  # noqa: E402
    Arm,
    Settings,
    Trajectory,
    log,
    record_trajectory,
)
from benchmarks.floor import FloorRatio, step_floor_ratio  # noqa: E402
from benchmarks.harness import (  # noqa: E402
    Timing,
    time_calls,
)
from benchmarks.qp_layouts import LayoutTiming, record_gradients, time_layouts  # noqa: E402


@dataclass
class StepResult:
    """Step timing of one (arm, Nc) case."""

    arm: str
    n: int
    Nc: int
    observer: str
    timing: Timing
    source: str
    floor: FloorRatio | None = None


def time_step(
    arm: Arm, Nc: int, trajectory: Trajectory, settings: Settings, floor: bool = False
) -> StepResult:
    """Time ``HierarchicalMPC.step`` along ``trajectory`` (warm-up, then timed steps); with
    ``floor``, also step and floor in alternating blocks (:mod:`benchmarks.floor`)."""
    ref = arm.reference()
    ctrl = hmpc_pin.make_controller(arm.robot, arm.config(Nc))
    tr = trajectory
    ctrl.reset(tr.q[0], tr.dq[0])
    count = settings.warmup + settings.steps
    calls = [(float(tr.t[i]), tr.q[i].copy(), tr.dq[i].copy(), ref) for i in range(count)]
    timing = time_calls(ctrl.step, calls, settings.warmup)
    ratio = None
    if floor:
        k = settings.warmup + min(settings.steps, settings.floor_steps)
        ratio = step_floor_ratio(ctrl, ref, tr.t[:k], tr.q[:k], tr.dq[:k],
                                 warmup=settings.warmup, blocks=settings.floor_blocks)  # fmt: skip
    return StepResult(arm.name, arm.n, Nc, arm.observer, timing, tr.source, ratio)


# ------------------------------------------------------------------------ benchmarks
def bench_steps(settings: Settings, arms: list[Arm], floor: bool = False) -> list[StepResult]:
    """Step time at Nc = 1 and 5 for every arm in ``arms`` (with ``floor``: and its ratio
    to the floor, alternating blocks)."""
    out = []
    for arm in arms:
        traj = record_trajectory(arm, settings.warmup + settings.steps)
        for Nc in (1, 5):
            r = time_step(arm, Nc, traj, settings, floor)
            extra = ""
            if r.floor is not None:
                extra = (f", floor {r.floor.floor_median_us:.1f} µs, step/floor "
                         f"{r.floor.ratio:.2f}")  # fmt: skip
            log(
                f"  step {arm.name:<10} n={arm.n:<2} Nc={Nc}: median {r.timing.median_us:7.1f} µs,"
                f" p99 {r.timing.p99_us:7.1f} µs{extra}"
            )
            out.append(r)
    return out


def bench_qp_layouts(settings: Settings, arms: list[Arm]) -> list[LayoutTiming]:
    """The joint QPs as one block QP, n QPs, and ProxSuite's BatchQP (``qp_layouts.py``),
    on the gradients of the step benchmark's closed-loop states, Nc = 1 and 5."""
    out = []
    for arm in arms:
        traj = record_trajectory(arm, settings.warmup + settings.steps)
        for Nc in (1, 5):
            ctrl = hmpc_pin.make_controller(arm.robot, arm.config(Nc))
            grads = record_gradients(ctrl, traj.t, traj.q, traj.dq, arm.reference())
            r = time_layouts(arm.name, ctrl, grads, settings.warmup)
            log(f"  QPs {arm.name:<10} Nc={Nc}: " + ", ".join(
                f"{k} {v:.1f} µs" for k, v in r.median_us.items()))  # fmt: skip
            out.append(r)
    return out


class GravityCompensation:
    """A near-free controller, :math:`\\tau = G(q)` [N·m], to time the plant and the
    simulation loop without the MPC (same interface as :class:`hmpc_pin.HierarchicalMPC`).

    Args:
        robot: The controller's model. Ts: Control period [s].
    """

    def __init__(self, robot: hmpc_pin.Robot, Ts: float):
        self.robot = robot
        self.Ts = Ts
        self.disturbance_estimate = np.zeros(robot.nq)

    def reset(self, q0: np.ndarray, dq0: np.ndarray) -> None:
        """Nothing to reset."""

    def step(self, t: float, q: np.ndarray, dq: np.ndarray, reference) -> np.ndarray:
        """Gravity torque at ``q`` [N·m]."""
        return self.robot.gravity_torque(q)
