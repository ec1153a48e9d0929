"""Numpy oracles of the compiled core's components.

Each module re-implements one component of ``cpp/`` in plain numpy, written from the paper's
equations (cited in its docstring) rather than from the C++; the tests check the compiled
component against it on random states and along closed loops (as Crocoddyl's
``unittest/bindings`` do). Nothing in ``hmpc_pin`` imports these modules.
"""
