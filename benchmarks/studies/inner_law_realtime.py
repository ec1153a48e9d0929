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

With ``--planner auto,0,10,fifo`` the threaded law runs once per planner scheduling
(``InnerLawThreaded.planner_scheduling``: the rule, a niceness, ``SCHED_FIFO`` one below
the loop) beside the whole step, and ``--priority 0`` runs the loop under the normal
policy (default ``auto``: ``SCHED_FIFO`` where permitted); the planner's longest solve by
its clock and by its CPU time (the ratio: how long it waited for a core) is printed too.

Run: ``python benchmarks/studies/inner_law_realtime.py [--blocks 3] [--duration 10]
[--planner auto,0,10,fifo] [--priority 0]``.
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


def _one(config, law: str, out: Path, planner=None) -> dict:
    from hmpc_pin.apps.realtime import run_realtime, tracking_summary
    from hmpc_pin.realtime.threaded_law import InnerLawThreaded

    if planner is not None:
        InnerLawThreaded.planner_scheduling = planner
    cfg = replace(config, realtime=replace(config.realtime, inner_law=law))
    run, _ = run_realtime(cfg, out, stem=law.replace("-", "_"))
    s = run.stats
    law_s = s["inner_law"]
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
        "fallbacks": law_s.get("fallbacks", 0),
        "nice": law_s.get("planner_nice"),
        "policy": law_s.get("planner_policy"),
        "solve": law_s.get("max_solve", float("nan")) * 1e3,
        "cpu": law_s.get("max_solve_cpu", float("nan")) * 1e3,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--blocks", type=int, default=3)
    parser.add_argument("--duration", type=float, default=10.0)
    parser.add_argument("--config", default="panda_sine")
    parser.add_argument("--planner", default=None, help="e.g. auto,0,10,fifo")
    parser.add_argument("--priority", default="auto", help="the loop's: auto or 0")
    args = parser.parse_args()
    if args.planner:
        variants = [("whole-step", None)] + [
            ("threaded", p if p in ("auto", "fifo") else int(p)) for p in args.planner.split(",")
        ]
    else:
        variants = [(law, None) for law in LAWS]
    warnings.simplefilter("ignore")

    from hmpc_pin.apps.common import read_config, with_overrides

    config = with_overrides(read_config(Path(args.config)), False, args.duration)
    priority = args.priority if args.priority == "auto" else int(args.priority)
    config = replace(
        config,
        realtime=replace(config.realtime, max_misses=10_000, watchdog=1.0, priority=priority),
    )
    names = [law if p is None else f"{law}[{p}]" for law, p in variants]
    rows: dict[str, list[dict]] = {name: [] for name in names}
    load0 = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(args.blocks):
            for name, (law, p) in zip(names, variants, strict=True):
                rows[name].append(_one(config, law, Path(tmp), p))
    load1 = os.getloadavg()[0]
    print(
        f"{args.config}, 1 kHz, Ts = {config.controller.Ts:g} s, {args.blocks} blocks of "
        f"{args.duration:g} s per law (medians over blocks), loop priority {args.priority}"
    )
    print(
        f"{'law':16s} {'worst RMS e [rad]':>18s} {'latency p50':>12s} {'p99':>8s} "
        f"{'p99.9 [us]':>11s} {'compute p50':>12s} {'misses':>7s} {'fallbacks':>9s} "
        f"{'solve max/cpu [ms]':>19s}  planner"
    )
    for law, rs in rows.items():

        def med(k, rs=rs):
            return float(np.nanmedian([r[k] for r in rs]))  # (a stopped run: no RMS)

        stopped = sum(not r["complete"] for r in rs)
        print(
            f"{law:16s} {med('rms'):18.2e} {med('median'):12.0f} {med('p99'):8.0f} "
            f"{med('p999'):11.0f} {med('compute'):12.0f} {sum(r['misses'] for r in rs):7d} "
            f"{sum(r['fallbacks'] for r in rs):9d} "
            f"{med('solve'):9.1f}/{med('cpu'):<9.1f}  {rs[0]['policy'] or ''} "
            f"{'' if rs[0]['nice'] is None else 'nice ' + str(rs[0]['nice'])}"
            + (f"  ({stopped} stopped: {[r['stop'] for r in rs if r['stop']]})" if stopped else "")
        )
    print(f"load average (1 min) {load0:.2f} before, {load1:.2f} after")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
