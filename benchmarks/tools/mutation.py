"""The runner the mutation campaigns share (``one_line_mutants.py``, ``mutants_cpp.py``):
apply a one-line mutant, run its tests, revert; one line per mutant and the kill rate.

A mutant is ``(group, file, old line part, new line part, tests)``. Its old part must occur
exactly once in its file: a mutant whose file is gone or whose text is missing (the code
moved since the list was written) or ambiguous is an *error*, reported on its own line and
in the summary (exit 1), never skipped and never run. ``--check`` checks every picked
mutant's target that way without running anything.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

#: (group, file, old line part, new line part, tests)
Mutant = tuple[str, str, str, str, list[str]]


def target_problem(mutant: Mutant, root: Path = ROOT) -> str | None:
    """Why ``mutant`` cannot be applied (its file missing, its old text found not exactly
    once), or ``None``."""
    path = root / mutant[1]
    if not path.is_file():
        return f"{mutant[1]}: no such file"
    count = path.read_text(encoding="utf-8").count(mutant[2])
    if count != 1:
        return f"{mutant[1]}: target text occurs {count} times; expected once"
    return None


def run_tests(
    selections: Sequence[Sequence[str]], timeout: float, nice: bool = False
) -> tuple[bool, str]:
    """Run each selection of tests (``pytest -x -q``, one run each, the next only while
    none failed): whether one failed (the mutant killed; a timeout counts) and the last
    run's summary (its first failure and last line)."""
    tail = ""
    for selection in selections:
        if not selection:
            continue
        cmd = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", *selection]
        try:
            proc = subprocess.run(
                ["nice", *cmd] if nice else cmd,
                cwd=ROOT, capture_output=True, text=True, timeout=timeout,
            )  # fmt: skip
        except subprocess.TimeoutExpired:
            return True, "timeout"
        lines = proc.stdout.strip().splitlines() or [""]
        failed = [x for x in lines if x.startswith(("FAILED", "ERROR"))]
        tail = (failed[0][:160] + " | " if failed else "") + lines[-1]
        if proc.returncode != 0:
            return True, tail
    return False, tail


def with_mutant(
    mutant: Mutant, work: Callable[[], tuple[str, str]], root: Path = ROOT
) -> tuple[str, str]:
    """``work()`` (a verdict and a detail) with ``mutant`` applied to its file, which is
    put back as it was afterwards, whatever happens."""
    path = root / mutant[1]
    text = path.read_text(encoding="utf-8")
    path.write_text(text.replace(mutant[2], mutant[3]), encoding="utf-8")
    try:
        return work()
    finally:
        path.write_text(text, encoding="utf-8")


def parser(doc: str | None) -> argparse.ArgumentParser:
    """The campaigns' common options: ``--only``, ``--index``, ``--check``."""
    out = argparse.ArgumentParser(description=(doc or "").splitlines()[0])
    out.add_argument("--only", default="", help="run the mutants whose file contains this")
    out.add_argument("--index", default="", help="comma-separated indices into MUTANTS")
    out.add_argument(
        "--check",
        action="store_true",
        help="check that every picked mutant's text occurs once in its file; run nothing",
    )
    return out


def picked(mutants: Sequence[Mutant], args, keep: Callable[[Mutant], bool] = bool) -> list[int]:
    """The indices of the mutants ``--index``, ``--only`` and ``keep`` pick."""
    indices = [int(x) for x in args.index.split(",") if x] or range(len(mutants))
    return [i for i in indices if args.only in mutants[i][1] and keep(mutants[i])]


def campaign(
    mutants: Sequence[Mutant],
    indices: Sequence[int],
    run: Callable[[Mutant], tuple[str, str]],
    check: bool = False,
    root: Path = ROOT,
) -> int:
    """Each picked mutant run by ``run`` (applied for it: :func:`with_mutant`), which
    returns a verdict (``killed``, ``SURVIVED`` or another word) and a detail; a mutant that
    cannot be applied is an ``ERROR``. One line per mutant, then per group the kill rate and
    the errors. Returns 1 when a mutant was an error, else 0. With ``check``, only the
    errors are reported and nothing runs."""
    tally: dict[str, list[int]] = {}
    errors = 0
    for i in indices:
        mutant = mutants[i]
        counts = tally.setdefault(mutant[0], [0, 0, 0])
        head = f"#{i:03d}"
        where = f"{mutant[1]}: {mutant[2]!r} -> {mutant[3]!r}"
        problem = target_problem(mutant, root)
        if problem is not None:
            errors += 1
            counts[2] += 1
            print(f"{head} ERROR    {problem} ({mutant[0]}: {mutant[2]!r})", flush=True)
            continue
        if check:
            continue
        start = time.perf_counter()
        verdict, detail = with_mutant(mutant, lambda m=mutant: run(m), root)
        seconds = time.perf_counter() - start
        counts[0] += verdict == "killed"
        counts[1] += 1
        print(f"{head} {verdict:<8} {seconds:6.1f} s  {where} [{detail}]", flush=True)
    if check:
        print(f"{len(indices) - errors} of {len(indices)} targets found once")
        return 1 if errors else 0
    for group, (killed, ran, bad) in tally.items():
        rate = f"{killed} of {ran} killed ({100 * killed / ran:.0f} %)" if ran else "none run"
        print(f"{group}: {rate}" + (f", {bad} error(s): target not found once" if bad else ""))
    return 1 if errors else 0
