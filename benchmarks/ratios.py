"""Benchmarks measured as ratios in one process (issue 18): long horizons, references and
the plant's ABA floor. Each case alternates its variants block by block, so that the slow
and fast phases of a shared machine hit every variant alike; a figure is the median over
blocks of the per-block ratio, beside the median of the blocks' absolute medians.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

import hmpc_pin
from hmpc_pin.compensation.observers import DisturbanceObserver
from hmpc_pin.controllers.hierarchical import HierarchicalMPC, MPCSettings

__all__ = ["Alternated", "aba_floor", "alternate_steps", "long_horizon", "references"]


@dataclass
class Alternated:
    """Per variant, the median step of each block [µs]; ratios are to ``base``.

    Attributes:
        blocks_us: Variant name → array of per-block medians [µs].
        base: The variant the ratios are taken to.
        steps: Timed steps per block and variant. note: How the states were made.
    """

    blocks_us: dict[str, np.ndarray]
    base: str
    steps: int
    note: str = ""

    def median_us(self, name: str) -> float:
        """Median over blocks of the variant's block medians [µs]."""
        return float(np.median(self.blocks_us[name]))

    def ratio(self, name: str) -> float:
        """Median over blocks of (variant / base)."""
        return float(np.median(self.blocks_us[name] / self.blocks_us[self.base]))


def alternate_steps(variants: dict, states, warmup: int, blocks: int) -> dict[str, np.ndarray]:
    """Time ``ctrl.step`` of every ``(ctrl, reference)`` in ``variants`` on ``states``
    (t, q, dq arrays; or a dict of them by variant name), ``blocks`` times in turn; each
    block restarts the controller and warms it up on the first ``warmup`` states
    (untimed). Returns per-block medians [µs]."""
    by_name = states if isinstance(states, dict) else {name: states for name in variants}
    args = {
        name: [(float(t[i]), q[i].copy(), dq[i].copy()) for i in range(len(t))]
        for name, (t, q, dq) in by_name.items()
    }
    clock = time.perf_counter_ns
    out: dict[str, list[float]] = {name: [] for name in variants}
    for _ in range(blocks):
        for name, (ctrl, ref) in variants.items():
            calls = args[name]
            ctrl.reset(calls[0][1], calls[0][2])
            step = ctrl.step
            for ti, qi, dqi in calls[:warmup]:
                step(ti, qi, dqi, ref)
            samples = np.empty(len(calls) - warmup, dtype=np.int64)
            for j, (ti, qi, dqi) in enumerate(calls[warmup:]):
                t0 = clock()
                step(ti, qi, dqi, ref)
                samples[j] = clock() - t0
            out[name].append(float(np.median(samples)) / 1e3)
    return {name: np.array(v) for name, v in out.items()}


def _panda(Ts: float, N: int, Nc: int, layout: str, robot):
    settings = MPCSettings(Ts=Ts, N=N, Nc=Nc, qp_layout=layout)
    return HierarchicalMPC(robot, settings, DisturbanceObserver(robot.nq, Ts, 100.0, "general"))


def long_horizon(arm, steps: int, blocks: int, warmup: int = 50) -> tuple[Alternated, float]:
    """Panda at Ts = 1 ms, N = Nc = 100 (layouts ``auto`` and ``block``) against N = 100,
    Nc = 1 and against the step benchmark's controller (Ts = 10 ms, N = 10, Nc = 1), on the
    reference's own states (the 0.3 rad sine around home, 1 ms apart).

    Returns:
        The alternated timings (base: N = 100, Nc = 1) and the largest difference between
        the accelerations v of ``auto`` and ``block`` along the states [rad/s²].
    """
    robot, ref = arm.robot, arm.reference()
    Ts = 0.001
    t = Ts * np.arange(warmup + steps)
    q, dq = ref.sample_many(t)
    variants = {
        "N = 100, Nc = 1": (_panda(Ts, 100, 1, "auto", robot), ref),
        "N = Nc = 100, auto": (_panda(Ts, 100, 100, "auto", robot), ref),
        "N = Nc = 100, block": (_panda(Ts, 100, 100, "block", robot), ref),
        "benchmark step (Ts = 10 ms, N = 10, Nc = 1)": (
            hmpc_pin.make_controller(robot, arm.config(1)),
            ref,
        ),
    }
    blocks_us = alternate_steps(variants, (t, q, dq), warmup, blocks)
    auto, block = variants["N = Nc = 100, auto"][0], variants["N = Nc = 100, block"][0]
    auto.reset(q[0], dq[0])
    block.reset(q[0], dq[0])
    worst = 0.0
    for i in range(len(t)):
        auto.step(float(t[i]), q[i], dq[i], ref)
        block.step(float(t[i]), q[i], dq[i], ref)
        worst = max(worst, float(np.abs(auto.v - block.v).max()))
    note = f"auto resolves to '{auto.qps.layout}'"
    return Alternated(blocks_us, "N = 100, Nc = 1", steps, note), worst


class SampleOnly:
    """A reference with only ``sample(t)`` (the sine's), adapted point by point."""

    def __init__(self, sine):
        self.sine = sine

    def sample(self, t: float):
        """The sine at ``t``."""
        return self.sine.sample(t)


def _closed_loop(arm, reference, count: int):
    """States (t, q, dq) of a closed-loop run (Nc = 1, no disturbance) on ``reference``."""
    ctrl = hmpc_pin.make_controller(arm.robot, arm.config(1))
    q0 = reference.sample(0.0)[0] if hasattr(reference, "sample") else reference(0.0)[0]
    res = hmpc_pin.simulate(arm.robot, ctrl, reference, None, duration=(count - 1) * ctrl.Ts,
                            q0=q0, dq0=np.zeros(arm.n))  # fmt: skip
    return res.t, res.q, res.dq


def references(arm, steps: int, blocks: int, warmup: int = 100) -> Alternated:
    """The step (Nc = 1) with the sine, a vectorised quintic (home − 0.3 rad to home +
    0.3 rad over 30 s), the sine behind an object with only ``sample(t)``, and the sine as
    a plain callable ``f(t)``, each on the states of its own closed-loop run; base: the
    sine."""
    sine = arm.reference()
    quintic = hmpc_pin.QuinticReference(arm.home - 0.3, arm.home + 0.3, 0.0, 30.0)
    refs = {
        "SineReference": sine,
        "QuinticReference (vectorised)": quintic,
        "object with only sample(t)": SampleOnly(sine),
        "plain callable f(t)": sine.sample,
    }
    variants = {
        name: (hmpc_pin.make_controller(arm.robot, arm.config(1)), ref)
        for name, ref in refs.items()
    }
    count = warmup + steps
    sine_states = _closed_loop(arm, sine, count)
    states = {name: sine_states for name in refs}
    states["QuinticReference (vectorised)"] = _closed_loop(arm, quintic, count)
    blocks_us = alternate_steps(variants, states, warmup, blocks)
    return Alternated(blocks_us, "SineReference", steps)


def aba_floor(plant, calls: int) -> float:
    """Wall time [s] of ``calls`` bare ``pin.aba`` calls on the plant's model and data, at
    a fixed state: the least the RK4 plant's ABA evaluations can cost from Python."""
    model, data = plant.model, plant.data
    n = model.nq
    buf = np.zeros(3 * n)
    q, v, tau = buf[:n], buf[n : 2 * n], buf[2 * n :]
    aba = pin.aba
    start = time.perf_counter()
    for _ in range(calls):
        aba(model, data, q, v, tau)
    return time.perf_counter() - start
