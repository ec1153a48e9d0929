"""A starting config for any arm: ``hmpc-pin init ROBOT`` (docs, "Your own arm").

:func:`init_config` looks at the URDF (and its SRDF where ``example-robot-data`` ships one)
and writes a commented TOML experiment that runs as written:

* **Joints.** Gripper, finger, hand and wheel joints (by name: :data:`LOCK_PATTERN`) are
  *locked* at the reference posture: the experiment is about the arm, and a finger link of
  a few grams has :math:`M_{ii}` five to eight orders below the shoulder's. Mimic followers
  go with their leader. When locking would leave no joint (a hand), every joint is
  controlled. Continuous joints are controlled as revolute joints without position limits.
* **Reference.** A sine per joint, :math:`r_i = o_i + a_i\\sin(2\\pi f t)`, around the
  reference posture: the SRDF's (``pin.loadReferenceConfigurations``; the loader's posture
  name, else the first), else the middle of the limits (0 without limits). The amplitude is
  0.3 rad (0.05 m on a prismatic joint), at most a quarter of the range; the offset is
  moved inside so that :math:`o \\pm a` keeps 5 % of the range from each limit; the
  frequency 0.1 Hz, lowered until the peak speed :math:`2\\pi f a` is at most half of every
  URDF velocity limit.
* **Workspace.** The whole sine keeps every moving link's collision geometry ``margin``
  above the mounting plane and clear of the other links
  (:class:`~hmpc_pin.model.workspace.Workspace`; ``[workspace]``, written to the file):
  a posture that does not is moved by :func:`~hmpc_pin.experiment.posture.place`, the
  amplitude scaled down when no posture fits; with the plane given and nothing fitting,
  :class:`~hmpc_pin.exceptions.URDFError` names the links. With the default plane (the
  root link's height) and nothing fitting, the root stands on no table (a hand, an arm on
  a body): the posture is kept and the plane put under its whole sine, with a warning.
* **Run length.** Long enough for ``hmpc-pin identify``: the pulses over
  (:attr:`InitPlan.identify_after`), then a whole period of the sine
  (:attr:`InitPlan.identify_duration`); the file says how to identify.
* **Limits.** A zero or inverted URDF range (``double_pendulum``: 0/0) means the URDF gives
  none: ``[controller.constraints] position = false``, and the joint is unbounded.
* **Observer.** Chen's NDO (the paper's, Eq 28–30, gain 100) on a planar serial chain;
  elsewhere the general NDO with a bandwidth of :data:`BANDWIDTH_PERIODS` / Ts per joint
  (the estimate moves 91 % of the way per period) and a declared measurement latency of
  one 1 kHz interface cycle (``[controller] latency = 0.001``): with the latency
  compensated, any bandwidth keeps the observer stable
  (:mod:`hmpc_pin.compensation.bandwidth`); without it the rule would cap it near
  1/(5 Ts), which tracks about ten times worse. Below Ts = 1.33 ms the bandwidth is
  lowered to :func:`~hmpc_pin.compensation.bandwidth.overdeclared_limit` (4/Ts at 1 ms),
  so that the config survives a latency declared half a 1 kHz cycle too long.
* **Control period.** The largest of :data:`PERIODS` whose trial run (:data:`TRIAL` s)
  tracks within :data:`TRIAL_RMS`, among those that suit the URDF's joint damping: with
  :math:`T_j` the damping time constant at the offset posture
  (:func:`~hmpc_pin.model.robot.damping_time_constants`), a period with
  :math:`T_s \\le x_{\\max} \\min_j T_j`, :math:`x_{\\max} = 1.594`, where the
  zero-order-hold gain :math:`g = x/(1 - e^{-x})` the compiled step gives a damped joint
  is at most 2 (its torque correction at most the inertial torque; at Z1's 10 ms it is
  13); the shortest of :data:`PERIODS` when none does. The MPC keeps N = 10 (a horizon of
  ten periods): on Z1 with a 0.5 Hz, 0.5 rad sine at Ts = 2 ms it tracks at 1.4e-3 rad
  against 2.2e-3 with N = 50 (the 0.1 s of the 10 ms horizon).
* **Disturbances.** As the arm configs (``ur5_sine``, ``panda_sine``): friction 2.0·|q̇| +
  0.5·sgn(q̇) and Gaussian pulses of amplitude 1.0, each times :math:`M_{ii}(q_0)`
  (``scale = "inertia"``: the same acceleration-level disturbance on any arm), pulse j at
  :math:`t = 1 + (j \\bmod 9)` s.
"""

from __future__ import annotations

import math
import re
import warnings
from dataclasses import replace
from pathlib import Path
from tempfile import TemporaryDirectory

import numpy as np
import pinocchio as pin

from ..compensation.observers import DEFAULT_DESIGN, DEFAULT_GAIN, general_gain_bound
from ..data import robot_path
from ..exceptions import ConfigError, OutputError, SimulationError, URDFError, ValidityWarning
from ..identification.friction import PULSE_SIGMAS
from ..model.catalogue import example_robot_srdf, example_robot_urdf
from ..model.robot import Robot, damping_time_constants, load_robot, urdf_mimics
from ..model.urdf_checks import check_urdf
from .config.workspace import WorkspaceConfig
from .init_choices import (  # noqa: F401  (every name importable from here, as before)
    AMPLITUDE,
    AMPLITUDE_SCALES,
    BANDWIDTH_PERIODS,
    FREQUENCY,
    LATENCY,
    LOCK_PATTERN,
    MODEL_AT_LINES,
    PERIODS,
    PLANT_STEPS,
    POSTURES,
    PULSE_CENTER,
    PULSE_SIGMA,
    TRIAL,
    TRIAL_RMS,
    ZOH_GAIN_MAX,
    ZOH_X_MAX,
)
from .init_text import render, vec
from .plants import DAMPING_STEP_LIMIT, damping_rates
from .posture import HOLD, PATH_SAMPLES, SLACK, gravity_along, hold_gravity, place
from .posture import path as sine_path
from .workspace import make_workspace

__all__ = [
    "BANDWIDTH_PERIODS",
    "LATENCY",
    "LOCK_PATTERN",
    "InitPlan",
    "init_config",
    "plan",
    "write_config",
]


def _resolve(source: str | Path) -> tuple[Path, tuple[str, str], str | None]:
    """The URDF path of ``source``, its ``[robot]`` key and value, and its
    example-robot-data name (``None`` for a path or a packaged robot)."""
    path = Path(source)
    if not path.exists() and not path.suffix and len(path.parts) == 1:
        packaged = robot_path(str(source))
        if packaged is not None:
            return packaged, ("model", str(source)), None
        return example_robot_urdf(str(source)), ("model", str(source)), str(source)
    return path, ("urdf", str(path.resolve())), None


def _say_what_is_assumed(name: str | None, robot: Robot) -> None:
    """Warn (:class:`~hmpc_pin.exceptions.ValidityWarning`) about what the config assumes
    silently otherwise: a model example-robot-data mounts on a floating base (legged,
    flying or mobile robots) is controlled with its base fixed to the world; a URDF effort
    of 0 is no torque limit."""
    if name is not None:
        from example_robot_data import robots_loader

        loader = robots_loader.ROBOTS.get(name)
        if loader is not None and loader.free_flyer:
            warnings.warn(
                f"{name}: example-robot-data gives it a floating base (a legged, flying or "
                "mobile robot, or an arm mounted that way); the config controls its "
                f"{robot.nq} joints with the base fixed to the world",
                ValidityWarning,
                stacklevel=4,
            )
    zero = [j for j, e in zip(robot.joint_names, robot.effort_limit, strict=True) if e == 0]
    if zero:
        warnings.warn(
            f'joint(s) {zero} have effort="0" in the URDF: taken as no torque limit '
            "(the plant never clips their torque); set plant.effort_limit to impose one",
            ValidityWarning,
            stacklevel=4,
        )


def _posture(path: Path, name: str | None) -> tuple[dict[str, float], str]:
    """Joint name -> angle [rad or m] of the SRDF reference posture, and where it came from
    (empty when there is no SRDF)."""
    srdf, wanted = example_robot_srdf(name) if name else (None, None)
    if srdf is None:
        beside = (path.with_suffix(".srdf"), path.parent.parent / "srdf" / f"{path.stem}.srdf")
        for candidate in beside:
            if candidate.is_file():
                srdf = candidate
                break
    if srdf is None:
        return {}, ""
    model = pin.buildModelFromUrdf(str(path))
    try:
        pin.loadReferenceConfigurations(model, str(srdf), False)
    except (RuntimeError, ValueError):
        return {}, ""
    names = [e.key() for e in model.referenceConfigurations]
    order = [wanted, *POSTURES, *names]
    key = next((k for k in order if k in names), None)
    if key is None:
        return {}, ""
    q = np.asarray(model.referenceConfigurations[key])
    out = {}
    for jid in range(1, model.njoints):
        joint = model.joints[jid]
        if joint.nq == 1:
            out[model.names[jid]] = float(q[joint.idx_q])
        elif joint.nq == 2:  # Pinocchio's continuous joint: (cos θ, sin θ)
            out[model.names[jid]] = math.atan2(q[joint.idx_q + 1], q[joint.idx_q])
    return out, f"SRDF {srdf.name}, posture {key!r}"


def _inside(value: float, lo: float, hi: float) -> float:
    """``value`` if inside [lo, hi], else the middle of a finite range (0 otherwise)."""
    if lo <= value <= hi:
        return value
    if np.isfinite(lo) and np.isfinite(hi):
        return 0.5 * (lo + hi)
    return float(np.clip(0.0, lo, hi))


class InitPlan:
    """What :func:`init_config` decided for one robot (also what the benchmark reports).

    Attributes:
        source: The ``[robot]`` key and value (``("model", "ur5")`` or ``("urdf", path)``).
        robot: The controlled robot (locked joints removed).
        locked: Locked joint -> position [rad or m].
        posture_source: Where the posture came from (SRDF and posture, or mid-range).
        amplitude, offset: Per controlled joint [rad or m]; frequency [Hz].
        position_limits: Whether the URDF's position ranges are usable (``False``: a
            zero or inverted range, ``position = false``).
        bad_ranges: Joints whose URDF range is zero or inverted.
        compensation, gain, gain_bound: The observer and its gain (bound for ``general``,
            reported; the config gets :attr:`bandwidth` instead).
        bandwidth: The general observer's bandwidth [1/s] (``None`` for ``chen``).
        workspace: The arm's :class:`~hmpc_pin.model.workspace.Workspace` the sine was
            placed in (``None``: the URDF has no collision geometry).
        workspace_settings: The ``[workspace]`` table written (the plane as placed).
        plane_given: Whether the plane is the caller's (else the root link's height, put
            under the robot when no posture clears it: :attr:`plane_note` says so).
        touching: Pairs of links touching at the reference posture (allowed, written).
        plane_note: Why the plane was put under the robot (``""`` when it was not).
    """

    def __init__(
        self,
        source: str | Path,
        workspace: WorkspaceConfig | None = None,
        plane_given: bool | None = None,
    ):
        path, self.source, name = _resolve(source)
        root = check_urdf(path)
        mimics = urdf_mimics(root)
        movable = [
            j.get("name", "")
            for j in root.findall("joint")
            if j.get("type") in ("revolute", "prismatic", "continuous")
            and j.get("name") not in mimics
        ]
        posture, self.posture_source = _posture(path, name)
        full = pin.buildModelFromUrdf(str(path))  # every joint's URDF limits, by name
        limits = {
            full.names[j]: (
                (full.lowerPositionLimit[full.idx_qs[j]], full.upperPositionLimit[full.idx_qs[j]])
                if full.nqs[j] == 1
                else (-np.inf, np.inf)
            )
            for j in range(1, full.njoints)
        }
        links = {link.get("name") for link in root.findall("link")}
        # Pinocchio cannot lock a joint that shares its name with a link (so100's gripper).
        lock = [n for n in movable if LOCK_PATTERN.search(n) and n not in links]
        if len(lock) == len(movable):  # a hand: control every joint
            lock = []
        self.locked = {n: _inside(posture.get(n, 0.0), *limits[n]) for n in lock if n in limits}
        self.robot: Robot = load_robot(path, gravity=9.81, locked_joints=self.locked)
        robot = self.robot
        _say_what_is_assumed(name, robot)
        lo, hi = robot.lower, robot.upper
        names = robot.joint_names
        self.bad_ranges = tuple(n for n, a, b in zip(names, lo, hi, strict=True) if a >= b)
        self.position_limits = not self.bad_ranges
        if not self.position_limits:
            lo, hi = np.full_like(lo, -np.inf), np.full_like(hi, np.inf)
        center = np.array(
            [
                posture[n]
                if n in posture
                else (0.5 * (a + b) if np.isfinite(a) and np.isfinite(b) else 0.0)
                for n, a, b in zip(robot.joint_names, lo, hi, strict=True)
            ]
        )
        if not self.posture_source:
            self.posture_source = "middle of the URDF limits (no SRDF)"
        span = hi - lo
        amp0 = np.array([AMPLITUDE[k] for k in robot.joint_kinds])
        amp0 = np.where(np.isfinite(span), np.minimum(amp0, 0.25 * span), amp0)
        margin = np.where(np.isfinite(span), 0.05 * span, 0.0)
        self.plane_given = workspace is not None if plane_given is None else plane_given
        self.plane_note = ""
        self.workspace_settings = workspace if workspace is not None else WorkspaceConfig()
        self.workspace = make_workspace(robot, self.workspace_settings, name)
        self.touching: list[list[str]] = []
        if self.workspace is not None:  # links touching at the reference posture: by design
            ref = np.clip(center, lo, hi)
            self.touching = sorted({tuple(sorted(p)) for p in self.workspace.colliding(ref)})
            if self.touching:
                pairs = [*self.workspace_settings.allowed_pairs, *map(list, self.touching)]
                self.workspace_settings = replace(self.workspace_settings, allowed_pairs=pairs)
                self.workspace = make_workspace(robot, self.workspace_settings, name)
        self.offset, amp, moved = self._place(robot, center, amp0, lo, hi, margin)
        if moved == "gravity":
            self.posture_source += (
                f", lowered toward hanging until gravity needs <= {HOLD:.0%} of the effort limits"
            )
        elif moved == "workspace":
            self.posture_source += (
                ", moved until the whole sine keeps every link above the mounting plane "
                "and clear of the others"
            )
        elif moved == "clear":
            self.posture_source += ", moved until the whole sine keeps the links apart"
        self.amplitude = amp
        vmax = robot.velocity_limit
        speed_cap = np.where(vmax > 0, 0.5 * vmax / (2 * np.pi * amp), np.inf)
        self.frequency = float(min(FREQUENCY, speed_cap.min()))
        # Acceleration bounds the effort limits can pay for at the offset posture:
        # |tau_j| <= sum_k |M_jk| b_k + |G_j| <= 0.9 effort_j with b_j <= 100 (the paper's).
        M = robot.mass_matrix(self.offset)
        G = gravity_along(robot, self.offset, amp)
        effort = np.where(robot.effort_limit > 0, robot.effort_limit, np.inf)
        budget = (0.9 * effort - G) / np.abs(M).sum(axis=1)
        self.v_max = np.clip(np.where(np.isfinite(budget), budget, 100.0), 5.0, 100.0)
        if robot.is_planar_chain():
            self.compensation, self.gain, self.gain_bound = DEFAULT_DESIGN, DEFAULT_GAIN, None
        else:
            bound = general_gain_bound(robot, samples=50)
            self.compensation, self.gain_bound = "general", bound
            self.gain = float(max(100.0, math.ceil(1.2 * bound)))
        self.name = name or (self.source[1] if self.source[0] == "model" else robot.name)
        self.Ts = 0.01
        # The plant's step: an explicit integrator needs dt·λ_j within DAMPING_STEP_LIMIT
        # for the URDF's joint damping (λ_j = b_j (M⁻¹)_jj), with a factor 2 for the
        # postures along the sine; a damping too stiff for the shortest step is left out of
        # the simulation (plant and controller), which a real arm applies.
        self.damping_rate = float(damping_rates(robot, self.offset).max(initial=0.0))
        taus = damping_time_constants(robot, self.offset)
        self.damping_tau = float(taus.min(initial=math.inf))
        self.damped_joint = (
            robot.joint_names[int(np.argmin(taus))] if np.isfinite(self.damping_tau) else None
        )
        self.plant_dt, self.joint_dynamics = PLANT_STEPS[0], True
        if self.damping_rate > 0:
            fits = [
                dt
                for dt in PLANT_STEPS
                if dt * self.damping_rate <= 0.5 * DAMPING_STEP_LIMIT["rk4"]
            ]
            if fits:
                self.plant_dt = fits[0]
            else:
                self.joint_dynamics = False

    def _place(self, robot, center, amp0, lo, hi, margin):
        """The offset and amplitude of the sine, and what moved the offset from
        ``center`` (``""``, ``"gravity"``, ``"workspace"`` or, the plane put under the
        robot, ``"clear"``): per amplitude of
        :data:`AMPLITUDE_SCALES`, the posture gravity allows (``hold_gravity``),
        moved inside the workspace when it is not (:func:`~hmpc_pin.experiment.posture.place`).

        Raises:
            URDFError: Gravity needs more than the effort limits everywhere, or no posture
                keeps the sine inside the workspace (the message names the link).
        """
        effort = np.where(robot.effort_limit > 0, robot.effort_limit, np.inf)

        def excess(q):
            return max(0.0, float(np.max(gravity_along(robot, q, amp) / (HOLD * effort))) - 1)

        gravity: URDFError | None = None
        outside = None
        fallbacks = []
        for scale in AMPLITUDE_SCALES:  # a smaller sine when no posture suits the larger
            amp = scale * amp0
            lo_o, hi_o = lo + amp + margin, hi - amp - margin
            start = np.clip(center, lo + amp + margin, hi - amp - margin)
            try:
                held = hold_gravity(robot, start, amp, lo_o, hi_o)
            except URDFError as exc:
                gravity, held = exc, None
                if self.workspace is None:
                    continue
            moved = "" if held is not None and np.allclose(held, start) else "gravity"
            if self.workspace is None:
                return held, amp, moved
            first = held if held is not None else start
            if held is not None:
                fallbacks.append((held, amp, lo_o, hi_o, moved))
            offset, inside = place(self.workspace, first, amp, lo_o, hi_o, excess)
            if inside:
                return offset, amp, (moved if np.allclose(offset, first) else "workspace")
            if held is not None:
                outside = (offset, amp)
        if outside is None:
            assert gravity is not None
            raise gravity
        ws = self.workspace
        for held, amp, lo_o, hi_o, moved in [] if self.plane_given else fallbacks:
            height, ws.height = ws.height, -math.inf  # no plane: clear of the other links
            offset, inside = place(ws, held, amp, lo_o, hi_o, excess)
            ws.height = height
            if inside:
                self._plane_under(offset, amp)
                return offset, amp, (moved if np.allclose(offset, held) else "clear")
            outside = (offset, amp)
        raise self._outside(*outside, plane=self.plane_given)

    def _plane_under(self, posture: np.ndarray, amp: np.ndarray) -> None:
        """No posture keeps the sine above the default plane (the root link's height, none
        given): the root does not stand on a table (a hand, a pendulum, an arm on a body).
        The plane is put under the whole sine of ``posture`` (the nearest posture whose
        sine keeps the links clear of one another), less the margin; said in
        :attr:`plane_note` and in a warning."""
        ws = self.workspace
        assert ws is not None
        scan = ws.clearance(sine_path(posture, amp, 4 * PATH_SAMPLES - 3))[:, ws.checked]
        height = math.floor(1e3 * (float(scan.min()) - ws.margin)) / 1e3
        ws.height = height
        self.workspace_settings = replace(self.workspace_settings, height=height)
        self.plane_note = (
            "no posture keeps the sine above the root link's height: the root does not "
            "stand on a table (a hand, a pendulum, an arm on a body), so the plane is put "
            f"under the whole sine, {-height:.3g} m below the root; state the real table "
            "with --plane-height (init refuses when no posture clears it)"
        )
        warnings.warn(f"{self.robot.source}: {self.plane_note}", ValidityWarning, stacklevel=5)

    def _outside(self, offset, amp, plane: bool = True) -> URDFError:
        """No posture keeps the sine inside the workspace (``plane``: above the plane and
        clear of the other links; else clear of them alone): the message names the links."""
        ws = self.workspace
        assert ws is not None
        height = ws.height
        if not plane:
            ws.height = -math.inf
        scan = ws.scan(sine_path(offset, amp, 41), np.linspace(-1.0, 1.0, 41))
        ws.height = height
        what = (
            "; ".join(
                [f"{v.link!r} {abs(v.lowest):.3g} m {'below' if v.lowest < 0 else 'above'} it"
                 for v in scan.below]
                + [f"{c.links[0]!r} against {c.links[1]!r}" for c in scan.collisions]
            )
            or f"a link within {1e3 * SLACK:g} mm of the margin"
        )  # fmt: skip
        s = self.workspace_settings
        if not plane:
            return URDFError(
                self.robot.source,
                "no posture found whose sine (amplitude down to "
                f"{AMPLITUDE_SCALES[-1]:g} x) keeps every link clear of the others within "
                f"the effort limits (nor above the mounting plane); the best found puts {what}"
                "; the URDF's collision geometry may overlap where the real links do not "
                "(list such pairs in [workspace] allowed_pairs of a config written by hand)",
            )
        return URDFError(
            self.robot.source,
            "no posture found whose sine (amplitude down to "
            f"{AMPLITUDE_SCALES[-1]:g} x) keeps every link {s.margin:g} m above the mounting "
            f"plane (height {s.height:g} m, normal {vec(s.normal)}) and clear of the others "
            f"within the effort limits; the best found puts {what}; if the arm is mounted "
            "higher than its root link (a humanoid's or a mobile base's arm), pass "
            "--plane-height (the plane's height in the URDF's root frame, negative below it)",
        )

    @property
    def bandwidth(self) -> float | None:
        """The general observer's bandwidth [1/s] at the chosen Ts (``None`` for ``chen``)."""
        if self.compensation == "chen":
            return None
        from ..compensation.bandwidth import overdeclared_excess, overdeclared_limit

        # no faster than the rule for the declared latency half a cycle too long allows
        # (Ts·ω <= 4 at Ts = 1 ms; no bound from Ts = 1.33 ms on)
        limit = overdeclared_limit(self.Ts, overdeclared_excess(self.Ts, LATENCY))
        return min(BANDWIDTH_PERIODS / self.Ts, limit)

    def periods(self) -> tuple[float, ...]:
        """The control periods the trial may pick: those of :data:`PERIODS` with
        :math:`T_s \\le x_{\\max} \\min_j T_j` for the URDF's joint damping (module
        docstring), else the shortest; all of them without damping (or with a damping left
        out of the simulation)."""
        if not self.joint_dynamics or not np.isfinite(self.damping_tau):
            return PERIODS
        fit = tuple(Ts for Ts in PERIODS if Ts <= ZOH_X_MAX * self.damping_tau)
        return fit or PERIODS[-1:]

    def trial(self, duration: float = TRIAL) -> None:
        """Pick the control period: the largest of :data:`PERIODS` whose ``duration`` s trial
        run of the written config keeps the worst RMS error after 1 s within
        :data:`TRIAL_RMS` (the last one otherwise). Holding the torque over a period while
        M(q) changes costs a tracking error that grows as Ts³ (talos_arm: 4.9e-3 rad at
        10 ms, 6.1e-4 at 5 ms); most arms keep 10 ms."""
        from .build import Experiment
        from .config import load_config

        for Ts in self.periods():
            self.Ts = Ts
            text = self.text(duration)
            with TemporaryDirectory() as tmp:
                path = Path(tmp, "trial.toml")
                path.write_text(text, encoding="utf-8")
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    try:
                        result = Experiment.from_config(load_config(path)).run()
                    except SimulationError:
                        continue
            after = result.t >= 1.0
            if np.sqrt(np.mean(result.error[after] ** 2, axis=0)).max() <= TRIAL_RMS:
                return

    def text(self, duration: float | None = None) -> str:
        """The TOML text (:func:`init_config`; ``duration`` [s] default
        :attr:`identify_duration`)."""
        return render(self, self.identify_duration if duration is None else duration)

    @property
    def identify_after(self) -> float:
        """The time [s] past the torque pulses (the last centre plus
        :data:`~hmpc_pin.identification.friction.PULSE_SIGMAS` deviations): friction is
        identified from the samples after it (``hmpc-pin identify --after``)."""
        last = max(PULSE_CENTER + (j % 9) for j in range(self.robot.nq))
        return last + PULSE_SIGMAS * PULSE_SIGMA

    @property
    def identify_duration(self) -> float:
        """The shortest run [s] from which ``hmpc-pin identify`` fits the friction: the
        pulses over (:attr:`identify_after`), then a whole period of the sine, in which
        every joint moves both ways at its peak speed (whole seconds, rounded up)."""
        return float(math.ceil(self.identify_after + 1.0 / self.frequency - 1e-9))


def init_config(
    source: str | Path,
    duration: float | None = None,
    workspace: WorkspaceConfig | None = None,
    *,
    plane_given: bool | None = None,
) -> str:
    """The text of a commented TOML experiment for ``source`` (URDF path or robot name)
    that runs as written (module docstring: what is decided and why), ``duration`` [s]
    long (default: long enough for friction identification,
    :attr:`InitPlan.identify_duration`).

    Args:
        workspace: The mounting plane and margin (default: the plane through the root
            link, 2 cm), written to the ``[workspace]`` table.
        plane_given: Whether the plane is the user's (default: ``workspace`` given). When
            it is not and no posture keeps the sine above it, the plane is put under the
            robot's own posture (module docstring) instead of refusing.

    Raises:
        URDFError: The URDF cannot be controlled (the message names the joint or link),
            or no posture keeps the sine inside a plane given.
    """
    p = InitPlan(source, workspace, plane_given)
    p.trial()
    return p.text(duration)


def write_config(
    source: str | Path,
    out: str | Path | None = None,
    duration: float | None = None,
    *,
    overwrite: bool = False,
    workspace: WorkspaceConfig | None = None,
    plane_given: bool | None = None,
) -> Path:
    """Write :func:`init_config` of ``source`` to ``out`` (default ``<name>.toml`` in the
    current directory) and return the path (``workspace``, ``plane_given``: as
    :func:`init_config`).

    Raises:
        ConfigError: ``out`` exists and ``overwrite`` is false (nothing is written).
        OutputError: ``out`` cannot be written.
    """
    text = init_config(source, duration, workspace, plane_given=plane_given)
    name = re.search(r'^name = "(.*)_init"$', text, re.MULTILINE)
    path = Path(out) if out is not None else Path(f"{name.group(1) if name else 'robot'}.toml")
    if path.exists() and not overwrite:
        raise ConfigError(
            "--out",
            f"{str(path)!r} exists; pass --force (overwrite=True) to replace it, or another path",
        )
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise OutputError(path, exc.strerror or str(exc)) from exc
    return path


def plant_step_hint(text: str) -> str | None:
    """The note ``init`` prints when the config ``text`` it wrote steps the plant shorter
    than the default 1 ms (a stiff URDF damping): the steps per control period and per
    run it costs, and the ``[plant]`` keys that trade it (``None`` at the default step)."""
    import tomllib

    raw = tomllib.loads(text)
    dt = raw.get("plant", {}).get("dt")
    if dt is None or dt >= PLANT_STEPS[0]:
        return None
    Ts = float(raw.get("controller", {}).get("Ts", 0.01))
    duration = float(raw.get("simulation", {}).get("duration", 10.0))
    return (
        f"note: the plant steps at dt = {dt:g} s ({Ts / dt:.0f} steps a control period, "
        f"{duration / dt:.3g} for the {duration:g} s run) for the URDF's stiff joint damping; "
        "to let the plant choose its step by its error, replace dt in [plant] by "
        "tolerance = 1e-4 [rad] (guide: Joint dynamics, the plant step chosen by its "
        "error), or leave the URDF's damping out of the plant with joint_dynamics = false"
    )


def plan(source: str | Path, workspace: WorkspaceConfig | None = None) -> InitPlan:
    """The decisions :func:`init_config` writes, as an object."""
    return InitPlan(source, workspace)
