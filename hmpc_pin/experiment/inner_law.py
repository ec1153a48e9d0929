"""The inner law a real-time command runs, chosen in one place and built by one factory.

Under an arm faster than the controller (the interface period :math:`P`, ``Ts`` a
multiple :math:`m` of it) ``hmpc-pin realtime``, ``hmpc-pin ros`` and ``hmpc-pin franka``
run the controller one of three ways, ``[realtime] inner_law`` (``--inner-law`` over it):

- ``"whole-step"``: the controller's whole step every ``Ts``, its torque held for the
  :math:`m` cycles in between (any controller);
- ``"every-cycle"``: the MPC every ``Ts``, the inverse dynamics (Eq 4) and the
  disturbance observer (Eq 13) every cycle at the fresh state
  (:class:`~hmpc_pin.realtime.inner_law.InnerLawEveryCycle`);
- ``"threaded"``: the same with the MPC in a compiled thread, its latest plan used shifted
  within a staleness bound of its control horizon, ``max(Nc, 2) Ts``, and the brake when
  none is (:class:`~hmpc_pin.realtime.threaded_law.InnerLawThreaded`); also at ``Ts``
  equal to the interface period (a long horizon's MPC off the torque cycle); its planner
  thread scheduled by ``[realtime] planner`` (only with this law).

The last two apply to the hierarchical MPC with a disturbance observer, no declared
latency and (``"every-cycle"``) ``Ts`` above the interface period; asked for elsewhere
they are an error that says what was wrong and what to do (:func:`check_inner_law`).
``"auto"`` (the default) is the command's own choice (:data:`AUTO`): ``franka`` runs
``"every-cycle"`` where it applies and ``"whole-step"`` elsewhere; ``realtime`` and
``ros`` run ``"whole-step"`` (measured against the others on ``panda_sine`` at 1 kHz: the
guide "The inner law").
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from ..exceptions import ConfigError
from ..realtime.inner_law import InnerLawEveryCycle
from .config.realtime import INNER_LAWS

__all__ = [
    "AUTO",
    "INNER_LAWS",
    "check_inner_law",
    "chosen_inner_law",
    "close_law",
    "inner_law_controller",
    "inner_law_of",
    "inner_law_summary",
    "why_not_inner_law",
]

#: What ``"auto"`` means for each command: ``"every-cycle-where-it-applies"`` (Franka's
#: default since its driver came) or ``"whole-step"``.
AUTO = {
    "franka": "every-cycle-where-it-applies",
    "realtime": "whole-step",
    "ros": "whole-step",
}


def why_not_inner_law(controller: Any, period: float, law: str = "every-cycle") -> str | None:
    """Why the two-rate ``law`` (``"every-cycle"`` or ``"threaded"``) does not apply to
    ``controller`` at the interface ``period`` [s], with what to do instead (``None``: it
    applies). ``"threaded"`` also applies at ``Ts`` equal to the period (the MPC off the
    torque cycle)."""
    from ..compensation.base import NoCompensation
    from ..controllers.hierarchical import HierarchicalMPC

    if not isinstance(controller, HierarchicalMPC):
        return (
            f"the controller is a {type(controller).__name__}, not the hierarchical MPC "
            "(with a collision watch or another wrapper the whole step runs): use "
            "whole-step"
        )
    if not controller.Ts > (0.5 if law == "threaded" else 1.5) * period:
        return (
            f"controller.Ts = {controller.Ts:g} s equals the interface period {period:g} s: "
            "the whole step already runs every cycle; use whole-step, or a Ts that is a "
            "multiple of the period"
        )
    if isinstance(controller.compensation, NoCompensation):
        return (
            "the controller has no disturbance observer (the inner law runs one every "
            "cycle): use whole-step, or enable [controller.observer]"
        )
    latency = float(controller.latency or 0.0)
    if latency > 0:
        return (
            f"the controller declares a latency ({latency:g} s; its prediction and torque "
            "alignment are the compiled step's): use whole-step, or set [controller] "
            "latency = 0"
        )
    return None


def inner_law_of(choice: str, command: str, controller: Any, period: float, key: str) -> str:
    """The law ``command`` runs: ``choice`` (``--inner-law``, else ``[realtime]
    inner_law``) with ``"auto"`` resolved (:data:`AUTO`), checked (:func:`check_inner_law`).

    Args:
        choice: One of :data:`INNER_LAWS`.
        command: ``"realtime"``, ``"ros"`` or ``"franka"``.
        controller: The experiment's controller.
        period: The interface period [s].
        key: The name the error gives the choice (``--inner-law`` or
            ``realtime.inner_law``).

    Raises:
        ConfigError: An unknown law, or one that does not apply, named by ``key``.
    """
    check_inner_law(choice, controller, period, key)
    if choice == "auto":
        auto = AUTO[command]
        if auto == "every-cycle-where-it-applies":
            reason = why_not_inner_law(controller, period, "every-cycle")
            return "every-cycle" if reason is None else "whole-step"
        return auto
    return choice


def check_inner_law(choice: str, controller: Any, period: float, key: str) -> None:
    """``choice`` (one of :data:`INNER_LAWS`) applies to ``controller`` at ``period`` [s].

    Raises:
        ConfigError: An unknown choice, or a two-rate law where it does not apply
            (:func:`why_not_inner_law`), named by ``key``.
    """
    if choice not in INNER_LAWS:
        raise ConfigError(key, f"expected one of {', '.join(INNER_LAWS)}, got {choice!r}")
    if choice in ("auto", "whole-step"):
        return
    reason = why_not_inner_law(controller, period, choice)
    if reason is not None:
        raise ConfigError(key, f"{choice} does not apply: {reason}")


def chosen_inner_law(experiment, period: float, command: str, choice: str | None = None) -> str:
    """The law ``command`` runs for ``experiment`` at the interface ``period`` [s]:
    ``choice`` (``--inner-law``) else ``[realtime] inner_law``, ``"auto"`` resolved and
    checked (:func:`inner_law_of`); the commands call it before they write anything.

    Raises:
        ConfigError: As :func:`inner_law_of`, named ``--inner-law`` or
            ``realtime.inner_law``.
    """
    key = "realtime.inner_law" if choice is None else "--inner-law"
    given = experiment.config.realtime.inner_law if choice is None else choice
    law = inner_law_of(given, command, experiment.controller, period, key)
    planner = experiment.config.realtime.planner
    if planner is not None:
        from ..realtime.threaded_law import checked_planner_scheduling

        checked_planner_scheduling(planner, "realtime.planner")
        if law != "threaded":
            raise ConfigError(
                "realtime.planner",
                f"does not apply: the inner law is {law} (the planner is the threaded "
                "law's MPC thread); drop it, or run the threaded law (--inner-law threaded)",
            )
    return law


def inner_law_controller(
    experiment,
    period: float,
    command: str,
    effort_limit=None,
    choice: str | None = None,
) -> Any:
    """The controller the real-time loop runs: the experiment's own (``"whole-step"``), or
    it wrapped in the law chosen (:func:`inner_law_of`) with an observer of its own at
    ``period``. A threaded law's planner thread runs from here: close it
    (:func:`close_law`) on every way out.

    Args:
        experiment: The built experiment (:class:`~hmpc_pin.experiment.build.Experiment`).
        period: The interface period [s].
        command: ``"realtime"``, ``"ros"`` or ``"franka"`` (what ``"auto"`` means).
        effort_limit: Per-joint limit [N·m] the arm applies the torque within (the law's
            observer is fed the clipped torque), or ``None``.
        choice: ``--inner-law`` (named so in errors), else ``None``: ``[realtime]
            inner_law``.

    Raises:
        ConfigError: The law chosen does not apply (:func:`check_inner_law`).
    """
    ctrl = experiment.controller
    law = chosen_inner_law(experiment, period, command, choice)
    if law == "whole-step":
        return ctrl
    from ..realtime.threaded_law import InnerLawThreaded
    from .controllers import make_compensation

    cc = experiment.config.controller
    fast = make_compensation(experiment.robot, replace(cc, Ts=period), experiment.q0)
    if law == "threaded":
        threaded = InnerLawThreaded(ctrl, fast, period, effort_limit)
        planner = experiment.config.realtime.planner
        if planner is not None:  # (checked by chosen_inner_law)
            threaded.planner_scheduling = planner
        return threaded
    return InnerLawEveryCycle(ctrl, fast, period, effort_limit)


def _law(controller: Any) -> Any:
    """The inner law inside ``controller``'s wrappers (``None``: the whole step runs)."""
    c = controller
    while c is not None:
        if isinstance(c, InnerLawEveryCycle):  # (the threaded law is one)
            return c
        c = c.__dict__.get("controller") if hasattr(c, "__dict__") else None
    return None


def inner_law_summary(controller: Any, period: float) -> dict:
    """What ran, for the run's record: the law's own summary (its name, label, cycles per
    MPC step, a threaded law's planner counts and fallbacks), or the whole step's
    (``name`` ``"whole-step"``, ``mpc_every`` cycles per step)."""
    law = _law(controller)
    if law is not None:
        return law.summary()
    Ts = float(controller.Ts)
    m = max(1, round(Ts / period))
    return {
        "name": "whole-step",
        "label": "whole step every cycle" if m == 1 else "held between steps",
        "mpc_every": m,
        "period": float(period),
    }


def close_law(controller: Any) -> None:
    """Close the inner law inside ``controller``'s wrappers (the threaded law's planner
    thread stopped and joined; idempotent; nothing for the others)."""
    law = _law(controller)
    if law is not None:
        law.close()
