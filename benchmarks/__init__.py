"""Benchmarks of hmpc_pin (issue 6): controller step, closed-loop simulation, memory, and
comparisons with a centralized linear MPC and a Crocoddyl nonlinear MPC, and the peers
(``peers.py``: CasADi's QP solvers on the identical joint QPs, Crocoddyl's step).

Run ``python benchmarks/run.py`` from the repository root; it writes ``BENCHMARKS.md``.
"""
