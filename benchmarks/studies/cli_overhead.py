"""The command line around its work: ``hmpc-pin run`` and ``hmpc-pin --help`` against what
they cannot avoid.

For each config, every block measures, one after the other:

* the wall time of ``hmpc-pin run <config> --out <tmp>`` (a fresh process: imports,
  config, URDF, controller, run, files, figures), the same with its figures drawn in its
  own process, one after the other (:data:`IN_PROCESS`: no figure process), and with
  ``--no-figures``;
* the wall time of a fresh ``python -c "import numpy, pinocchio, proxsuite, matplotlib"``
  (the imports no command can skip), and of the same with matplotlib's figure machinery
  (``matplotlib.figure`` and the Agg canvas: what drawing any figure imports; the second
  reading of "importing matplotlib");
* the in-process ``Experiment.run()`` of the same config in this process (built once).

The ratio of a block is run wall / (imports + in-process run), with either reading of the
imports; the table gives the median of
the ratios over the blocks beside the median absolute times, and the same ratio of CPU
time (user + system, of the command and every process it waited for: ``hmpc-pin run``
draws its figures in processes of its own, beside the run). On a machine busy with other
work the wall ratio tends to the CPU ratio (every process gets its share of a core); on an
idle one the figures' processes use the second core. ``--help`` is measured the
same way against a bare ``python -c pass``: the difference [s] and the ratio. The modules a
bare ``import hmpc_pin`` loads are counted (of the package's own, and whether numpy,
pinocchio or matplotlib are among them). Blocks alternate the measurements, so a machine
shared with other work loads each alike.

The commands run as an installed package runs: the package's modules compiled to bytecode
once before the blocks (``compileall``, as ``pip install`` does) and the environment's
``PYTHONDONTWRITEBYTECODE`` dropped for them (with it set and no bytecode, every command
compiles the package's modules it imports from source: about 0.13 s more per command,
measured here).

With ``--baseline PYTHON`` every block also runs the ``hmpc-pin`` beside that interpreter
(another checkout's environment, e.g. the version before a change), figures drawn, so that
the two versions are compared under the same load.

Usage: python benchmarks/studies/cli_overhead.py [--repeats 5] [--configs panda_sine paper_combined]
       [--parts]  (also: the parts of a run, timed one after the other in one process)
       [--baseline PATH/TO/OTHER/python]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks.harness import machine_info  # noqa: E402
from hmpc_pin.experiment.build import Experiment  # noqa: E402
from hmpc_pin.experiment.config import load_config  # noqa: E402

PYTHON = sys.executable
IMPORTS = "import numpy, pinocchio, proxsuite, matplotlib"
#: The second reading: with what drawing a figure imports.
IMPORTS_DRAW = IMPORTS + ", matplotlib.figure, matplotlib.backends.backend_agg"

#: The commands' environment: bytecode read and written as an installed package's.
ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def compile_package(python: str) -> None:
    """Compile the ``hmpc_pin`` that ``python`` imports to bytecode (as an install does)."""
    code = ("import compileall, os, hmpc_pin; "
            "compileall.compile_dir(os.path.dirname(hmpc_pin.__file__), quiet=1)")  # fmt: skip
    subprocess.run([python, "-c", code], env=ENV, check=True)


#: ``hmpc-pin`` with its figures drawn in its own process, one after the other (no figure
#: process): what the figure process saves, measured beside it.
IN_PROCESS = (
    "import sys; sys.argv[0] = 'hmpc-pin'; "
    "from hmpc_pin.apps import figure_worker; figure_worker.start = lambda: False; "
    "from hmpc_pin.apps.cli import main; sys.exit(main())"
)


def command(python: str = PYTHON) -> list[str]:
    """The ``hmpc-pin`` script beside ``python``, else ``python -m hmpc_pin``."""
    script = Path(python).parent / "hmpc-pin"
    return [str(script)] if script.exists() else [python, "-m", "hmpc_pin"]


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def wall(argv: list[str]) -> tuple[float, float]:
    """Wall and CPU time [s] of a fresh process running ``argv`` (output discarded; must
    succeed); the CPU time counts the processes it waited for."""
    c0, t0 = _children_cpu(), time.perf_counter()
    subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True, env=ENV)
    return time.perf_counter() - t0, _children_cpu() - c0


def in_process(experiment: Experiment) -> tuple[float, float]:
    """Wall and CPU time [s] of ``experiment.run()`` in this process."""
    c0, t0 = time.process_time(), time.perf_counter()
    experiment.run()
    return time.perf_counter() - t0, time.process_time() - c0


def loaded_by_import() -> tuple[int, int, list[str]]:
    """(the package's modules loaded by ``import hmpc_pin``, all of them, heavy ones loaded)."""
    code = ("import json, pkgutil, sys, hmpc_pin; "
            "ours = sorted(m for m in sys.modules if m.startswith('hmpc_pin')); "
            "heavy = sorted(h for h in ('numpy', 'pinocchio', 'proxsuite', 'matplotlib', "
            "'scipy') if h in sys.modules); "
            "n = sum(1 for _ in pkgutil.walk_packages(hmpc_pin.__path__, 'hmpc_pin.', "
            "onerror=lambda name: None)) + 1; "
            "print(json.dumps([ours, n, heavy]))")  # fmt: skip
    out = subprocess.run([PYTHON, "-c", code], capture_output=True, text=True, check=True)
    ours, total, heavy = json.loads(out.stdout.strip().splitlines()[-1])
    return len(ours), total, heavy


#: ``hmpc-pin run``'s steps timed one after the other in a fresh process (``--parts``).
PARTS = """
import sys, tempfile, time
from pathlib import Path
T = time.perf_counter
t = [T()]
import numpy, pinocchio, proxsuite, matplotlib
t.append(T())
import hmpc_pin.apps.cli
t.append(T())
from hmpc_pin.experiment.build import Experiment
from hmpc_pin.experiment.config import load_config
experiment = Experiment.from_config(load_config(sys.argv[1]))
t.append(T())
result = experiment.run()
t.append(T())
from hmpc_pin.apps import plots
t.append(T())
out = Path(tempfile.mkdtemp())
jobs = [("tracking", out / "t.png", "t", ""), ("disturbance", out / "d.png", "d", ""),
        ("error", out / "e.png", "e", "run")]
assert all(exc is None for _, exc in plots.draw_all(jobs, result))
t.append(T())
print(" ".join(f"{b - a:.3f}" for a, b in zip(t, t[1:])))
"""
PART_NAMES = ("numpy, pinocchio, proxsuite, matplotlib", "the command line (hmpc_pin.apps.cli)",
              "the library, config and build (URDF check)", "Experiment.run()",
              "matplotlib's figure module (plots)",
              "the three figures, one after the other on one figure (draw_all)")  # fmt: skip


def parts(names: list[str], repeats: int) -> None:
    """Print the median time [s] of each of :data:`PART_NAMES` per config."""
    print(f"\n| part [s] | {' | '.join(names)} |")
    print(f"|---|{'---|' * len(names)}")
    times: dict[str, list] = {}
    for _ in range(repeats):
        for name in names:
            out = subprocess.run([PYTHON, "-c", PARTS, name], capture_output=True, text=True,
                                 check=True, env=ENV)  # fmt: skip
            times.setdefault(name, []).append([float(x) for x in out.stdout.split()])
    med = {name: np.median(np.array(v), axis=0) for name, v in times.items()}
    for i, part in enumerate(PART_NAMES):
        print(f"| {part} | {' | '.join(f'{med[n][i]:.2f}' for n in names)} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="blocks per measurement")
    parser.add_argument("--configs", nargs="+", default=["panda_sine", "paper_combined"])
    parser.add_argument(
        "--parts",
        action="store_true",
        help="also time a run's parts one after the other in one process",
    )
    parser.add_argument(
        "--baseline",
        metavar="PYTHON",
        help="also run the hmpc-pin of this interpreter (another version) in every block",
    )
    args = parser.parse_args()
    cli = command()
    for python in [PYTHON] + ([args.baseline] if args.baseline else []):
        compile_package(python)
    for key, value in machine_info().items():
        print(f"- {key}: {value}")
    ours, total, heavy = loaded_by_import()
    print(
        f"- `import hmpc_pin` loads {ours} of the package's {total} modules; "
        f"heavy dependencies loaded: {', '.join(heavy) or 'none'}\n"
    )
    print(
        "| command | median wall [s] | median reference [s] (imports + run) | "
        "median ratio (min–max) | median CPU [s] | median CPU ratio | "
        "median ratio, imports with matplotlib's figure machinery |"
    )
    print("|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.configs:
            experiment = Experiment.from_config(load_config(name))
            in_process(experiment)  # warm: the first run pays for lazy imports
            # per variant: (wall, CPU) of the command and of the reference, per block
            variants: dict[str, tuple[list, list, list]] = {
                "": ([], [], []),
                " (figures drawn in the command's process)": ([], [], []),
                " --no-figures": ([], [], []),
            }
            if args.baseline:
                variants[f" (baseline: {args.baseline})"] = ([], [], [])
            for _ in range(args.repeats):
                for flags, (runs, refs, refs_draw) in variants.items():
                    argv = ["run", name, "--out", tmp]
                    if flags.startswith(" --"):
                        argv.append(flags.strip())
                    prog = [PYTHON, "-c", IN_PROCESS] if flags.startswith(" (f") else cli
                    if flags.startswith(" (b"):
                        prog = command(args.baseline)
                    runs.append(wall([*prog, *argv]))
                    run_t = in_process(experiment)
                    refs.append(np.add(wall([PYTHON, "-c", IMPORTS]), run_t))
                    refs_draw.append(np.add(wall([PYTHON, "-c", IMPORTS_DRAW]), run_t))
            for flags, (runs, refs, refs_draw) in variants.items():
                run_t, ref_t = np.array(runs), np.array(refs)
                ratio = run_t[:, 0] / ref_t[:, 0]
                cpu_ratio = run_t[:, 1] / ref_t[:, 1]
                ratio_draw = run_t[:, 0] / np.array(refs_draw)[:, 0]
                print(
                    f"| `hmpc-pin run {name}{flags}` | {np.median(run_t[:, 0]):.2f} | "
                    f"{np.median(ref_t[:, 0]):.2f} | {np.median(ratio):.2f} "
                    f"({ratio.min():.2f}–{ratio.max():.2f}) | {np.median(run_t[:, 1]):.2f} | "
                    f"{np.median(cpu_ratio):.2f} | {np.median(ratio_draw):.2f} "
                    f"({ratio_draw.min():.2f}–{ratio_draw.max():.2f}) |",
                    flush=True,
                )
    helps, bares = [], []
    for _ in range(args.repeats):
        helps.append(wall([*cli, "--help"])[0])
        bares.append(wall([PYTHON, "-c", "pass"])[0])
    diff = np.array(helps) - np.array(bares)
    ratio = np.array(helps) / np.array(bares)
    print(
        f"| `hmpc-pin --help` | {np.median(helps):.3f} | {np.median(bares):.3f} (bare "
        f"`python -c pass`) | {np.median(ratio):.1f} ({ratio.min():.1f}–{ratio.max():.1f}); "
        f"over the bare start: median {np.median(diff):.3f} s |"
    )
    if args.parts:
        parts(args.configs, args.repeats)


if __name__ == "__main__":
    main()
