"""``hmpc-pin ros-lifecycle``: change or get the lifecycle state of the `ros` node (extra:
ros). Its arguments (``add_arguments``) and its entry point (``main``).
"""

from __future__ import annotations

__all__ = ["add_arguments", "main"]


def add_arguments(parser) -> None:
    """``hmpc-pin ros-lifecycle`` (:mod:`hmpc_pin.apps.ros_client`)."""
    from ..ros_client import lifecycle_arguments

    lifecycle_arguments(parser)


def main(args) -> int:
    """``hmpc-pin ros-lifecycle`` (:mod:`hmpc_pin.apps.ros_client`)."""
    from ..ros_client import run_lifecycle

    return run_lifecycle(args)
