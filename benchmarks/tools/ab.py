"""A/B timing of this code against an older version of the package, in one process.

The older version is a copy of its ``hmpc_pin`` folder renamed ``hmpc_pin_old`` (the
package imports itself relatively, so both load side by side):

    git archive 596fa7b hmpc_pin | tar -x -C /tmp/old && mv /tmp/old/hmpc_pin /tmp/old/hmpc_pin_old
    python benchmarks/tools/ab.py --old /tmp/old run      # the paper's 10 s run, 7 rounds
    python benchmarks/tools/ab.py --old /tmp/old step     # planar3 and Panda steps, Nc = 1
    python benchmarks/tools/ab.py --old /tmp/old sweep    # the README's sweep: 200 samples, 2 jobs

Old and new alternate (old, new, old, new, ...), so that the slow and fast phases of a
shared machine hit both alike; the figure is the median over rounds of old / new (the
speed-up), printed beside the absolute medians.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

PAPER = ROOT / "configs" / "paper_combined.toml"


def _packages(old: Path):
    sys.path.insert(0, str(old))
    return importlib.import_module("hmpc_pin_old"), importlib.import_module("hmpc_pin")


def _alternate(fn_old, fn_new, rounds: int) -> tuple[np.ndarray, np.ndarray]:
    """Wall times [s] of ``rounds`` alternating calls of each."""
    t_old, t_new = [], []
    for _ in range(rounds):
        for fn, out in ((fn_old, t_old), (fn_new, t_new)):
            start = time.perf_counter()
            fn()
            out.append(time.perf_counter() - start)
    return np.array(t_old), np.array(t_new)


def _report(name: str, t_old: np.ndarray, t_new: np.ndarray, unit: float, label: str) -> dict:
    ratio = float(np.median(t_old / t_new))
    old_med, new_med = float(np.median(t_old)) * unit, float(np.median(t_new)) * unit
    print(f"{name}: old {old_med:.4g} {label}, new {new_med:.4g} {label}, "
          f"old/new {ratio:.2f} (rounds: {np.round(t_old / t_new, 2)})")  # fmt: skip
    return {"old": old_med, "new": new_med, "speedup": ratio}


def ab_run(old_pkg, new_pkg, rounds: int) -> dict:
    """The paper's 10 s combined run, ``Experiment.from_config(...).run()`` each round."""

    def runner(pkg):
        build = importlib.import_module(pkg.__name__ + ".experiment.build")
        experiment = importlib.import_module(pkg.__name__ + ".experiment")
        config = experiment.load_config(PAPER)

        def run():
            build.Experiment.from_config(config).run()

        run()  # warm-up
        return run

    t_old, t_new = _alternate(runner(old_pkg), runner(new_pkg), rounds)
    out = _report("paper 10 s run", t_old, t_new, 1.0, "s")
    out["rtf_old"], out["rtf_new"] = 10.0 / out["old"], 10.0 / out["new"]
    print(f"  real-time factor: old {out['rtf_old']:.0f}, new {out['rtf_new']:.0f}")
    return out


def ab_sweep(old_pkg, new_pkg, rounds: int, samples: int, jobs: int) -> dict:
    """``run_sweep(paper_combined, samples, seed 0, jobs)`` (the README's command's work)."""

    def runner(pkg):
        sweep = importlib.import_module(pkg.__name__ + ".apps.sweep")
        experiment = importlib.import_module(pkg.__name__ + ".experiment")
        config = experiment.load_config(PAPER)
        return lambda: sweep.run_sweep(config, samples, 0, jobs=jobs, progress=False)

    t_old, t_new = _alternate(runner(old_pkg), runner(new_pkg), rounds)
    return _report(f"sweep {samples} samples, {jobs} jobs", t_old, t_new, 1.0, "s")


def ab_step(old_pkg, new_pkg, rounds: int) -> dict:
    """Median ``step`` of planar3 and Panda (Nc = 1) along the step benchmark's states."""
    from benchmarks._fixtures import HOMES, PANDA_LOCKED, load_arm, record_trajectory

    out = {}
    arms = [
        load_arm("planar3", ROOT / "robots" / "planar3.urdf", HOMES["planar3"], "chen"),
        load_arm("panda", "panda", HOMES["panda"], "general", PANDA_LOCKED),
    ]
    for arm in arms:
        tr = record_trajectory(arm, 1200)
        ctrls = []
        for pkg in (old_pkg, new_pkg):
            robot = pkg.load_robot(
                arm.robot.source,
                gravity=9.8,
                locked_joints=PANDA_LOCKED if arm.name == "panda" else None,
            )
            cfg = pkg.ControllerConfig(Nc=1, observer=pkg.ObserverConfig(kind=arm.observer))
            ctrls.append(pkg.make_controller(robot, cfg))
        ref = arm.reference()
        args = [(float(tr.t[i]), tr.q[i].copy(), tr.dq[i].copy()) for i in range(len(tr.t))]

        def block(ctrl, tr=tr, args=args, ref=ref):
            def run():
                ctrl.reset(tr.q[0], tr.dq[0])
                for t, q, dq in args:
                    ctrl.step(t, q, dq, ref)

            return run

        t_old, t_new = _alternate(block(ctrls[0]), block(ctrls[1]), rounds)
        out[arm.name] = _report(f"{arm.name} step (per step)", t_old / len(args),
                                t_new / len(args), 1e6, "µs")  # fmt: skip
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("what", choices=("run", "step", "sweep"))
    parser.add_argument(
        "--old", type=Path, required=True, help="folder holding the old package as hmpc_pin_old"
    )
    parser.add_argument("--rounds", type=int, default=None)
    parser.add_argument("--samples", type=int, default=200)
    parser.add_argument("--jobs", type=int, default=2)
    args = parser.parse_args(argv)
    old_pkg, new_pkg = _packages(args.old)
    if args.what == "run":
        ab_run(old_pkg, new_pkg, args.rounds or 7)
    elif args.what == "step":
        ab_step(old_pkg, new_pkg, args.rounds or 10)
    else:
        ab_sweep(old_pkg, new_pkg, args.rounds or 1, args.samples, args.jobs)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
