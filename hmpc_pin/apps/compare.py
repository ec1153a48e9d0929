"""``hmpc-pin compare``: every controller on the same experiment, side by side.

Each controller × compensation (docs, "Controllers"; by default the seven of
:data:`~hmpc_pin.experiment.config.legacy.CONTROLLER_KINDS`) runs on the same robot model,
plant, reference, disturbance, initial state and MPC settings — only the controller
and its compensation change. Per controller
and joint the table holds RMS and max tracking error after 1 s, the time to stay
within 0.01 rad, the RMS observer error (where there is an observer), the control
effort (RMS τ), two chattering measures (:func:`~hmpc_pin.apps.metrics.chattering`: total
variation of τ per second and the share of τ's energy above 10 Hz, both after 1 s),
constraint violations (position-limit excursion, saturated periods) and the median
controller step time, measured around ``step`` during the run.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..controllers.wrappers import TimedController
from ..exceptions import ConfigError, RunInterrupted, SimulationError
from ..experiment.build import Experiment, uses_observer, with_controller
from ..experiment.config import CONTROLLER_KINDS, ExperimentConfig, parse_combination
from ..sim.result import Result
from .metrics import DEFAULT_ERROR_THRESHOLD, Metrics, compute_metrics, run_warnings

__all__ = [
    "Comparison",
    "ControllerRun",
    "TimedController",
    "boundary_layer_sweep",
    "compare",
    "parse_controllers",
    "run_comparison",
]


@dataclass
class ControllerRun:
    """One controller's run: result, metrics, median step time, failure message."""

    kind: str
    result: Result
    metrics: Metrics | None
    step_us: float
    observer: bool
    failure: str | None = None


@dataclass
class Comparison:
    """Runs of several controllers on one experiment, in the order requested."""

    config: ExperimentConfig
    runs: dict[str, ControllerRun] = field(default_factory=dict)
    interrupted: str = ""  # where Ctrl-C stopped it ("" if it ran to the end)

    @property
    def joint_names(self) -> tuple[str, ...]:
        return next(iter(self.runs.values())).result.joint_names


def parse_controllers(text: str | None, config: ExperimentConfig | None = None) -> tuple[str, ...]:
    """``"hmpc,hmpc-ism"`` → ``("hmpc", "hmpc-ism")``; ``None`` → the seven of
    :data:`CONTROLLER_KINDS` (those that are the same pair for ``config`` once).

    Each name is a controller × compensation (:func:`parse_combination`).

    Raises:
        ConfigError: An unknown name, none, or two names that are the same controller.
    """
    names = (
        CONTROLLER_KINDS if text is None else tuple(k.strip() for k in text.split(",") if k.strip())
    )
    if not names:
        raise ConfigError("--controllers", f"no controller given; choose from {CONTROLLER_KINDS}")
    seen: dict[tuple[str, str], str] = {}
    kept = []
    for name in names:
        parse_combination(name, "--controllers")
        if config is None:
            kept.append(name)
            continue
        cc = with_controller(config, name).controller
        pair = (cc.kind, cc.compensation)
        if pair in seen:
            if text is None:
                continue
            raise ConfigError(
                "--controllers",
                f"{name!r} and {seen[pair]!r} are the same controller ({cc.label}) on "
                f"{config.name}; give each once",
            )
        seen[pair] = name
        kept.append(name)
    return tuple(kept)


def run_one_controller(config: ExperimentConfig, kind: str) -> ControllerRun:
    """Run ``config`` with the controller ``kind`` (:func:`with_controller`); a failed run
    keeps its partial result."""
    config = with_controller(config, kind)
    exp = Experiment.from_config(config)
    timed = TimedController(exp.controller)
    exp.controller = timed
    failure = None
    try:
        result = exp.run()
    except SimulationError as exc:
        if exc.result is None:
            raise
        result, failure = exc.result, str(exc)
    metrics = compute_metrics(result) if result.t[-1] >= 1.0 else None
    step_us = float(np.median(timed.samples_ns)) / 1e3 if timed.samples_ns else float("nan")
    return ControllerRun(kind, result, metrics, step_us, uses_observer(config.controller), failure)


def ism_gain_hint(config: ExperimentConfig, run: ControllerRun) -> str | None:
    """Why an integral-sliding-mode run failed when its switching gain is more than the
    arm's effort limits can pay (``None`` otherwise): :math:`M_{jj}(q_0) K` per joint
    against the effort limit, and the largest gain that fits,
    :math:`\\min_j \\tau_{\\max,j} / M_{jj}(q_0)`. The default K = 200 rad/s² is the paper
    arm's (its limits are 10,000 N·m); on a real arm's limits the plant clips the
    switching torque, tracking is lost and the MPC's QP fails after it."""
    from ..experiment.build import load_robot_config

    if run.failure is None or "ism" not in run.kind:
        return None
    tau, applied = run.result.tau, run.result.tau_applied
    with np.errstate(invalid="ignore"):
        clipped = np.nan_to_num(np.abs(tau - applied)) > 1e-9
    if not clipped.any():
        return None
    robot = load_robot_config(config.robot)
    limit = np.asarray(robot.effort_limit, dtype=float)
    gain = float(with_controller(config, run.kind).controller.ism.gain)
    asked = np.diag(robot.mass_matrix(run.result.q[0])) * gain
    over = np.flatnonzero((limit > 0) & (asked > limit))
    if over.size == 0:
        return None
    j = int(over[np.argmax(asked[over] / limit[over])])
    fit = float(np.min(limit[limit > 0] / np.diag(robot.mass_matrix(run.result.q[0]))[limit > 0]))
    return (
        f"{run.kind}: the switching gain K = {gain:g} rad/s² ([controller.ism] gain; the "
        f"paper arm's) asks M(q) K beyond this arm's effort limits (M_jj(q0) K = "
        f"{asked[j]:.3g} N·m on {robot.joint_names[j]!r}, limit {limit[j]:.3g} N·m): the "
        "plant clipped the torque and tracking was lost before the QP failed; compare ISM "
        f"with K <= {fit:.3g} rad/s² (min over joints of effort / M_jj(q0)) from a config "
        'with compensation = "ism" and [controller.ism] gain, or leave it out '
        "(--controllers)"
    )


def run_comparison(
    config: ExperimentConfig, controllers=None, progress: bool = False
) -> Comparison:
    """Run every controller in ``controllers`` (default: :func:`parse_controllers`) on
    ``config``."""
    from tqdm import tqdm

    if controllers is None:
        controllers = parse_controllers(None, config)

    comp = Comparison(config)
    bar = tqdm(controllers, desc="compare", unit="run", disable=not progress)
    try:
        for kind in bar:
            bar.set_postfix_str(kind)
            comp.runs[kind] = run_one_controller(config, kind)
    except KeyboardInterrupt as exc:  # Ctrl-C: keep the finished runs and the partial one
        where = exc.where if isinstance(exc, RunInterrupted) else "set-up"
        done = f"{len(comp.runs)} of {len(controllers)} controllers finished"
        comp.interrupted = f"{where} in {kind} ({done})"
        partial = getattr(exc, "result", None)
        if partial is not None and len(partial.t):
            metrics = compute_metrics(partial) if partial.t[-1] >= 1.0 else None
            observer = bool(partial.meta.get("observer"))
            comp.runs[kind] = ControllerRun(
                kind, partial, metrics, float("nan"), observer, partial.message
            )
    finally:
        bar.close()
    return comp


def boundary_layer_sweep(
    config: ExperimentConfig, factors=(0.25, 0.45, 0.55, 1.0, 2.0)
) -> list[tuple[float, Metrics]]:
    """``hmpc-ism-bl`` with φ = factor·K·Ts for each factor: the chattering/accuracy trade-off.

    Below factor 0.5 the linear loop inside the layer, of gain :math:`T_s K/\\varphi > 2`,
    is unstable in discrete time and the switching returns.
    """
    cc = config.controller
    out = []
    for f in factors:
        base = with_controller(config, "hmpc-ism-bl")
        ism = replace(base.controller.ism, boundary_layer=f * base.controller.ism.gain * cc.Ts)
        cfg = replace(base, controller=replace(base.controller, ism=ism))
        out.append((f, run_one_controller(cfg, "hmpc-ism-bl").metrics))
    return out


COLUMNS = (
    ("RMS e after 1 s [rad]", "rms_error", ".2e"),
    ("max |e| after 1 s [rad]", "max_error", ".2e"),
    ("within 0.01 rad from [s]", "settling_time", ".2f"),
    ("RMS d−d̂ [N·m]", "observer_rms", ".2e"),
    ("RMS τ [N·m]", "tau_rms", ".3g"),
    ("peak |τ| commanded [N·m]", "tau_peak", ".4g"),
    ("peak |τ| applied [N·m]", "tau_applied_peak", ".4g"),
    ("TV(τ) [N·m/s]", "tau_tv", ".3g"),
    ("τ energy > 10 Hz", "tau_hf_share", ".1e"),
    ("limit excursion [rad]", "limit_violation", ".1e"),
    ("saturated periods", "saturated_steps", "d"),
)


def _cells(run: ControllerRun, i: int) -> list[str]:
    m = run.metrics
    cells = []
    for _, attr, spec in COLUMNS:
        if m is None:
            cells.append("n/a")
            continue
        v = getattr(m, attr)[i]
        if attr == "observer_rms" and not run.observer:
            cells.append("—")
        elif attr == "settling_time" and v != v:
            cells.append("never")
        elif v != v:
            cells.append("n/a")
        else:
            cells.append(format(int(v) if spec == "d" else v, spec))
    return cells


def markdown_table(comp: Comparison) -> str:
    """The comparison as a Markdown table, one row per controller and joint."""
    from .metrics import joint_label, joint_units, unit_labels

    first = next(iter(comp.runs.values())).result
    labels = unit_labels(first)
    head = (
        ["controller", "joint"]
        + [
            c[0].replace("[rad]", f"[{labels['rad']}]").replace("[N·m]", f"[{labels['N·m']}]")
            for c in COLUMNS
        ]
        + ["step median [µs]"]
    )
    units = joint_units(first)
    lines = [
        "| " + " | ".join(h.replace("|", "\\|") for h in head) + " |",
        "|" + "---|" * len(head),
    ]
    for kind, run in comp.runs.items():
        for i, joint in enumerate(comp.joint_names):
            step = f"{run.step_us:.1f}" if i == 0 else ""
            name = kind + (" (failed)" if run.failure else "")
            row = [name, joint_label(joint, units[i]), *_cells(run, i), step]
            lines.append("| " + " | ".join(row) + " |")
    tasks = {
        k: r.metrics.task
        for k, r in comp.runs.items()
        if r.metrics is not None and r.metrics.task is not None
    }
    if tasks:  # an end-effector task: its task-space errors, one row per controller
        frame = next(iter(tasks.values())).frame
        lines += [
            "",
            f"| controller | position RMS after 1 s [m] ({frame}) | max position "
            "error [m] | orientation RMS after 1 s [rad] | max orientation error [rad] |",
            "|---|---|---|---|---|",
        ]
        lines += [
            f"| {k} | {t.position_rms:.3e} | {t.position_max:.3e} | "
            f"{t.orientation_rms:.3e} | {t.orientation_max:.3e} |"
            for k, t in tasks.items()
        ]
    return "\n".join(lines)


def write_csv(comp: Comparison, path: Path) -> Path:
    """One row per controller and joint, full precision; empty cells where not defined."""
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(
            [
                "controller",
                "joint",
                *(a for _, a, _ in COLUMNS),
                "step_median_us",
                "observer",
                "complete",
            ]
        )
        for kind, run in comp.runs.items():
            for i, joint in enumerate(comp.joint_names):
                m = run.metrics
                values = [
                    ""
                    if m is None or (a == "observer_rms" and not run.observer)
                    else repr(float(getattr(m, a)[i]))
                    for _, a, _ in COLUMNS
                ]
                w.writerow(
                    [kind, joint, *values, f"{run.step_us:.3f}", run.observer, run.failure is None]
                )
    return path


def compare(
    config: ExperimentConfig,
    out: Path,
    controllers=None,
    progress: bool = False,
    sweep_boundary_layer: bool = True,
    error_threshold: float = DEFAULT_ERROR_THRESHOLD,
) -> tuple[Comparison, list[Path]]:
    """Run the comparison and write ``<name>_compare.md``, ``.csv`` and two figures to ``out``.

    The Markdown lists the :func:`~hmpc_pin.apps.metrics.run_warnings` of every run
    (saturated torque, tracking error above ``error_threshold`` [rad]).

    Returns:
        The :class:`Comparison` and the files written.

    Raises:
        RunInterrupted: Ctrl-C; the table of the runs done so far (the interrupted one
            marked) is written first, ``exc.files`` names it.
    """
    from . import plots

    if controllers is None:
        controllers = parse_controllers(None, config)
    comp = run_comparison(config, controllers, progress)
    if comp.interrupted and not comp.runs:  # Ctrl-C before any controller ran: no file
        raise RunInterrupted(comp.interrupted, files=[])
    stem = f"{config.name}_compare"
    title = config.description or config.name
    results = {k: r.result for k, r in comp.runs.items() if len(r.result.t) > 1}
    files = [write_csv(comp, out / f"{stem}.csv")] if comp.runs else []
    figures = []
    if results and not comp.interrupted:
        figures.append(plots.plot_error(results, out / f"{stem}_error.png", title))
        t_end = float(min(r.t[-1] for r in results.values()))
        window = (min(2.0, 0.5 * t_end), min(2.5, t_end))
        figures.append(plots.plot_torques(results, out / f"{stem}_tau.png", title, window))
    lines = [
        f"# Controller comparison: {config.name}",
        "",
        f"{config.description}. Every controller runs on the same robot model, plant, "
        "reference, disturbances, initial state and MPC settings (config "
        f"`{config.source or config.name}`); only the controller × compensation changes. "
        "Rerun with "
        f"`hmpc-pin compare {config.source or 'CONFIG'} --controllers {','.join(controllers)}`.",
        "",
        markdown_table(comp),
        "",
        "Errors, observer error, effort and chattering are taken over t ≥ 1 s; chattering is "
        "the total variation of τ per second and the share of the energy of τ − mean(τ) above "
        "10 Hz. Step time: median wall time of the controller's `step` in this run.",
    ]
    failed = {k: r.failure for k, r in comp.runs.items() if r.failure}
    if failed:
        lines += ["", "Failed runs (metrics from the part before the failure):", ""]
        lines += [f"- `{k}`: {v}" for k, v in failed.items()]
    warned = [
        (k, line) for k, r in comp.runs.items() for line in run_warnings(r.result, error_threshold)
    ]
    if warned:
        lines += ["", "Warnings (runs that completed but were not controlled as designed):", ""]
        lines += [f"- `{k}`: {line}" for k, line in warned]
    if comp.interrupted:
        lines += ["", f"**Interrupted** (Ctrl-C) at {comp.interrupted}."]
    if sweep_boundary_layer and "hmpc-ism-bl" in controllers and not comp.interrupted:
        lines += ["", boundary_layer_table(config, comp.joint_names)]
    for path in figures:
        lines += ["", f"![{path.stem}]({path.name})"]
    md = out / f"{stem}.md"
    md.write_text("\n".join(lines) + "\n", encoding="utf-8")
    files = [md, *files, *figures]
    if comp.interrupted:
        raise RunInterrupted(comp.interrupted, files=files)
    return comp, files


def boundary_layer_table(config: ExperimentConfig, joint_names) -> str:
    """Markdown: the :func:`boundary_layer_sweep` of ``hmpc-ism-bl`` on ``config``."""
    cc = with_controller(config, "hmpc-ism-bl").controller
    rows = boundary_layer_sweep(config)
    lines = [
        f"## Boundary layer of hmpc-ism-bl (K = {cc.ism.gain:g} rad/s², Ts = {cc.Ts:g} s)",
        "",
        "φ = factor·K·Ts; below factor 0.5 the loop inside the layer (gain Ts·K/φ > 2) is "
        "unstable in discrete time and the switching comes back.",
        "",
        "| φ/(K·Ts) | φ [rad/s] | RMS e after 1 s [rad] per joint | TV(τ) [N·m/s] per joint |",
        "|---|---|---|---|",
    ]
    for f, m in rows:
        rms = ", ".join(f"{x:.2e}" for x in m.rms_error) if m else "n/a"
        tv = ", ".join(f"{x:.3g}" for x in m.tau_tv) if m else "n/a"
        lines.append(f"| {f:g} | {f * cc.ism.gain * cc.Ts:.3g} | {rms} | {tv} |")
    return "\n".join(lines)
