"""A small timing harness: ``time.perf_counter_ns`` around each call, warm-up, median and p99.

Garbage collection stays enabled while timing (unlike :mod:`timeit`): a controller running
an arm pays for it too, and it shows up in the 99th percentile, not in the median.
"""

from __future__ import annotations

import importlib.util
import os
import platform
import resource
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

import numpy as np

import hmpc_pin.apps.compare

__all__ = [
    "LOOP_ORACLE",
    "TimedController",
    "Timing",
    "machine_info",
    "package_versions",
    "peak_rss_bytes",
    "per_step_oracle",
    "rss_bytes",
    "time_calls",
]

_PAGE = os.sysconf("SC_PAGE_SIZE")

#: The closed loop's per-step oracle: a file of the tests, kept beside the tests that check
#: the compiled loop against it. The package has no per-step loop (every run goes through
#: the compiled loop), so a program that times or compares against it loads this file by
#: its path (its ``--oracle`` option), without importing the ``tests`` package.
LOOP_ORACLE = Path(__file__).resolve().parent.parent / "tests" / "reference" / "loop.py"


def per_step_oracle(path: Path = LOOP_ORACLE):
    """The ``per_step()`` context manager of the closed-loop oracle file ``path``: within
    it, :func:`hmpc_pin.simulate` (and ``Experiment.run``) run the oracle's per-step loop.

    Raises:
        SystemExit: ``path`` is not a file (naming ``--oracle``).
    """
    path = Path(path)
    if not path.is_file():
        raise SystemExit(
            f"--oracle: {path} not found; pass the per-step loop oracle "
            "(tests/reference/loop.py of a clone of the repository)"
        )
    spec = importlib.util.spec_from_file_location("benchmarks_loop_oracle", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.per_step


@dataclass(frozen=True)
class Timing:
    """Statistics of repeated call durations.

    Attributes:
        samples_ns: Every timed call's duration [ns], shape (count,).
    """

    samples_ns: np.ndarray

    @classmethod
    def of(cls, samples_ns) -> Timing:
        """Wrap a sequence of durations [ns]."""
        return cls(np.asarray(samples_ns, dtype=np.int64))

    @property
    def count(self) -> int:
        """Number of timed calls."""
        return int(self.samples_ns.size)

    @property
    def median_us(self) -> float:
        """Median duration [µs]."""
        return float(np.median(self.samples_ns)) / 1e3

    @property
    def p99_us(self) -> float:
        """99th percentile of the duration [µs]."""
        return float(np.percentile(self.samples_ns, 99)) / 1e3

    @property
    def mean_us(self) -> float:
        """Mean duration [µs]."""
        return float(np.mean(self.samples_ns)) / 1e3

    @property
    def min_us(self) -> float:
        """Shortest duration [µs]."""
        return float(np.min(self.samples_ns)) / 1e3


def time_calls(fn: Callable[..., object], calls: Sequence[tuple], warmup: int) -> Timing:
    """Call ``fn(*calls[i])`` for every i in order; time all but the first ``warmup`` calls.

    The arguments are built beforehand, so that only the call itself is timed.

    Args:
        fn: The call to time.
        calls: One argument tuple per call (e.g. the states of a recorded trajectory, so
            that warm starts see a realistic sequence); more than ``warmup`` of them.
        warmup: Number of untimed calls before the timed ones (>= 0).

    Returns:
        The :class:`Timing` of the ``len(calls) - warmup`` timed calls [ns each].
    """
    if len(calls) <= warmup:
        raise ValueError(f"{len(calls)} calls but {warmup} warm-up calls: nothing to time")
    clock = time.perf_counter_ns
    for args in calls[:warmup]:
        fn(*args)
    timed = calls[warmup:]
    samples = np.empty(len(timed), dtype=np.int64)
    for j, args in enumerate(timed):
        t0 = clock()
        fn(*args)
        samples[j] = clock() - t0
    return Timing(samples)


class TimedController(hmpc_pin.apps.compare.TimedController):
    """:class:`hmpc_pin.apps.compare.TimedController` with :class:`Timing` statistics."""

    def timing(self, skip: int = 0) -> Timing:
        """Statistics of the recorded steps, the first ``skip`` (warm-up) left out."""
        return Timing.of(self.samples_ns[skip:])


def rss_bytes() -> int:
    """Resident set size of this process now [bytes] (``/proc/self/statm``)."""
    with open("/proc/self/statm", encoding="ascii") as f:
        return int(f.read().split()[1]) * _PAGE


def peak_rss_bytes() -> int:
    """Peak resident set size of this process's address space so far [bytes].

    ``VmHWM`` from ``/proc/self/status`` (or the current RSS if larger: Linux updates the
    high-water mark lazily, so it can lag by a few hundred KiB). Not ``ru_maxrss``: that
    one survives ``exec``, so a child started by ``subprocess`` from a large parent
    reports the parent's peak at ``fork`` time.
    """
    with open("/proc/self/status", encoding="ascii") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return max(int(line.split()[1]) * 1024, rss_bytes())
    return max(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024, rss_bytes())


def package_versions(names: tuple[str, ...]) -> dict[str, str]:
    """Installed distribution versions; ``"not installed"`` for a missing one."""
    out = {}
    for name in names:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def machine_info() -> dict[str, str]:
    """CPU model, core count, load average, OS and Python version of this machine."""
    cpu = platform.processor() or "unknown"
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    try:
        load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:
        load = "unknown"
    return {
        "cpu": cpu,
        "cores": str(os.cpu_count()),
        "load average (1, 5, 15 min) at start": load,
        "os": f"{platform.system()} {platform.release()}",
        "python": sys.version.split()[0],
    }
