"""Franka driver benchmark: per-cycle compute and the robot's success rate, at 1 kHz.

``python benchmarks/studies/franka_cycle.py [--config fr3_sine] [--duration 60] [--robot-ip HOST]
[--ts 0.001]`` (from the repository root) runs ``hmpc-pin franka``'s driver in this
process (:func:`hmpc_pin.apps.franka.run_franka`) against ``--robot-ip`` or, without it,
against the FCI simulator franky-sim started here (``franky-sim -s mujoco`` on
127.0.0.1:1337, in its own process, stopped by its pid; the port must be free), and
prints, from the driver's own record of every robot cycle:

* the compute per cycle, from ``readOnce`` returning to ``writeOnce`` (p50, p99, p99.9,
  max) [µs], over every cycle, over the MPC cycles and over the others;
* ``control_command_success_rate`` (min, mean) and the lost cycles;
* the tracking (worst joint's RMS error after 1 s).

``--ts`` overrides the controller period (0.001: the whole step every cycle), ``--horizon``
and ``--nc`` its N and Nc; ``--inner-law threaded`` runs the MPC in its compiled thread. The
simulator is itself a Python process on the same cores: it models no deadline (it slows
down instead of losing cycles), so its success rate says what the client sent, not what a
robot would have accepted. Exit code 0.
"""

from __future__ import annotations

import argparse
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy (the driver's hygiene)

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def _port_open(host: str, port: int) -> bool:
    with socket.socket() as s:
        s.settimeout(0.2)
        return s.connect_ex((host, port)) == 0


def _start_simulator() -> subprocess.Popen:
    if _port_open("127.0.0.1", 1337):
        raise SystemExit("127.0.0.1:1337 is busy (another FCI simulator): wait for it to end")
    proc = subprocess.Popen(
        [sys.executable, "-c", "from franky_sim.run_server import main; main()", "-s", "mujoco"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    deadline = time.monotonic() + 60.0
    while not _port_open("127.0.0.1", 1337):
        if proc.poll() is not None or time.monotonic() > deadline:
            raise SystemExit("franky-sim did not start")
        time.sleep(0.2)
    return proc


def _stats(x: np.ndarray) -> str:
    x = x[np.isfinite(x)] * 1e6
    if x.size == 0:
        return "n/a"
    p50, p99, p999 = np.percentile(x, [50, 99, 99.9])
    return f"p50 {p50:.0f}, p99 {p99:.0f}, p99.9 {p999:.0f}, max {x.max():.0f} (n={x.size})"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--config", default="fr3_sine")
    parser.add_argument("--duration", type=float, default=60.0)
    parser.add_argument("--robot-ip", default=None)
    parser.add_argument("--realtime", default="ignore", choices=("enforce", "ignore"))
    parser.add_argument("--ts", type=float, default=None, help="controller period [s]")
    parser.add_argument(
        "--inner-law",
        default="auto",
        choices=("auto", "whole-step", "every-cycle", "threaded", "held"),
        help="the command's --inner-law [auto: every-cycle where it applies]",
    )
    parser.add_argument("--horizon", type=int, default=None, help="controller N (and Nc: --nc)")
    parser.add_argument("--nc", type=int, default=None, help="controller Nc")
    args = parser.parse_args()

    from hmpc_pin.apps.franka import FrankaOptions, run_franka
    from hmpc_pin.data import config_path
    from hmpc_pin.experiment.config import load_config

    path = config_path(args.config) or Path(args.config)
    config = load_config(path)
    config = replace(config, simulation=replace(config.simulation, duration=args.duration))
    if args.ts is not None:
        config = replace(config, controller=replace(config.controller, Ts=args.ts))
    if args.horizon is not None:
        config = replace(config, controller=replace(config.controller, N=args.horizon))
    if args.nc is not None:
        config = replace(config, controller=replace(config.controller, Nc=args.nc))
    proc = _start_simulator() if args.robot_ip is None else None
    try:
        with tempfile.TemporaryDirectory() as tmp:
            options = FrankaOptions(
                args.robot_ip or "127.0.0.1", realtime=args.realtime, inner_law=args.inner_law
            )
            run, _, summary = run_franka(config, options, Path(tmp))
            cycles = dict(np.load(Path(tmp) / f"{config.name}_franka_cycles.npz"))
    finally:
        if proc is not None:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(10.0)
            except subprocess.TimeoutExpired:
                proc.kill()
    compute = cycles["compute"]
    m = round(config.controller.Ts / 1e-3)
    mpc = np.zeros(compute.size, dtype=bool)
    k = np.rint(run.result.t / 1e-3).astype(int)
    k = k[k % m == 0]  # the MPC's cycles (the record may hold every cycle)
    rows = k + 1  # the loop's cycle k answered the robot state of row k + 1
    mpc[rows[rows < compute.size]] = True
    keep = run.result.t >= 1.0
    rms = np.sqrt(np.mean((run.result.q[keep] - run.result.q_ref[keep]) ** 2, axis=0))
    rate = cycles["success_rate"][np.isfinite(cycles["success_rate"])]
    print(
        f"config {config.name}, Ts = {config.controller.Ts:g} s (MPC every {m} cycles), "
        f"{args.duration:g} s, against {args.robot_ip or 'franky-sim (started here)'}"
    )
    cc = config.controller
    print(f"  inner law: {summary['inner_law']}; N = {cc.N}, Nc = {cc.Nc}")
    if "planner" in summary:
        print(f"  planner: {summary['planner']}")
    stop = "complete" if run.complete else f"{run.stop['cause']}: {run.stop.get('reason')}"
    print(f"  stop: {stop}")
    print(f"  compute readOnce->writeOnce [us], all cycles: {_stats(compute)}")
    print(f"  MPC cycles: {_stats(compute[mpc])}")
    print(f"  other cycles: {_stats(compute[~mpc])}")
    print(
        f"  success rate: min {rate.min():.4f}, mean {rate.mean():.4f}; lost cycles "
        f"{summary['lost_cycles']} of {compute.size}"
    )
    print(f"  tracking: worst joint RMS after 1 s {rms.max():.3e} rad ({np.argmax(rms) + 1})")
    print(f"  load average: {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
