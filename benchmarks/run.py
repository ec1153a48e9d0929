"""Benchmarks of hmpc_pin (issue 6); writes a Markdown report (default ``BENCHMARKS.md``).

Run from the repository root, in the project's environment:

    python benchmarks/run.py            # full run, about a minute; writes BENCHMARKS.md
    python benchmarks/run.py --quick --out /tmp/bench.md     # smoke run, < 60 s

Measured:

1. ``HierarchicalMPC.step`` (dynamics, observer, every joint QP) on planar3, UR5 and
   Panda at Nc = 1 and Nc = 5: median and 99th percentile over a recorded closed-loop
   trajectory (0.3 rad, 0.1 Hz sines around a home pose, joint limits as soft state
   constraints, the default), after a warm-up along the same trajectory.
2. The paper's 10 s combined scenario (``configs/paper_combined.toml``, 1 ms RK4 plant):
   wall time of ``Experiment.run()`` and real-time factor.
3. Step time against the number of joints: planar chains of 2, 3, 6, 7 and 12 uniform
   rods generated with yourdfpy (``benchmarks/chains.py``), and the real UR5 and Panda;
   and the joint QPs alone as one block-diagonal QP, n QPs, or ProxSuite's ``BatchQP``
   (``benchmarks/qp_layouts.py``) on planar3 and Panda.
4. Memory, each in a fresh process (``benchmarks/memory.py``): peak RSS of the 10 s run,
   and RSS sampled every simulated minute over a 10-minute simulated run.
5. Comparisons on the same arm, reference, disturbance, horizon and plant (issue 6,
   item 3): the hierarchical MPC with and without its observer, a centralized linear MPC
   (``benchmarks/centralized.py``) and a Crocoddyl nonlinear MPC
   (``benchmarks/crocoddyl_mpc.py``, skipped with a message if crocoddyl is missing):
   step time, tracking RMS after 1 s, torque limits, and ratios to the hierarchical MPC.
6. Peers (``benchmarks/peers.py``): the joint QPs against CasADi's qpOASES, OSQP, ProxQP
   and DAQP on the identical problem (solutions checked to 1e-7 rad/s²), the step against
   the same step built on CasADi's QP (torques checked), and the step against Crocoddyl's
   Box-FDDP NMPC, alternating in one process (CasADi and Crocoddyl:
   the ``bench`` extra; skipped with a message without them).

Sections measured by other programs are copied from ``benchmarks/recorded.md``.

``--quick`` shortens every run (fewer steps, shorter simulations, a 30 s soak) to check
that the suite works; its numbers are not meant to be quoted.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks import crocoddyl_mpc, peers  # noqa: E402
from benchmarks._fixtures import (  # noqa: E402
    CHAIN_SIZES,
    HOMES,
    PANDA_LOCKED,
    QUICK,
    Settings,
    load_arm,
    log,
    spatial_observer_kind,
)
from benchmarks.chains import write_planar_chain  # noqa: E402
from benchmarks.closed_loop import bench_memory, bench_simulation  # noqa: E402
from benchmarks.comparisons import bench_compare, panda_scenario, planar3_scenario  # noqa: E402
from benchmarks.harness import (  # noqa: E402
    machine_info,
    package_versions,
)
from benchmarks.ratios import long_horizon, references  # noqa: E402
from benchmarks.report import PeersPart, Round2, bench_ab, find_step, report  # noqa: E402
from benchmarks.steps import bench_qp_layouts, bench_steps  # noqa: E402

__all__ = ["Settings", "main"]


def git_state() -> str:
    """The repository's commit and whether ``hmpc_pin/`` differs from it (read-only git)."""
    try:
        head = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True
        )
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--", "hmpc_pin"],
            cwd=ROOT,
            capture_output=True,
            text=True,
        )
    except OSError:
        return "unknown (git not available)"
    if head.returncode != 0:
        return "unknown (not a git checkout)"
    changed = [line[3:] for line in dirty.stdout.splitlines() if line.strip()]
    if not changed:
        return f"{head.stdout.strip()}, hmpc_pin/ unmodified"
    return f"{head.stdout.strip()} with uncommitted changes in {', '.join(changed)}"


# ----------------------------------------------------------------------------- main
def main(argv: list[str] | None = None) -> int:
    """Run the benchmarks and write the report; returns the exit code (0; 1 when a peer's
    solutions differ from the package's, ``benchmarks/peers.py``)."""
    parser = argparse.ArgumentParser(
        prog="python benchmarks/run.py",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--quick", action="store_true", help="short runs (< 60 s), smoke test")
    parser.add_argument(
        "--out",
        type=Path,
        default=ROOT / "BENCHMARKS.md",
        help="Markdown report to write (default: BENCHMARKS.md at the repository root)",
    )
    parser.add_argument(
        "--old",
        type=Path,
        default=None,
        help="folder holding an older version of the package as hmpc_pin_old: adds old vs "
        "new timings in one process (benchmarks/tools/ab.py)",
    )
    parser.add_argument(
        "--ab-sweep-samples",
        type=int,
        default=0,
        help="with --old: also time the README's sweep (this many samples, in this process, "
        "3 rounds), old and new",
    )
    parser.add_argument(
        "--old-source",
        default="",
        help="with --old: where the old version came from (e.g. its commit), for the report",
    )
    args = parser.parse_args(argv)
    settings = QUICK if args.quick else Settings()
    command = "python benchmarks/run.py" + (" --quick" if args.quick else "")
    if args.out.resolve() != (ROOT / "BENCHMARKS.md").resolve():
        command += f" --out {args.out}"
    start = time.perf_counter()
    info = machine_info()
    info["hmpc_pin source (git)"] = git_state()
    versions = package_versions(("pin", "proxsuite", "numpy", "crocoddyl", "casadi", "hmpc_pin"))
    if not crocoddyl_mpc.AVAILABLE:
        versions["crocoddyl"] = "not importable: comparison skipped"
    if not peers.AVAILABLE:
        versions["casadi"] = "not importable: comparison skipped"

    spatial = spatial_observer_kind()
    log("loading arms")
    arms = [
        load_arm("planar3", ROOT / "robots" / "planar3.urdf", HOMES["planar3"], "chen"),
        load_arm("ur5", "ur5", HOMES["ur5"], spatial),
        load_arm("panda", "panda", HOMES["panda"], spatial, PANDA_LOCKED),
    ]
    log("controller step (and its floor, alternating blocks)")
    steps = bench_steps(settings, arms, floor=True)
    unit = find_step(steps, "planar3", 1).floor.floor_median_us  # type: ignore[union-attr]
    log(f"  floor unit (planar3, Nc = 1): {unit:.2f} µs")
    log("long horizons (Panda, Ts = 1 ms, N = Nc = 100)")
    long, long_diff = long_horizon(arms[2], settings.long_steps, settings.ratio_blocks)
    log("  " + ", ".join(f"{k}: {long.median_us(k):.0f} µs ({long.ratio(k):.2f})"
                         for k in long.blocks_us))  # fmt: skip
    log("references")
    refs = {arm.name: references(arm, settings.ratio_steps, settings.ratio_blocks)
            for arm in (arms[0], arms[2])}  # fmt: skip
    for name, r in refs.items():
        log(f"  {name}: " + ", ".join(f"{k} {r.ratio(k):.2f}" for k in r.blocks_us))
    log("step time against n (generated planar chains)")
    with tempfile.TemporaryDirectory(prefix="hmpc_chains_") as tmp:
        chain_arms = [
            load_arm(f"planar chain {n}", write_planar_chain(n, tmp), np.zeros(n), "chen")
            for n in CHAIN_SIZES
        ]
        chains = bench_steps(settings, chain_arms)
    log("joint QP layouts")
    layouts = bench_qp_layouts(settings, [arms[0], arms[2]])
    log("closed-loop simulation")
    sim = bench_simulation(settings)
    log("memory")
    mem = bench_memory(settings)
    log("comparisons")
    planned = [(planar3_scenario(), settings.compare_duration)]
    if settings.compare_panda_duration > 0:
        planned.append((panda_scenario(), settings.compare_panda_duration))
    compares = [(sc, d, bench_compare(sc, d, settings)) for sc, d in planned]
    log("peers (benchmarks/peers.py)")
    part = PeersPart()
    if peers.AVAILABLE:
        try:
            part.cases = peers.qp_peers(
                blocks=settings.peer_blocks, steps_scale=settings.peer_scale
            )
            part.steps = peers.step_peers(
                blocks=settings.peer_blocks, steps_scale=settings.peer_scale
            )
        except AssertionError as exc:  # a peer solved another problem: no report
            log(f"benchmarks/peers.py: {exc}")
            return 1
    else:
        part.skipped.append(f"The CasADi comparison {peers.EXTRA_MESSAGE}.")
        log(f"  {part.skipped[-1]}")
    if crocoddyl_mpc.AVAILABLE:
        part.crocoddyl = peers.crocoddyl_rows(compares, settings)
    ab_lines: list[str] = []
    if args.old is not None:
        log("old vs new (benchmarks/tools/ab.py)")
        ab_lines = bench_ab(args.old, settings, args.ab_sweep_samples, args.quick, args.old_source)
        command += (
            " --old OLD_DIR"
            + (f" --old-source {args.old_source}" if args.old_source else "")
            + (f" --ab-sweep-samples {args.ab_sweep_samples}" if args.ab_sweep_samples else "")
        )
    total = time.perf_counter() - start
    with contextlib.suppress(OSError):  # the machine's load while it ran, for the reader
        load = os.getloadavg()
        info["load average (1, 5, 15 min) at the end"] = ", ".join(f"{x:.2f}" for x in load)
    text = report(
        settings,
        args.quick,
        command,
        info,
        versions,
        steps,
        chains,
        layouts,
        sim,
        mem,
        compares,
        spatial,
        total,
        Round2(unit, long, long_diff, refs, ab_lines),
        part,
    )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text, encoding="utf-8")
    log(f"wrote {args.out} ({total:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
