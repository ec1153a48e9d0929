"""Deprecated: the threaded two-rate law moved to :mod:`hmpc_pin.realtime.threaded_law`
(it is not Franka's: ``hmpc-pin realtime`` and ``hmpc-pin ros`` run it too).
``InnerLawThreaded`` and ``planner_qps`` are still answered here, with a
:class:`DeprecationWarning`."""

from __future__ import annotations

from typing import Any

__all__: list[str] = []


def __getattr__(name: str) -> Any:
    from ..._deprecated import deprecated

    return deprecated(__name__, name)
