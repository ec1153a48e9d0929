"""The part the refactoring checks share (``arrays_check.py``, ``refactor_check.py``): the
command line ``record|compare FOLDER [--tol]``, the saving of each run's arrays to
``FOLDER/<name>.npz`` and their comparison with a rerun, one line per run.

A difference is the largest absolute one divided by max(1, the array's largest magnitude)
(torques reach 100 N·m), NaN only where NaN (else infinite), and infinite for arrays of
another shape or kind or, for arrays that are not floating point (a run's completion, its
message), unequal ones. Saved outputs are used only by these tools: tests compare against
independent computations.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

import numpy as np

#: A run by name: a thunk returning its arrays.
Runs = dict[str, Callable[[], dict[str, np.ndarray]]]


def parser(doc: str | None, tol: float) -> argparse.ArgumentParser:
    """The command line of a check: ``record|compare FOLDER [--tol TOL]`` (``tol`` its
    default), with the check's docstring as its help."""
    out = argparse.ArgumentParser(
        description=doc, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    out.add_argument("action", choices=("record", "compare"))
    out.add_argument("folder", type=Path)
    out.add_argument("--tol", type=float, default=tol)
    return out


def difference(a: np.ndarray, b: np.ndarray) -> float:
    """The largest difference of ``b`` from ``a`` relative to max(1, max |a|) (module
    docstring)."""
    a, b = np.asarray(a), np.asarray(b)
    if a.shape != b.shape or a.dtype.kind != b.dtype.kind:
        return np.inf
    if a.dtype.kind not in "fc":
        return 0.0 if np.array_equal(a, b) else np.inf
    if not np.array_equal(np.isnan(a), np.isnan(b)):
        return np.inf
    ok = ~np.isnan(a)
    scale = max(1.0, float(np.max(np.abs(a[ok]), initial=0.0)))
    return float(np.max(np.abs(a[ok] - b[ok]), initial=0.0)) / scale


def record(folder: Path, runs: Runs) -> None:
    """Every run's arrays to ``folder/<name>.npz``."""
    folder.mkdir(parents=True, exist_ok=True)
    for name, thunk in runs.items():
        arrays = thunk()
        np.savez(folder / f"{name}.npz", **arrays)
        print(f"recorded {name} (complete {bool(arrays['complete'])})", flush=True)


def row(name: str, worst: float, tol: float, detail: str = "") -> bool:
    """Print one run's line (``ok`` or ``FAIL``, its largest difference, ``detail``); whether
    it failed."""
    bad = not worst <= tol
    print(f"{'FAIL' if bad else 'ok  '} {name:<40} {worst:.1e} {detail}".rstrip(), flush=True)
    return bad


def compare(folder: Path, runs: Runs, tol: float) -> tuple[bool, float]:
    """Rerun every run and compare it with ``folder/<name>.npz``: the same arrays, each
    within ``tol``; one line per run. Returns whether any failed and the largest difference."""
    failed, worst_all = False, 0.0
    for name, thunk in runs.items():
        old = dict(np.load(folder / f"{name}.npz"))
        new = thunk()
        if set(old) != set(new):
            print(f"FAIL {name}: arrays {sorted(set(old) ^ set(new))} appear on one side only")
            failed = True
            continue
        diffs = {k: difference(old[k], new[k]) for k in old}
        worst = max(diffs.values(), default=0.0)
        worst_all = max(worst_all, worst)
        failed |= row(name, worst, tol, ", ".join(f"{k} {v:.1e}" for k, v in diffs.items() if v))
    return failed, worst_all
