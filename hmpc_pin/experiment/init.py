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

import json
import math
import re
import textwrap
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
from ..model.robot import (
    Robot,
    check_urdf,
    damping_time_constants,
    example_robot_srdf,
    example_robot_urdf,
    load_robot,
    urdf_mimics,
)
from .config.workspace import WorkspaceConfig
from .plants import DAMPING_STEP_LIMIT, damping_rates
from .posture import HOLD, PATH_SAMPLES, SLACK, _gravity_along, _hold_gravity, place
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

#: The RK4 plant steps ``init`` chooses from [s] (the first that suits the URDF damping).
PLANT_STEPS = (1e-3, 5e-4, 2e-4, 1e-4, 5e-5, 2e-5, 1e-5)
#: The general observer's bandwidth ``init`` writes, times Ts (Ts·ω = 10).
BANDWIDTH_PERIODS = 10.0
#: The observer's model at the start of the period (the state the held torque was computed
#: from): its estimate is then the correction Eq (4) needs for the next period.
MODEL_AT_LINES = [
    'model_at = "start"                 # M, C dq + G where the held torque was computed',
    "                                   # (guide: Joint dynamics, the observer's model)",
]

#: The measurement latency ``init`` declares [s]: one cycle of a 1 kHz interface.
LATENCY = 0.001

#: Joints locked by ``init`` (case-insensitive search in the joint name).
LOCK_PATTERN = re.compile(
    r"finger|gripper|hand|thumb|index|middle|ring|little|pinky|palm|jaw|claw|knuckle|wheel|caster"
    r"|suspension",
    re.IGNORECASE,
)
#: Reference postures looked for in an SRDF, in order, after the loader's own.
POSTURES = ("default", "half_sitting", "ready", "home", "standing", "arm_up", "neutral")
AMPLITUDE = {"revolute": 0.3, "prismatic": 0.05}  # [rad], [m]
#: The first torque pulse's centre [s] (joint j's at PULSE_CENTER + j mod 9) and the
#: pulses' standard deviation [s].
PULSE_CENTER, PULSE_SIGMA = 1.0, 0.3
FREQUENCY = 0.1  # [Hz]
#: Amplitude scales tried, in order, until gravity along the sine fits the effort limits.
AMPLITUDE_SCALES = (1.0, 0.5, 0.25)
#: Control periods tried, in order [s].
PERIODS = (0.01, 0.005, 0.002)
#: The largest zero-order-hold gain g = x/(1 − e^−x), x = Ts/T_j, a damped joint may need
#: at the chosen Ts (g = 2 at x = 1.594): the period's torque correction for the damping
#: is then at most the inertial torque itself (module docstring, "Control period").
ZOH_GAIN_MAX = 2.0
#: x at which g(x) = :data:`ZOH_GAIN_MAX` (by bisection; a test checks it).
ZOH_X_MAX = 1.5936242600400397
#: The trial run's pass mark, RMS error over its second half [rad or m].
TRIAL_RMS = 2.5e-3
#: The trial run's length [s].
TRIAL = 2.0


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
        G = _gravity_along(robot, self.offset, amp)
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
        :data:`AMPLITUDE_SCALES`, the posture gravity allows (``_hold_gravity``),
        moved inside the workspace when it is not (:func:`~hmpc_pin.experiment.posture.place`).

        Raises:
            URDFError: Gravity needs more than the effort limits everywhere, or no posture
                keeps the sine inside the workspace (the message names the link).
        """
        effort = np.where(robot.effort_limit > 0, robot.effort_limit, np.inf)

        def excess(q):
            return max(0.0, float(np.max(_gravity_along(robot, q, amp) / (HOLD * effort))) - 1)

        gravity: URDFError | None = None
        outside = None
        fallbacks = []
        for scale in AMPLITUDE_SCALES:  # a smaller sine when no posture suits the larger
            amp = scale * amp0
            lo_o, hi_o = lo + amp + margin, hi - amp - margin
            start = np.clip(center, lo + amp + margin, hi - amp - margin)
            try:
                held = _hold_gravity(robot, start, amp, lo_o, hi_o)
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
            f"plane (height {s.height:g} m, normal {_vec(s.normal)}) and clear of the others "
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
        return _render(self, self.identify_duration if duration is None else duration)

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


def _identify_lines(p: InitPlan, duration: float) -> list[str]:
    """What a run needs for ``hmpc-pin identify`` to fit the friction, as comments."""
    need, after = p.identify_duration, p.identify_after
    stem = re.sub(r"[^A-Za-z0-9_]+", "_", p.name)
    longer = f" --duration {need:g}" if duration < need else ""
    return [
        f"# Friction identification (hmpc-pin identify) needs {need:g} s"
        + (f", longer than this run's {duration:g} s" if longer else "")
        + ": the pulses",
        f"# are over at {after:.3g} s, then a period of the sine moves every joint both ways:",
        f"#   hmpc-pin run FILE{longer} --out out; hmpc-pin identify out/{stem}_init.npz "
        f"--after {after:.3g}",
    ]


def _workspace_lines(p: InitPlan) -> list[str]:
    """The ``[workspace]`` table init placed the sine in (nothing without collision
    geometry)."""
    ws = p.workspace
    if ws is None:
        return []
    scan = ws.scan(sine_path(p.offset, p.amplitude, 4 * PATH_SAMPLES - 3))
    low = min(scan.clearance.items(), key=lambda kv: kv[1], default=None)
    s = p.workspace_settings
    lines = [
        "[workspace]",
        "# The plane the arm is mounted on (its table), in the URDF's root frame: along the",
        "# whole sine every moving link's collision geometry keeps `margin` above it and",
        "# clear of the other links"
        + (" (pairs the SRDF disables excepted)" if ws.srdf is not None else "")
        + "; `hmpc-pin check` flags a reference that does not.",
    ]
    if p.plane_note:
        note = p.plane_note[0].upper() + p.plane_note[1:] + "."
        lines += textwrap.wrap(note, 86, initial_indent="# ", subsequent_indent="# ")
    if low is not None:
        lines.append(f"# Lowest along the sine: {low[0]} at {low[1]:.3g} m above the plane.")
    pairs = []
    if s.allowed_pairs:
        listed = ", ".join(f"[{json.dumps(a)}, {json.dumps(b)}]" for a, b in s.allowed_pairs)
        pairs = [
            "# Links touching at the reference posture: taken as touching by design (as",
            "# MoveIt's setup assistant disables them), not checked.",
            f"allowed_pairs = [{listed}]",
        ]
    return [
        *lines,
        f"height = {s.height:g}                       # [m]",
        f"normal = {_vec(s.normal)}",
        f"margin = {s.margin:g}                    # [m]",
        *([] if s.self_collision else ["self_collision = false"]),
        *pairs,
        "",
    ]


def _plant_lines(p: InitPlan) -> list[str]:
    """The ``[plant]`` table when the URDF's joint damping needs it (else nothing)."""
    if p.joint_dynamics and p.plant_dt == PLANT_STEPS[0]:
        return []
    tau = 1.0 / p.damping_rate
    if p.joint_dynamics:
        return [
            "[plant]",
            f"# The URDF's joint damping (time constant down to {tau:.3g} s) needs a short",
            "# step of the RK4 plant.",
            f"dt = {p.plant_dt:g}",
            "",
        ]
    return [
        "[plant]",
        f"# The URDF's joint damping (time constant down to {tau:.3g} s) is too stiff for",
        f"# the RK4 plant even at dt = {PLANT_STEPS[-1]:g} s: the simulated arm leaves it out.",
        "joint_dynamics = false",
        "",
    ]


def _vec(values, digits: int = 4) -> str:
    return "[" + ", ".join(f"{round(float(v), digits):g}" for v in values) + "]"


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


def _render(p: InitPlan, duration: float) -> str:
    robot = p.robot
    n = robot.nq
    key, value = p.source
    stem = re.sub(r"[^A-Za-z0-9_]+", "_", p.name)
    kinds = sorted(set(robot.joint_kinds))
    unit = " / ".join({"revolute": "rad", "prismatic": "m"}[k] for k in kinds)
    lines = [
        f"# {p.name}: written by `hmpc-pin init` (hmpc_pin.experiment.init). Every joint",
        f"# tracks a sine around the reference posture ({p.posture_source})",
        "# under inertia-scaled friction and torque pulses; the URDF limits are soft state",
        "# constraints of every joint's MPC, the URDF effort limits saturate the plant.",
    ]
    lines += textwrap.wrap(
        f"Controlled ({n}): {', '.join(robot.joint_names)}",
        88,
        initial_indent="# ",
        subsequent_indent="#   ",
    )
    if robot.continuous_joints:
        lines += textwrap.wrap(
            "Continuous joints (revolute, no position limit, the angle does not wrap): "
            + ", ".join(robot.continuous_joints),
            88,
            initial_indent="# ",
            subsequent_indent="#   ",
        )
    if robot.mimic_joints:
        lines += textwrap.wrap(
            "Mimic joints (follow their leader, not controlled on their own): "
            + ", ".join(f"{f} = {m:g}*{j} + {o:g}" for f, (j, m, o) in robot.mimic_joints.items()),
            88,
            initial_indent="# ",
            subsequent_indent="#   ",
        )
    lines += [
        f'name = "{stem}_init"',
        f'description = "{p.name}, {n} joints: sine around the reference posture (hmpc-pin init)"',
        "",
        "[robot]",
        f'{key} = "{value}"',
        "gravity = 9.81",
    ]
    if p.locked:
        lines += [
            "",
            "# Gripper, finger, hand and wheel joints are locked at the reference posture",
            "# (not controlled; their mass still loads the arm). Delete a line to control",
            "# that joint (a mimic follower goes with its leader).",
            "[robot.locked_joints]",
            *(f'"{j}" = {round(v, 6):g}' for j, v in p.locked.items()),
        ]
    lines += ["", "[controller]"]
    damped = p.periods() != PERIODS
    if damped:
        x = p.Ts / p.damping_tau
        lines += [
            f"# The URDF damping of {p.damped_joint!r} (time constant {1e3 * p.damping_tau:.3g} "
            "ms): periods up to",
            f"# {1e3 * ZOH_X_MAX * p.damping_tau:.3g} ms keep its zero-order-hold gain "
            f"x/(1 - e^-x), x = Ts/T, within {ZOH_GAIN_MAX:g}",
            f"# (here x = {x:.3g}); "
            + (
                "the shortest period offered."
                if p.Ts == PERIODS[-1] and x > ZOH_X_MAX
                else "the longest such period that tracks."
            ),
        ]
    elif p.Ts != 0.01:
        lines += [
            "# 10 ms (the paper's) tracks worse than 2.5e-3 rad on this arm in a 2 s trial:",
            "# the torque is held over a period while M(q) changes (error ~ Ts^3).",
        ]
    lines += [f"Ts = {p.Ts:g}", "N = 10", "Nc = 1"]
    if not p.joint_dynamics:
        lines += [
            "# The URDF's joint damping is too stiff to simulate (see [plant]); on the real",
            "# arm, which applies it, set this to true (the default) to compensate it.",
            "joint_dynamics = false",
        ]
    if np.any(p.v_max < 100.0):
        lines += [
            "# Acceleration bounds [rad/s² or m/s²] the URDF effort limits can pay for at the",
            "# offset posture (sum_k |M_jk| v_k + |G_j| <= 0.9 effort_j; at most the paper's 100)",
            f"v_min = {_vec(-p.v_max, 2)}",
            f"v_max = {_vec(p.v_max, 2)}",
        ]
    if p.compensation == "chen":
        lines += [
            'compensation = "chen"              # planar serial chain: the paper\'s NDO',
            "",
            "[controller.observer]",
            f"gain = {DEFAULT_GAIN}",
            *MODEL_AT_LINES,
        ]
    else:
        lines += [
            'compensation = "general"           # valid on any arm (Chen\'s Y only on planar',
            "                                   # chains)",
            f"latency = {LATENCY:g}                    # [s] age of the measurements: one 1 kHz "
            "cycle;",
            "                                   # set your driver's (guide: Sensing and latency)",
            "",
            "[controller.observer]",
            f"bandwidth = {p.bandwidth:g}                 # [1/s] per joint: Ts x bandwidth = "
            f"{p.Ts * p.bandwidth:.3g}",
            *MODEL_AT_LINES,
        ]
    if not p.position_limits:
        lines += [
            "",
            "[controller.constraints]",
            f"# The URDF gives {', '.join(p.bad_ranges)} a zero or inverted position range,",
            "# i.e. no usable limits: none are imposed.",
            "position = false",
        ]
    lines += [
        "",
        *_plant_lines(p),
        *_workspace_lines(p),
        "[reference]",
        'kind = "sine"',
        f"amplitude = {_vec(p.amplitude)}     # [{unit}]",
        f"frequency = {p.frequency:.4g}                  # [Hz], peak speed <= half the URDF "
        "velocity limits",
        f"offset = {_vec(p.offset)}",
        "",
        "[disturbance]",
        'scale = "inertia"                  # coefficients x M_ii(q0)',
        "",
        "[disturbance.friction]",
        "viscous = 2.0",
        "coulomb = 0.5",
        "",
        "[disturbance.pulse]",
        "amplitude = 1.0",
        f"center = {_vec([PULSE_CENTER + (j % 9) for j in range(n)])}",
        f"sigma = {PULSE_SIGMA:g}",
        "",
        "[simulation]",
        *_identify_lines(p, duration),
        f"duration = {duration:g}",
        "# Start on the reference: position r(0) (the default) and velocity dr/dt(0).",
        f"dq0 = {_vec(2 * np.pi * p.frequency * p.amplitude, 6)}",
        "",
    ]
    return "\n".join(lines)


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
