"""The result of a friction fit (:func:`~hmpc_pin.identification.friction.fit_friction`):
per joint the viscous and Coulomb coefficients with their confidence intervals, what was
left out and why, as a Markdown table and as the ``[controller.friction]`` table of a
config."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["MIN_DEGREES_OF_FREEDOM", "SETTLING_TIME_CONSTANTS", "FrictionFit", "JointFriction"]


#: Fewest degrees of freedom :math:`m_e - p` of an interval: below it the residual is so
#: correlated (:math:`m_e` so small) that the AR(1) correction, itself estimated from the
#: residual, cannot be trusted, and no interval is given (NaN, printed "n/a").
MIN_DEGREES_OF_FREEDOM = 10
#: Observer time constants left out after a joint was stuck (the observer source): the
#: holding torque the friction law does not hold leaves the observer's estimate as
#: :math:`e^{-t/\tau}`, below :math:`e^{-5} < 1\,\%` of itself after five.
SETTLING_TIME_CONSTANTS = 5.0


@dataclass(frozen=True)
class JointFriction:
    """The friction fit of one joint.

    Attributes:
        name: The joint.
        viscous: :math:`\\hat a` [N·m·s/rad]. coulomb: :math:`\\hat b` [N·m].
        viscous_ci, coulomb_ci: Their confidence intervals (low, high); NaN when the
            residual leaves too few effective samples (:data:`MIN_DEGREES_OF_FREEDOM`).
        residual_rms: RMS of the fit's residual [N·m].
        samples: Samples used, :math:`m`. effective_samples: :math:`m_e` (AR(1)).
        condition: Condition number of the column-normalised regressor.
        coverage: Fractions of the samples moving forward and backward (> v_0, < -v_0).
    """

    name: str
    viscous: float
    coulomb: float
    viscous_ci: tuple[float, float]
    coulomb_ci: tuple[float, float]
    residual_rms: float
    samples: int
    effective_samples: float
    condition: float
    coverage: tuple[float, float]

    @property
    def has_interval(self) -> bool:
        """Whether the intervals are given (enough effective samples)."""
        return bool(np.all(np.isfinite(self.viscous_ci + self.coulomb_ci)))


def _ci(value: float, ci: tuple[float, float], digits: int) -> str:
    if not np.all(np.isfinite(ci)):
        return f"{value:.{digits}g} [n/a]"
    return f"{value:.{digits}g} [{ci[0]:.{digits}g}, {ci[1]:.{digits}g}]"


@dataclass(frozen=True)
class FrictionFit:
    """Friction fitted for every joint of a run.

    Attributes:
        joints: One :class:`JointFriction` per joint.
        source: ``"observer"`` or ``"dynamics"``.
        confidence: Level of the intervals (e.g. 0.95).
        run: The run it was fitted from (file or config name), for the TOML comment.
        excluded: Samples left out because a recorded column used by the fit (q, q̇,
            τ, :math:`\\hat d`) is NaN or infinite there (the observer source: and the
            observer's start-up, ``after``, once its filter starts again after each gap).
        unmodelled: The disturbances besides friction the run is known to have had within
            the samples fitted (its config's ``[disturbance.pulse]``), in words, or ``""``:
            named as the cause of a missing interval.
        unmodelled_until: The time after which those disturbances are negligible [s]
            (the ``--after`` that leaves them out; 0 when not known).
        stuck: Samples left out (of those the fit would use) because a joint was stuck
            there, or the observer was still settling after it (the observer source).
        stuck_joints: The joints found stuck (:func:`.stuck_samples`).
        settling: Time left out after each stuck interval [s]:
            :data:`SETTLING_TIME_CONSTANTS` × ``time_constant``.
        time_constant: The slowest time constant of the observer that ran [s]
            (:meth:`.ObserverModel.time_constant`), 0 when not known.
    """

    joints: tuple[JointFriction, ...]
    source: str
    confidence: float
    run: str = ""
    excluded: int = 0
    unmodelled: str = ""
    stuck: int = 0
    stuck_joints: tuple[str, ...] = ()
    settling: float = 0.0
    time_constant: float = 0.0
    unmodelled_until: float = 0.0

    def impossible(self) -> list[tuple[str, str, float]]:
        """The coefficients no friction can have, (joint, ``"viscous"`` or ``"Coulomb"``,
        fitted value): a negative :math:`\\hat a` or :math:`\\hat b` would feed energy in
        where friction takes it out. :meth:`toml` leaves them out (0: nothing fed forward)."""
        return [
            (j.name, term, value)
            for j in self.joints
            for term, value in (("viscous", j.viscous), ("Coulomb", j.coulomb))
            if value < 0
        ]

    def notes(self) -> list[str]:
        """Why an interval is missing, and what was left out (one sentence each)."""
        out = []
        short = [j for j in self.joints if not j.has_interval]
        if short:
            names = ", ".join(f"{j.name} (m_e = {j.effective_samples:.1f})" for j in short)
            out.append(
                f"no confidence interval for {names}: the residual is so correlated that "
                "its effective samples m_e = m(1-rho)/(1+rho) (rho: lag-1 autocorrelation) "
                f"leave fewer than {MIN_DEGREES_OF_FREEDOM} degrees of freedom "
                + (
                    f"(the run had {self.unmodelled}, which the friction model does not "
                    "hold); fit a run without them, or pass "
                    + (
                        f"--after {self.unmodelled_until:.3g} (past them)"
                        if self.unmodelled_until > 0
                        else "--after past them"
                    )
                    if self.unmodelled
                    else "(a disturbance the friction model does not hold, or the observer's "
                    "lag); record a longer run"
                )
                + (", or try --source dynamics" if self.source == "observer" else "")
            )
        if self.stuck:
            out.append(
                f"{self.stuck} samples left out where {', '.join(self.stuck_joints)} stuck "
                "(the measured velocity within its noise band for a period or more: the "
                "friction there is a holding torque within +/- the Coulomb level, which "
                "the law a q̇ + b sgn q̇ does not hold)"
                + (
                    f" and for {self.settling:.3g} s after each, the observer's settling "
                    f"({SETTLING_TIME_CONSTANTS:g} x its time constant "
                    f"{self.time_constant:.3g} s)"
                    if self.settling > 0
                    else ""
                )
            )
        if self.excluded:
            out.append(
                f"{self.excluded} samples left out: NaN or inf in a recorded column"
                + (
                    " (and, after each such gap, the observer's start-up, --after)"
                    if self.source == "observer"
                    else ""
                )
            )
        bad = self.impossible()
        if bad:
            listed = ", ".join(f"{name}'s {term} {value:.4g}" for name, term, value in bad)
            out.append(
                f"left out (0 written, nothing fed forward): {listed}; a negative friction "
                "coefficient would feed energy in, which no friction does: the fit holds "
                "something else"
                + (
                    f" ({self.unmodelled}: pass --after {self.unmodelled_until:.3g})"
                    if self.unmodelled and self.unmodelled_until > 0
                    else " (a disturbance the friction model does not hold, too little "
                    "motion, or a wrong model); check the run"
                )
            )
        return out

    @property
    def viscous(self) -> np.ndarray:
        """:math:`\\hat a` per joint [N·m·s/rad]."""
        return np.array([j.viscous for j in self.joints])

    @property
    def coulomb(self) -> np.ndarray:
        """:math:`\\hat b` per joint [N·m]."""
        return np.array([j.coulomb for j in self.joints])

    def table(self) -> str:
        """A Markdown table: coefficient, interval, residual, samples, condition, coverage."""
        pct = f"{100 * self.confidence:g} %"
        lines = [
            f"| joint | viscous [N·m·s/rad] ({pct} CI) | Coulomb [N·m] ({pct} CI) | "
            "residual RMS [N·m] | samples (effective) | cond | moving +/- |",
            "|---|---|---|---|---|---|---|",
        ]
        for j in self.joints:
            lines.append(
                f"| {j.name} | {_ci(j.viscous, j.viscous_ci, 4)} "
                f"| {_ci(j.coulomb, j.coulomb_ci, 4)} | {j.residual_rms:.3g} | "
                f"{j.samples} ({j.effective_samples:.0f}) | "
                f"{j.condition:.3g} | {100 * j.coverage[0]:.0f} % / {100 * j.coverage[1]:.0f} % |"
            )
        return "\n".join(lines + [f"note: {n}" for n in self.notes()])

    def toml(self) -> str:
        """The ``[controller.friction]`` table (feed-forward friction compensation) with
        the intervals as comments; paste it into a config (or merge it with
        ``hmpc-pin identify --config``). A negative coefficient (:meth:`impossible`) is
        written as 0, and a note says why."""
        pct = f"{100 * self.confidence:g} %"
        names = ", ".join(j.name for j in self.joints)
        lines = [
            f"# Friction identified by `hmpc-pin identify` from {self.run or 'a run'} "
            f"(source: {self.source}); joints: {names}",
            f"# {pct} confidence intervals and fit residual per joint:",
        ]
        for j in self.joints:
            lines.append(
                f"#   {j.name}: viscous {_ci(j.viscous, j.viscous_ci, 6)} N·m·s/rad, Coulomb "
                f"{_ci(j.coulomb, j.coulomb_ci, 6)} N·m, residual RMS {j.residual_rms:.3g} N·m"
            )
        lines += [f"# note: {n}" for n in self.notes()]
        viscous, coulomb = np.maximum(self.viscous, 0.0), np.maximum(self.coulomb, 0.0)
        lines += [
            "[controller.friction]",
            f"viscous = [{', '.join(f'{v:.6g}' for v in viscous)}]   # [N·m·s/rad]",
            f"coulomb = [{', '.join(f'{v:.6g}' for v in coulomb)}]   # [N·m]",
        ]
        return "\n".join(lines) + "\n"
