"""Comparisons on the same arm, reference, disturbance, horizon and plant: the hierarchical
MPC with and without its observer, a centralized linear MPC and a Crocoddyl NMPC."""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import hmpc_pin  # noqa: E402
from benchmarks import crocoddyl_mpc  # noqa: E402
from benchmarks._fixtures import (  # noqa: E402
    PAPER_CONFIG,
    Settings,
    log,
)
from benchmarks.centralized import CentralizedMPC  # noqa: E402
from benchmarks.harness import (  # noqa: E402
    TimedController,
    Timing,
)
from hmpc_pin.experiment.build import Experiment  # noqa: E402
from hmpc_pin.experiment.config import load_config  # noqa: E402


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
        log(
            '  crocoddyl is not installed (the extra "bench": pip install -e ".[bench]"): its '
            "comparison is skipped"
        )
    return rows
