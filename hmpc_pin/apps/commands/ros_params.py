"""``hmpc-pin ros-params``: print the parameters of the `ros` node (extra: ros). Its arguments
(``add_arguments``) and its entry point (``main``).
"""

from __future__ import annotations

__all__ = ["add_arguments", "main"]


def add_arguments(parser) -> None:
    """``hmpc-pin ros-params`` (:mod:`hmpc_pin.apps.ros_client`)."""
    from ..ros_client import params_arguments

    params_arguments(parser)


def main(args) -> int:
    """``hmpc-pin ros-params`` (:mod:`hmpc_pin.apps.ros_client`)."""
    from ..ros_client import run_params

    return run_params(args)
