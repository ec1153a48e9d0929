"""The observer bandwidth rule against a simulated joint (guide "Sensing and latency").

One joint, a double integrator whose inertia is 1/r of the model's, a constant
disturbance, the package's general NDO (compiled, implicit) with bandwidth ω, an outer PD
loop (kp = 100, kd = 20, and the paper MPC's equivalent gains), the measurement D periods
old and not compensated.
For D = 0..3 and r = 1, 1.25 it prints the largest stable Ts·ω of a geometric grid and
the rule's bound ω r (Ts + L) <= 1/2.

    python benchmarks/observer_rule.py
"""

from __future__ import annotations

import numpy as np

from hmpc_pin.compensation.bandwidth import bandwidth_limit
from hmpc_pin.compensation.observers import DisturbanceObserver


def final_error(w: float, Ts: float, r: float, D: int, steps: int = 3000,
                kp: float = 100.0, kd: float = 20.0) -> float:  # fmt: skip
    """Max |d − d̂| [N·m] over the last 50 steps (unit disturbance, unit model inertia)."""
    obs = DisturbanceObserver(1, Ts, 1.0, "general", cY=np.array([[w]]))
    obs.reset(np.zeros(1), np.zeros(1))
    q = dq = 0.0
    hist = [(q, dq)] * (D + 1)
    tau_prev = np.zeros(1)
    errors = []
    for k in range(steps):
        qm, dqm = hist[-1 - D]
        d_hat = (
            obs.update(np.eye(1), np.zeros(1), np.array([qm]), np.array([dqm]), tau_prev)
            if k else np.zeros(1)
        )  # fmt: skip
        tau = np.array([-kp * qm - kd * dqm]) - d_hat
        a = r * (tau[0] + 1.0)
        if not np.isfinite(a) or abs(a) > 1e12:
            return float("inf")
        q, dq = q + Ts * dq + 0.5 * Ts * Ts * a, dq + Ts * a
        hist.append((q, dq))
        tau_prev = tau
        errors.append(abs(1.0 - d_hat[0]))
    return float(max(errors[-50:]))


def main() -> None:
    from hmpc_pin.controllers.computed_torque import CTSettings
    from hmpc_pin.controllers.hierarchical import MPCSettings

    Ts = 0.01
    grid = np.geomspace(0.01, 100, 41)
    mpc = CTSettings.matching(MPCSettings(Ts=Ts), pid=False)  # the paper MPC's own gains
    loops = {"PD 100, 20": (100.0, 20.0), f"MPC {mpc.kp:.0f}, {mpc.kd:.1f}": (mpc.kp, mpc.kd)}
    print("| outer loop (kp, kd) | D | r | largest stable Ts·ω | rule's Ts·ω bound |")
    print("|---|---|---|---|---|")
    for label, (kp, kd) in loops.items():
        for D in (0, 1, 2, 3):
            for r in (1.0, 1.25):
                stable = [x for x in grid if final_error(x / Ts, Ts, r, D, kp=kp, kd=kd) < 1e-3]
                bound = Ts * bandwidth_limit(Ts, D * Ts, r)
                top = f"{max(stable):.3g}" if stable else "none"
                print(f"| {label} | {D} | {r:g} | {top} | {bound:.3g} |")


if __name__ == "__main__":
    main()
