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

``--quick`` shortens every run (fewer steps, shorter simulations, a 30 s soak) to check
that the suite works; its numbers are not meant to be quoted.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import hmpc_pin  # noqa: E402
from benchmarks import crocoddyl_mpc  # noqa: E402
from benchmarks.centralized import CentralizedMPC  # noqa: E402
from benchmarks.chains import write_planar_chain  # noqa: E402
from benchmarks.harness import (  # noqa: E402
    TimedController,
    Timing,
    machine_info,
    package_versions,
    time_calls,
)
from benchmarks.floor import FloorRatio, step_floor_ratio  # noqa: E402
from benchmarks.qp_layouts import LayoutTiming, record_gradients, time_layouts  # noqa: E402
from benchmarks.ratios import Alternated, aba_floor, long_horizon, references  # noqa: E402
from hmpc_pin.experiment.schema import load_config  # noqa: E402
from hmpc_pin.experiment.build import Experiment  # noqa: E402
from benchmarks._fixtures import (  # noqa: E402
    AMPLITUDE,
    FREQUENCY,
    GRAVITY,
    HOMES,
    PANDA_LOCKED,
    Arm,
    Trajectory,
    load_arm,
    log,
    observer_kinds,
    record_trajectory,
    spatial_observer_kind,
)

__all__ = ["Settings", "main"]

#: The paper's Section 5.3 scenario (friction + pulses, 10 s, planar3).
PAPER_CONFIG = ROOT / "configs" / "paper_combined.toml"
CHAIN_SIZES = (2, 3, 6, 7, 12)
MiB = 2**20


@dataclass(frozen=True)
class Settings:
    """Sizes of the runs (full or ``--quick``).

    Attributes:
        warmup: Untimed controller steps before the timed ones.
        steps: Timed controller steps per case.
        sim_repeats: Repetitions of the 10 s simulation (wall-time median over them).
        soak_duration: Simulated time of the memory soak [s].
        soak_every: RSS sampling period of the soak, simulated [s].
        compare_duration: Simulated time of each comparison run on planar3 [s].
        compare_panda_duration: The same on Panda [s] (0 skips Panda).
        crocoddyl_iterations: Crocoddyl's (Box-)FDDP iteration budget per step.
    """

    warmup: int = 200
    steps: int = 2000
    sim_repeats: int = 5
    soak_duration: float = 600.0
    soak_every: float = 60.0
    compare_duration: float = 10.0
    compare_panda_duration: float = 10.0
    crocoddyl_iterations: int = 3
    floor_blocks: int = 8
    floor_steps: int = 800
    ratio_blocks: int = 6
    ratio_steps: int = 600
    long_steps: int = 300


QUICK = Settings(
    warmup=20,
    steps=200,
    sim_repeats=1,
    soak_duration=30.0,
    soak_every=10.0,
    compare_duration=2.0,
    compare_panda_duration=2.0,
    floor_blocks=2,
    floor_steps=100,
    ratio_blocks=2,
    ratio_steps=100,
    long_steps=40,
)


# --------------------------------------------------------------------------- helpers
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


@dataclass
class StepResult:
    """Step timing of one (arm, Nc) case."""

    arm: str
    n: int
    Nc: int
    observer: str
    timing: Timing
    source: str
    floor: FloorRatio | None = None


def time_step(
    arm: Arm, Nc: int, trajectory: Trajectory, settings: Settings, floor: bool = False
) -> StepResult:
    """Time ``HierarchicalMPC.step`` along ``trajectory`` (warm-up, then timed steps); with
    ``floor``, also step and floor in alternating blocks (:mod:`benchmarks.floor`)."""
    ref = arm.reference()
    ctrl = hmpc_pin.make_controller(arm.robot, arm.config(Nc))
    tr = trajectory
    ctrl.reset(tr.q[0], tr.dq[0])
    count = settings.warmup + settings.steps
    calls = [(float(tr.t[i]), tr.q[i].copy(), tr.dq[i].copy(), ref) for i in range(count)]
    timing = time_calls(ctrl.step, calls, settings.warmup)
    ratio = None
    if floor:
        k = settings.warmup + min(settings.steps, settings.floor_steps)
        ratio = step_floor_ratio(ctrl, ref, tr.t[:k], tr.q[:k], tr.dq[:k],
                                 warmup=settings.warmup, blocks=settings.floor_blocks)  # fmt: skip
    return StepResult(arm.name, arm.n, Nc, arm.observer, timing, tr.source, ratio)


# ------------------------------------------------------------------------ benchmarks
def bench_steps(settings: Settings, arms: list[Arm], floor: bool = False) -> list[StepResult]:
    """Step time at Nc = 1 and 5 for every arm in ``arms`` (with ``floor``: and its ratio
    to the floor, alternating blocks)."""
    out = []
    for arm in arms:
        traj = record_trajectory(arm, settings.warmup + settings.steps)
        for Nc in (1, 5):
            r = time_step(arm, Nc, traj, settings, floor)
            extra = ""
            if r.floor is not None:
                extra = (f", floor {r.floor.floor_median_us:.1f} µs, step/floor "
                         f"{r.floor.ratio:.2f}")  # fmt: skip
            log(
                f"  step {arm.name:<10} n={arm.n:<2} Nc={Nc}: median {r.timing.median_us:7.1f} µs,"
                f" p99 {r.timing.p99_us:7.1f} µs{extra}"
            )
            out.append(r)
    return out


def bench_qp_layouts(settings: Settings, arms: list[Arm]) -> list[LayoutTiming]:
    """The joint QPs as one block QP, n QPs, and ProxSuite's BatchQP (``qp_layouts.py``),
    on the gradients of the step benchmark's closed-loop states, Nc = 1 and 5."""
    out = []
    for arm in arms:
        traj = record_trajectory(arm, settings.warmup + settings.steps)
        for Nc in (1, 5):
            ctrl = hmpc_pin.make_controller(arm.robot, arm.config(Nc))
            grads = record_gradients(ctrl, traj.t, traj.q, traj.dq, arm.reference())
            r = time_layouts(arm.name, ctrl, grads, settings.warmup)
            log(f"  QPs {arm.name:<10} Nc={Nc}: " + ", ".join(
                f"{k} {v:.1f} µs" for k, v in r.median_us.items()))  # fmt: skip
            out.append(r)
    return out


class GravityCompensation:
    """A near-free controller, :math:`\\tau = G(q)` [N·m], to time the plant and the
    simulation loop without the MPC (same interface as :class:`hmpc_pin.HierarchicalMPC`).

    Args:
        robot: The controller's model. Ts: Control period [s].
    """

    def __init__(self, robot: hmpc_pin.Robot, Ts: float):
        self.robot = robot
        self.Ts = Ts
        self.disturbance_estimate = np.zeros(robot.nq)

    def reset(self, q0: np.ndarray, dq0: np.ndarray) -> None:
        """Nothing to reset."""

    def step(self, t: float, q: np.ndarray, dq: np.ndarray, reference) -> np.ndarray:
        """Gravity torque at ``q`` [N·m]."""
        return self.robot.gravity_torque(q)


@dataclass
class SimResult:
    """Wall times of the paper's 10 s scenario [s].

    Attributes:
        build: ``Experiment.from_config`` wall times [s].
        run: ``Experiment.run()`` wall times [s].
        plant_only: The same simulation with :class:`GravityCompensation` instead of
            the MPC [s] (plant integration, disturbance and loop overhead).
        duration: Simulated time [s]. complete: Whether every run finished.
    """

    build: list[float]
    run: list[float]
    plant_only: list[float]
    duration: float
    complete: bool
    aba_only: list[float] = field(default_factory=list)

    @property
    def median(self) -> float:
        """Median wall time of ``run()`` [s]."""
        return float(np.median(self.run))

    @property
    def rtf(self) -> float:
        """Real-time factor: simulated time / median wall time."""
        return self.duration / self.median


def plant_floor(plant, periods: int) -> float:
    """Wall time [s] of the plant alone over ``periods`` control periods, τ = 0 held from
    rest at zero: the native plant's ``advance`` calls (kernel, disturbance table), or for
    the Python plant its ``4 · substeps · periods`` bare ``pin.aba`` calls."""
    if not getattr(plant, "native", False):
        return aba_floor(plant, 4 * plant.substeps * periods)
    n = plant.nq
    plant.reset(np.zeros(n), np.zeros(n))
    tau = np.zeros(n)
    start = time.perf_counter()
    for _ in range(periods):
        plant.advance(tau)
    return time.perf_counter() - start


def bench_simulation(settings: Settings) -> SimResult:
    """Wall time of ``Experiment.from_config(cfg)`` and of ``.run()`` on the paper scenario."""
    cfg = load_config(PAPER_CONFIG)
    build, run, plant_only, aba_only = [], [], [], []
    complete = True
    for _ in range(settings.sim_repeats):
        t0 = time.perf_counter()
        exp = Experiment.from_config(cfg)
        t1 = time.perf_counter()
        result = exp.run()
        t2 = time.perf_counter()
        build.append(t1 - t0)
        run.append(t2 - t1)
        complete &= bool(result.complete)
        t0 = time.perf_counter()
        replace(exp, controller=GravityCompensation(exp.robot, exp.controller.Ts)).run()
        plant_only.append(time.perf_counter() - t0)
        plant = exp.make_plant()
        periods = round(cfg.simulation.duration / exp.controller.Ts)
        aba_only.append(plant_floor(plant, periods))
    out = SimResult(build, run, plant_only, cfg.simulation.duration, complete, aba_only)
    log(
        f"  10 s simulation: median {out.median:.3f} s, real-time factor {out.rtf:.1f}; "
        f"with tau = G(q) instead of the MPC {np.median(plant_only):.3f} s"
    )
    return out


def run_memory_child(duration: float, every: float) -> dict:
    """Run ``benchmarks/memory.py`` in a fresh interpreter and return its JSON result."""
    cmd = [sys.executable, "-m", "benchmarks.memory", "--duration", str(duration)]
    cmd += ["--every", str(every)]
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{proc.stderr}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


@dataclass
class MemoryResult:
    """RSS figures [bytes] of the 10 s run and of the soak."""

    peak: dict
    soak: dict

    @property
    def soak_rss(self) -> np.ndarray:
        """Sampled RSS of the soak [bytes]."""
        return np.array([s[1] for s in self.soak["samples"]], dtype=float)

    @property
    def growth_start(self) -> float:
        """Simulated time of the sample the growth is measured from [s]: the second one
        (after the first interval, once every buffer of the run exists)."""
        samples = self.soak["samples"]
        return float(samples[min(1, len(samples) - 1)][0])

    @property
    def soak_growth(self) -> float:
        """RSS growth from the sample at :attr:`growth_start` to the last [bytes]."""
        rss = self.soak_rss
        return float(rss[-1] - rss[min(1, rss.size - 1)])


def bench_memory(settings: Settings) -> MemoryResult:
    """Peak RSS of the 10 s scenario and RSS over the soak, each in a fresh process."""
    peak = run_memory_child(10.0, 0.0)
    log(f"  peak RSS of the 10 s run: {peak['peak_rss'] / MiB:.1f} MiB")
    soak = run_memory_child(settings.soak_duration, settings.soak_every)
    out = MemoryResult(peak, soak)
    rss = out.soak_rss / MiB
    log(
        f"  soak {settings.soak_duration:g} s: RSS first {rss[0]:.1f}, last {rss[-1]:.1f}, "
        f"max {rss.max():.1f} MiB"
    )
    return out


# ----------------------------------------------------------------------- comparisons
@dataclass
class Scenario:
    """One arm's closed-loop comparison setting."""

    name: str
    robot: hmpc_pin.Robot
    plant: hmpc_pin.Robot
    config: hmpc_pin.ControllerConfig
    reference: object
    disturbance: hmpc_pin.Disturbance
    q0: np.ndarray
    dq0: np.ndarray
    effort_limit: np.ndarray | None
    dt: float
    integrator: str
    description: str


def config_scenario(name: str, path: Path, description: str) -> Scenario:
    """The comparison setting of an experiment config, built by ``Experiment.from_config``
    (robot, plant, reference, disturbance, effort limits exactly as ``hmpc-pin run``)."""
    cfg = load_config(path)
    exp = Experiment.from_config(cfg)
    return Scenario(
        name=name,
        robot=exp.robot,
        plant=exp.plant,
        config=cfg.controller,
        reference=exp.reference,
        disturbance=exp.disturbance,
        q0=exp.q0,
        dq0=exp.dq0,
        effort_limit=exp.effort_limit,
        dt=cfg.plant.dt,
        integrator=cfg.plant.integrator,
        description=description,
    )


def planar3_scenario() -> Scenario:
    """The paper's Section 5.3 scenario from ``configs/paper_combined.toml``."""
    return config_scenario(
        "planar3",
        PAPER_CONFIG,
        "configs/paper_combined.toml: sine 1 rad, 0.1 Hz, q0 = (1, 1, 1), "
        "friction + Gaussian pulses (Eq 34), N = 10, Nc = 1, Ts = 10 ms",
    )


def panda_scenario() -> Scenario:
    """Panda from ``configs/panda_sine.toml``: 0.3 rad, 0.1 Hz sines around the home pose,
    friction (2, 0.5) and pulses (1 at 1..7 s, σ = 0.3 s), each × :math:`M_{ii}(q_0)`."""
    return config_scenario(
        "panda",
        ROOT / "configs" / "panda_sine.toml",
        "configs/panda_sine.toml: sine 0.3 rad, 0.1 Hz around the home pose, from rest on "
        "r(0), friction (2, 0.5) + pulses (1 at t = 1..7 s) × M_ii(q0), fingers locked at "
        "0.02, N = 10, Nc = 1, Ts = 10 ms, observer 'general'",
    )


@dataclass
class CompareRow:
    """One controller's closed-loop run."""

    controller: str
    timing: Timing | None
    rms: np.ndarray | None
    peak_ratio: float | None
    saturated_steps: int | None
    complete: bool
    message: str = ""
    extra: dict = field(default_factory=dict)


def run_compare(
    scenario: Scenario, name: str, make: Callable[[], object], duration: float
) -> CompareRow:
    """Run ``make()`` in closed loop on ``scenario`` for ``duration`` [s] and measure it."""
    try:
        ctrl = make()
    except Exception as exc:  # a comparison that cannot be built is reported, not fatal
        return CompareRow(name, None, None, None, None, False, f"not built: {exc}")
    timed = TimedController(ctrl)
    message = ""
    try:
        result = hmpc_pin.simulate(
            scenario.robot,
            timed,
            scenario.reference,
            scenario.disturbance,
            duration=duration,
            q0=scenario.q0,
            dq0=scenario.dq0,
            plant=scenario.plant,
            dt=scenario.dt,
            integrator=scenario.integrator,
            effort_limit=scenario.effort_limit,
        )
    except hmpc_pin.SimulationError as exc:
        result = exc.result
        message = str(exc)
    skip = min(10, max(0, len(timed.samples_ns) - 1))
    timing = timed.timing(skip) if timed.samples_ns else None
    rms = None
    if result is not None and result.t.size and result.t[-1] >= 1.0:
        rms = hmpc_pin.compute_metrics(result, after=1.0).rms_error
    elif result is not None and result.t.size:
        rms = np.sqrt(np.mean(result.error**2, axis=0))
        message = message or "run shorter than 1 s: RMS over the whole run"
    peak_ratio = sat = None
    if result is not None and scenario.effort_limit is not None and result.t.size:
        lim = np.asarray(scenario.effort_limit, dtype=float)
        peak_ratio = float(np.max(np.abs(result.tau) / lim))
        sat = int(np.sum(result.meta.get("saturation", {}).get("steps", [0])))
    extra = {}
    if isinstance(ctrl, crocoddyl_mpc.CrocoddylMPC):
        extra["iterations"] = ctrl.budget
    row = CompareRow(name, timing, rms, peak_ratio, sat, message == "", message, extra)
    med = f"{timing.median_us:.0f} µs" if timing else "n/a"
    worst = f"{rms.max():.2e} rad" if rms is not None else "n/a"
    log(
        f"  {scenario.name}/{name}: step median {med}, worst RMS {worst}"
        + (f" ({message})" if message else "")
    )
    return row


def bench_compare(scenario: Scenario, duration: float, settings: Settings) -> list[CompareRow]:
    """hmpc (NDO on/off), centralized and Crocoddyl on ``scenario`` for ``duration`` [s]."""
    cfg = scenario.config
    robot = scenario.robot
    no_ndo = replace(cfg, compensation="none", observer=None)  # hmpc x none
    # Crocoddyl optimises all N inputs (no move blocking): the hierarchical MPC with Nc = N
    # (no observer) separates that from the nonlinear model in the tracking comparison.
    no_ndo_full = replace(no_ndo, Nc=cfg.N)
    rows = [
        run_compare(scenario, "hmpc", lambda: hmpc_pin.make_controller(robot, cfg), duration),
        run_compare(
            scenario, "hmpc, no NDO", lambda: hmpc_pin.make_controller(robot, no_ndo), duration
        ),
        run_compare(
            scenario,
            f"hmpc, no NDO, Nc = N = {cfg.N}",
            lambda: hmpc_pin.make_controller(robot, no_ndo_full),
            duration,
        ),
        run_compare(scenario, "centralized", lambda: CentralizedMPC(robot, cfg), duration),
    ]
    if crocoddyl_mpc.AVAILABLE:
        rows.append(
            run_compare(
                scenario,
                "crocoddyl",
                lambda: crocoddyl_mpc.CrocoddylMPC(robot, cfg, settings.crocoddyl_iterations),
                duration,
            )
        )
    else:
        log("  crocoddyl is not installed (pip install crocoddyl): its comparison is skipped")
    return rows


# --------------------------------------------------------------------------- report
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
    return table(["target (issue 6)", "target", "measured", "verdict"], rows)


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
    """Table of the joint-QP layout timings [µs] (floor units in brackets)."""
    names = list(layouts[0].median_us) if layouts else []
    headers = ["arm", "n", "Nc", *(f"{k} [µs] (floor units)" for k in names),
               "largest |Δv| vs block"]  # fmt: skip
    rows = [
        [
            r.arm,
            str(r.n),
            str(r.Nc),
            *(f"{fmt_us(r.median_us[k])} ({per_unit(r.median_us[k], unit)})" for k in names),
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


#: Speed-ups measured by :func:`bench_ab` (for the targets table): "run", "sweep".
AB_SPEEDUPS: dict[str, float] = {}


def bench_ab(old: Path, settings: Settings, sweep_samples: int, quick: bool) -> list[str]:
    """Old vs new in one process, alternating (``benchmarks/ab.py``): the report lines."""
    from benchmarks import ab

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
        f"The old package (version {version}, from `--old {old}`: a `git archive` of the older "
        "commit with its `hmpc_pin` folder renamed `hmpc_pin_old`, see `benchmarks/ab.py`) "
        "and this one, alternating "
        "in one process (`benchmarks/ab.py`): the 10 s run 9 rounds each, the steps 10 "
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
    bench = r2.long.blocks_us["N = Nc = 100, auto"] / r2.long.blocks_us[
        "benchmark step (Ts = 10 ms, N = 10, Nc = 1)"]
    rows.append(["the same / the benchmark's Panda step (Ts = 10 ms, N = 10, Nc = 1)", "≤ 6",
                 f"{np.median(bench):.2f}", verdict(np.median(bench) <= 6.0)])  # fmt: skip
    for arm, a in r2.refs.items():
        q = a.ratio("QuinticReference (vectorised)")
        rows.append([f"{arm}: step with the vectorised quintic / with the sine", "≤ 1.15",
                     f"{q:.2f}", verdict(q <= 1.15)])  # fmt: skip
    rows.append(["paper 10 s run, real-time factor (absolute: depends on the machine's phase)",
                 "≥ 100", f"{sim.rtf:.0f}", verdict(sim.rtf >= 100)])  # fmt: skip
    if "run" in AB_SPEEDUPS:
        rows.append(["paper 10 s run, old / this code in one process (`--old`)", "≥ 3",
                     f"{AB_SPEEDUPS['run']:.2f}", verdict(AB_SPEEDUPS["run"] >= 3.0)])  # fmt: skip
    if "sweep" in AB_SPEEDUPS:
        rows.append(["sweep, old / this code in one process (1 job)", "≥ 2.5",
                     f"{AB_SPEEDUPS['sweep']:.2f}", verdict(AB_SPEEDUPS["sweep"] >= 2.5)])  # fmt: skip
    return table(["target (issue 18)", "target", "measured", "verdict"], rows)


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
) -> str:
    """The Markdown report."""
    unit = r2.unit
    rss_first = mem.soak_rss[0] / MiB
    soak = mem.soak
    soak_rows = [[f"{t:g}", f"{rss / MiB:.2f}"] for t, rss in soak["samples"]]
    lines = [
        "# Benchmarks",
        "",
        "Generated by `benchmarks/run.py` (issue 6). "
        + ("**Quick run (`--quick`): short runs, numbers not to be quoted.** " if quick else "")
        + f"Total benchmark time {total:.0f} s.",
        "",
        "Rerun, from the repository root in the project's environment:",
        "",
        "```bash",
        "pip install crocoddyl        # optional: the Crocoddyl comparison is skipped without it",
        command,
        "```",
        "",
        "## Machine and versions",
        "",
        table(["", ""], [[k, v] for k, v in info.items()] + [[k, v] for k, v in versions.items()]),
        "",
        "Timings are wall-clock (`time.perf_counter_ns` around each call, garbage collector "
        "enabled), on a shared 2-core machine: other processes (tests, builds) add noise, "
        "mostly to the 99th percentiles.",
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
        "### Issue 18 (ratios)",
        "",
        round2_targets(steps, sim, r2),
        "",
        "### Issue 6 (absolute, on this machine)",
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
        "bindings). The step (native backend, the default where it builds: "
        "`hmpc_pin/native`) is one call into C++ that samples the reference, computes "
        "the gradients, M, C q̇ + G, the observer, the QPs and the joint-limit test there: "
        "it can cost less than the floor. With `backend = \"python\"` the same step is about "
        "30 numpy calls around the floor's calls, 4.5–5.2 floors (BENCHMARKS.md of "
        "`c3d49fe`).",
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
        "The QP layout is chosen by size (`controller.qp_layout = \"auto\"`, the default: "
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
        "step: `python benchmarks/long_horizon_active.py` (section \"Long horizons with "
        "active constraints\" below).",
        "",
        "A run whose median step exceeds Ts/2 says so: `simulate` attaches the step times to "
        "the result (`result.step_time`, not saved: a run's files stay bit-identical) and a "
        "warning to `result.meta[\"warnings\"]`, which `hmpc-pin run` prints.",
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
        "warm-started; median per step of the solver calls alone; the last column is the "
        "largest difference of the solutions from the block QP's over the last 50 steps "
        "(solver tolerance). Two OpenMP threads on this shared 2-core machine: about "
        "10–17 µs per solve while the second core is free, but ≈ 8 ms whenever the worker "
        "thread must be woken while another process holds that core (the median is one or "
        "the other depending on the load during the run).",
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
        "out). Ratios are to the hierarchical MPC with its observer (`hmpc`); the last "
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
        lines += ["Crocoddyl is not installed: its comparison was skipped.", ""]
    for scenario, duration, rows in compares:
        lines += [
            f"### {scenario.name} ({duration:g} s)",
            "",
            scenario.description + ".",
            "",
            compare_table(rows, scenario.effort_limit is not None, unit),
            "",
        ]
    lines += [
        "## Method",
        "",
        "- Step: `benchmarks/harness.py` `time_calls`: `perf_counter_ns` before and after "
        "each call (its arguments built beforehand), median and 99th percentile (numpy "
        "`percentile`, linear) of the timed calls; warm-up calls untimed.",
        "- Controllers are built once per case; nothing in `hmpc_pin` is changed or tuned "
        "by the benchmark.",
        f"- Observer kinds accepted by this `hmpc_pin`: {', '.join(observer_kinds())}.",
        "",
    ]
    return "\n".join(lines)


# ----------------------------------------------------------------------------- main
def main(argv: list[str] | None = None) -> int:
    """Run the benchmarks and write the report; returns the exit code (0)."""
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
        "new timings in one process (benchmarks/ab.py)",
    )
    parser.add_argument(
        "--ab-sweep-samples",
        type=int,
        default=0,
        help="with --old: also time the README's sweep (this many samples, in this process, "
        "3 rounds), old and new",
    )
    args = parser.parse_args(argv)
    settings = QUICK if args.quick else Settings()
    command = "python benchmarks/run.py" + (" --quick" if args.quick else "")
    if args.out.resolve() != (ROOT / "BENCHMARKS.md").resolve():
        command += f" --out {args.out}"
    start = time.perf_counter()
    info = machine_info()
    info["hmpc_pin source (git)"] = git_state()
    versions = package_versions(("pin", "proxsuite", "numpy", "crocoddyl", "hmpc_pin"))
    if not crocoddyl_mpc.AVAILABLE:
        versions["crocoddyl"] = "not importable: comparison skipped"

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
    ab_lines: list[str] = []
    if args.old is not None:
        log("old vs new (benchmarks/ab.py)")
        ab_lines = bench_ab(args.old, settings, args.ab_sweep_samples, args.quick)
        command += f" --old {args.old}" + (
            f" --ab-sweep-samples {args.ab_sweep_samples}" if args.ab_sweep_samples else "")
    total = time.perf_counter() - start
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
    )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text, encoding="utf-8")
    log(f"wrote {args.out} ({total:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
