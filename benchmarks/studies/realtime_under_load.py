"""The real-time loop on a loaded machine: how long the arm's state goes stale and how many
deadlines are missed in a row, the two figures the safe stops ``[realtime] watchdog`` and
``max_misses`` are set against.

Runs ``hmpc-pin realtime CONFIG --rate RATE --duration D`` with both stops relaxed out of
reach (``--watchdog 10 --max-misses 1000000``) while ``--load`` busy processes (Python
busy loops, started and stopped by this script) compete for the cores, then reads the
run's timing file:

* the longest time the loop saw the same stamp (the arm process not stepping: what the
  watchdog measures), and its percentiles over every stale stretch;
* the longest run of consecutive missed cycles (what ``max_misses`` counts);
* the 1-minute load average at the end.

    python benchmarks/studies/realtime_under_load.py [--config panda_sine] [--rate 1000]
        [--duration 60] [--load 4] [--priority 0]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

BUSY = "while True: pass"


def _runs(flags: np.ndarray) -> int:
    """The longest run of True in ``flags``."""
    best = cur = 0
    for f in flags:
        cur = cur + 1 if f else 0
        best = max(best, cur)
    return best


def stale_stretches(timing: dict, period: float) -> np.ndarray:
    """How long [s] each stamp the loop read stayed the newest: from the first cycle that
    read it to the last cycle that read it again (the watchdog's measure)."""
    stamp, wake = timing["stamp"], timing["wake"]
    k = np.flatnonzero(np.isfinite(stamp))
    if k.size == 0:
        return np.zeros(0)
    t = k * period + wake[k]  # when each cycle read its state [s after the loop's start]
    s = stamp[k]
    change = np.flatnonzero(np.diff(s) != 0) + 1
    starts = np.concatenate([[0], change])
    ends = np.concatenate([change - 1, [k.size - 1]])
    return t[ends] - t[starts]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="panda_sine")
    parser.add_argument("--rate", type=float, default=1000.0)
    parser.add_argument("--duration", type=float, default=60.0)
    parser.add_argument("--load", type=int, default=4, help="busy processes started")
    parser.add_argument("--priority", type=int, default=0)
    args = parser.parse_args(argv)
    busy = [subprocess.Popen([sys.executable, "-c", BUSY]) for _ in range(args.load)]
    try:
        with tempfile.TemporaryDirectory() as tmp:
            cmd = [sys.executable, "-m", "hmpc_pin", "realtime", args.config,
                   "--rate", str(args.rate), "--duration", str(args.duration),
                   "--watchdog", "10", "--max-misses", "1000000", "--out", tmp]  # fmt: skip
            if args.priority:
                cmd += ["--priority", str(args.priority)]
            proc = subprocess.run(cmd, capture_output=True, text=True)
            load = os.getloadavg()[0]
            name = Path(args.config).stem
            if not (Path(tmp) / f"{name}_realtime_timing.npz").exists():
                print(proc.stdout, proc.stderr, file=sys.stderr)
                return proc.returncode
            timing = dict(np.load(Path(tmp) / f"{name}_realtime_timing.npz"))
    finally:
        for p in busy:
            p.kill()
            p.wait()
    period = 1.0 / args.rate
    stale = stale_stretches(timing, period)
    missed = timing["missed"]
    done = timing["latency"]
    ran = np.isfinite(done)
    print(" ".join(cmd[1:-2]))
    stopped = [x for x in proc.stderr.splitlines() if x.startswith("error:")]
    print(f"exit {proc.returncode}" + (f": {stopped[0]}" if stopped else ""))
    print(f"busy processes {args.load}, 1-min load average at the end {load:.2f}, "
          f"{int(ran.sum())} of {missed.size} cycles run")  # fmt: skip
    p50, p99, p999 = np.percentile(stale, [50, 99, 99.9]) * 1e3
    print(f"stamp unchanged [ms]: median {p50:.2f}, p99 {p99:.2f}, p99.9 {p999:.2f}, "
          f"max {1e3 * stale.max():.2f}")  # fmt: skip
    print(f"missed cycles: {int(missed.sum())} ({100 * missed.mean():.2f} %), longest run "
          f"{_runs(missed)}")  # fmt: skip
    lat = done[ran] * 1e6
    print(f"latency [us]: median {np.median(lat):.0f}, p99 {np.percentile(lat, 99):.0f}, "
          f"max {lat.max():.0f}")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
