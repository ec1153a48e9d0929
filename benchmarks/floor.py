"""The floor of a controller step, and step / floor ratios measured in alternating blocks.

The step of :class:`~hmpc_pin.HierarchicalMPC` cannot cost less than what it must call:
Pinocchio's ``crba`` and ``nonLinearEffects`` at the measured state and one warm-started
ProxSuite box QP ``update`` + ``solve`` of the same size (n·Nc variables, the package's
solver settings, the gradients the step computes along the same states). That sum is the
*floor*. A shared machine has slow and fast phases of several seconds, so step and floor
are timed in alternating blocks (``blocks`` × (one block of steps, one block of floor
calls), each over the same states), and the figure that travels between machines is the
median over blocks of (median step in the block) / (median floor in the block).

The *exact floor* (:class:`ExactFloor`, Nc = 1) is what no step can avoid, timed in C++ per
state (``hmpc_pin._core.Dynamics.exact_floor``): ``crba`` + ``nonLinearEffects`` through the
compiled core's Pinocchio, the box QP in closed form (each joint's v = clip(−g/h)) and Eq 4.

Run alone: ``python -m benchmarks.floor`` prints the ratios of planar3 and Panda (Nc = 1),
to the ProxSuite floor and to the exact floor, all three alternating in one process.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

import hmpc_pin

if str(Path(__file__).resolve().parent.parent) not in sys.path:  # run as a script
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._fixtures import new_qp

__all__ = ["ExactFloor", "Floor", "FloorRatio", "step_floor_ratio"]


class Floor:
    """``crba`` + ``nonLinearEffects`` + one warm-started box QP update + solve.

    Args:
        ctrl: The controller whose step is compared (its robot, QP size and settings).
        grads: The QP gradients the step computes along the states, (steps, n, Nc).
    """

    def __init__(self, ctrl: hmpc_pin.HierarchicalMPC, grads: np.ndarray):
        s, mpc = ctrl.settings, ctrl.mpc
        n, Nc = ctrl.n, mpc.Nc
        v_min, v_max = s.bounds(n)
        self.model, self.data = ctrl.robot.model, ctrl.robot.data
        self.qp = qp = new_qp(n * Nc, 0, s.eps_abs, s.max_iter)
        qp.init(np.kron(np.eye(n), mpc.H), np.zeros(n * Nc), None, None, None, None, None,
                np.repeat(v_min, Nc), np.repeat(v_max, Nc))  # fmt: skip
        qp.solve()
        self.grads = np.ascontiguousarray(grads.reshape(len(grads), n * Nc))

    def __call__(self, k: int, q: np.ndarray, dq: np.ndarray) -> None:
        """The floor's calls at state ``k`` (``q``, ``dq``)."""
        model, data, qp = self.model, self.data, self.qp
        pin.crba(model, data, q)
        pin.nonLinearEffects(model, data, q, dq)
        qp.update(g=self.grads[k])
        qp.solve()


class ExactFloor:
    """The exact floor of a step with Nc = 1, timed in C++ per state.

    Args:
        ctrl: The controller whose step is compared (its robot, horizon, bounds).
        grads: The QP gradients the step computes along the states, (steps, n, 1).
    """

    def __init__(self, ctrl: hmpc_pin.HierarchicalMPC, grads: np.ndarray):
        from hmpc_pin.native import load, model_string

        if ctrl.mpc.Nc != 1:
            raise ValueError("the exact floor is the closed form of Nc = 1")
        self.dyn = load().Dynamics(model_string(ctrl.robot))
        self.h = float(np.asarray(ctrl.mpc.H)[0, 0])
        self.v_min, self.v_max = ctrl.settings.bounds(ctrl.n)
        self.grads = np.ascontiguousarray(grads.reshape(len(grads), ctrl.n))
        self.d_hat = np.zeros(ctrl.n)

    def __call__(self, q: np.ndarray, dq: np.ndarray, first: int) -> np.ndarray:
        """Per state of ``q``, ``dq`` (K, n; gradients from state ``first`` on): [ns]."""
        g = self.grads[first : first + len(q)]
        return self.dyn.exact_floor(q, dq, g, self.h, self.v_min, self.v_max, self.d_hat)


@dataclass(frozen=True)
class FloorRatio:
    """Step and floor medians over alternating blocks, and their ratio.

    Attributes:
        ratios: Per block, median step / median floor.
        step_us, floor_us: Per block, the medians [µs].
        exact_us: Per block, the exact floor's median [µs] (None unless asked for).
    """

    ratios: np.ndarray
    step_us: np.ndarray
    floor_us: np.ndarray
    exact_us: np.ndarray | None = None

    @property
    def exact_ratio(self) -> float:
        """Median over blocks of step / exact floor."""
        assert self.exact_us is not None
        return float(np.median(self.step_us / self.exact_us))

    @property
    def exact_median_us(self) -> float:
        """Median over blocks of the blocks' median exact floor [µs]."""
        assert self.exact_us is not None
        return float(np.median(self.exact_us))

    @property
    def ratio(self) -> float:
        """Median over blocks of the step / floor ratio."""
        return float(np.median(self.ratios))

    @property
    def step_median_us(self) -> float:
        """Median over blocks of the blocks' median step [µs]."""
        return float(np.median(self.step_us))

    @property
    def floor_median_us(self) -> float:
        """Median over blocks of the blocks' median floor [µs]."""
        return float(np.median(self.floor_us))


def step_floor_ratio(
    ctrl: hmpc_pin.HierarchicalMPC,
    reference,
    t: np.ndarray,
    q: np.ndarray,
    dq: np.ndarray,
    *,
    warmup: int = 200,
    blocks: int = 10,
    exact: bool = False,
) -> FloorRatio:
    """Time ``ctrl.step`` and its :class:`Floor` in ``blocks`` alternating blocks.

    Each block replays the states after the first ``warmup`` through the step (the
    controller restarted and warmed up along the first ``warmup`` states before each
    step block, untimed), then the same states through the floor (and, with ``exact``,
    through the :class:`ExactFloor`, after as many untimed calls).
    """
    from benchmarks.qp_layouts import record_gradients

    grads = record_gradients(ctrl, t, q, dq, reference)
    floor = Floor(ctrl, grads)
    count = len(t)
    args = [(float(t[i]), q[i].copy(), dq[i].copy()) for i in range(count)]
    clock = time.perf_counter_ns
    exact_floor = ExactFloor(ctrl, grads) if exact else None
    qs, dqs = np.ascontiguousarray(q[:count]), np.ascontiguousarray(dq[:count])
    step_med, floor_med, exact_med = [], [], []
    for _ in range(blocks):
        ctrl.reset(q[0], dq[0])
        for ti, qi, dqi in args[:warmup]:
            ctrl.step(ti, qi, dqi, reference)
        step = ctrl.step
        samples = np.empty(count - warmup, dtype=np.int64)
        for j, (ti, qi, dqi) in enumerate(args[warmup:]):
            t0 = clock()
            step(ti, qi, dqi, reference)
            samples[j] = clock() - t0
        step_med.append(np.median(samples) / 1e3)
        for k in range(warmup):
            floor(k, args[k][1], args[k][2])
        for j, k in enumerate(range(warmup, count)):
            qi, dqi = args[k][1], args[k][2]
            t0 = clock()
            floor(k, qi, dqi)
            samples[j] = clock() - t0
        floor_med.append(np.median(samples) / 1e3)
        if exact_floor is not None:
            exact_floor(qs[:warmup], dqs[:warmup], 0)
            exact_med.append(np.median(exact_floor(qs[warmup:], dqs[warmup:], warmup)) / 1e3)
    step_us, floor_us = np.array(step_med), np.array(floor_med)
    exact_us = np.array(exact_med) if exact else None
    return FloorRatio(step_us / floor_us, step_us, floor_us, exact_us)


def main() -> int:
    """Print step / floor for planar3 and Panda (Nc = 1, the step benchmark's trajectory)."""
    from benchmarks._fixtures import HOMES, PANDA_LOCKED, ROOT, load_arm, record_trajectory

    arms = [
        load_arm("planar3", ROOT / "robots" / "planar3.urdf", HOMES["planar3"], "chen"),
        load_arm("panda", "panda", HOMES["panda"], "general", PANDA_LOCKED),
    ]
    # the exact floor where the compiled core times it (an older core: the ProxSuite floor only)
    exact = hasattr(hmpc_pin.native.load().Dynamics, "exact_floor")
    for arm in arms:
        traj = record_trajectory(arm, 1200)
        ctrl = hmpc_pin.make_controller(arm.robot, arm.config(1))
        r = step_floor_ratio(ctrl, arm.reference(), traj.t, traj.q, traj.dq, exact=exact,
                             blocks=16)  # fmt: skip
        print(
            f"{arm.name:<8} step {r.step_median_us:6.2f} µs  floor {r.floor_median_us:6.2f} µs"
            f"  step/floor {r.ratio:.2f} (range {r.ratios.min():.2f}–{r.ratios.max():.2f})"
        )
        if r.exact_us is not None:
            ratios = r.step_us / r.exact_us
            print(
                f"{'':<8} exact floor {r.exact_median_us:6.2f} µs  step/exact {r.exact_ratio:.2f}"
                f" (range {ratios.min():.2f}–{ratios.max():.2f})"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
