"""Trigger every safe-stop cause on purpose against the arm in a separate process.

For each cause — Ctrl-C (a real SIGINT), a non-finite torque, a QP not solved (ProxSuite
with one iteration allowed), a joint beyond its bound, k consecutive missed deadlines
(an interface that takes 1.2 periods to read), and the watchdog (the arm process stops
publishing) — the planar3 arm tracks a sine at 1 kHz (MPC at 100 Hz) in wall-clock time
until the cause strikes at t = 0.3 s. The script prints the loop's one-line reason, the
time from detection (and from the cycle's deadline) to the safe torque written, how the
stop sequence ended (the brake, τ = G(q) − D q̇ on each fresh state until the arm is
still or ``hold`` has passed, then the held-safe G(q) with no velocity term; at once
after a watchdog stop), the speed left, and saves each partial run (``complete = False``)
to ``--out``.
"""

from __future__ import annotations

import argparse
import functools
import os
import signal
import time
from pathlib import Path

import numpy as np

import hmpc_pin
from hmpc_pin.controllers.base import ControllerWrapper
from hmpc_pin.controllers.hierarchical import MPCSettings
from hmpc_pin.realtime import (
    LoopSettings,
    ProcessArm,
    RealtimeLoop,
    SafeTorque,
    SafetySettings,
    fifo_priority,
)
from hmpc_pin.sim import RK4Plant
from hmpc_pin.tasks import SineReference

T_FAULT = 0.3  # [s]


def planar_plant(period: float = 0.001):
    return RK4Plant(hmpc_pin.load_robot("planar3"), None, period, period)


class After(ControllerWrapper):
    """The wrapped controller before ``T_FAULT``, then ``act(t, q, dq, reference)``."""

    def __init__(self, controller, act):
        super().__init__(controller)
        self.act = act

    def step(self, t, q, dq, reference):
        if t >= T_FAULT:
            return self.act(t, q, dq, reference)
        return self.controller.step(t, q, dq, reference)


class SlowRead:
    """The arm, read in 1.2 periods from ``T_FAULT`` on (every cycle misses)."""

    def __init__(self, arm):
        self.arm, self.nq, self.period = arm, arm.nq, arm.period

    def read(self):
        stamp, q, dq = self.arm.read()
        if stamp >= T_FAULT + 0.05:  # (the arm's clock runs ahead of the loop's by start-up)
            time.sleep(1.2e-3)
        return stamp, q, dq

    def write(self, tau):
        self.arm.write(tau)

    def close(self):
        self.arm.close()


def run_cause(name, robot, out: Path, priority: int = 0):
    ref = SineReference(3, amplitude=[0.5, 0.3, 0.2], frequency=[0.5, 0.4, 0.3],
                        offset=[0.3, -0.4, 0.2])  # fmt: skip
    q0 = ref.sample(0.0)[0]
    ctrl = inner = hmpc_pin.make_controller(robot)
    inf = np.full(3, np.inf)
    safety = SafetySettings(-inf, inf.copy(), inf.copy(), max_misses=5, watchdog=0.02, hold=2.0)
    with ProcessArm(functools.partial(planar_plant, 0.001), q0, priority=priority) as arm:
        iface = arm
        if name == "ctrl-c":

            def act(t, q, dq, r):
                os.kill(os.getpid(), signal.SIGINT)
                return inner.step(t, q, dq, r)

            ctrl = After(ctrl, act)
        elif name == "non-finite torque":
            ctrl = After(ctrl, lambda t, q, dq, r: np.full(3, np.nan))
        elif name == "QP not solved":
            failing = hmpc_pin.HierarchicalMPC(robot, MPCSettings(max_iter=1))
            failing.reset(q0, np.zeros(3))
            ctrl = After(ctrl, failing.step)
        elif name == "joint beyond its bound":
            upper = np.array([q0[0] + 0.5 * np.sin(2 * np.pi * 0.5 * T_FAULT), np.inf, np.inf])
            safety = SafetySettings(-inf, upper, inf.copy(), max_misses=5, watchdog=0.02,
                                    hold=2.0)  # fmt: skip
        elif name == "k missed deadlines":
            iface = SlowRead(arm)
        elif name == "watchdog":

            def act(t, q, dq, r):
                arm.stall()
                return inner.step(t, q, dq, r)

            ctrl = After(ctrl, act)
        loop = RealtimeLoop(iface, ctrl, ref, SafeTorque(robot, brake_time=BRAKE_TIME),
                            LoopSettings(1000.0, 2.0), safety,
                            joint_names=tuple(robot.joint_names))  # fmt: skip
        with fifo_priority(priority):
            run = loop.run()
        _, _, dq = arm.read()  # after the stop sequence
    stop = run.stop
    path = run.result.save(out / f"safe_stop_{name.replace(' ', '_')}.npz")
    print(f"{name}:\n  {stop['reason']}\n  safe torque "
          f"{1e6 * stop['safe_after_detection']:.0f} us after detection, "
          f"{1e6 * stop['safe_after_deadline']:.0f} us after the cycle's deadline; max |dq| "
          f"{np.abs(stop['dq']).max():.3f} rad/s at the stop, {np.abs(dq).max():.3f} rad/s "
          f"after the brake (ended: {stop['brake']['ended']})\n  saved {path} "
          f"(complete = {run.result.complete}, "
          f"{len(run.result.t)} samples)")  # fmt: skip
    return stop


#: [s] The brake's time constant: the inertia brake M(q) q̇ / T_b slows every joint as
#: e^(−t/T_b) (the planar3 arm's inertia about joint 1 is ~16 kg·m²: a diagonal damping of
#: 2 N·m·s/rad would need ~7 s per time constant); hold/6, the configs' default.
BRAKE_TIME = 2.0 / 6

CAUSES = ("ctrl-c", "non-finite torque", "QP not solved", "joint beyond its bound",
          "k missed deadlines", "watchdog")  # fmt: skip


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--out", type=Path, default=Path("out"), help="output directory")
    parser.add_argument("--cause", choices=CAUSES, action="append",
                        help="only this cause (repeatable; default: all)")  # fmt: skip
    parser.add_argument("--priority", type=int, default=0,
                        help="SCHED_FIFO priority of loop and arm (0: normal) [0]")  # fmt: skip
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    robot = hmpc_pin.load_robot("planar3")
    for name in args.cause or CAUSES:
        run_cause(name, robot, args.out, args.priority)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
