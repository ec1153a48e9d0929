"""A damped arm: Z1 with its URDF's joint damping and friction, a brisk sine.

Z1 declares ``<dynamics damping friction>`` on every joint (1-2 N·m·s/rad, 1-2 N·m); at
the posture below its wrist's damping time constant is 0.8 ms, below Ts = 10 ms. The
config is the one ``hmpc-pin init z1`` writes (observer bandwidth 10/Ts, its model at the
start of the period, a declared 1 ms latency), with a 0.5 Hz, 0.5 rad sine on every joint
(joints 2 and 3 moved to offsets 0.6, −0.6 to keep it inside the limits) and no added
disturbance: the URDF's joint dynamics are the only friction. Each row is one 10 s run;
the worst joint's RMS tracking error [rad].

Run: ``python -m benchmarks.studies.damped_arm [--duration S]`` (about a minute).

``--latency-error``: instead, Ts = 1 ms (N = 10) with ``[controller] latency = 0.001``
declared, the measurements 1, 0.5 and 0 ms old
(:class:`~hmpc_pin.sim.sensing.SensedController` with a
:class:`~hmpc_pin.sim.sensing.Latency` only), the observer's bandwidth 10/Ts, the 4/Ts
``hmpc-pin init`` writes at 1 ms (:func:`~hmpc_pin.compensation.bandwidth.overdeclared_limit`),
1/Ts and 0.5/Ts: the worst joint's RMS, or when the run stopped; the sweep's whole
interface model with the latency declared right; then the stopped 10/Ts run again with a
higher QP iteration cap.
``python -m benchmarks.studies.damped_arm --latency-error --duration 2`` (seconds).
"""

from __future__ import annotations

import argparse
import os
from dataclasses import replace

import numpy as np

import hmpc_pin
from hmpc_pin.experiment.config import ExperimentConfig, load_config
from hmpc_pin.experiment.init import InitPlan
from hmpc_pin.model.robot import damping_time_constants

CONFIG = """
name = "z1_damped_sine"
description = "Z1 with its URDF joint dynamics, 0.5 Hz 0.5 rad sine"
[robot]
model = "z1"
gravity = 9.81
[robot.locked_joints]
"jointGripper" = 0
[controller]
Ts = 0.01
v_min = [-100, -100, -39.18, -100, -100, -100]
v_max = [100, 100, 39.18, 100, 100, 100]
compensation = "general"
latency = 0.001
[controller.observer]
bandwidth = 1000
model_at = "start"
[plant]
dt = 0.0001
[reference]
kind = "sine"
amplitude = 0.5
frequency = 0.5
offset = [0, 0.6, -0.6, 0, 0, 0]
[simulation]
duration = 10
dq0 = 1.5707963267948966
"""


def config(path) -> ExperimentConfig:
    path.write_text(CONFIG)
    return load_config(path)


def worst_rms(cfg: ExperimentConfig, observer: bool = True) -> tuple[float, int]:
    r = hmpc_pin.Experiment.from_config(cfg, observer=observer).run()
    if not r.complete:
        return float("inf"), -1
    rms = np.sqrt(((r.q - r.q_ref) ** 2).mean(axis=0))
    return float(rms.max()), int(rms.argmax()) + 1


def latency_error(base: ExperimentConfig) -> int:
    """The ``--latency-error`` table (module docstring)."""
    import warnings

    from hmpc_pin.sim.sensing import Latency, SensedController, Sensing

    warnings.simplefilter("ignore")  # the bandwidth check's warning on 10/Ts
    Ts = 0.001

    def run(age: float, periods: float, **controller):
        obs = replace(base.controller.observer, bandwidth=periods / Ts)
        cc = replace(base.controller, Ts=Ts, N=10, latency=0.001, observer=obs, **controller)
        ex = hmpc_pin.Experiment.from_config(replace(base, controller=cc))
        if age > 0:  # the measurements age [s] old, nothing else modelled
            sensing = Sensing(rate=1000.0, latency=Latency(age))
            ex.controller = SensedController(ex.controller, sensing)
        try:
            return ex, ex.run()
        except hmpc_pin.SimulationError as exc:
            return ex, exc.result

    print("| declared [ms] | measurements' age [ms] | bandwidth | worst RMS [rad] |")
    print("|---|---|---|---|")
    for age in (0.001, 0.0005, 0.0):
        for periods in (10.0, 4.0, 1.0, 0.5):
            _, r = run(age, periods)
            out = (f"{np.sqrt(((r.q - r.q_ref) ** 2).mean(axis=0)).max():.2e}" if r.complete
                   else f"stopped at {r.t[-1]:.3f} s")  # fmt: skip
            print(f"| 1 | {1e3 * age:g} | {periods:g}/Ts | {out} |", flush=True)
    # The sweep's whole interface model ([sweep.sensing]: 2^19-count encoders, finite
    # differences at 1 kHz, 1 ms latency declared right, 100 Hz torque filter).
    from hmpc_pin.apps.sweep import SampleParams, run_sample

    params = SampleParams(0, (1.0,) * 6, (1.0,) * 6, (1.0,) * 6, 0)  # the nominal plant
    for periods in (10.0, 4.0):
        obs = replace(base.controller.observer, bandwidth=periods / Ts)
        cc = replace(base.controller, Ts=Ts, N=10, latency=0.001, observer=obs)
        sweep = replace(base.sweep, known_latency=True, variants=None)
        row = run_sample(replace(base, controller=cc, sweep=sweep), params, "ndo", "all")
        out = f"{row['rms_max']:.2e}" if row["complete"] else f"stopped at {row['t_end']:.3f} s"
        print(f"| 1 | 1, the sweep's interface model | {periods:g}/Ts | {out} |", flush=True)
    # The failed QP: the same run with a higher iteration cap, the state where it failed.
    _, failed = run(0.0, 10.0)
    j = int(np.abs(failed.d_hat).max(axis=0).argmax())
    d = failed.d_hat[:, j]
    grow = (np.abs(d[1:]) > 0.1) & (np.abs(d[1:]) < 0.5 * np.abs(d).max())  # before saturating
    factor = np.median(d[1:][grow] / d[:-1][grow])
    print(
        f"\nage 0, 10/Ts: joint {j + 1}'s estimate multiplied by {factor:.3f} per period "
        "before it saturated (the rule's root at r = 1, g = 10/11: -1.446)"
    )
    ex, r = run(0.0, 10.0, max_iter=10000)
    upto = r.t <= failed.t[-1] + 1e-12
    ratio = np.abs(r.dq[upto]).max(axis=0) / ex.robot.model.velocityLimit
    print(
        f"age 0, 10/Ts with controller.max_iter = 10000: passes t = {failed.t[-1]:.3f} s "
        f"(the default cap's stop): {bool(r.t[-1] > failed.t[-1])}; there the largest "
        f"|dq|/velocity limit is {ratio.max():.2f} (joint {int(ratio.argmax()) + 1}); over "
        f"the run (to t = {r.t[-1]:.3f} s, complete {r.complete}) "
        f"{(np.abs(r.dq).max(axis=0) / ex.robot.model.velocityLimit).max():.2f}, max |d̂| "
        f"{np.abs(r.d_hat).max():.3g} N·m"
    )
    return 0


def main(argv=None) -> int:
    import tempfile
    from pathlib import Path

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--duration", type=float, default=10.0)
    p.add_argument("--latency-error", action="store_true",
                   help="Ts = 1 ms, 1 ms declared, the measurements 1, 0.5, 0 ms old")  # fmt: skip
    args = p.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        base = config(Path(tmp) / "z1_damped.toml")
    base = replace(base, simulation=replace(base.simulation, duration=args.duration))
    if args.latency_error:
        return latency_error(base)
    ex = hmpc_pin.Experiment.from_config(base)
    tau = damping_time_constants(ex.robot, ex.q0)
    print(f"1/(b_j (M^-1)_jj) [ms]: {np.array2string(1e3 * tau, precision=2)}; Ts = 10 ms")
    try:
        import mujoco  # noqa: F401

        engines = ["pinocchio", "mujoco"]
    except ImportError:
        engines = ["pinocchio"]
    print("| plant | plant joint dynamics | controller compensates | observer (model at) "
          "| worst RMS [rad] |")  # fmt: skip
    print("|---|---|---|---|---|")
    for engine in engines + (["mujoco, friction_timeconst = 2 ms"] if "mujoco" in engines else []):
        # the Pinocchio plant at 0.1 ms: RK4 resolves the 0.8 ms time constant
        if engine == "pinocchio":
            pc = replace(base.plant, dt=1e-4)
        else:
            pc = replace(base.plant, engine="mujoco", dt=0.001)  # MuJoCo's own timestep
            if "friction_timeconst" in engine:  # MuJoCo's friction closer to Coulomb's
                pc = replace(pc, mujoco=replace(pc.mujoco, friction_timeconst=0.002))
        for plant_jd, ctrl_jd, obs, at in [
            (False, False, True, "end"), (False, False, True, "start"),
            (True, False, True, "start"),
            (True, True, True, "end"), (True, True, True, "start"), (True, True, False, "-"),
        ]:  # fmt: skip
            cc = base.controller
            if obs:
                cc = replace(cc, observer=replace(cc.observer, model_at=at))
            cfg = replace(base, plant=replace(pc, joint_dynamics=plant_jd),
                          controller=replace(cc, joint_dynamics=ctrl_jd))  # fmt: skip
            rms, joint = worst_rms(cfg, obs)
            what = f"general ({at})" if obs else "none"
            print(f"| {engine} | {plant_jd} | {ctrl_jd} | {what} | {rms:.3g} (joint {joint}) |",
                  flush=True)  # fmt: skip
    # The period hmpc-pin init picks for this damping (2 ms, the shortest it offers: the
    # wrist's 0.76 ms asks for Ts <= 1.2 ms), bandwidth 10/Ts, N = 10.
    Ts = InitPlan("z1").periods()[0]
    cc = replace(base.controller, Ts=Ts, observer=replace(base.controller.observer,
                                                          bandwidth=10.0 / Ts))  # fmt: skip
    print(f"\nTs = {1e3 * Ts:g} ms as hmpc-pin init picks it (bandwidth 10/Ts, N = 10):")
    for engine in engines:
        pc = replace(base.plant, dt=1e-4) if engine == "pinocchio" else replace(
            base.plant, engine="mujoco", dt=0.001)  # fmt: skip
        if engine == "mujoco":
            pc = replace(pc, mujoco=replace(pc.mujoco, friction_timeconst=0.002))
        for obs in (True, False):
            rms, joint = worst_rms(replace(base, plant=pc, controller=cc), obs)
            print(f"| {engine} | True | True | {'general (start)' if obs else 'none'} | "
                  f"{rms:.3g} (joint {joint}) |", flush=True)  # fmt: skip
    # the horizon in seconds of the 10 ms config (0.1 s) instead of ten periods
    cc50 = replace(cc, N=round(0.1 / Ts))
    rms, joint = worst_rms(replace(base, plant=replace(base.plant, dt=1e-4), controller=cc50))
    print(f"| pinocchio, N = {cc50.N} | True | True | general (start) | {rms:.3g} "
          f"(joint {joint}) |", flush=True)  # fmt: skip
    return 0


if __name__ == "__main__":
    os.environ.setdefault("PYTHONWARNINGS", "ignore")
    raise SystemExit(main())
