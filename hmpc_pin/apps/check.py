"""``hmpc-pin check CONFIG``: what to know about an arm before anything runs on it.

Per joint, from the config's models alone (the arm is not simulated; the loops' linear models are):

* **observer bandwidth** :math:`\\omega_j` [1/s] and :math:`\\omega_j T_s`: the rate at which
  joint j's estimation error decays, :math:`\\omega_j = (cY M(q_0)^{-1})_{jj}` for the NDO
  of Eq (13) (``chen``, ``general``;
  :func:`~hmpc_pin.compensation.bandwidth.implied_bandwidth`), :math:`K_j` for the momentum
  observer;
* **margin** of the rule of :mod:`hmpc_pin.compensation.bandwidth` for an arm:
  :math:`\\omega_j r (T_s + L_u) \\le 1/2` with :math:`L_u` one control period the
  controller is not told about (none declared), or, with a latency declared,
  :math:`\\omega_j (r T_s + 2\\Delta L - 2T_s) \\le 1` with :math:`\\Delta L = \\min(L, T_s)/2`
  (:func:`~hmpc_pin.compensation.bandwidth.overdeclared_limit`), r = 1.25: the margin is
  :math:`\\omega_{\\max}/\\omega_j` [-];
* **damping time constant** :math:`1/(b_j (M(q_0)^{-1})_{jj})` [s] of the URDF's joint
  damping (:func:`~hmpc_pin.model.robot.damping_time_constants`);
* **torque headroom** along the reference: :math:`1 - \\max_t |\\tau_j(t)| / \\tau_{j,\\max}`
  with :math:`\\tau = M(r)\\ddot r + C(r, \\dot r)\\dot r + G(r)
  + B\\dot r + F\\,\\mathrm{sgn}\\,\\dot r - d(t, r, \\dot r)` (B, F when the plant applies
  the URDF's joint dynamics, d the config's disturbance; RNEA along the reference sampled
  every :math:`T_s/4` over the run, :math:`\\ddot r` by central differences) against the
  plant's effort limits;

the **workspace**: the reference against the mounting plane of ``[workspace]`` (the root
link's height without the table) and for self-collision, on the URDF's collision geometry
(:func:`~hmpc_pin.experiment.workspace.scan_reference`);

and, with MuJoCo installed, **the model against a second engine**: :math:`M(q)` and the
forward dynamics :math:`\\ddot q(q, \\dot q, \\tau)` of Pinocchio and MuJoCo (the bare arm)
at :data:`.ENGINE_SAMPLES` seeded states within the limits, within :data:`ENGINE_RTOL`.

The loops' linear models are a library: :mod:`hmpc_pin.compensation.loop_analysis` (one
joint's loop at a posture) and :mod:`hmpc_pin.experiment.observer_analysis` (the observer
along the reference); this module turns their figures into problems and warnings.

**Problems and warnings.** A *problem* is what ``hmpc-pin run`` would show: the run
leaves its tolerance, and the change the problem names (:attr:`CheckReport.fixes`,
:func:`apply_fix`) makes it track (the package's tests check both over every packaged
config, ``init``'s files and variants of them). A *warning* matters on a
real arm, not in ``run``. ``run`` hands the controller fresh
measurements of a plant equal to the model (r = 1 unless the plant differs); so:

* the margin below 1 is a warning (the paper's configs keep their settings, and say so);
* a declared latency L is L too long in ``run``: a problem when the observer's loop then
  has a pole at :math:`|z| \\ge 1`, or at :math:`|z| \\ge` :data:`MAX_RADIUS` decaying
  slower than :data:`.MIN_DECAY` times the observer's own (:func:`.overdeclared_radius`),
  or when the MPC, acting on the state predicted L ahead, decays slower than
  :data:`.MIN_DECAY` times its rate without the prediction (:func:`.lead_radius`), or when
  the two together (:func:`.loop_radius`) grow at :math:`q_0` (a fraction of a period
  over-declared can pass each alone); the two growing only at a posture along the
  reference where the observer's modes (:func:`.observer_modes`) are faster: a warning
  (measured over the package's corpus, ``run`` leaves its tolerance in half such cases);
  a whole loop that decays, however slowly, is neither (in ``run`` it tracks, init's UR5
  at half a period: 0.977 per period against 0.887 without the latency);
* an observer too slow for the disturbance: the error its lag along the reference leaves
  through the MPC's loop (:func:`.observer_lag_error`) above ``run``'s tracking threshold
  after its start-up: a problem whose fix raises the observer's gain (a warning when no
  gain within the explicit form's limit does);
* the explicit observer with :math:`T_s\\omega_j \\ge 2`: a problem; below, its loop with
  the MPC (its estimate keeps :math:`-(T_s\\omega)^2` times the acceleration) decaying
  slower than :data:`.MIN_DECAY` times the implicit form's, or growing
  (:func:`.explicit_loop_slow`): a problem whose fix is the implicit form;
* a damping time constant below :math:`2T_s` that plant and controller treat differently
  (one applies it, the other not): a problem; left out of both: a warning (the real arm
  applies it);
* headroom below :data:`MIN_HEADROOM`: a problem;
* friction with the literal sign (it feeds energy in) and no compensation: a problem (a
  warning for the paper's baseline, which is expected to lose the reference); with an
  observer a warning (nothing here bounds the error it leaves);
* a link leaving the workspace (closer to the plane than the margin) or two links
  colliding, named with the time: a problem when the config declares its ``[workspace]``
  (``run`` simulates neither, the arm would hit them), else a warning;
* MuJoCo refusing the URDF, or the engines differing: a problem with a MuJoCo plant,
  else a warning (the table is printed either way).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..compensation.bandwidth import (
    MASS_RATIO,
    bandwidth_limit,
    compensation_bandwidth,
    overdeclared_excess,
    overdeclared_limit,
)
from ..compensation.loop_analysis import (
    MIN_DECAY,
    explicit_loop_slow,
    lead_radius,
    loop_radius,
    overdeclared_radius,
)
from ..exceptions import HmpcError, URDFError
from ..experiment.build import Experiment
from ..experiment.config import ExperimentConfig, WorkspaceConfig
from ..experiment.observer_analysis import (
    lag_inputs,
    observer_lag_error,
    observer_modes,
    running_observer,
    worst_along,
)
from ..experiment.plants import plant_effort_limit
from ..experiment.torque_headroom import torque_headroom
from ..experiment.workspace import scan_reference
from ..model.robot import damping_time_constants
from ..sim.engine_agreement import ENGINE_SAMPLES, engine_agreement
from ..sim.engines import DEFAULT_ENGINE, engine_spec
from .metrics import DEFAULT_ERROR_THRESHOLD, RUN_WARN_AFTER

__all__ = [
    "ENGINE_RTOL",
    "ENGINE_SAMPLES",
    "MAX_RADIUS",
    "MIN_DECAY",
    "MIN_HEADROOM",
    "CheckReport",
    "apply_fix",
    "check_config",
    "explicit_loop_slow",
    "lead_radius",
    "loop_radius",
    "observer_lag_error",
    "observer_modes",
    "overdeclared_radius",
]

#: Smallest torque headroom along the reference [-] that is not a problem: runs of the
#: packaged arms whose every effort limit is 5 % above the torque the reference and the
#: disturbance need leave their tolerance (the start and the observer need the rest).
MIN_HEADROOM = 0.1
#: Largest pole modulus [-] of the observer loop with the declared latency too long
#: (:func:`.overdeclared_radius`) that is not a problem: measured on the Panda (init's
#: Ts w = 10 and the shipped config's Ts w up to 153), runs track at |z| <= 0.96 and
#: oscillate from |z| = 0.99 (a pole that close to -1 rings with the outer loop).
MAX_RADIUS = 0.95
#: Largest relative difference of M(q) and q̈ between Pinocchio and MuJoCo [-] (both are
#: exact rigid-body algorithms on the same inertias: only rounding separates them).
ENGINE_RTOL = 1e-6


@dataclass
class CheckReport:
    """The figures of :func:`check_config` and the problems found.

    Attributes:
        joints: Joint names.
        Ts: Control period [s].
        latency: The latency the controller is told about, ``[controller] latency`` [s].
        bandwidth: Observer bandwidth per joint [1/s] (``None``: no observer).
        margin: The rule's margin :math:`\\omega_{\\max}/\\omega_j` per joint [-] (below 1: a
            problem; inf: no bound; ``None``: no observer).
        damping_tau: Damping time constant per joint [s] (inf: none;
            :func:`~hmpc_pin.model.robot.damping_time_constants`).
        headroom: Torque headroom per joint [-] (inf: no limit).
        engine: ``(max rel. difference of M, of q̈)`` against MuJoCo, or a sentence why
            not compared.
        problems: One line per problem: ``run`` would not track within its tolerance,
            and the change the line suggests (``fixes``) makes it track (empty: fine).
        fixes: Per problem the config change that removes it (:func:`apply_fix`), or
            ``None`` when there is no single change.
        warnings: One line per finding that does not affect ``run`` but matters on an arm
            (an interface's latency, lighter links, the real arm's damping, a second
            engine).
        workspace: The reference against the mounting plane and for self-collision, one
            line (``""``: not scanned).
    """

    joints: tuple[str, ...]
    Ts: float
    latency: float
    bandwidth: np.ndarray | None
    margin: np.ndarray | None
    damping_tau: np.ndarray
    headroom: np.ndarray
    engine: tuple[float, float] | str
    problems: list[str] = field(default_factory=list)
    fixes: list[dict[str, Any] | None] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    workspace: str = ""

    def add_problem(self, text: str, fix: dict[str, Any] | None) -> None:
        """One problem and the change of the config that removes it in ``run``
        (:func:`apply_fix`; ``None``: no single change)."""
        self.problems.append(text)
        self.fixes.append(fix)

    def format(self) -> str:
        """The per-joint table, the engine comparison and the problems, as text."""
        lines = [
            f"Ts = {self.Ts:g} s, latency = {self.latency:g} s",
            f"{'joint':<24} {'w [1/s]':>9} {'w*Ts':>7} {'margin':>8} {'T_b [s]':>9} "
            f"{'headroom':>9}",
        ]
        for j, name in enumerate(self.joints):
            bw = "-" if self.bandwidth is None else f"{self.bandwidth[j]:.3g}"
            wts = "-" if self.bandwidth is None else f"{self.bandwidth[j] * self.Ts:.3g}"
            mg = (
                "-"
                if self.margin is None
                else "inf"
                if np.isinf(self.margin[j])
                else f"{self.margin[j]:.2g}x"
            )
            tau = "-" if not np.isfinite(self.damping_tau[j]) else f"{self.damping_tau[j]:.3g}"
            hr = "-" if not np.isfinite(self.headroom[j]) else f"{100 * self.headroom[j]:.0f} %"
            lines.append(f"{name:<24} {bw:>9} {wts:>7} {mg:>8} {tau:>9} {hr:>9}")
        if self.workspace:
            lines.append(f"workspace: {self.workspace}")
        if isinstance(self.engine, str):
            lines.append(f"MuJoCo: {self.engine}")
        else:
            lines.append(
                f"MuJoCo: M(q) within {self.engine[0]:.2g}, forward dynamics within "
                f"{self.engine[1]:.2g} (relative) of Pinocchio's"
            )
        return "\n".join(lines)


def _explicit(config: ExperimentConfig) -> bool:
    """The observer is the NDO in its forward-Euler form (the momentum observer has one
    form, semi-implicit: :math:`g = T_sK_O/(1 + T_sK_O)`)."""
    cc = config.controller
    return (
        cc.compensation != "momentum" and getattr(cc.observer, "discretization", "") == "explicit"
    )


def _run_ratio(ex: Experiment) -> float:
    """r of the simulated plant: the largest :math:`M_{jj}` of the controller's model
    over the plant's at :math:`q_0` (1 when the plant is the controller's model)."""
    plant = getattr(ex, "plant", None)
    if plant is None or getattr(plant, "nq", None) != ex.robot.nq:
        return MASS_RATIO
    m_model = np.diag(ex.robot.mass_matrix(ex.q0))
    m_plant = np.diag(plant.mass_matrix(ex.q0))
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(m_plant > 0, m_model / m_plant, 1.0)
    return float(max(np.max(ratio), 1e-3))


def _is_paper(config: ExperimentConfig) -> bool:
    """A config reproducing the paper (``paper_*``): its settings are kept as the paper's."""
    return str(getattr(config, "name", "")).startswith("paper_")


def _observer_findings(
    report: CheckReport, config: ExperimentConfig, ex: Experiment, bw: np.ndarray
) -> np.ndarray:
    """The observer's rules: problems for ``run``, warnings for an arm; the margin."""
    names, Ts, latency = report.joints, report.Ts, report.latency
    uncompensated = 0.0 if latency > 0 else Ts
    excess = overdeclared_excess(Ts, latency)
    limit = overdeclared_limit(Ts, excess) if latency > 0 else bandwidth_limit(Ts, uncompensated)
    margin = np.where(bw > 0, limit / np.where(bw > 0, bw, 1.0), np.inf)
    # an arm: its interface delays the measurements (one period unknown, or the declared
    # latency off by half an interface cycle) and its links may be 20 % lighter
    over = np.flatnonzero(margin < 1.0 - 1e-9)
    if over.size:
        listed = ", ".join(f"{names[j]!r} ({bw[j]:.3g} 1/s, w Ts = {bw[j] * Ts:.3g})" for j in over)
        if latency > 0:
            report.warnings.append(
                f"on an arm: observer bandwidth above {limit:.4g} 1/s on joint(s) {listed}, "
                f"the rule w (r Ts + 2 dL - 2 Ts) <= 1 for a latency declared dL = {excess:g} "
                f"s longer than it is (half an interface cycle, r = {MASS_RATIO:g}): the "
                "observer's estimate would alternate in sign and grow; lower the "
                "bandwidth or measure the latency"
            )
        else:
            kept = " (the paper's setting, kept: its simulation has no latency)"
            report.warnings.append(
                f"on an arm: observer bandwidth above {limit:.3g} 1/s on joint(s) {listed}, "
                f"the rule w r (Ts + L) <= 1/2 for a latency of L = {uncompensated:g} s the "
                f"controller is not told about (r = {MASS_RATIO:g}); `run` simulates "
                f"measurements without latency{kept if _is_paper(config) else ''}; on an "
                "arm declare its latency ([controller] latency) or lower the observer gain"
            )
    return margin


def _explicit_loop_findings(
    report: CheckReport, config: ExperimentConfig, ex: Experiment, bw: np.ndarray
) -> None:
    """The explicit observer inside the MPC's loop without latency
    (:func:`.explicit_loop_slow`) on a joint whose own pole :math:`|1 - T_s\\omega_j|` is
    inside the unit circle (outside: the rule of :func:`check_config`): a problem whose
    fix is the implicit form."""
    from ..controllers.computed_torque import mpc_feedback_gain
    from ..mpc.condensed import CondensedMPC

    if not _explicit(config):
        return
    cc, Ts, names = config.controller, report.Ts, report.joints
    kp, kd = mpc_feedback_gain(CondensedMPC(Ts, cc.N, cc.Nc, cc.Q, cc.R, cc.P))
    ratio = _run_ratio(ex)
    bad = np.flatnonzero(explicit_loop_slow(kp, kd, Ts, bw * Ts, ratio) & (bw * Ts < 2.0))
    if bad.size:
        listed = ", ".join(
            f"{names[j]!r} (w Ts = {bw[j] * Ts:.3g}, |z| = "
            f"{loop_radius(kp, kd, Ts, bw[j] * Ts, 0.0, ratio, True):.3g})"
            for j in bad
        )
        report.add_problem(
            "the observer's forward-Euler form keeps -(w Ts)^2 times the arm's acceleration "
            "in its estimate, which feeds the MPC's input back: the loop of the two "
            f"(loop_radius) decays slower than {MIN_DECAY:g} x the implicit form's loop at "
            f"the same bandwidth, or grows, on joint(s) {listed}; set discretization = "
            "'implicit' (or lower the observer's gain)",
            {"controller.observer.discretization": "implicit"},
        )


def _run_latency_findings(
    report: CheckReport, config: ExperimentConfig, ex: Experiment, bw: np.ndarray | None
) -> None:
    """``run`` simulates measurements without latency: a declared latency L is L too
    long there. A problem when the observer's loop (:func:`.overdeclared_radius`) has a
    pole of modulus >= 1, or >= :data:`MAX_RADIUS` and decaying slower than
    :data:`.MIN_DECAY` times the observer's own pole :math:`|1 - gr|` (a slow observer's
    lies near 1 by design), or the
    outer loop (:func:`.lead_radius`) then decays slower than :data:`.MIN_DECAY` times
    its rate without the prediction, or the two together (:func:`.loop_radius`) grow at
    :math:`q_0`. A warning when they grow only at the observer's modal bandwidths at
    other postures along the reference (:func:`.observer_modes`)."""
    from ..controllers.computed_torque import mpc_feedback_gain
    from ..mpc.condensed import CondensedMPC

    names, Ts, latency = report.joints, report.Ts, report.latency
    if latency <= 0:
        return
    cc = config.controller
    over = latency / Ts
    parts = []
    kp, kd = mpc_feedback_gain(CondensedMPC(Ts, cc.N, cc.Nc, cc.Q, cc.R, cc.P))
    whole_bad: np.ndarray = np.array([], dtype=int)
    along, w_along, t_along = 0.0, 0.0, 0.0
    if bw is not None:
        ratio = _run_ratio(ex)
        explicit = _explicit(config)
        whole = np.array([loop_radius(kp, kd, Ts, w * Ts, over, ratio, explicit) for w in bw])
        whole0 = np.array([loop_radius(kp, kd, Ts, w * Ts, 0.0, ratio, explicit) for w in bw])
        whole_bad = np.flatnonzero((whole >= 1.0) & (whole0 < 1.0))
        if not whole_bad.size and np.all(whole0 < 1.0):  # the observer's modes elsewhere
            t_modes, modes = observer_modes(ex)
            along, w_along, t_along = worst_along(
                lambda w: loop_radius(kp, kd, Ts, w * Ts, over, ratio, explicit),
                t_modes,
                modes,
            )
        radius = np.array([overdeclared_radius(w * Ts, ratio, over, explicit) for w in bw])
        own = np.array([overdeclared_radius(w * Ts, ratio, 0.0, explicit) for w in bw])
        # a slow observer's own pole (1 - g r) lies near 1 by design: only a pole that
        # also decays slower than MIN_DECAY times it counts
        with np.errstate(divide="ignore"):
            slower = np.log(np.minimum(radius, 1.0)) > MIN_DECAY * np.log(own)
        # own >= 1: unstable without the latency too (an explicit w Ts >= 2, its own problem)
        bad = np.flatnonzero(((radius >= 1.0) | ((radius >= MAX_RADIUS) & slower)) & (own < 1.0))
        if bad.size:
            listed = ", ".join(
                f"{names[j]!r} ({bw[j]:.3g} 1/s, |z| = {radius[j]:.3g})" for j in bad
            )
            parts.append(
                f"the observer pairs each velocity change with a torque {over:.3g} periods "
                f"too early and its loop's pole reaches |z| >= {MAX_RADIUS:g} on joint(s) "
                f"{listed}"
            )
    base, lead = lead_radius(kp, kd, Ts, 0.0), lead_radius(kp, kd, Ts, over)
    decay, decay0 = -math.log(min(lead, 1.0)) / Ts, -math.log(base) / Ts
    if decay < MIN_DECAY * decay0:
        parts.append(
            f"the MPC acts on the state predicted {latency:g} s ahead of the measured one, "
            f"and its loop (kp = {kp:.4g} 1/s², kd = {kd:.4g} 1/s) then decays at "
            f"{decay:.3g} 1/s (|z| = {lead:.3g}), below {MIN_DECAY:g} x its {decay0:.3g} 1/s "
            "without the prediction"
        )
    together = (
        "the MPC acting on the state predicted that far ahead and the observer pairing "
        f"each velocity change with torques {over:.3g} periods too early together "
        "(loop_radius) grow"
    )
    if not parts and whole_bad.size:  # each loop alone passes; together they do not
        listed = ", ".join(
            f"{names[j]!r} (|z| = {whole[j]:.3g}, {whole0[j]:.3g} without)" for j in whole_bad
        )
        parts.append(f"{together} on joint(s) {listed}")
    elif not parts and along >= 1.0:  # at q0 they decay; where the inertia changes not
        report.warnings.append(
            f"latency = {latency:g} s ({over:.3g} periods) is declared, but `run` simulates "
            f"measurements without latency: {together} where the reference takes the arm "
            f"at t = {t_along:.3g} s (an observer mode there has w = {w_along:.4g} 1/s, w Ts "
            f"= {w_along * Ts:.3g}: the eigenvalues of M(q)^-1 cY; the loop |z| = "
            f"{along:.3g}); whether the run leaves its tolerance there is beyond this "
            "frozen-posture model: run it, or set [controller] latency = 0 in `run`"
        )
    if parts:
        report.add_problem(
            f"latency = {latency:g} s ({over:.3g} periods) is declared, but `run` simulates "
            f"measurements without latency: {'; and '.join(parts)}; in `run` set "
            "[controller] latency = 0 (on an arm: the latency it measures, "
            "`hmpc-pin realtime` reports it)",
            {"controller.latency": 0.0},
        )


def _observer_lag_findings(
    report: CheckReport, config: ExperimentConfig, ex: Experiment, bw: np.ndarray
) -> None:
    r"""An observer too slow for the disturbance (:func:`.observer_lag_error` above
    `run`'s tracking tolerance): a problem whose fix raises the bandwidth by the
    smallest power of 2 that brings the predicted error within half the tolerance
    (below the explicit form's :math:`T_s\omega < 2`); a warning when none does."""
    from ..controllers.computed_torque import mpc_feedback_gain
    from ..mpc.condensed import CondensedMPC

    cc = config.controller
    Ts = report.Ts
    kp, kd = mpc_feedback_gain(CondensedMPC(Ts, cc.N, cc.Nc, cc.Q, cc.R, cc.P))
    if not np.any(bw > 0) or (
        _explicit(config)
        and (
            np.max(bw) * Ts >= 2.0
            or np.any(explicit_loop_slow(kp, kd, Ts, bw * Ts, _run_ratio(ex)))
        )
    ):
        return  # no observer, or an unstable one, or its loop with the MPC (their problems)
    inputs = lag_inputs(ex)
    err = observer_lag_error(ex, kp, kd, RUN_WARN_AFTER, inputs=inputs)
    bad = np.flatnonzero(err > DEFAULT_ERROR_THRESHOLD)
    if not bad.size or not np.all(np.isfinite(err)):
        return  # (an estimate that diverges along the reference is no lag)
    listed = ", ".join(f"{report.joints[j]!r} ({bw[j]:.3g} 1/s: {err[j]:.3g} rad)" for j in bad)
    text = (
        f"observer too slow for the disturbance: what it has not yet caught leaves a "
        f"predicted tracking error above `run`'s {DEFAULT_ERROR_THRESHOLD:g} rad after "
        f"{RUN_WARN_AFTER:g} s on joint(s) {listed} (its lag along the reference, "
        "through the MPC's loop: observer_lag_error)"
    )
    for power in range(1, 13):
        scale = 2.0**power
        if _explicit(config) and (
            np.max(bw) * scale * Ts >= 2.0
            or np.any(explicit_loop_slow(kp, kd, Ts, bw * scale * Ts, _run_ratio(ex)))
        ):
            break
        if np.all(
            observer_lag_error(ex, kp, kd, RUN_WARN_AFTER, scale, inputs)
            <= 0.5 * DEFAULT_ERROR_THRESHOLD
        ):
            obs = cc.observer
            if obs is None:  # a compensation without the observer's table: no key to raise
                break
            if obs.bandwidth is not None:
                key, value = "bandwidth", np.asarray(obs.bandwidth, dtype=float) * scale
            else:
                key, value = "gain", np.asarray(obs.gain, dtype=float) * scale
            fix = value.tolist() if value.ndim else float(value)
            report.add_problem(
                f"{text}; raise [controller.observer] {key} {scale:g} x (to {fix})",
                {f"controller.observer.{key}": value if value.ndim else float(value)},
            )
            return
    report.warnings.append(f"{text}; no observer bandwidth within its limits removes it")


def _friction_findings(report: CheckReport, config: ExperimentConfig) -> None:
    """A disturbance and nothing compensating it: with friction read with the literal sign
    (it feeds energy in) the arm runs away from the reference (a problem, kept as a
    warning for the paper's baseline), otherwise `run` warns about the error (a
    warning)."""
    friction = getattr(config.disturbance, "friction", None)
    if config.controller.compensation != "none":
        if getattr(friction, "sign", None) == "literal":  # the observer must outrun it
            report.warnings.append(
                "[disturbance.friction] sign = 'literal' feeds energy in (d = +(B q' + F "
                "sgn q'): negative damping): the observer must cancel a disturbance that "
                "grows with the error it leaves, which no rule here bounds; `run`'s "
                "tracking error may exceed its --warn-error threshold"
                + (
                    " (the paper's literal reading of Eq 32, kept)"
                    if _is_paper(config)
                    else "; sign = 'physical' simulates friction that dissipates"
                )
            )
        return
    if getattr(friction, "sign", None) != "literal":
        pulse = getattr(config.disturbance, "pulse", None)
        if friction is not None or (pulse is not None and np.any(np.asarray(pulse.amplitude))):
            report.warnings.append(
                "the [disturbance] is not compensated (compensation 'none'): `run`'s "
                "tracking error is expected above its --warn-error threshold"
                + (
                    " (the paper's baseline without the observer, kept)"
                    if _is_paper(config)
                    else "; choose a compensation (an observer) to reject it"
                )
            )
        return
    text = (
        "[disturbance.friction] sign = 'literal' feeds energy in (d = +F) and the "
        "controller compensates nothing (compensation 'none'): the arm is expected to "
        "lose the reference"
    )
    if _is_paper(config):
        report.warnings.append(f"{text} (the paper's baseline without the observer, kept)")
    else:
        report.add_problem(f"{text}; choose a compensation (an observer)", None)


def _damping_findings(report: CheckReport, config: ExperimentConfig) -> None:
    """The URDF damping against Ts, in the controller and in the simulated plant."""
    names, Ts, tau = report.joints, report.Ts, report.damping_tau
    controller = bool(getattr(config.controller, "joint_dynamics", False))
    plant = bool(config.plant.joint_dynamics)
    fast = np.flatnonzero(tau < 2 * Ts)
    if not fast.size or controller == plant == True:  # noqa: E712
        return
    listed = ", ".join(f"{names[j]!r} ({tau[j]:.3g} s)" for j in fast)
    rule = f"damping time constant 1/(b (M^-1)_jj) below 2 Ts = {2 * Ts:g} s on joint(s) {listed}"
    if plant and not controller:
        report.add_problem(
            f"{rule}; the plant applies the damping ([plant] joint_dynamics) but "
            "controller.joint_dynamics is false; set it true (compensation with the "
            "zero-order-hold gain) or lower Ts",
            {"controller.joint_dynamics": True},
        )
    elif controller and not plant:
        report.add_problem(
            f"{rule}; controller.joint_dynamics compensates it but the simulated plant "
            "leaves it out ([plant] joint_dynamics = false): the compensation then drives "
            "the arm; in `run` set controller.joint_dynamics = false as the plant (on the "
            "real arm, which applies the damping, keep it true)",
            {"controller.joint_dynamics": False},
        )
    else:
        report.warnings.append(
            f"{rule}; `run` leaves it out of the plant and the controller alike, but a "
            "real arm applies it: there set controller.joint_dynamics = true"
        )


def _workspace_findings(report: CheckReport, config: ExperimentConfig, ex: Experiment) -> None:
    """The reference against the mounting plane and for self-collision
    (:func:`~hmpc_pin.experiment.workspace.scan_reference`): each link that leaves the
    workspace and each colliding pair, with the times. A problem when the config declares
    its ``[workspace]`` (the real arm would hit its table or itself; ``run`` simulates
    neither), a warning measured against the default plane otherwise."""
    scan = scan_reference(ex)
    if scan is None:
        report.workspace = "not checked (the URDF has no collision geometry)"
        return
    low = min(scan.clearance.items(), key=lambda kv: kv[1], default=None)
    pairs = "no two links collide" if not scan.collisions else "links collide"
    plane = config.workspace or WorkspaceConfig()
    report.workspace = (
        f"plane height {plane.height:g} m, margin {plane.margin:g} m"
        + (f"; lowest link {low[0]!r} at {low[1]:.3g} m" if low else "")
        + f"; {pairs}"
    )
    for line in scan.lines():
        if config.workspace is not None:
            report.add_problem(
                f"{line}: the reference leaves the [workspace]; move or shrink it", None
            )
        else:
            report.warnings.append(
                f"{line} (against a table at the root link's height, {plane.margin:g} m "
                "margin; declare the real mounting plane in a [workspace] table)"
            )


def check_config(config: ExperimentConfig, engines: bool = True) -> CheckReport:
    """The figures, problems and warnings of ``config`` (module docstring), nothing run.

    Args:
        config: A validated experiment config.
        engines: Compare the model against MuJoCo (when installed).
    """
    refused: HmpcError | None = None
    try:
        ex = Experiment.from_config(config)
    except URDFError as exc:  # a MuJoCo plant refusing the URDF: the figures without it
        if engine_spec(config.plant.engine).integrated:
            raise
        refused = exc
        bare = replace(config.plant, engine=DEFAULT_ENGINE, mujoco=None)
        ex = Experiment.from_config(replace(config, plant=bare))
    robot = ex.robot
    names = robot.joint_names
    Ts = config.controller.Ts
    M0 = robot.mass_matrix(ex.q0)
    latency = float(getattr(config.controller, "latency", None) or 0.0)
    plant_damped = bool(config.plant.joint_dynamics)
    report = CheckReport(
        names,
        Ts,
        latency,
        None,
        None,
        damping_time_constants(robot, ex.q0),
        torque_headroom(ex, plant_effort_limit(config, ex.plant), damped=plant_damped),
        "not compared (--no-engine)",
    )

    bw = compensation_bandwidth(running_observer(ex), M0)
    if bw is not None:
        report.bandwidth = bw
        report.margin = _observer_findings(report, config, ex, bw)
        for j in np.flatnonzero(_explicit(config) & (bw * Ts >= 2.0)):
            report.add_problem(
                f"joint {names[j]!r}: observer bandwidth {bw[j]:.3g} 1/s: w Ts = "
                f"{bw[j] * Ts:.3g} >= 2 puts the explicit observer's pole outside the "
                f"unit circle; use w < {2 / Ts:.4g} 1/s or discretization = 'implicit'",
                {"controller.observer.discretization": "implicit"},
            )

        _explicit_loop_findings(report, config, ex, bw)
    _run_latency_findings(report, config, ex, bw)
    if bw is not None:
        _observer_lag_findings(report, config, ex, bw)
    _damping_findings(report, config)
    _friction_findings(report, config)
    _workspace_findings(report, config, ex)

    headroom = report.headroom
    for j in np.flatnonzero(headroom < MIN_HEADROOM):
        report.add_problem(
            f"joint {names[j]!r}: the reference needs {100 * (1 - headroom[j]):.0f} % of the "
            f"effort limit (headroom {100 * headroom[j]:.0f} %, expected >= "
            f"{100 * MIN_HEADROOM:.0f} %: the feedback and the disturbance compensation need "
            "the rest); slow or shrink the reference",
            None,
        )

    if refused is not None:
        report.engine = "refused the URDF"
        why = " ".join(str(refused).split())  # MuJoCo's message spans lines
        report.add_problem(
            f"the MuJoCo plant cannot be built ({why}); `run` cannot simulate this arm on "
            "MuJoCo: correct the URDF, or set plant.engine = 'pinocchio' (the figures above "
            "are for it); --no-engine does not skip the plant",
            {"plant.engine": "pinocchio", "plant.mujoco": None},
        )
    elif engines:
        try:
            report.engine = engine_agreement(ex.robot, ENGINE_SAMPLES)
        except HmpcError as exc:  # MuJoCo refuses the URDF: one line, the table stays
            report.engine = "refused the URDF"
            why = " ".join(str(exc).split())  # MuJoCo's message spans lines
            text = (
                f"MuJoCo cannot load the arm's URDF ({why}); the engines cannot be "
                "compared (pass --no-engine to skip the comparison)"
            )
            if not engine_spec(config.plant.engine).integrated:  # `run` refused as well
                report.add_problem(text, None)
            else:  # `run` simulates it with Pinocchio: a MuJoCo plant would refuse it
                report.warnings.append(f"{text}; a MuJoCo plant would refuse it too")
        if not isinstance(report.engine, str):
            for what, err in zip(("M(q)", "the forward dynamics"), report.engine, strict=True):
                if err > ENGINE_RTOL:
                    text = (
                        f"model: MuJoCo's {what} differs from Pinocchio's by {err:.2g} "
                        f"(relative, expected <= {ENGINE_RTOL:g}); the engines read the "
                        "URDF differently (check its <inertial> frames)"
                    )
                    if not engine_spec(config.plant.engine).integrated:  # not the model
                        report.add_problem(text, None)
                    else:
                        report.warnings.append(text)
    return report


def apply_fix(config: ExperimentConfig, fix: dict[str, Any]) -> ExperimentConfig:
    """``config`` with the changes of a problem's fix (``{"controller.latency": 0.0}``):
    dotted keys of the config's tables, the keys of one table changed together (so that
    ``{"plant.engine": "pinocchio", "plant.mujoco": None}`` is one valid change)."""
    nested: dict[str, Any] = {}
    for key, value in fix.items():
        *tables, name = key.split(".")
        level = nested
        for table in tables:
            level = level.setdefault(table, {})
        level[name] = value

    def changed(obj, changes: dict[str, Any]):
        return replace(
            obj,
            **{
                k: changed(getattr(obj, k), v) if isinstance(v, dict) else v
                for k, v in changes.items()
            },
        )

    return changed(config, nested)
