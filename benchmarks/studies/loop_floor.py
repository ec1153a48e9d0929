"""The real-time loop's tail against the machine's floor: how much of it is the loop's.

Alternating blocks, several pairs: ``cyclictest`` (the machine's floor: one thread at the
same rate and ``SCHED_FIFO`` priority, memory locked, ``-m``) and ``hmpc-pin realtime
CONFIG --rate RATE`` (its ``*_timing.npz``: every cycle's wake-up and deadline -> torque
latency, the missed ones). Per block: median, p99, p99.9, max [µs] and the stalls (cycles
later than ``--stall`` µs; a period the loop skipped counts as one), the load, and the
*steal* [ms]: the time the hypervisor did not run the machine's vCPUs while they had work,
summed over the CPUs (``/proc/stat``; 0 on bare metal), the stalls no loop can avoid; per
pair, the ratio ours / machine of p99.9, max and stalls; then the median of each ratio
over the pairs. On a virtual machine, whose vCPUs the host preempts, a loop is judged
against that floor, not against absolute figures.

``--ours`` names the loop's variants to run in each pair (rotated in order between
pairs), for A/B tests of what the loop does for its tail: ``new`` (as it is), and
variants undoing one measure each (module :data:`VARIANTS`); the ratio between two
variants per pair is printed with ``--ab A B``.

    python benchmarks/studies/loop_floor.py [--config panda_sine] [--rate 1000]
        [--duration 20] [--pairs 4] [--priority 80] [--ours new] [--ab old new]
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from hmpc_pin.realtime.machine import steal_time

_SPIN_READ = (
    "import hmpc_pin.realtime.process_arm as A; A.READ_SPINS = 100_000; A.READ_GIVE_UP = 0.0"
)

#: The loop's variants: Python run in the loop's process before the command line (each
#: undoes one measure of the loop; ``new`` is the loop as it is).
VARIANTS = {
    "new": "",
    # the process's memory not locked (no mlockall)
    "nolock": "R.RealtimeLoop = partial(R.RealtimeLoop, lock_memory=False)",
    # the CPUs' idle-exit latency held at 0 us (/dev/cpu_dma_latency, as cyclictest does)
    "dma": "R.RealtimeLoop = partial(R.RealtimeLoop, cpu_latency=0)",
    # the arm process at the loop's own FIFO priority
    "armsame": "R.ProcessArm = partial(R.ProcessArm, below=0)",
    # the arm process's collector automatic
    "armgc": "R.ProcessArm = partial(R.ProcessArm, gc_frozen=False)",
    # sleeping the whole wait (no busy-wait stretch before the deadline)
    "nospin": 'sys.argv += ["--spin", "0"]',
    # no status line thread
    "nostatus": "R.StatusLine = _Quiet",
    # the arm's state read by spinning only (up to 100 000 tries, no sleep)
    "spinread": _SPIN_READ,
    # everything the loop did before these measures
    "old": "R.RealtimeLoop = partial(R.RealtimeLoop, lock_memory=False, cpu_latency=None); "
    "R.ProcessArm = partial(R.ProcessArm, below=0, gc_frozen=False); " + _SPIN_READ,
}

_PRELUDE = """
import sys
from functools import partial
import hmpc_pin.apps.realtime as R
from hmpc_pin.apps.cli import main
class _Quiet:
    def __init__(self, *a, **k): pass
    def close(self): pass
{patch}
sys.exit(main(sys.argv[1:]))
"""


def summary(x_us: np.ndarray, stall_us: float = 300.0, skipped: int = 0) -> dict:
    """Median, p99, p99.9, max [µs] and stalls (> ``stall_us``, plus ``skipped``)."""
    x = np.asarray(x_us, dtype=float)
    x = x[np.isfinite(x)]
    p50, p99, p999 = np.percentile(x, [50, 99, 99.9])
    return {
        "median": float(p50),
        "p99": float(p99),
        "p999": float(p999),
        "max": float(x.max()),
        "stalls": int(np.count_nonzero(x > stall_us)) + skipped,
        "n": int(x.size),
    }


def machine_block(rate: float, duration: float, priority: int, stall: float, tmp: Path):
    """One cyclictest block: the wake-up latency of a FIFO thread at ``rate`` [Hz]."""
    hist = tmp / "hist.txt"
    loops = round(duration * rate)
    interval = round(1e6 / rate)
    cmd = [
        "cyclictest",
        "-t1",
        f"-p{priority}",
        f"-i{interval}",
        f"-l{loops}",
        "-q",
        "-m",
        "-h20000",
        f"--histfile={hist}",
    ]
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    counts = np.zeros(20001, dtype=np.int64)
    overflows, mx = 0, 0.0
    for line in hist.read_text().splitlines():
        if line.startswith("# Histogram Overflows:"):
            overflows = int(line.split()[-1])
        elif line.startswith("# Max Latencies:"):
            mx = float(line.split()[-1])
        elif line.strip() and not line.startswith("#"):
            b, c = line.split()[:2]
            counts[int(b)] = int(c)
    # the overflows are counted, not listed with their values: at the histogram's end
    values = np.concatenate([np.repeat(np.arange(counts.size), counts), [20000.0] * overflows])
    s = summary(values, stall)
    s["max"] = max(mx, s["max"])
    return {"wake": s, "latency": s}


def loop_block(args, variant: str, tmp: Path, pair: int = 0):
    """One ``hmpc-pin realtime`` block in ``variant``: wake-up and latency summaries
    (the run's files in ``--keep``/``<pair>_<variant>`` if given)."""
    out = (Path(args.keep) if args.keep else tmp) / f"{pair}_{variant}"
    prelude = _PRELUDE.format(patch=VARIANTS[variant])
    cmd = [
        sys.executable,
        "-c",
        prelude,
        "realtime",
        args.config,
        "--rate",
        f"{args.rate:g}",
        "--duration",
        f"{args.duration:g}",
        "--priority",
        str(args.priority),
        "--max-misses",
        "1000000",
        "--watchdog",
        "10",
        "--out",
        str(out),
        "--force",
        *args.extra,
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode not in (0, 1):
        raise RuntimeError(f"{variant}: exit {proc.returncode}\n{proc.stderr[-2000:]}")
    timing = np.load(next(out.glob("*_timing.npz")))
    lat, wake = 1e6 * timing["latency"], 1e6 * timing["wake"]
    # the skipped periods (NaN after the first cycle ran) are stalls of their own
    ran = np.flatnonzero(np.isfinite(lat))
    skipped = int(np.count_nonzero(~np.isfinite(lat[ran[0] :]))) if ran.size else 0
    return {
        "latency": summary(lat, args.stall, skipped),
        "wake": summary(wake, args.stall, skipped),
        "missed": int(np.count_nonzero(timing["missed"])),
        "safe_stop": proc.returncode != 0,
    }


def _line(name: str, s: dict, r: dict) -> str:
    """A table row: the summary ``s`` with block ``r``'s load and steal time [ms]."""
    return (
        f"| {name} | {s['median']:.0f} | {s['p99']:.0f} | {s['p999']:.0f} | {s['max']:.0f} "
        f"| {s['stalls']} | {r['load']:.1f} | {1e3 * r['steal']:.0f} |"
    )


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="panda_sine")
    parser.add_argument("--rate", type=float, default=1000.0)
    parser.add_argument("--duration", type=float, default=20.0)
    parser.add_argument("--pairs", type=int, default=4)
    parser.add_argument("--priority", type=int, default=80)
    parser.add_argument("--stall", type=float, default=300.0, help="a stall: later than [µs]")
    parser.add_argument("--ours", nargs="+", default=["new"], choices=sorted(VARIANTS))
    parser.add_argument("--ab", nargs=2, metavar=("A", "B"), help="print the ratio B / A")
    parser.add_argument("--no-floor", action="store_true", help="skip the cyclictest blocks")
    parser.add_argument("--keep", help="keep the runs' files in this directory")
    parser.add_argument("extra", nargs="*", help="more hmpc-pin realtime arguments (after --)")
    args = parser.parse_args(argv)
    if not args.no_floor and shutil.which("cyclictest") is None:
        parser.error("cyclictest not found (rt-tests); or --no-floor")
    names = ([] if args.no_floor else ["machine"]) + list(args.ours)
    rows: dict[str, list[dict]] = {n: [] for n in names}
    print(
        f"{args.config} at {args.rate:g} Hz, {args.duration:g} s blocks, FIFO {args.priority}, "
        f"stall > {args.stall:g} us; {os.cpu_count()} CPUs"
    )
    print("| block | median | p99 | p99.9 | max | stalls | load | steal [ms] |")
    print("|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        for pair in range(args.pairs):
            order = names[pair % len(names) :] + names[: pair % len(names)]
            for name in order:
                stolen = steal_time()
                if name == "machine":
                    r = machine_block(args.rate, args.duration, args.priority, args.stall, tmp)
                else:
                    r = loop_block(args, name, tmp, pair + 1)
                r["load"] = os.getloadavg()[0]
                r["steal"] = steal_time() - stolen  # [s]
                rows[name].append(r)
                tag = "" if name == "machine" else f", missed {r['missed']}"
                stop = " SAFE STOP" if r.get("safe_stop") else ""
                print(_line(f"{pair + 1} {name} latency{tag}{stop}", r["latency"], r))
                if name != "machine":
                    print(_line(f"{pair + 1} {name} wake", r["wake"], r))
                sys.stdout.flush()
    print()
    for name in names:
        lat = [r["latency"] for r in rows[name]]
        med = {k: float(np.median([s[k] for s in lat])) for k in ("median", "p99", "p999", "max")}
        stalls = int(np.sum([s["stalls"] for s in lat]))
        stops = sum(bool(r.get("safe_stop")) for r in rows[name])
        print(
            f"{name}: latency medians over blocks: median {med['median']:.0f}, p99 "
            f"{med['p99']:.0f}, p99.9 {med['p999']:.0f}, max {med['max']:.0f} us; stalls "
            f"{stalls} in {len(lat)} blocks; safe stops {stops}"
        )

    def ratios(a: str, b: str, part: str = "latency") -> str:
        out = []
        for key in ("p999", "max", "stalls"):
            r = [
                (y[part][key] + (key == "stalls")) / (x[part][key] + (key == "stalls"))
                for x, y in zip(rows[a], rows[b], strict=True)
            ]
            out.append(f"{key} {np.median(r):.2f} ({', '.join(f'{v:.2f}' for v in r)})")
        return "; ".join(out)

    if not args.no_floor:
        for name in args.ours:
            print(f"ours/machine ({name}), median of per-pair ratios: {ratios('machine', name)}")
            w = ratios("machine", name, "wake")
            print(f"  wake-up ours/machine ({name}): {w}")
    if args.ab:
        a, b = args.ab
        print(f"{b}/{a}, median of per-pair ratios (latency): {ratios(a, b)}")
        print(f"{b}/{a} (wake): {ratios(a, b, 'wake')}")
    print("(stalls ratios as (b + 1) / (a + 1))")
    return 0


if __name__ == "__main__":
    sys.exit(main())
