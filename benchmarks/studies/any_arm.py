"""Every fixed-base example-robot-data arm through ``hmpc-pin init`` then a run (issue 15).

For each model (the 31 fixed-base models ``example-robot-data-loaders`` lists, plus so100
and so101): ``hmpc-pin init NAME --out DIR/NAME.toml`` (the CLI, in-process), then the
experiment of that file run as ``hmpc-pin run`` runs it, with the controller's step
timed. A model *tracks* when the run completes, the worst joint's RMS error after 1 s is
at most 5e-3 (rad or m) and no position limit in force is exceeded by more than 1e-3; a
model refused with exit 2 (bad input) is *out of scope* and its one-line message is kept.

The step median [µs] is given beside a floor measured in the same process on the same
model: the median of ``pin.crba`` + ``pin.nonLinearEffects`` (the inverse dynamics the step
needs anyway), so ``step / floor`` is the MPC and observer overhead.

Usage::

    python -m benchmarks.studies.any_arm --out out/any_arm            # full table (10 s runs)
    python -m benchmarks.studies.any_arm --duration 2 --models ur5,kinova
"""

from __future__ import annotations

import argparse
import atexit
import contextlib
import functools
import io
import re
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

RMS_TARGET = 5e-3
LIMIT_TOL = 1e-3
EXTRA = ("so100", "so101")


def models() -> tuple[str, ...]:
    """The 31 fixed-base example-robot-data models and so100, so101 (which
    :func:`~hmpc_pin.model.catalogue.example_robot_names` lists too: each once)."""
    from hmpc_pin.model.catalogue import example_robot_names

    return tuple(dict.fromkeys((*example_robot_names(), *EXTRA)))


def _floor_us(robot, q, dq, repeats: int = 300) -> float:
    """Median time [µs] of ``pin.crba`` + ``pin.nonLinearEffects`` at (q, dq)."""
    model, data = robot.model, robot.data
    samples = []
    for _ in range(repeats):
        start = time.perf_counter_ns()
        pin.crba(model, data, q)
        pin.nonLinearEffects(model, data, q, dq)
        samples.append(time.perf_counter_ns() - start)
    return float(np.median(samples)) / 1e3


def run_model(name: str, out: Path, duration: float | None = None) -> dict:
    """``init`` then run one model; a row of the table."""
    from hmpc_pin.apps.cli import main
    from hmpc_pin.controllers.wrappers import TimedController
    from hmpc_pin.exceptions import HmpcError, SimulationError
    from hmpc_pin.experiment.build import Experiment
    from hmpc_pin.experiment.config import load_config

    path = out / f"{name}.toml"
    row: dict = {"model": name}
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main(["init", name, "--out", str(path), "--force", "--duration", "10"])
    if code != 0:
        lines = [x for x in err.getvalue().splitlines() if not x.startswith("warning: ")]
        text = lines[-1] if lines else ""  # the error line (warnings, e.g. of inertias, before)
        why = re.sub(r"/\S+/(\S+\.urdf)", r"\1", text.strip().removeprefix("error: "))
        return {**row, "status": f"exit {code}", "why": why}
    try:
        config = load_config(path)
        if duration is not None:
            from dataclasses import replace

            config = replace(config, simulation=replace(config.simulation, duration=duration))
        exp = Experiment.from_config(config)
    except SimulationError:
        raise
    except HmpcError as exc:
        return {**row, "status": "exit 2", "why": str(exc).splitlines()[0]}
    timed = TimedController(exp.controller)
    exp.controller = timed
    robot = exp.robot
    row.update(
        n=robot.nq,
        locked=len(robot.locked_joints),
        observer=observer_cell(config.controller),
        Ts=config.controller.Ts,
        prismatic=sum(k == "prismatic" for k in robot.joint_kinds),
        continuous=len(robot.continuous_joints),
    )
    wall = time.perf_counter()
    try:
        result = exp.run()
    except SimulationError as exc:
        return {**row, "status": "exit 1", "why": str(exc).splitlines()[0]}
    row["wall_s"] = time.perf_counter() - wall
    after = result.t >= 1.0
    rms = np.sqrt(np.mean(result.error[after] ** 2, axis=0))
    cons = config.controller.constraints
    lo, hi = robot.lower, robot.upper
    if cons is not None and not cons.position:
        viol = np.zeros(robot.nq)
    else:
        viol = np.maximum(np.maximum(lo - result.q, result.q - hi), 0.0).max(axis=0)
    row.update(
        worst_rms=float(rms.max()),
        worst_joint=robot.joint_names[int(rms.argmax())],
        limit_violation=float(viol.max()),
        step_us=float(np.median(timed.samples_ns)) / 1e3,
        floor_us=_floor_us(robot, result.q[-1], result.dq[-1]),
    )
    ok = row["worst_rms"] <= RMS_TARGET and row["limit_violation"] <= LIMIT_TOL
    row["status"] = "tracks" if ok else "misses"
    return row


@functools.cache
def rows(duration: float | None = None) -> tuple[dict, ...]:
    """Every model's row (:func:`run_model`, files in a temporary folder), computed once per
    process for each ``duration``: the docs' check (docs/regenerate.py) and the slow test
    of ``init`` share the 3 s runs."""
    out = Path(tempfile.mkdtemp(prefix="hmpc_any_arm_"))
    atexit.register(shutil.rmtree, out, ignore_errors=True)
    return tuple(run_model(name, out, duration) for name in models())


def observer_cell(cc) -> str:
    """What ``init`` chose for the observer: its kind, bandwidth ω [1/s] or gain c, and the
    declared latency [ms] (the tutorial's column; the docs test reads it back)."""
    obs = cc.observer
    if obs is None:
        return cc.compensation
    if obs.bandwidth is not None:
        w = np.unique(np.atleast_1d(obs.bandwidth))
        size = f"ω {w[0]:g} 1/s" if len(w) == 1 else f"ω {w.min():g}–{w.max():g} 1/s"
    else:
        size = f"c {obs.gain:g}"
    latency = f", latency {1e3 * cc.latency:g} ms" if cc.latency else ""
    return f"{cc.compensation} ({size}{latency})"


def markdown(rows: list[dict]) -> str:
    """The README table."""
    head = (
        "| model | joints controlled (locked) | observer | Ts [ms] | worst RMS after 1 s "
        "| limit excess | step median [µs] | step / floor | status |\n"
        "|---|---|---|---|---|---|---|---|---|"
    )
    lines = [head]
    for r in rows:
        if "worst_rms" not in r:
            lines.append(f"| {r['model']} | | | | | | | | {r['status']}: {r['why']} |")
            continue
        extra = []
        if r["continuous"]:
            extra.append(f"{r['continuous']} continuous")
        if r["prismatic"]:
            extra.append(f"{r['prismatic']} prismatic")
        joints = f"{r['n']} ({r['locked']})" + (f", {', '.join(extra)}" if extra else "")
        lines.append(
            f"| {r['model']} | {joints} | {r['observer']} | {1e3 * r['Ts']:g} | "
            f"{r['worst_rms']:.2e} ({r['worst_joint']}) | {r['limit_violation']:.1e} | "
            f"{r['step_us']:.0f} | {r['step_us'] / r['floor_us']:.1f} | {r['status']} |"
        )
    tracks = sum(r["status"] == "tracks" for r in rows)
    lines += ["", f"{tracks} of {len(rows)} track (RMS <= {RMS_TARGET:g}, limit excess <= "
              f"{LIMIT_TOL:g})."]  # fmt: skip
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path("out/any_arm"))
    parser.add_argument("--models", help="comma-separated subset [all 33]")
    parser.add_argument("--duration", type=float, help="simulated time [s] [the config's, 10]")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    names = args.models.split(",") if args.models else models()
    rows = []
    for name in names:
        row = run_model(name, args.out, args.duration)
        rows.append(row)
        print(f"{name}: {row['status']} {row.get('worst_rms', row.get('why', ''))}",
              file=sys.stderr, flush=True)  # fmt: skip
    table = markdown(rows)
    (args.out / "any_arm.md").write_text(table + "\n", encoding="utf-8")
    print(table)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
