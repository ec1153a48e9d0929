"""The observer bandwidth rule against a simulated joint (guide "Sensing and latency").

One joint, a double integrator whose inertia is 1/r of the model's, a constant
disturbance, the package's general NDO (compiled, implicit) with bandwidth ω, an outer PD
loop (kp = 100, kd = 20, and the paper MPC's equivalent gains), the measurement D periods
old and not compensated.
For D = 0..3 and r = 1, 1.25 it prints the largest stable Ts·ω of a geometric grid and
the rule's bound ω r (Ts + L) <= 1/2.

With ``--over``: the opposite mistake, the controller told of a latency the measurements do
not have, ΔL = β Ts too long (β = 0.25 … 1; the observer fed the torque of the interval
ΔL earlier, the state carried ΔL ahead with the commanded accelerations), at Ts = 1 ms and
10 ms, beside the stability bound ω (r Ts + 2ΔL − 2Ts) < 2 and the package's rule (half of
it, :func:`~hmpc_pin.compensation.bandwidth.overdeclared_limit`).

    python benchmarks/studies/observer_rule.py
    python benchmarks/studies/observer_rule.py --over
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from hmpc_pin.compensation.bandwidth import bandwidth_limit, overdeclared_limit
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


def final_error_over(w: float, Ts: float, r: float, beta: float, steps: int = 3000,
                     kp: float = 100.0, kd: float = 20.0) -> float:  # fmt: skip
    """As :func:`final_error` with a fresh measurement (no latency) and the controller told
    of a latency of ``beta`` periods (0 <= β <= 1): the observer is fed the mean torque over
    :math:`[t_{k-1} - βT_s, t_k - βT_s]`, i.e. :math:`βτ_{k-2} + (1 − β)τ_{k-1}`, and the
    outer loop acts on the state carried βTs ahead with the accelerations commanded then."""
    obs = DisturbanceObserver(1, Ts, 1.0, "general", cY=np.array([[w]]))
    obs.reset(np.zeros(1), np.zeros(1))
    q = dq = 0.0
    tau1 = tau2 = v1 = 0.0  # τ_{k-1}, τ_{k-2}; v_{k-1}
    errors = []
    for k in range(steps):
        paired = beta * tau2 + (1.0 - beta) * tau1
        d_hat = (
            obs.update(np.eye(1), np.zeros(1), np.array([q]), np.array([dq]),
                       np.array([paired]))
            if k else np.zeros(1)
        )  # fmt: skip
        qp, dqp = q, dq  # predicted from t_k - βTs: v_{k-1} held over the whole of it (β <= 1)
        h = beta * Ts
        qp, dqp = qp + h * dqp + 0.5 * h * h * v1, dqp + h * v1
        v = -kp * qp - kd * dqp
        tau = v - d_hat[0]
        a = r * (tau + 1.0)
        if not np.isfinite(a) or abs(a) > 1e12:
            return float("inf")
        q, dq = q + Ts * dq + 0.5 * Ts * Ts * a, dq + Ts * a
        tau1, tau2, v1 = tau, tau1, v
        errors.append(abs(1.0 - d_hat[0]))
    return float(max(errors[-50:]))


def main_over() -> None:
    from hmpc_pin.controllers.computed_torque import CTSettings
    from hmpc_pin.controllers.hierarchical import MPCSettings

    grid = np.geomspace(0.1, 100, 61)
    print("| Ts [ms] | outer loop (kp, kd) | β = ΔL/Ts | r | largest stable Ts·ω "
          "| stability bound | rule's Ts·ω |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    for Ts in (0.001, 0.01):
        mpc = CTSettings.matching(MPCSettings(Ts=Ts), pid=False)  # the paper MPC at Ts
        loops = {"PD 100, 20": (100.0, 20.0), f"MPC {mpc.kp:.0f}, {mpc.kd:.1f}": (mpc.kp, mpc.kd)}
        for label, (kp, kd) in loops.items():
            for beta in (0.25, 0.5, 1.0):
                for r in (1.0, 1.25):
                    errs = [final_error_over(x / Ts, Ts, r, beta, kp=kp, kd=kd) for x in grid]
                    stable = [x for x, e in zip(grid, errs, strict=True) if e < 1e-3]
                    den = r + 2 * beta - 2
                    bound = 2 / den if den > 0 else math.inf
                    rule = Ts * overdeclared_limit(Ts, beta * Ts, r)
                    top = f"{max(stable):.3g}" if stable else "none"
                    print(f"| {Ts * 1e3:g} | {label} | {beta:g} | {r:g} | {top} | {bound:.3g} "
                          f"| {rule:.3g} |")  # fmt: skip


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
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--over", action="store_true",
                        help="the latency declared longer than it is")  # fmt: skip
    if parser.parse_args().over:
        main_over()
    else:
        main()
