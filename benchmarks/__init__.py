"""Benchmarks of hmpc_pin (issue 6): controller step, closed-loop simulation, memory, and
comparisons with a centralized linear MPC and a Crocoddyl nonlinear MPC.

Run ``python benchmarks/run.py`` from the repository root; it writes ``BENCHMARKS.md``.
"""
