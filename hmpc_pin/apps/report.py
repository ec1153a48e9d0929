"""``hmpc-pin reproduce``: every experiment of the paper's Section 5, its figures and a report.

The report (``report.md``) holds a metrics table per experiment and joint, each
of the paper's claims next to the measured numbers with a verdict, and every
figure captioned with the paper figure it corresponds to.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..controllers.registry import REGISTRY as CONTROLLERS
from ..data import DATA
from ..experiment.build import load_robot_config
from ..experiment.config import load_config
from .metrics import DEFAULT_ERROR_THRESHOLD, Metrics, compute_metrics, run_warnings

__all__ = ["PAPER_EXPERIMENTS", "comparison_claims", "reproduce"]

REPO_CONFIGS = DATA / "configs"  # the packaged configs (also the repository's configs/)


@dataclass(frozen=True)
class PaperExperiment:
    """One experiment of Section 5 and the paper figures it reproduces."""

    name: str  # config stem, e.g. "paper_friction"
    section: str
    disturbance_figure: str
    tracking_figure: str
    baseline: str | None  # config stem of the run without NDO


PAPER_EXPERIMENTS = (
    PaperExperiment("paper_friction", "5.1", "Figure 4", "Figure 5", "paper_friction_no_ndo"),
    PaperExperiment("paper_external", "5.2", "Figure 6", "Figure 7", "paper_external_no_ndo"),
    PaperExperiment("paper_combined", "5.3", "Figure 8", "Figure 9", "paper_combined_no_ndo"),
    PaperExperiment(
        "paper_cartesian",
        "5.4",
        "(not drawn in the paper)",
        "(Figure 10)",
        "paper_cartesian_no_ndo",
    ),
    PaperExperiment(
        "paper_friction_literal",
        "5.1, Eq 32 read literally",
        "(Figure 4's scenario with d = +F, not in the paper)",
        "(Figure 5's scenario with d = +F, not in the paper)",
        "paper_friction_literal_no_ndo",
    ),
)

#: Runs whose failure is the measured answer (Eq 32 read literally, no observer: friction
#: feeding energy in), reported but not a failure of ``reproduce``.
EXPECTED_FAILURES = frozenset({"paper_friction_literal_no_ndo"})


@dataclass
class Claim:
    """A sentence of the paper, how it is checked, and the verdict."""

    section: str
    text: str
    check: str
    evidence: str = ""
    agrees: bool | None = None


def _fmt(arr, spec=".2e") -> str:
    return ", ".join("never" if v != v else format(v, spec) for v in arr)


class _Claims(list):
    """The claims checked so far; :meth:`add` checks one whose runs all ran."""

    def __init__(self, runs: dict, metrics: dict):
        super().__init__()
        self.runs, self.metrics = runs, metrics

    def add(self, section, text, check, fn: Callable[[], tuple[bool, str]], needs=()) -> None:
        if not all(k in self.metrics for k in needs):
            return
        ok, ev = fn()
        self.append(Claim(section, text, check, ev, ok))


def _claims(runs: dict, metrics: dict, cart: dict | None) -> list[Claim]:
    """Every claim of the paper's section 5, each with its reading and evidence."""
    out = _Claims(runs, metrics)
    _friction_claims(out, runs, metrics)
    _external_and_combined_claims(out, metrics)
    if cart is not None:
        _cartesian_claims(out, cart)
    return list(out)


def _relative_observer_error(runs: dict, metrics: dict, name: str, joints) -> np.ndarray:
    """RMS(d − d̂) after 1 s over RMS(d) of run ``name`` on ``joints``."""
    r = runs[name]
    mask = r.t >= 1.0
    scale = np.sqrt(np.mean(r.d[mask] ** 2, axis=0))
    rel = metrics[name].observer_rms / np.maximum(scale, 1e-12)
    return rel[joints]


def _friction_claims(out: _Claims, runs: dict, metrics: dict) -> None:
    """Section 5.1 (unknown friction), with both readings of Eq 32's sign."""
    add = out.add

    def rel_obs(name, joints):
        return _relative_observer_error(runs, metrics, name, joints)

    add(
        "5.1",
        "For joints 1 and 2, at about one second, the estimated values of the NDO approximate "
        "the actual values of the unknown frictions.",
        "RMS(d − d̂) after 1 s below 20 % of RMS(d) on joints 1 and 2",
        lambda: (
            bool(np.all(rel_obs("paper_friction", [0, 1]) < 0.2)),
            f"relative observer error {_fmt(100 * rel_obs('paper_friction', [0, 1]), '.1f')} %",
        ),
        ("paper_friction",),
    )
    cannot = "The system cannot converge without the compensation of the NDO."
    add(
        "5.1",
        cannot,
        "physical sign (d = −F), 'converge' read as 'reach and stay within 0.01 rad': without "
        "NDO some joint never stays within 0.01 rad",
        lambda: (
            bool(np.any(np.isnan(metrics["paper_friction_no_ndo"].settling_time))),
            "without NDO: within 0.01 rad from "
            f"[{_fmt(metrics['paper_friction_no_ndo'].settling_time, '.2f')}] s, RMS error after "
            f"1 s [{_fmt(metrics['paper_friction_no_ndo'].rms_error)}] rad",
        ),
        ("paper_friction_no_ndo",),
    )
    add(
        "5.1",
        cannot,
        "physical sign (d = −F), 'converge' read as 'stay bounded': without NDO the run "
        "fails or max |e| after 1 s exceeds 1 rad",
        lambda: (
            bool(
                not runs["paper_friction_no_ndo"].complete
                or np.any(metrics["paper_friction_no_ndo"].max_error > 1.0)
            ),
            "without NDO the run completes, bounded: max |e| after 1 s "
            f"[{_fmt(metrics['paper_friction_no_ndo'].max_error)}] rad (an offset, not "
            "divergence)",
        ),
        ("paper_friction_no_ndo",),
    )
    if "paper_friction_literal_no_ndo" in runs:
        lit = runs["paper_friction_literal_no_ndo"]
        out.append(
            Claim(
                "5.1",
                cannot,
                "Eq 32 read literally (d = +F), 'converge' read as 'stay bounded': the run "
                "without NDO fails (divergence or an infeasible MPC QP) before its end",
                f"without NDO: {'completed' if lit.complete else 'stopped'} at t = "
                f"{lit.t[-1]:.2f} s of {runs['paper_friction_literal'].t[-1]:.0f} s"
                + (f" ({lit.message.split(':')[0]})" if lit.message else ""),
                not lit.complete,
            )
        )
    add(
        "5.1",
        "Each joint can track the reference trajectory from an initial position in less than "
        "half a second.",
        "|e| stays below 0.02 rad (2 % of the amplitude: on the reference in a plot like "
        "Figure 5) from before 0.5 s on every joint; the 0.01 rad band is shown too",
        lambda: (
            bool(np.all(metrics["paper_friction_band"] < 0.5)),
            f"within 0.02 rad from [{_fmt(metrics['paper_friction_band'], '.2f')}] s; "
            f"within 0.01 rad from [{_fmt(metrics['paper_friction'].settling_time, '.2f')}] s",
        ),
        ("paper_friction",),
    )
    add(
        "5.1",
        "Each joint can track the reference trajectory from an initial position in less than "
        "half a second.",
        "Eq 32 read literally (d = +F), observer gain c = 300 (c = 100 tracks badly, c = 20 "
        "diverges): |e| stays below 0.02 rad from before 0.5 s on every joint",
        lambda: (
            bool(np.all(metrics["paper_friction_literal_band"] < 0.5)),
            f"within 0.02 rad from [{_fmt(metrics['paper_friction_literal_band'], '.2f')}] s; "
            f"RMS error after 1 s [{_fmt(metrics['paper_friction_literal'].rms_error)}] rad",
        ),
        ("paper_friction_literal",),
    )


def _external_and_combined_claims(out: _Claims, metrics: dict) -> None:
    """Sections 5.2 (external disturbances) and 5.3 (both together)."""
    add = out.add
    add(
        "5.2",
        "The estimated values of the NDO approximate the actual values of the unknown external "
        "disturbances well.",
        "peak |d − d̂| after 1 s below 25 % of the pulse amplitude on joints 1 and 2",
        lambda: (
            bool(np.all(metrics["paper_external"].observer_peak[:2] < 0.25 * np.array([10, 8]))),
            f"peak observer error [{_fmt(metrics['paper_external'].observer_peak, '.2f')}] N·m "
            "for pulses of 10, 8, 0.3 N·m",
        ),
        ("paper_external",),
    )
    add(
        "5.2",
        "Each joint can also track the reference trajectory from an initial position in a "
        "limited time.",
        "every joint stays within 0.01 rad from some finite time on",
        lambda: (
            bool(np.all(np.isfinite(metrics["paper_external"].settling_time))),
            f"within 0.01 rad from [{_fmt(metrics['paper_external'].settling_time, '.2f')}] s",
        ),
        ("paper_external",),
    )
    add(
        "5.3",
        "The NDO can compensate for the total unknown interferences well, enhancing the "
        "robustness of the proposed controller.",
        "RMS error after 1 s with NDO at least 5× lower than without, on every joint",
        lambda: (
            bool(
                np.all(
                    metrics["paper_combined_no_ndo"].rms_error
                    >= 5 * metrics["paper_combined"].rms_error
                )
            ),
            "ratio without/with NDO ["
            + _fmt(
                metrics["paper_combined_no_ndo"].rms_error / metrics["paper_combined"].rms_error,
                ".1f",
            )
            + "]",
        ),
        ("paper_combined", "paper_combined_no_ndo"),
    )
    add(
        "5.3",
        "Each joint of the robot manipulator can quickly track the reference trajectory from "
        "an initial position.",
        "time to stay within 0.01 rad at most 0.6 s on every joint",
        lambda: (
            bool(np.all(metrics["paper_combined"].settling_time <= 0.6)),
            f"within 0.01 rad from [{_fmt(metrics['paper_combined'].settling_time, '.2f')}] s",
        ),
        ("paper_combined",),
    )


def _cartesian_claims(out: _Claims, cart: dict) -> None:
    """Section 5.4 (a Cartesian target)."""
    out.append(
        Claim(
            "5.4",
            "The robot manipulator can still reach the preset position in Cartesian space "
            "well even under unknown frictions and external disturbances.",
            "final tool position error below 1e-3 and link-3 angle error below 1e-3 rad",
            f"final tool position error {cart['pos_err']:.2e}, angle error "
            f"{cart['ang_err']:.2e} rad (t = {cart['t']:.1f} s)"
            + (
                f"; without NDO the final error is {cart['base_pos_err']:.2e} m: this "
                "check passes without the observer too"
                if "base_pos_err" in cart
                else ""
            ),
            bool(cart["pos_err"] < 1e-3 and cart["ang_err"] < 1e-3),
        )
    )
    if "base_path_dev" in cart:
        t0, t1 = cart["move"]
        out.append(
            Claim(
                "5.4",
                "... even under unknown frictions and external disturbances (the "
                "observer's part in it).",
                f"max tool position error during the move ({t0:g}–{t1:g} s) with NDO at "
                "least 5× below the run without NDO",
                f"max |p(q) − p(r)| during the move: {cart['path_dev']:.2e} m with NDO, "
                f"{cart['base_path_dev']:.2e} m without",
                bool(5 * cart["path_dev"] <= cart["base_path_dev"]),
            )
        )


def comparison_claims(comp) -> list[Claim]:
    """The paper's comparative claims checked on a :class:`~hmpc_pin.apps.compare.Comparison`.

    Needs the runs ``hmpc``, ``hmpc-none``, ``hmpc-ism``, ``hmpc-ism-bl`` and
    ``computed-torque``(``-pid``); claims whose runs are missing are skipped.
    """
    m = {k: r.metrics for k, r in comp.runs.items() if r.metrics is not None}
    out = []

    def add(section, text, check, needs, fn):
        if all(k in m for k in needs):
            ok, ev = fn()
            out.append(Claim(section, text, check, ev, bool(ok)))

    def ratio(a, b, attr):
        return getattr(m[a], attr) / getattr(m[b], attr)

    add(
        "1",
        "The ISM-based hierarchical MPC (Incremona et al. 2017) suffers from chattering; the "
        "NDO-based scheme does not.",
        "TV(τ) of hmpc-ism at least 10× that of hmpc on every joint (t ≥ 1 s)",
        ("hmpc", "hmpc-ism"),
        lambda: (
            np.all(ratio("hmpc-ism", "hmpc", "tau_tv") >= 10),
            f"TV ratio ISM/NDO [{_fmt(ratio('hmpc-ism', 'hmpc', 'tau_tv'), '.3g')}]; share of "
            f"τ energy above 10 Hz: ISM [{_fmt(m['hmpc-ism'].tau_hf_share, '.2f')}], NDO "
            f"[{_fmt(m['hmpc'].tau_hf_share, '.1e')}]",
        ),
    )
    add(
        "1",
        'Abstract: "the proposed controller provides comparative accuracy and robustness" '
        "(compared with the ISM-based scheme of Incremona et al., Section 1).",
        "read as 'at least as accurate': RMS error after 1 s of hmpc below hmpc-ism on every joint",
        ("hmpc", "hmpc-ism"),
        lambda: (
            np.all(m["hmpc"].rms_error < m["hmpc-ism"].rms_error),
            f"RMS hmpc [{_fmt(m['hmpc'].rms_error)}] vs hmpc-ism "
            f"[{_fmt(m['hmpc-ism'].rms_error)}] rad",
        ),
    )
    add(
        "1",
        "(Not claimed by the paper; the fair test.) The NDO also beats the ISM with the usual "
        "anti-chattering boundary layer.",
        "RMS error after 1 s of hmpc below hmpc-ism-bl (φ = K·Ts) on every joint",
        ("hmpc", "hmpc-ism-bl"),
        lambda: (
            np.all(m["hmpc"].rms_error < m["hmpc-ism-bl"].rms_error),
            f"RMS hmpc [{_fmt(m['hmpc'].rms_error)}] vs hmpc-ism-bl "
            f"[{_fmt(m['hmpc-ism-bl'].rms_error)}] rad; TV ratio BL/NDO "
            f"[{_fmt(ratio('hmpc-ism-bl', 'hmpc', 'tau_tv'), '.2f')}]",
        ),
    )
    add(
        "1",
        "Without the NDO the system cannot converge.",
        "hmpc-none: some joint never stays within 0.01 rad, RMS error ≥ 5× hmpc's on every joint",
        ("hmpc", "hmpc-none"),
        lambda: (
            np.any(np.isnan(m["hmpc-none"].settling_time))
            and np.all(ratio("hmpc-none", "hmpc", "rms_error") >= 5),
            f"within 0.01 rad from [{_fmt(m['hmpc-none'].settling_time, '.2f')}] s; RMS ratio "
            f"[{_fmt(ratio('hmpc-none', 'hmpc', 'rms_error'), '.1f')}]",
        ),
    )
    for kind in (name for name, spec in CONTROLLERS.items() if not spec.mpc):  # the classical
        add(
            "1",
            f"(Classical reference.) The scheme beats {kind} tuned to the same bandwidth.",
            f"RMS error after 1 s of hmpc below {kind} on at least 2 of the joints",
            ("hmpc", kind),
            lambda kind=kind: (
                np.sum(m["hmpc"].rms_error < m[kind].rms_error) >= 2,
                f"RMS ratio {kind}/hmpc [{_fmt(ratio(kind, 'hmpc', 'rms_error'), '.1f')}]",
            ),
        )
    return out


def _metrics_table(metrics: dict[str, Metrics], runs: dict, joint_names) -> str:
    """Per experiment and joint; the observer error both after 1 s (the paper's figures
    after the start-up) and from t = 0 (with the start-up transient, and when its peak is)."""
    lines = [
        "| experiment | joint | RMS e after 1 s [rad] | max \\|e\\| after 1 s [rad] "
        "| within 0.01 rad from [s] | RMS d−d̂ after 1 s [N·m] | peak \\|d−d̂\\| after 1 s [N·m] "
        "| RMS d−d̂ from 0 s [N·m] | peak \\|d−d̂\\| from 0 s [N·m] (at t [s]) "
        "| peak \\|τ\\| [N·m] | peak \\|τ\\| applied [N·m] |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, m in metrics.items():
        if not isinstance(m, Metrics) or name.endswith("_t0"):
            continue
        m0, w = metrics[name + "_t0"], np.abs(runs[name].observer_error)
        for i, j in enumerate(joint_names):
            st = m.settling_time[i]
            t_peak = runs[name].t[int(np.argmax(w[:, i]))]
            lines.append(
                f"| {name} | {j} | {m.rms_error[i]:.2e} | {m.max_error[i]:.2e} | "
                f"{'never' if st != st else f'{st:.2f}'} | {m.observer_rms[i]:.2e} | "
                f"{m.observer_peak[i]:.2e} | {m0.observer_rms[i]:.2e} | "
                f"{m0.observer_peak[i]:.2e} ({t_peak:.2f}) | {m.tau_peak[i]:.0f} | "
                f"{m.tau_applied_peak[i]:.0f} |"
            )
    return "\n".join(lines)


def _tool_deviation(robot, result, t0: float, t1: float) -> float:
    """max over t0 <= t <= t1 of the tool's distance from where the reference puts it,
    :math:`\\|p(q(t)) - p(r(t))\\|` [m] (forward kinematics of both)."""
    from ..model.planar import tool_pose

    mask = (result.t >= t0 - 1e-12) & (result.t <= t1 + 1e-12)
    dev = [
        np.hypot(*(np.array(tool_pose(robot, q)[:2]) - np.array(tool_pose(robot, r)[:2])))
        for q, r in zip(result.q[mask], result.q_ref[mask], strict=True)
    ]
    return float(max(dev)) if dev else float("nan")


def reproduce(out: Path, configs_dir: Path | None = None, progress: bool = True) -> bool:
    """Run every paper experiment into ``out`` and write ``out/report.md``.

    Returns:
        ``True`` if every run completed.
    """
    from .compare import compare

    configs_dir = Path(configs_dir) if configs_dir else REPO_CONFIGS
    start = time.perf_counter()
    tasks = []
    for exp in PAPER_EXPERIMENTS:
        tasks.append(exp.name)
        if exp.baseline:
            tasks.append(exp.baseline)
    configs = {name: load_config(configs_dir / f"{name}.toml") for name in tasks}
    runs, metrics, failures = _run_paper(configs, tasks, out, progress)
    figures = _paper_figures(runs, out)
    robot = load_robot_config(configs["paper_combined"].robot)
    figures.insert(0, _workspace_figure(robot, configs["paper_combined"], out))
    cart = _cartesian(robot, configs, runs, out, figures)
    claims = _claims(runs, metrics, cart)
    comp, comp_files = compare(
        configs["paper_combined"], out, progress=False, sweep_boundary_layer=False
    )
    claims += comparison_claims(comp)
    figures += [
        (
            comp_files[-2],
            "Controller comparison, Section 5.3 scenario: tracking error of every "
            "controller (log scale).",
        ),
        (
            comp_files[-1],
            "Controller comparison, Section 5.3 scenario: torque over 2–2.5 s "
            "(the ISM's chattering).",
        ),
    ]
    elapsed = time.perf_counter() - start
    lines = _report_lines(
        out, elapsed, configs, runs, metrics, failures, claims, comp, cart, figures
    )
    (out / "report.md").write_text("\n".join(lines), encoding="utf-8")
    if progress:
        print(f"wrote {out / 'report.md'} ({len(figures)} figures) in {elapsed:.1f} s")
    return not set(failures) - EXPECTED_FAILURES


def _run_paper(configs: dict, tasks: list[str], out: Path, progress: bool):
    """Run ``tasks`` (config names) into ``out``: ``(runs, metrics, failures)``."""
    from tqdm import tqdm

    from .metrics import settling_time
    from .run import run_one

    runs, metrics, failures = {}, {}, {}
    bar = tqdm(tasks, desc="reproduce", unit="run", disable=not progress)
    for name in bar:
        bar.set_postfix_str(name)
        _, result, _, failure = run_one(configs[name], out, name)
        runs[name] = result
        if failure:
            failures[name] = failure
        if result.t[-1] >= 1.0:
            metrics[name] = compute_metrics(result)
            metrics[name + "_band"] = settling_time(result.t, result.error, 0.02)
            metrics[name + "_t0"] = compute_metrics(result, after=0.0)

    return runs, metrics, failures


def _paper_figures(runs: dict, out: Path) -> list[tuple]:
    """The figures in the paper's numbering, ``(path, caption)``, and each run's error
    against its baseline."""
    from . import plots

    figures: list[tuple] = []
    for exp in PAPER_EXPERIMENTS:
        if exp.baseline and exp.name in runs and exp.baseline in runs:
            figures.append(
                (
                    plots.plot_error(
                        {"with NDO": runs[exp.name], "without NDO": runs[exp.baseline]},
                        out / f"{exp.name}_error_vs_baseline.png",
                        f"Section {exp.section}: tracking error with and without NDO",
                    ),
                    f"Section {exp.section} (extra): tracking error |q − r| on a log scale, "
                    "with and without the NDO.",
                )
            )
        for suffix, fig in (
            ("disturbance", exp.disturbance_figure),
            ("tracking", exp.tracking_figure),
        ):
            path = out / f"{exp.name}_{suffix}.png"
            if path.exists():
                what = (
                    "true vs NDO-estimated disturbance per joint"
                    if suffix == "disturbance"
                    else "reference vs joint angle per joint"
                )
                figures.append((path, f"Paper {fig} — Section {exp.section}: {what}."))

    return figures


def _workspace_figure(robot, config, out: Path) -> tuple:
    """Paper Figure 3(b), ``(path, caption)``."""
    from ..model.planar import workspace_points
    from . import plots

    q0 = config.vector("simulation.q0", robot.nq)
    ws = plots.plot_workspace(
        robot,
        out / "figure3b_workspace.png",
        {"q = 0": np.zeros(robot.nq), f"start pose q = {q0.tolist()}": q0},
        workspace_points(robot),
        "Workspace within the joint limits of Eq 27",
    )
    return (
        ws,
        "Paper Figure 3(b): the arm's workspace (tool positions reachable "
        "within the joint limits of Eq 27), the arm drawn at q = 0 and at the "
        "start pose of Sections 5.1–5.3.",
    )


def _cartesian(robot, configs: dict, runs: dict, out: Path, figures: list) -> dict | None:
    """Section 5.4's figures (appended to ``figures``): the final tool errors, the path
    deviation with and without the NDO; ``None`` without the Cartesian run."""
    from ..model.planar import tool_pose
    from . import plots

    cart = None
    if "paper_cartesian" in runs and len(runs["paper_cartesian"].t) > 1:
        cc = configs["paper_cartesian"].reference.cartesian
        r = runs["paper_cartesian"]
        x, z, phi = tool_pose(robot, r.q[-1])
        cart = {
            "pos_err": float(np.hypot(x - cc.goal_position[0], z - cc.goal_position[1])),
            "ang_err": float(abs(np.angle(np.exp(1j * (phi - np.deg2rad(cc.goal_angle)))))),
            "t": float(r.t[-1]),
            "move": (cc.t_start, cc.t_start + cc.move_time),
            "path_dev": _tool_deviation(robot, r, cc.t_start, cc.t_start + cc.move_time),
        }
        t_end_move = cc.t_start + cc.move_time
        for key, window in (
            ("obs_move", (r.t >= 1.0) & (r.t < t_end_move)),
            ("obs_rest", r.t >= t_end_move),
        ):
            w = r.observer_error[window]
            cart[key] = np.sqrt(np.mean(w**2, axis=0)) if len(w) else np.full(r.q.shape[1], np.nan)
        base = runs.get("paper_cartesian_no_ndo")
        if base is not None and len(base.t) > 1:
            xb, zb, _ = tool_pose(robot, base.q[-1])
            cart["base_pos_err"] = float(
                np.hypot(xb - cc.goal_position[0], zb - cc.goal_position[1])
            )
            cart["base_path_dev"] = _tool_deviation(
                robot, base, cc.t_start, cc.t_start + cc.move_time
            )
        fig10 = plots.plot_cartesian(
            robot,
            r,
            out / "figure10_cartesian.png",
            cc.start_position,
            cc.goal_position,
            "Section 5.4: tool motion in Cartesian space",
            window=(cc.t_start, cc.t_start + cc.move_time),
        )
        figures.append(
            (
                fig10,
                "Paper Figure 10 — Section 5.4: tool path in the x–z plane "
                "(the paper's x–y), start, goal and arm poses.",
            )
        )

    return cart


def _report_lines(
    out: Path,
    elapsed: float,
    configs: dict,
    runs: dict,
    metrics: dict,
    failures: dict,
    claims: list,
    comp,
    cart,
    figures,
) -> list[str]:
    """The report's Markdown lines."""
    import pinocchio as pin
    import proxsuite

    from .._version import __version__
    from .compare import markdown_table

    joint_names = runs["paper_combined"].joint_names
    lines = [
        "# hmpc_pin — reproduction of Li et al. (2022), Section 5",
        "",
        f"Generated by `hmpc-pin reproduce --out {out}` in {elapsed:.1f} s "
        f"(hmpc_pin {__version__}, Pinocchio {pin.__version__}, ProxSuite "
        f"{proxsuite.__version__}, NumPy {np.__version__}). Every number below comes from "
        "this run; the trajectories are in the `.npz`/`.csv` files next to this report.",
        "",
        "Settings: the paper's controller (Ts = 0.01, N = 10, Nc = 1, Q = diag(50, 0), "
        "R = 1e-6, P = 2Q, v ∈ [−100, 100]) with observer gain c = "
        f"{configs['paper_combined'].controller.observer.gain:g} (not given in the paper); "
        "plant integrated with RK4 at 1 ms; friction opposing motion (documentation: "
        "Concepts, decisions the paper leaves open).",
        "",
        "## The paper's claims",
        "",
        "| § | paper says | checked as | measured | agrees |",
        "|---|---|---|---|---|",
    ]
    for c in claims:
        verdict = {True: "yes", False: "**no**", None: "n/a"}[c.agrees]
        cells = (cell.replace("|", "\\|") for cell in (c.text, c.check, c.evidence))
        lines.append(f"| {c.section} | {' | '.join(cells)} | {verdict} |")
    if failures:
        lines += ["", "## Failed runs", ""]
        lines += [
            f"- `{k}`: {v}"
            + (
                " (expected: the measured answer of a claim above)"
                if k in EXPECTED_FAILURES
                else ""
            )
            for k, v in failures.items()
        ]
    warned = [(k, w) for k, r in runs.items() for w in run_warnings(r)]
    warned += [(f"compare {k}", w) for k, r in comp.runs.items() for w in run_warnings(r.result)]
    if warned:
        lines += [
            "",
            "## Warnings",
            "",
            "Runs that completed but were not controlled as designed (torque clipped "
            "by the plant, or max |e| after 1 s above "
            f"{DEFAULT_ERROR_THRESHOLD:g} rad):",
            "",
        ]
        lines += [f"- `{k}`: {w}" for k, w in warned]
    table = _metrics_table(metrics, runs, joint_names)
    lines += ["", "## Metrics per experiment and joint", "", table]
    if "paper_cartesian" in metrics and cart is not None:
        lines += [
            "",
            "The observer error of `paper_cartesian` after 1 s "
            f"([{_fmt(metrics['paper_cartesian'].observer_rms)}] N·m) comes from the arm "
            "holding still at the goal after its move: there the velocity hovers around zero "
            "and changes sign from period to period, so the plant's Coulomb term b·sgn(q̇) "
            "jumps by 2b, which the observer cannot follow within one period "
            f"(RMS d − d̂ over 1–{cart['move'][1]:g} s, during the move: "
            f"[{_fmt(cart['obs_move'])}] N·m; after it: [{_fmt(cart['obs_rest'])}] N·m). "
            "It is not a tracking failure.",
        ]
    lines += [
        "",
        "## Controller comparison on the Section 5.3 scenario",
        "",
        "Same robot, plant, reference, disturbances and MPC settings; only the controller "
        "changes (documentation: Concepts, controllers; "
        "`hmpc-pin compare paper_combined`). "
        "Errors, effort and chattering over t ≥ 1 s.",
        "",
        markdown_table(comp),
    ]
    if cart is not None:
        lines += [
            "",
            f"Section 5.4: final tool position error {cart['pos_err']:.2e}, link-3 angle error "
            f"{cart['ang_err']:.2e} rad at t = {cart['t']:.1f} s.",
        ]
    lines += ["", "## Figures", ""]
    for path, caption in figures:
        lines += [f"![{caption}]({Path(path).name})", "", f"*{caption}*", ""]
    return lines
