"""Memory of the paper's combined scenario, run in a fresh process (``benchmarks/run.py``).

``python -m benchmarks.memory [--duration S] [--every S]`` (from the repository root)
loads ``configs/paper_combined.toml``, builds the experiment, runs it for ``--duration``
simulated seconds and prints one JSON object:

- ``rss_imports``: resident set size after importing hmpc_pin, before loading the
  config [bytes];
- ``rss_setup``: resident set size after loading the config and building the
  experiment, before the run [bytes];
- ``peak_rss``: the process's peak RSS at the end (``VmHWM``, or the largest sample if
  Linux's lazily updated high-water mark lags it) [bytes];
- ``samples``: ``[t, rss]`` pairs, the RSS [bytes] read from ``/proc/self/statm`` in the
  ``on_step`` callback at t = 0 and every ``--every`` simulated seconds [s];
- ``wall``: wall time of the run [s]; ``complete``: whether it finished.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks.harness import peak_rss_bytes, rss_bytes  # noqa: E402
from hmpc_pin.experiment.build import Experiment  # noqa: E402
from hmpc_pin.experiment.config import load_config  # noqa: E402

#: The paper's Section 5.3 scenario.
CONFIG = ROOT / "configs" / "paper_combined.toml"


def measure(duration: float, every: float) -> dict:
    """Run the combined scenario for ``duration`` [s], sampling RSS every ``every`` [s].

    Args:
        duration: Simulated time [s].
        every: Sampling period of the RSS in simulated time [s]; 0 samples only at t = 0.

    Returns:
        The JSON-ready dict described in the module docstring.
    """
    imports = rss_bytes()
    experiment = Experiment.from_config(load_config(CONFIG))
    Ts = experiment.controller.Ts
    stride = max(1, round(every / Ts)) if every > 0 else None
    samples: list[list[float]] = []

    def on_step(t: float, q, q_ref) -> None:
        k = round(t / Ts)
        if k == 0 or (stride is not None and k % stride == 0):
            samples.append([float(t), rss_bytes()])

    setup = rss_bytes()
    t0 = time.perf_counter()
    result = experiment.run(duration=duration, on_step=on_step)
    wall = time.perf_counter() - t0
    return {
        "duration": duration,
        "rss_imports": imports,
        "rss_setup": setup,
        "peak_rss": max([peak_rss_bytes(), *(rss for _, rss in samples)]),
        "samples": samples,
        "wall": wall,
        "complete": bool(result.complete),
    }


def main(argv: list[str] | None = None) -> int:
    """Command-line entry point; prints the JSON result on stdout."""
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--duration", type=float, default=10.0, help="simulated time [s]")
    parser.add_argument(
        "--every", type=float, default=0.0, help="RSS sampling period, simulated [s]"
    )
    args = parser.parse_args(argv)
    print(json.dumps(measure(args.duration, args.every)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
