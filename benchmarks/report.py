"""The Markdown report of ``benchmarks/run.py`` (``BENCHMARKS.md``): tables, targets and
the A/B section."""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks import crocoddyl_mpc, peers  # noqa: E402
from benchmarks._fixtures import (  # noqa: E402
    AMPLITUDE,
    FREQUENCY,
    HOMES,
    MiB,
    Settings,
    observer_kinds,
)
from benchmarks.closed_loop import MemoryResult, SimResult  # noqa: E402
from benchmarks.comparisons import CompareRow, Scenario  # noqa: E402
from benchmarks.qp_layouts import LayoutTiming  # noqa: E402
from benchmarks.ratios import Alternated  # noqa: E402
from benchmarks.steps import StepResult  # noqa: E402


def table(headers: list[str], rows: list[list[str]]) -> str:
    """A Markdown table."""
    lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines)


def fmt_us(x: float) -> str:
    """Microseconds with a sensible number of digits."""
    return f"{x:.1f}" if x < 100 else f"{x:.0f}"


def verdict(ok: bool) -> str:
    """PASS or FAIL in bold."""
    return "**PASS**" if ok else "**FAIL**"


def find_step(results: list[StepResult], arm: str, Nc: int) -> StepResult | None:
    """The step result of ``(arm, Nc)``, if measured."""
    return next((r for r in results if r.arm == arm and r.Nc == Nc), None)


def targets_section(steps: list[StepResult], sim: SimResult, mem: MemoryResult) -> str:
    """The issue-6 targets with the measured values and a verdict each."""
    rows = []
    for arm, base in (("planar3", 25.0), ("panda", 50.0)):
        for Nc, limit in ((1, base), (5, 2 * base)):
            r = find_step(steps, arm, Nc)
            if r is None:
                continue
            rows.append(
                [
                    f"`HierarchicalMPC.step`, {arm}, Nc = {Nc}, median",
                    f"≤ {limit:g} µs",
                    f"{fmt_us(r.timing.median_us)} µs",
                    verdict(r.timing.median_us <= limit),
                ]
            )
    rows.append(
        [
            "paper 10 s combined simulation (1 ms RK4 plant), `run()` wall time, median",
            "≤ 0.2 s (real-time factor ≥ 50)",
            f"{sim.median:.3f} s (real-time factor {sim.rtf:.1f})",
            verdict(sim.median <= 0.2 and sim.complete),
        ]
    )
    soak_min = mem.soak["duration"] / 60.0
    rows.append(
        [
            f"no memory growth over a {soak_min:g}-minute simulated run "
            f"(RSS from t = {mem.growth_start:g} s to the end)",
            "≤ 1 MiB growth",
            f"{mem.soak_growth / MiB:+.2f} MiB",
            verdict(mem.soak_growth <= MiB and mem.soak["complete"]),
        ]
    )
    return table(["target", "target", "measured", "verdict"], rows)


def step_table(steps: list[StepResult], unit: float) -> str:
    """Table of the step timings (and the median in floor units, and step / own floor)."""
    rows = [
        [
            r.arm,
            str(r.n),
            str(r.Nc),
            f"`{r.observer}`",
            fmt_us(r.timing.median_us),
            fmt_us(r.timing.p99_us),
            fmt_us(r.timing.mean_us),
            fmt_us(r.timing.min_us),
            per_unit(r.timing.median_us, unit),
            f"{r.floor.ratio:.2f}" if r.floor is not None else "",
            str(r.timing.count),
            r.source,
        ]
        for r in steps
    ]
    headers = [
        "arm",
        "n",
        "Nc",
        "observer",
        "median [µs]",
        "p99 [µs]",
        "mean [µs]",
        "min [µs]",
        "median in floor units",
        "step / own floor",
        "timed steps",
        "states",
    ]
    return table(headers, rows)


def scaling_table(chains: list[StepResult], arms: list[StepResult], unit: float) -> str:
    """Step time against n (planar chains, UR5, Panda)."""
    entries = {}
    for r in [*chains, *arms]:
        entries.setdefault((r.n, r.arm), {})[r.Nc] = r
    rows = []
    for (n, arm), by_nc in sorted(entries.items()):
        one, five = by_nc.get(1), by_nc.get(5)
        rows.append(
            [
                str(n),
                arm,
                fmt_us(one.timing.median_us) if one else "",
                fmt_us(one.timing.p99_us) if one else "",
                fmt_us(one.timing.median_us / n) if one else "",
                per_unit(one.timing.median_us, unit) if one else "",
                fmt_us(five.timing.median_us) if five else "",
                fmt_us(five.timing.p99_us) if five else "",
                per_unit(five.timing.median_us, unit) if five else "",
            ]
        )
    headers = [
        "n",
        "arm",
        "Nc = 1 median [µs]",
        "Nc = 1 p99 [µs]",
        "Nc = 1 median / n [µs]",
        "Nc = 1 median in floor units",
        "Nc = 5 median [µs]",
        "Nc = 5 p99 [µs]",
        "Nc = 5 median in floor units",
    ]
    return table(headers, rows)


def compare_table(rows: list[CompareRow], effort: bool, unit: float) -> str:
    """Table of one scenario's comparison, with ratios to the hierarchical MPC."""
    base = next((r for r in rows if r.controller == "hmpc"), None)
    base_off = next((r for r in rows if r.controller == "hmpc, no NDO"), None)

    def ratio(a: float | None, b: float | None) -> str:
        return f"{a / b:.2f}" if a is not None and b else "n/a"

    out = []
    for r in rows:
        med = r.timing.median_us if r.timing else None
        p99 = r.timing.p99_us if r.timing else None
        worst = float(r.rms.max()) if r.rms is not None else None
        worst_base = float(base.rms.max()) if base and base.rms is not None else None
        worst_off = float(base_off.rms.max()) if base_off and base_off.rms is not None else None
        name = r.controller
        if r.extra.get("iterations"):
            name += f" ({r.extra['iterations']} it.)"
        limits = "n/a"
        if effort and r.peak_ratio is not None:
            limits = ("yes" if r.peak_ratio <= 1.0 else "**no**") + f" ({r.peak_ratio:.2f})"
        out.append(
            [
                name,
                fmt_us(med) if med is not None else "n/a",
                fmt_us(p99) if p99 is not None else "n/a",
                per_unit(med, unit) if med is not None else "n/a",
                ratio(med, base.timing.median_us if base and base.timing else None),
                ratio(p99, base.timing.p99_us if base and base.timing else None),
                ", ".join(f"{x:.1e}" for x in r.rms) if r.rms is not None else "n/a",
                ratio(worst, worst_base),
                ratio(worst, worst_off),
                limits,
                str(r.saturated_steps) if r.saturated_steps is not None else "n/a",
                "yes" if r.complete else f"**no**: {r.message}",
            ]
        )
    headers = [
        "controller",
        "step median [µs]",
        "step p99 [µs]",
        "step median in floor units",
        "median ratio",
        "p99 ratio",
        "RMS e after 1 s per joint [rad]",
        "worst-RMS ratio",
        "worst-RMS ratio vs no NDO",
        "commanded \\|τ\\| ≤ τ_max (peak \\|τ\\|/τ_max)",
        "saturated periods",
        "completed",
    ]
    return table(headers, out)


def layout_table(layouts: list[LayoutTiming], unit: float) -> str:
    """Table of the joint-QP layout timings [µs] with the ratio to the block QP (alternated
    blocks, one process) and floor units in brackets."""
    names = list(layouts[0].median_us) if layouts else []
    headers = ["arm", "n", "Nc", *(f"{k} [µs] (ratio to block; floor units)" for k in names),
               "largest |Δv| vs block"]  # fmt: skip
    rows = [
        [
            r.arm,
            str(r.n),
            str(r.Nc),
            *(
                f"{fmt_us(r.median_us[k])} ({r.ratio.get(k, float('nan')):.2f}; "
                f"{per_unit(r.median_us[k], unit)})"
                for k in names
            ),
            f"{max(r.max_diff.values()):.1e}",
        ]
        for r in layouts
    ]
    return table(headers, rows)


@dataclass
class Round2:
    """The issue-18 measurements: the floor unit [µs], long horizons, references."""

    unit: float
    long: Alternated
    long_diff: float
    refs: dict[str, Alternated]
    ab: list[str] = field(default_factory=list)


@dataclass
class PeersPart:
    """The peers' measurements (``benchmarks/peers.py``): the CasADi QP cases and the
    Crocoddyl rows (empty when skipped), and why a part was skipped."""

    cases: list = field(default_factory=list)
    steps: list = field(default_factory=list)
    crocoddyl: list = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)


#: The sections measured by other programs, copied into the report (each names its command
#: and source; ``benchmarks/run.py`` does not rerun them).
RECORDED = Path(__file__).resolve().parent / "recorded.md"


def peers_section(part: PeersPart, settings: Settings) -> list[str]:
    """The "Peers" section: CasADi's QP solvers on the identical joint QPs and Crocoddyl's
    Box-FDDP NMPC, each as a ratio measured in one process beside its absolute time."""
    lines = [
        "## Peers",
        "",
        "Ratios measured in one process, alternating blocks, median over blocks of the "
        "per-block ratio of medians, beside the absolute medians. Rerun this section alone "
        "with `python benchmarks/peers.py` (CasADi and Crocoddyl: the `bench` extra, "
        '`pip install -e ".[bench]"`; a missing one is skipped with a message).',
        "",
        "### QP solvers through CasADi, on the identical joint QPs",
        "",
        "The per-joint box QP of Eq (26) built from the package's own condensed matrices "
        "(`CondensedMPC`: the scaled H, each joint's gradient, |v| ≤ 100 rad/s²), solved by "
        "the package (`JointQPs`, the compiled QPs of the step; no state limits) and by "
        "`casadi.conic` with each plugin, in the package's layout (one block-diagonal QP up "
        "to n·Nc = 140 variables, one QP per joint above), warm-started from the previous "
        "solution where the plugin takes one (OSQP, ProxQP; CasADi re-initialises qpOASES at "
        "every call, its DAQP plugin documents no warm start). Gradients along a closed loop "
        "of the feedback-linearised arm (q̈ = v) tracking the benchmark's sine, kicked "
        f"±{peers.KICK:g} rad off the reference every 20 steps (so that bounds are active; "
        f"the share of steps is in the table); {settings.peer_blocks} alternating blocks over "
        "the sequence (sequence lengths: `SCENARIOS` in `benchmarks/peers.py`"
        + (f", scaled by {settings.peer_scale:g}" if settings.peer_scale != 1.0 else "")
        + "). Before timing, every peer solution along the whole sequence is checked: "
        f"max |U_peer − U| ≤ {peers.TOLERANCE:g} rad/s² or the program stops; the table "
        "gives that distance, the torque it makes through the arm's M(q), and each "
        "solution's box-QP optimality residual ‖u − Π(u − (Hu + g))‖∞ (0 exactly at the "
        "minimiser; H is scaled to a unit mean diagonal). Tolerances: ProxSuite in the "
        "package eps_abs = 1e-9; qpOASES and DAQP their defaults (active set); OSQP "
        "eps = 1e-10, polished with 10 refinement steps; ProxQP through CasADi eps_abs = "
        "1e-12 (block) or 1e-11 (per joint), the loosest that meet the check "
        "(`benchmarks/peers.py`, `PLUGINS`). The last row of each case is a CasADi "
        "`Function` that returns its inputs, called as the solvers are: the price of a call "
        "through CasADi's Python interface. Where the package solves the joints as one block "
        'QP, its per-joint layout (`controller.qp_layout = "joint"`, with its exact '
        "shortcuts) is timed on the same QPs too.",
        "",
    ]
    if part.cases:
        lines += [peers.qp_table(part.cases), ""]
    lines += [f"{why}" for why in part.skipped] + ([""] if part.skipped else [])
    if part.steps:
        lines += [
            "### The whole step against the same step built on CasADi",
            "",
            "The package's `HierarchicalMPC.step` (no observer, no joint dynamics, no state "
            "limits: `NoCompensation`, `joint_dynamics = False`, `limits = None`) against "
            "the same step written in Python around CasADi's QP (`CasadiStep` in "
            "`benchmarks/peers.py`: the reference over the horizon, the gradients from "
            "`CondensedMPC`, the QPs above through `casadi.conic`, Pinocchio's `crba` and "
            "`nonLinearEffects`, τ = M v₀ + C q̇ + G), on the states of the same kicked "
            "closed loops; every torque checked before timing (|Δτ| at most the QP "
            "tolerance through M, ‖M‖∞·1e-7 + 1e-9 N·m, the figure in brackets).",
            "",
            peers.step_table(part.steps),
            "",
        ]
    lines += [
        "### Crocoddyl's Box-FDDP NMPC",
        "",
        "The step of `HierarchicalMPC` (the comparison scenario's config, with its NDO) and "
        "of `CrocoddylMPC` (`benchmarks/crocoddyl_mpc.py`, described in the comparison "
        "section above) on the states of the hierarchical MPC's closed-loop run of the "
        f"scenario ({settings.peer_duration:g} s), alternating blocks "
        f"({settings.peer_blocks}), each controller reset and warmed up (10 steps) at the "
        "start of its block. Tracking: the worst joint's RMS error after 1 s of the "
        "comparison's closed-loop runs above (same process), Crocoddyl's over the "
        "hierarchical MPC's with and without its observer.",
        "",
    ]
    if part.crocoddyl:
        lines += [peers.crocoddyl_table(part.crocoddyl), ""]
    else:
        lines += [f"The Crocoddyl comparison {peers.EXTRA_MESSAGE}: skipped.", ""]
    return lines


#: Speed-ups measured by :func:`bench_ab` (for the targets table): "run", "sweep".
AB_SPEEDUPS: dict[str, float] = {}


def bench_ab(
    old: Path, settings: Settings, sweep_samples: int, quick: bool, source: str = ""
) -> list[str]:
    """Old vs new in one process, alternating (``benchmarks/tools/ab.py``): the report lines."""
    from benchmarks.tools import ab

    old_pkg, new_pkg = ab._packages(old)
    version = getattr(old_pkg, "__version__", "?")
    rows = []
    run = ab.ab_run(old_pkg, new_pkg, 3 if quick else 9)
    AB_SPEEDUPS["run"] = run["speedup"]
    rows.append(["paper 10 s run, `Experiment.run()` [s]", f"{run['old']:.3f}",
                 f"{run['new']:.3f}", f"**{run['speedup']:.2f}**"])  # fmt: skip
    rows.append(["real-time factor", f"{run['rtf_old']:.0f}", f"{run['rtf_new']:.0f}", ""])
    for arm, r in ab.ab_step(old_pkg, new_pkg, 3 if quick else 10).items():
        rows.append([f"{arm} step, Nc = 1 [µs]", fmt_us(r["old"]), fmt_us(r["new"]),
                     f"**{r['speedup']:.2f}**"])  # fmt: skip
    if sweep_samples:
        sw = ab.ab_sweep(old_pkg, new_pkg, 3, sweep_samples, 1)
        AB_SPEEDUPS["sweep"] = sw["speedup"]
        label = f"sweep of paper_combined, {sweep_samples} samples × 2 variants, 1 job [s]"
        rows.append([label, f"{sw['old']:.1f}", f"{sw['new']:.1f}", f"**{sw['speedup']:.2f}**"])
    return [
        "## Against the previous version (old / new in one process)",
        "",
        f"The old package (version {version}, from `--old OLD_DIR`"
        + (f", source `{source}`" if source else "")
        + ": a `git archive` of the older "
        "commit with its `hmpc_pin` folder renamed `hmpc_pin_old`, see `benchmarks/tools/ab.py`) "
        "and this one, alternating "
        "in one process (`benchmarks/tools/ab.py`): the 10 s run 9 rounds each, the steps 10 "
        "blocks each along the step benchmark's states, the sweep (`run_sweep`, jobs = 1, "
        "so that both run in this process) 3 rounds each. "
        "Speed-up = median over rounds of old / new.",
        "",
        table(["", "old", "new", "speed-up (old / new)"], rows),
        "",
    ]


def per_unit(us: float, unit: float) -> str:
    """A duration [µs] in floor units."""
    x = us / unit
    return f"{x:.2f}" if x < 10 else f"{x:.0f}" if x < 1e4 else f"{x:.3g}"


def floor_table(steps: list[StepResult]) -> str:
    """Step and floor per case, alternating blocks, median of the ratios."""
    rows = [
        [
            r.arm,
            str(r.Nc),
            fmt_us(r.floor.step_median_us),
            fmt_us(r.floor.floor_median_us),
            f"**{r.floor.ratio:.2f}**",
            f"{r.floor.ratios.min():.2f}–{r.floor.ratios.max():.2f}",
            str(len(r.floor.ratios)),
        ]
        for r in steps
        if r.floor is not None
    ]
    headers = ["arm", "Nc", "step [µs]", "floor [µs]", "step / floor (median of blocks)",
               "range over blocks", "blocks"]  # fmt: skip
    return table(headers, rows)


def alternated_table(a: Alternated, unit: float) -> str:
    """Median per variant, ratio to the base variant and to the floor unit."""
    rows = [
        [name, fmt_us(a.median_us(name)), f"{a.ratio(name):.2f}", per_unit(a.median_us(name), unit)]
        for name in a.blocks_us
    ]
    headers = ["variant", "median step [µs]", f"ratio to {a.base}", "in floor units"]
    return table(headers, rows)


def round2_targets(steps: list[StepResult], sim: SimResult, r2: Round2) -> str:
    """The issue-18 targets with the measured ratios and a verdict each."""
    rows = []
    for arm in ("planar3", "panda"):
        r = find_step(steps, arm, 1)
        if r is not None and r.floor is not None:
            rows.append([f"`step`, {arm}, Nc = 1: step / floor", "≤ 1.5",
                         f"{r.floor.ratio:.2f}", verdict(r.floor.ratio <= 1.5)])  # fmt: skip
    long = r2.long.ratio("N = Nc = 100, auto")
    rows.append(["Panda, Ts = 1 ms, N = Nc = 100 (auto layout) / N = 100, Nc = 1", "≤ 6",
                 f"{long:.2f}", verdict(long <= 6.0)])  # fmt: skip
    bench = (
        r2.long.blocks_us["N = Nc = 100, auto"]
        / r2.long.blocks_us["benchmark step (Ts = 10 ms, N = 10, Nc = 1)"]
    )
    rows.append(["the same / the benchmark's Panda step (Ts = 10 ms, N = 10, Nc = 1)", "≤ 6",
                 f"{np.median(bench):.2f}", verdict(np.median(bench) <= 6.0)])  # fmt: skip
    for arm, a in r2.refs.items():
        q = a.ratio("QuinticReference (vectorised)")
        rows.append([f"{arm}: step with the vectorised quintic / with the sine", "≤ 1.15",
                     f"{q:.2f}", verdict(q <= 1.15)])  # fmt: skip
    rows.append(["paper 10 s run, real-time factor (absolute, this machine)",
                 "≥ 100", f"{sim.rtf:.0f}", verdict(sim.rtf >= 100)])  # fmt: skip
    if "run" in AB_SPEEDUPS:
        rows.append(["paper 10 s run, old / this code in one process (`--old`)", "≥ 3",
                     f"{AB_SPEEDUPS['run']:.2f}", verdict(AB_SPEEDUPS["run"] >= 3.0)])  # fmt: skip
    if "sweep" in AB_SPEEDUPS:
        rows.append(["sweep, old / this code in one process (1 job)", "≥ 2.5",
                     f"{AB_SPEEDUPS['sweep']:.2f}",
                     verdict(AB_SPEEDUPS["sweep"] >= 2.5)])  # fmt: skip
    return table(["target", "target", "measured", "verdict"], rows)


def report(
    settings: Settings,
    quick: bool,
    command: str,
    info: dict,
    versions: dict,
    steps: list[StepResult],
    chains: list[StepResult],
    layouts: list[LayoutTiming],
    sim: SimResult,
    mem: MemoryResult,
    compares: list[tuple[Scenario, float, list[CompareRow]]],
    spatial_kind: str,
    total: float,
    r2: Round2,
    peers_part: PeersPart | None = None,
) -> str:
    """The Markdown report."""
    unit = r2.unit
    rss_first = mem.soak_rss[0] / MiB
    soak = mem.soak
    soak_rows = [[f"{t:g}", f"{rss / MiB:.2f}"] for t, rss in soak["samples"]]
    lines = [
        "# Benchmarks",
        "",
        "Generated by `benchmarks/run.py`. "
        + ("**Quick run (`--quick`): short runs, numbers not to be quoted.** " if quick else "")
        + f"Total benchmark time {total:.0f} s.",
        "",
        "Rerun, from the repository root in the project's environment:",
        "",
        "```bash",
        'pip install -e ".[bench]"    # optional: CasADi and Crocoddyl, for the peers',
        command,
        "```",
        "",
        "## Machine and versions",
        "",
        table(["", ""], [[k, v] for k, v in info.items()] + [[k, v] for k, v in versions.items()]),
        "",
        "Timings are wall-clock (`time.perf_counter_ns` around each call, garbage collector "
        "enabled), on the machine of the table above; the ratios below are what carries "
        "to another machine.",
        "",
        "**Figures that travel between machines.** Absolute times depend on the machine and "
        "on its load; ratios measured in one process do not, much. The *floor* of a step is "
        "what it cannot avoid calling: Pinocchio's `crba` and `nonLinearEffects` at the "
        "measured state plus one warm-started ProxSuite box QP `update` + `solve` of the same "
        "size (n·Nc variables, the package's settings, the gradients the step computes along "
        "the same states), back to back in one function (`benchmarks/floor.py`). Step and "
        "floor are timed in alternating blocks over the same states, and the ratio is the "
        "median over blocks of (median step / median floor). The *floor unit* of this report "
        f"is the floor of planar3 at Nc = 1: **{unit:.2f} µs** in this run; every other "
        "timing is also given in floor units (time / floor unit).",
        "",
        "## Targets",
        "",
        "### Ratios",
        "",
        round2_targets(steps, sim, r2),
        "",
        "### Absolute, on this machine",
        "",
        targets_section(steps, sim, mem),
        "",
        "## Step against its floor",
        "",
        "Each arm's step (the table below) and its floor in alternating blocks "
        f"({settings.floor_blocks} blocks of up to {settings.floor_steps} states after "
        f"{settings.warmup} untimed warm-up steps).",
        "",
        floor_table(steps),
        "",
        "The floor calls Pinocchio and ProxSuite from Python (four calls through their "
        "bindings). The step (the compiled core `hmpc_pin._core`, built with the package) is "
        "one call into C++ that samples the reference, computes the gradients, M, C q̇ + G, "
        "the observer, the QPs and the joint-limit test there: it can cost less than the "
        "floor. The former Python step (about 30 numpy calls around the floor's calls) took "
        "4.5–5.2 floors (BENCHMARKS.md of `c3d49fe`).",
        "",
        "## Controller step (`HierarchicalMPC.step`)",
        "",
        f"Dynamics (M, C q̇ + G), observer, every joint QP, for each arm tracking "
        f"{AMPLITUDE:g} rad, {FREQUENCY:g} Hz sines around a home pose inside its limits "
        f"(planar3 {HOMES['planar3']}, UR5 {HOMES['ur5']}, Panda {HOMES['panda']}; Panda's "
        f"fingers locked at 0). The paper's controller otherwise: Ts = 10 ms, N = 10, "
        f"Q = diag(50, 0), R = 1e-6, P = 2Q, |v| ≤ 100, joint limits as soft state "
        f"constraints (the default). Observer: `chen` on planar arms, `{spatial_kind}` "
        f"(Y = I) on UR5 and Panda. The states replayed through `step` were recorded from "
        f"a closed-loop run of the same controller (Nc = 1, 1 ms RK4 plant, no "
        f"disturbance, from rest on r(0)), so the warm starts see what they see in a run; "
        f"{settings.warmup} warm-up steps along the same trajectory, then "
        f"{settings.steps} timed steps, one sample each.",
        "",
        step_table(steps, unit),
        "",
        "## Long horizons (Panda, Ts = 1 ms, N = Nc = 100)",
        "",
        'The QP layout is chosen by size (`controller.qp_layout = "auto"`, the default: '
        "one block-diagonal QP up to n·Nc = 140 variables, one QP per joint above; "
        "`hmpc_pin.mpc.condensed.resolve_layout`). Panda at Ts = 1 ms with N = Nc = 100 "
        f"({r2.long.note}), with the block QP forced, against N = 100 with Nc = 1 and against "
        "the step benchmark's Panda controller (Ts = 10 ms, N = 10, Nc = 1); states: the "
        "0.3 rad sine around home sampled every 1 ms (the reference itself), "
        f"{r2.long.steps} timed steps per block, {len(next(iter(r2.long.blocks_us.values())))} "
        "alternating blocks. Largest difference of the commanded accelerations v between "
        f"the auto and the block layout along the same states: {r2.long_diff:.1e} rad/s² "
        "(solver tolerance).",
        "",
        alternated_table(r2.long, unit),
        "",
        "On these states every joint's unconstrained minimiser −H⁻¹g lies inside its box, so "
        "the per-joint layout takes it without a ProxSuite call (exact for a convex QP). "
        "With the bounds active ProxSuite solves each 100-variable QP, at milliseconds per "
        'step: `python benchmarks/studies/long_horizon_active.py` (section "Long horizons with '
        'active constraints" below).',
        "",
        "A run whose median step exceeds Ts/2 says so: `simulate` attaches the step times to "
        "the result (`result.step_time`, not saved: a run's files stay bit-identical) and a "
        'warning to `result.meta["warnings"]`, which `hmpc-pin run` prints.',
        "",
        "## References",
        "",
        "The step (Nc = 1, the paper's controller) with the `SineReference`, a vectorised "
        "`QuinticReference` (home − 0.3 rad to home + 0.3 rad over 30 s), the sine behind an "
        "object with only `sample(t)` (adapted point by point: N = 10 calls per step), and "
        "the sine's `sample` as a plain callable; each on the states of its own closed-loop "
        f"run; {settings.ratio_steps} timed steps per block, {settings.ratio_blocks} "
        "alternating blocks.",
        "",
    ]
    for name, a in r2.refs.items():
        lines += [f"### {name}", "", alternated_table(a, unit), ""]
    lines += r2.ab
    lines += [
        "## Step time against the number of joints",
        "",
        "Planar chains of n uniform rods (1 kg/m, 3.7 m total reach like planar3, axes "
        "(0, −1, 0), limits ±π/2, effort 1e4, velocity 100), generated and written with "
        "yourdfpy (`benchmarks/chains.py`), `chen` observer; same reference, settings and "
        "method as above; UR5 and Panda from the table above.",
        "",
        scaling_table(chains, steps, unit),
        "",
        "## Joint QPs: one block-diagonal QP, n QPs, ProxSuite BatchQP",
        "",
        "The n box-constrained joint QPs of one step (no state limits), solved on the "
        "gradient sequence of the step benchmark's states (`benchmarks/qp_layouts.py`): "
        "`block`, one block-diagonal ProxSuite dense QP of n·Nc variables, one `update` + "
        '`solve` (the default, `controller.qp_layout = "block"`); `joint`, one QP per '
        'joint (`"joint"`); `BatchQP`, `proxqp.dense.BatchQP` with one QP per joint '
        "(bounds as Nc inequality rows: `init_qp_in_place` has no box option), n `update` "
        "calls and one `solve_in_parallel` with 1 or 2 OpenMP threads. Same solver settings, "
        "warm-started; median per step of the solver calls alone, the ways alternating in "
        f"{layouts[0].blocks if layouts else 0} blocks over the whole sequence (ratio to "
        "`block`: median over blocks of the per-block ratio); the last column is the "
        "largest difference of the solutions from the block QP's over the last 50 steps "
        "(solver tolerance). With two OpenMP threads on two cores a solve is fast only while "
        "the worker thread's core is free: its median depends on what else holds the "
        "cores, so the BatchQP rows are not a figure of the solver.",
        "",
        layout_table(layouts, unit),
        "",
        "## Closed-loop simulation of the paper's combined scenario",
        "",
        "`hmpc_pin.experiment.build.Experiment.from_config(load_config("
        '"configs/paper_combined.toml")).run()`: 10 s simulated, controller every 10 ms, '
        f"plant RK4 at 1 ms (40 ABA calls and 10 disturbance evaluations per period). "
        f"{settings.sim_repeats} repetition(s).",
        "",
        table(
            ["", "median [s]", "min [s]", "max [s]", "median in floor units"],
            [
                [
                    "`run()` wall time",
                    f"{sim.median:.3f}",
                    f"{min(sim.run):.3f}",
                    f"{max(sim.run):.3f}",
                    per_unit(sim.median * 1e6, unit),
                ],
                [
                    "the same simulation with τ = G(q) instead of the MPC (plant, "
                    "disturbance, loop)",
                    f"{np.median(sim.plant_only):.3f}",
                    f"{min(sim.plant_only):.3f}",
                    f"{max(sim.plant_only):.3f}",
                    per_unit(float(np.median(sim.plant_only)) * 1e6, unit),
                ],
                [
                    "the plant alone over the 1000 periods (native kernel; for the Python plant "
                    "its 40 000 bare `pin.aba` calls)",
                    f"{np.median(sim.aba_only):.3f}",
                    f"{min(sim.aba_only):.3f}",
                    f"{max(sim.aba_only):.3f}",
                    per_unit(float(np.median(sim.aba_only)) * 1e6, unit),
                ],
                [
                    "`Experiment.from_config` (robot load, limit checks)",
                    f"{np.median(sim.build):.3f}",
                    f"{min(sim.build):.3f}",
                    f"{max(sim.build):.3f}",
                    per_unit(float(np.median(sim.build)) * 1e6, unit),
                ],
            ],
        ),
        "",
        f"Real-time factor (10 s / median `run()` wall time): **{sim.rtf:.1f}**; "
        f"run completed: {'yes' if sim.complete else 'no'}. The plant alone takes "
        f"{np.median(sim.aba_only) / sim.median:.0%} of the run (its 40 ABA evaluations per "
        "period are Pinocchio's C++ ABA, ≈ 1.1 µs each here): the real-time factor stays "
        f"below 10 s / that time ≈ {sim.duration / np.median(sim.aba_only):.0f} whatever "
        "else is made faster.",
        "",
        "## Memory",
        "",
        "Each figure from a fresh Python process (`python -m benchmarks.memory`) that loads "
        "the paper config, builds the experiment and runs it.",
        "",
        table(
            ["10 s paper run", "RSS [MiB]"],
            [
                ["after `import hmpc_pin`", f"{mem.peak['rss_imports'] / MiB:.1f}"],
                [
                    "after `load_config` + `Experiment.from_config`",
                    f"{mem.peak['rss_setup'] / MiB:.1f}",
                ],
                ["**peak** (`VmHWM`, whole process)", f"**{mem.peak['peak_rss'] / MiB:.1f}**"],
            ],
        ),
        "",
        f"Soak: `Experiment.run(duration={soak['duration']:g}, on_step=...)`, RSS read from "
        f"`/proc/self/statm` in the `on_step` callback at t = 0 and every "
        f"{settings.soak_every:g} simulated seconds (wall time {soak['wall']:.1f} s, "
        f"completed: {'yes' if soak['complete'] else 'no'}). The `Result` arrays are "
        "allocated once at the start of the run.",
        "",
        table(["simulated time [s]", "RSS [MiB]"], soak_rows),
        "",
        f"First {rss_first:.2f} MiB, last {mem.soak_rss[-1] / MiB:.2f} MiB, max "
        f"{mem.soak_rss.max() / MiB:.2f} MiB; growth after the first interval "
        f"{mem.soak_growth / MiB:+.2f} MiB; peak RSS of that process "
        f"{soak['peak_rss'] / MiB:.1f} MiB.",
        "",
        "## Comparison with a centralized linear MPC and a Crocoddyl nonlinear MPC",
        "",
        "Same arm, reference, disturbance, horizon (N = 10, Ts = 10 ms) and plant (1 ms RK4, "
        "plant clips τ to the URDF effort limits); each controller in one closed-loop run "
        "through `hmpc_pin.sim.simulate`, its `step` timed in the loop (first 10 steps left "
        "out). The runs are made one after the other in this process, not alternated: their "
        "step ratios carry the machine's phases (the section \"Peers\" times Crocoddyl's step "
        "against the package's in alternating blocks). "
        "Ratios are to the hierarchical MPC with its observer (`hmpc`); the last "
        "RMS ratio is to `hmpc, no NDO`, since neither comparison controller has a "
        "disturbance observer.",
        "",
        "- `hmpc`: `HierarchicalMPC` with the scenario's config; `hmpc, no NDO`: the same "
        "with `observer.enabled = false`; `hmpc, no NDO, Nc = N`: also with every input of "
        "the horizon free, as Crocoddyl's (FDDP has no move blocking).",
        "- `centralized` (`benchmarks/centralized.py`): one ProxSuite dense QP over the 2n "
        "states and n·Nc torques per step; dynamics linearised at the measured state and "
        "the previous torque (Pinocchio `computeABADerivatives`), exact zero-order-hold "
        "discretisation (matrix exponential), frozen over the horizon, condensed; the same "
        "Q, P (per joint, stacked) and R (on v = M⁻¹(τ − C q̇ − G)); the acceleration "
        "bounds |v| ≤ 100 as n·Nc general constraints on τ through τ = M v + C q̇ + G at "
        "the current state, and the URDF effort limits as a box on τ; warm-started, H, g "
        "and constraints updated every step; no state (joint-limit) constraints, no "
        "observer.",
        "- `crocoddyl` (`benchmarks/crocoddyl_mpc.py`): `SolverBoxFDDP` on the full "
        "nonlinear model (`DifferentialActionModelFreeFwdDynamics`, Euler at Ts), "
        f"at most {settings.crocoddyl_iterations} iterations per step, warm-started from the "
        "shifted previous solution; diagonal Q, P as the state weights, R as a "
        "regularisation of τ − G(r_j); all N inputs free; URDF effort limits as control "
        "bounds; one thread; "
        "no acceleration bounds, no observer.",
        "",
    ]
    if not crocoddyl_mpc.AVAILABLE:
        lines += [f"The Crocoddyl comparison {peers.EXTRA_MESSAGE}: skipped.", ""]
    for scenario, duration, rows in compares:
        lines += [
            f"### {scenario.name} ({duration:g} s)",
            "",
            scenario.description + ".",
            "",
            compare_table(rows, scenario.effort_limit is not None, unit),
            "",
        ]
    if peers_part is not None:
        lines += peers_section(peers_part, settings)
    lines += [
        "## Method",
        "",
        "- Step: `benchmarks/harness.py` `time_calls`: `perf_counter_ns` before and after "
        "each call (its arguments built beforehand), median and 99th percentile (numpy "
        "`percentile`, linear) of the timed calls; warm-up calls untimed.",
        "- Controllers are built once per case; nothing in `hmpc_pin` is changed or tuned "
        "by the benchmark.",
        f"- Observer kinds accepted by this `hmpc_pin`: {', '.join(observer_kinds())}.",
        "- Ratios measured in one process with the variants alternating block by block: "
        "step / floor, long horizons, references, the A/B section, the joint-QP layouts "
        '(ratio to `block`) and the peers. Not alternated: the "floor units" columns '
        "(a time over the floor unit measured earlier in the same process), the closed-loop "
        "simulation's rows (one after the other) and the comparison's closed-loop runs "
        '(one after the other); absolute by definition: the targets "Absolute, on this '
        'machine" and the memory sizes. The sections measured by other programs state their '
        "own method; the figures they quote from an earlier version were measured in "
        "another process.",
        "",
        "## Measured by other programs",
        "",
        "The sections below are not rerun by `benchmarks/run.py`: each names the program, "
        "the command and the source it was measured with; the report copies them from "
        "`benchmarks/recorded.md`.",
        "",
    ]
    if RECORDED.is_file():
        lines += [RECORDED.read_text(encoding="utf-8").rstrip("\n"), ""]
    return "\n".join(lines)
