"""``hmpc-pin tune``: tune observer gain, Q, R, N (and Ts) on the sweep's perturbed plants
(Optuna). Its arguments (``add_arguments``) and its entry point (``main``).
"""

from __future__ import annotations

from ..common import out_dir, read_config, with_overrides

__all__ = ["add_arguments", "main"]


def add_arguments(tun) -> None:
    """``hmpc-pin tune`` (:mod:`hmpc_pin.apps.tune`)."""
    from ..tune import tune_arguments

    tune_arguments(tun)


def main(args) -> int:
    """``hmpc-pin tune CONFIG`` (:mod:`hmpc_pin.apps.tune`): exit 2 naming the extra
    ``tune`` without Optuna, before anything runs."""
    from ..tune import _optuna, check_args
    from ..tune import cmd_tune as run_tune

    _optuna()
    config = with_overrides(read_config(args.config), False, args.duration)
    check_args(args, config)  # every option, before --out is created
    return run_tune(args, config, out_dir(args.out))
