"""Developer tools: the refactoring checks (``arrays_check.py``, ``refactor_check.py``), the
A/B timing against an older version (``ab.py``, also behind ``benchmarks/run.py --ab``) and
the mutation runs (``mutants_cpp.py``, ``one_line_mutants.py``); run from the repository
root."""
