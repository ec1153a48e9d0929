"""Benchmarks of hmpc_pin, in three parts:

* the suite ``run.py`` drives, with its harness (``harness.py``, ``_fixtures.py``) and its
  parts (controller step, closed-loop simulation, memory, comparisons with a centralized
  linear MPC and a Crocoddyl nonlinear MPC, and the peers, ``peers.py``: CasADi's QP solvers
  on the identical joint QPs, Crocoddyl's step); ``python benchmarks/run.py`` from the
  repository root writes ``BENCHMARKS.md``;
* ``studies/``: the one-off studies whose figures the documentation pages quote;
* ``tools/``: developer tools (refactoring checks, A/B timing, mutation runs).

None imports ``tests/``: the per-step loop oracle of ``tests/reference/loop.py`` is loaded
from its file (:func:`benchmarks.harness.per_step_oracle`, the ``--oracle`` option).
"""
