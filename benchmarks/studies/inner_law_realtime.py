"""The three inner laws in the real-time loop: tracking against latency.

``panda_sine`` (Panda, Ts = 10 ms) in ``hmpc-pin realtime``'s loop at 1 kHz against its
arm process, each law in turn (``whole-step``: the whole step every 10 cycles, its torque
held; ``every-cycle``: the MPC every 10 cycles, Eq 4 and the observer every cycle;
``threaded``: the same with the MPC in its compiled thread), in alternating blocks (A, B,
C, A, B, C, ...), each block a new run of ``--duration`` seconds. Per law, the medians
over blocks of: the worst joint's RMS tracking error after 1 s [rad] (over the runs
that reached 1 s); the loop's latency
(deadline to torque written, every cycle) median, p99 and p99.9 [µs]; the compute per
cycle (median [µs]); the misses; the threaded law's plan fallbacks (summed). The 1-minute
load average before and after. Wall clock on a shared machine: a measurement, not a test.

Run: ``python benchmarks/studies/inner_law_realtime.py [--blocks 3] [--duration 10]``.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

LAWS = ("whole-step", "every-cycle", "threaded")


def _one(config, law: str, out: Path) -> dict:
    from hmpc_pin.apps.realtime import run_realtime, tracking_summary

    cfg = replace(config, realtime=replace(config.realtime, inner_law=law))
    run, _ = run_realtime(cfg, out, stem=law.replace("-", "_"))
    s = run.stats
    tr = tracking_summary(run.result)
    return {
        "rms": max(tr["rms_error"]) if tr else float("nan"),
        "median": s["latency"]["median_us"],
        "p99": s["latency"]["p99_us"],
        "p999": s["latency"]["p999_us"],
        "compute": s["compute"]["median_us"],
        "misses": s["misses"],
        "complete": run.result.complete,
        "stop": None if run.stop is None else run.stop["cause"],
        "fallbacks": s["inner_law"].get("fallbacks", 0),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--blocks", type=int, default=3)
    parser.add_argument("--duration", type=float, default=10.0)
    parser.add_argument("--config", default="panda_sine")
    args = parser.parse_args()
    warnings.simplefilter("ignore")

    from hmpc_pin.apps.common import read_config, with_overrides

    config = with_overrides(read_config(Path(args.config)), False, args.duration)
    config = replace(config, realtime=replace(config.realtime, max_misses=10_000, watchdog=1.0))
    rows: dict[str, list[dict]] = {law: [] for law in LAWS}
    load0 = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(args.blocks):
            for law in LAWS:
                rows[law].append(_one(config, law, Path(tmp)))
    load1 = os.getloadavg()[0]
    print(
        f"{args.config}, 1 kHz, Ts = {config.controller.Ts:g} s, {args.blocks} blocks of "
        f"{args.duration:g} s per law (medians over blocks)"
    )
    print(
        f"{'law':12s} {'worst RMS e [rad]':>18s} {'latency p50':>12s} {'p99':>8s} "
        f"{'p99.9 [us]':>11s} {'compute p50':>12s} {'misses':>7s} {'fallbacks':>9s}"
    )
    for law, rs in rows.items():

        def med(k, rs=rs):
            return float(np.nanmedian([r[k] for r in rs]))  # (a stopped run: no RMS)

        stopped = sum(not r["complete"] for r in rs)
        print(
            f"{law:12s} {med('rms'):18.2e} {med('median'):12.0f} {med('p99'):8.0f} "
            f"{med('p999'):11.0f} {med('compute'):12.0f} {sum(r['misses'] for r in rs):7d} "
            f"{sum(r['fallbacks'] for r in rs):9d}"
            + (f"  ({stopped} stopped: {[r['stop'] for r in rs if r['stop']]})" if stopped else "")
        )
    print(f"load average (1 min) {load0:.2f} before, {load1:.2f} after")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
