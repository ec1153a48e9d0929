"""Developer tools: the refactoring checks (``arrays_check.py``, ``refactor_check.py``, their
shared command line and comparison in ``saved_outputs.py``), the A/B timing against an older
version (``ab.py``, also behind ``benchmarks/run.py --ab``) and the mutation runs
(``mutants_cpp.py``, ``one_line_mutants.py``); run from the repository root."""
