"""One simulated hour of the paper's combined scenario: is the loop stationary?

``python benchmarks/studies/long_run.py [--minutes 60] [--repeat 60] [--config FILE]`` (from the
repository root) runs ``configs/paper_combined.toml`` (Section 5.3: friction plus
Gaussian pulses, sine reference, NDO on) for ``--minutes`` simulated minutes in one
closed-loop run and prints, per minute, the RMS tracking error of each joint, its ratio
to the first minute (worst joint), the max |q − r| and the process's resident memory.

Decisions:

- *Disturbance repeated every minute.* The sine reference (0.1 Hz) repeats by itself
  (6 periods a minute); the paper's pulses (t = 1, 2, 3 s) happen once. They are
  repeated every ``--repeat`` seconds (:class:`hmpc_pin.sim.disturbances.Periodic`), so every
  minute has the same reference and disturbance, and a per-minute RMS that drifts would
  be the controller's doing. ``--repeat 0`` keeps the pulses only at the start.
- *The first second is left out* of minute 1 (the start-up transient from q = 1, as in
  every "RMS after 1 s" of this project).
- *Streaming metric, one run.* The per-minute sums are accumulated in the ``on_step``
  callback; the run itself is one :func:`hmpc_pin.sim.simulate` call, whose result arrays
  are allocated (and touched) once at the start: 360 001 samples × 7 arrays × n joints,
  ≈ 60 MB for an hour of planar3. Memory that grows from minute to minute is therefore
  a leak in the loop (controller, observer, ProxSuite, Pinocchio), which is what the
  RSS column measures.

Criterion (issue 7): every joint's per-minute RMS within 10 % of its first minute's.
Exit code 0 if it holds and the run completed, 1 otherwise.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks.harness import rss_bytes  # noqa: E402
from hmpc_pin.exceptions import SimulationError  # noqa: E402
from hmpc_pin.experiment.build import Experiment  # noqa: E402
from hmpc_pin.experiment.config import load_config  # noqa: E402
from hmpc_pin.sim.disturbances import Periodic  # noqa: E402

CONFIG = ROOT / "configs" / "paper_combined.toml"
MINUTE = 60.0


def long_run(
    minutes: int = 60, repeat: float = MINUTE, config: Path = CONFIG, skip: float = 1.0
) -> dict:
    """Run ``minutes`` simulated minutes; return per-minute metrics.

    Args:
        minutes: Simulated minutes.
        repeat: Period [s] of the repeated disturbance (0: the config's, once).
        config: Experiment TOML.
        skip: Seconds left out at the start of minute 1 (start-up transient).

    Returns:
        ``{"rms": (minutes, n), "max": (minutes,), "rss": (minutes,) [bytes], "wall": s,
        "complete": bool, "message": str, "joint_names": tuple}``.
    """
    experiment = Experiment.from_config(load_config(config))
    if repeat > 0:
        experiment.disturbance = Periodic(experiment.disturbance, repeat)
    n = experiment.robot.nq
    Ts = experiment.controller.Ts
    per_minute = round(MINUTE / Ts)
    first = round(skip / Ts)
    sq = np.zeros((minutes, n))
    count = np.zeros(minutes)
    peak = np.zeros(minutes)
    rss = np.zeros(minutes)

    def on_step(t, q, q_ref):
        k = round(t / Ts)
        m = k // per_minute
        if m >= minutes:  # the final sample, t = minutes * 60
            return
        if k >= first:
            e = q - q_ref
            sq[m] += e * e
            count[m] += 1
            peak[m] = max(peak[m], float(np.abs(e).max()))
        if k % per_minute == per_minute - 1:  # the minute's last sample
            rss[m] = rss_bytes()

    start = time.perf_counter()
    try:
        result = experiment.run(duration=minutes * MINUTE, on_step=on_step)
    except SimulationError as exc:
        result = exc.result
    wall = time.perf_counter() - start
    with np.errstate(invalid="ignore", divide="ignore"):
        rms = np.sqrt(sq / count[:, None])
    return {
        "rms": rms,
        "max": peak,
        "rss": rss,
        "wall": wall,
        "complete": bool(result.complete),
        "message": result.message,
        "joint_names": experiment.robot.joint_names,
    }


def deviation(rms: np.ndarray) -> np.ndarray:
    """Per minute, the largest relative deviation of a joint's RMS from minute 1's."""
    return np.abs(rms / rms[0] - 1.0).max(axis=1)


def format_table(run: dict) -> str:
    """The per-minute table and a verdict, as printed by :func:`main`."""
    names = run["joint_names"]
    dev = deviation(run["rms"])
    head = ["minute", *(f"RMS {j} [rad]" for j in names), "max dev. vs min 1",
            "max |e| [rad]", "RSS [MiB]"]  # fmt: skip
    lines = [" | ".join(head), " | ".join("---" for _ in head)]
    for m, row in enumerate(run["rms"]):
        cells = [f"{m + 1}", *(f"{x:.4e}" for x in row), f"{100 * dev[m]:.2f} %",
                 f"{run['max'][m]:.3e}", f"{run['rss'][m] / 2**20:.1f}"]  # fmt: skip
        lines.append(" | ".join(cells))
    rss = run["rss"] / 2**20
    ok = run["complete"] and bool(np.all(dev <= 0.10))
    lines += [
        "",
        f"largest per-minute RMS deviation from minute 1: {100 * dev.max():.2f} % "
        f"(criterion 10 %): {'PASS' if ok else 'FAIL'}",
        f"RSS: minute 1 {rss[0]:.1f} MiB, last minute {rss[-1]:.1f} MiB, "
        f"max - min over minutes 1..{len(rss)}: {rss.max() - rss.min():.2f} MiB",
        f"simulated {len(rss)} min in {run['wall']:.1f} s of wall time"
        + ("" if run["complete"] else f"; run stopped early: {run['message']}"),
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Command-line entry point; prints the table; exit 0 if the criterion holds."""
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--minutes", type=int, default=60, help="simulated minutes [60]")
    parser.add_argument(
        "--repeat", type=float, default=MINUTE, help="disturbance period [s] (0: once) [60]"
    )
    parser.add_argument("--config", type=Path, default=CONFIG, help="experiment TOML")
    args = parser.parse_args(argv)
    if args.minutes < 1:
        parser.error("--minutes must be >= 1")
    run = long_run(args.minutes, args.repeat, args.config)
    print(format_table(run))
    return 0 if run["complete"] and np.all(deviation(run["rms"]) <= 0.10) else 1


if __name__ == "__main__":
    raise SystemExit(main())
