"""Regenerate the numbers printed in the README and the guides from the code.

Every printed block and table of measured numbers sits in its Markdown file between two
comments::

    <!-- generated: NAME (python docs/regenerate.py) -->
    ...
    <!-- end generated: NAME -->

and :data:`BLOCKS` names the function that writes it, from runs of the package done
here. Usage (from the repository's root)::

    python docs/regenerate.py                 # rewrite every passage
    python docs/regenerate.py --check         # compare only; exit 1 naming what differs
    python docs/regenerate.py --only NAME ... # some of them
    python docs/regenerate.py --fast          # leave out the slow ones (minutes of tuning)

A passage agrees with its regeneration (:func:`agrees`) when the text around the numbers
is the same (line breaks aside) and each number is within one unit of its last printed
digit (the same code on another machine may round the last digit the other way). Timings
are machine-dependent: a block's ``volatile`` patterns (e.g. ``in 0.09 s``) are left out
of the comparison, and the prose calls them "about" or example values. Every run is
deterministic: the same code prints the same numbers. The ROS guide's passage runs ROS 2
nodes, only ever in a private network namespace (``unshare -n``), and is left out where
that or rclpy is not available. ``tests/test_docs_numbers.py`` runs the check.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import io
import re
import subprocess
import sys
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
TUNING = "docs/guide/identification-and-tuning.md"

START = "<!-- generated: {name} (python docs/regenerate.py) -->"
END = "<!-- end generated: {name} -->"


@dataclass(frozen=True)
class Block:
    """A generated passage: its name, file (from the root), writer, and whether it is slow
    (minutes); ``volatile``: regular expressions of machine-dependent spans (timings);
    ``needs_ros``: it runs ROS 2 nodes (rclpy, a private network namespace:
    :func:`ros_reason`)."""

    name: str
    file: str
    write: Callable[[], str]
    slow: bool = False
    volatile: tuple[str, ...] = ()
    needs_ros: bool = False


# --- helpers ------------------------------------------------------------------------------


def _minus(text: str) -> str:
    """A printed number's hyphen as the typographic minus of the docs' prose and tables."""
    return text.replace("-", "−")


def _pct(x: float) -> str:
    """A relative deviation in per cent with its sign: ``+0.3 %``, ``−1.7 %``."""
    return _minus(f"{100 * x:+.1f} %")


def _para(text: str) -> str:
    """A paragraph of prose wrapped as the docs' source is."""
    import textwrap

    glued = re.sub(r"(\d) (%|N·m|rad\b|s\b)", "\\1\x00\\2", " ".join(text.split()))
    return textwrap.fill(glued, 90, break_on_hyphens=False).replace("\x00", " ")


def _e(x: float) -> str:
    """Two significant digits in the docs' short exponent form: ``3.4e-4``."""
    mantissa, exponent = f"{x:.1e}".split("e")
    return f"{mantissa}e{int(exponent)}"


def _e3(x: float) -> str:
    """Three significant digits in the short exponent form: ``8.87e-5``."""
    mantissa, exponent = f"{x:.2e}".split("e")
    return f"{mantissa}e{int(exponent)}"


def _plain(x: float) -> str:
    """Two significant digits without an exponent; whole numbers from 100 up: ``1.6``, ``1317``."""
    return f"{x:.0f}" if abs(x) >= 100 else f"{x:.2g}"


def _e4(x: float) -> str:
    """Four significant digits in the short exponent form: ``4.312e-4``."""
    mantissa, exponent = f"{x:.3e}".split("e")
    return f"{mantissa}e{int(exponent)}"


def _joints(indices) -> str:
    """``joint 3``, ``joints 1 and 2``, ``joints 1, 2 and 3`` (1-based)."""
    names = [str(i + 1) for i in indices]
    if len(names) == 1:
        return f"joint {names[0]}"
    return "joints " + ", ".join(names[:-1]) + " and " + names[-1]


def _reversal_share(result, joint: int, window: float = 0.5, after: float = 1.0):
    """The share of ``joint``'s squared observer error after ``after`` that lies within
    ``window`` [s] of the reference's reversals (sign changes of q̇_ref), that share of
    the time, and the reversals' times."""
    from hmpc_pin.sim.result import Result

    r = Result.load(result)
    w = r.observer_error[:, joint]
    late = r.t >= after - 1e-12
    sign = np.sign(r.dq_ref[:, joint])
    reversals = r.t[np.flatnonzero(np.diff(sign) != 0)]
    near = np.zeros(len(r.t), dtype=bool)
    for tr in reversals:
        near |= np.abs(r.t - tr) <= window
    share = float(np.sum(w[late & near] ** 2) / np.sum(w[late] ** 2))
    return share, float(np.mean(near[late])), reversals


def _list(values, fmt: str) -> str:
    return ", ".join(format(float(v), fmt) for v in values)


def _cli(*args: str) -> str:
    """``hmpc-pin ARGS`` in this process; its standard output (exit 0 asserted)."""
    from hmpc_pin.apps.cli import main

    argv = [str(a) for a in args]
    buf, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(err):
        code = main(argv)
    if code != 0:
        raise RuntimeError(f"hmpc-pin {' '.join(argv)} exited {code}: {err.getvalue().strip()}")
    return buf.getvalue()


@functools.cache
def _workdir() -> Path:
    """A temporary folder for the runs, removed when the interpreter exits."""
    import atexit
    import shutil

    path = Path(tempfile.mkdtemp(prefix="hmpc_docs_"))
    atexit.register(shutil.rmtree, path, ignore_errors=True)
    return path


@functools.cache
def _run(config: str, duration: float | None = None, stem: str = "") -> Path:
    """``hmpc-pin run CONFIG [--duration D] --no-figures`` into a folder of its own; the
    ``.npz`` written."""
    name = stem or config.replace("/", "_").replace(".", "_")
    if duration is not None:  # a folder per run: a run never replaces another's files
        name += f"_{duration:g}s".replace(".", "_")
    out = _workdir() / name
    args = ["run", config, "--out", out, "--no-figures", "--force"]  # the same run again
    if duration is not None:
        args += ["--duration", str(duration)]
    _cli(*args)
    (npz,) = out.glob("*.npz")  # named after the config's name
    return npz


def _metrics(npz: Path):
    from hmpc_pin.apps.metrics import compute_metrics
    from hmpc_pin.sim.result import Result

    return compute_metrics(Result.load(npz))


def _fits(npz: Path, after: float = 0.5):
    """The friction fits of ``identify`` (observer and dynamics sources, its defaults)."""
    from hmpc_pin.apps.identify import observer_model
    from hmpc_pin.apps.runfile import load_run, run_robot
    from hmpc_pin.identification import fit_friction

    result = load_run(npz)
    robot = run_robot(result, None)
    observer = fit_friction(
        result, source="observer", robot=robot, observer=observer_model(result, robot), after=after
    )
    dynamics = fit_friction(result, source="dynamics", robot=robot, after=after)
    return result, observer, dynamics


def _friction_truth(config: str) -> tuple[np.ndarray, np.ndarray]:
    from hmpc_pin.experiment.config import load_config

    cfg = load_config(config)
    n = 3
    return (
        cfg.vector("disturbance.friction.viscous", n),
        cfg.vector("disturbance.friction.coulomb", n),
    )


def _fit_table(observer, dynamics, viscous, coulomb) -> list[str]:
    lines = [
        "| joint | observer: a | observer: b | dynamics: a | dynamics: b |",
        "|---|---|---|---|---|",
    ]
    for i in range(len(viscous)):
        oa, ob = observer.viscous[i], observer.coulomb[i]
        lines.append(
            f"| {i + 1} | {oa:#.4g} ({_pct(oa / viscous[i] - 1)}) | "
            f"{ob:#.4g} ({_pct(ob / coulomb[i] - 1)}) | "
            f"{dynamics.viscous[i]:#.4g} | {dynamics.coulomb[i]:#.4g} |"
        )
    return lines


# --- the passages -------------------------------------------------------------------------


def readme_demo() -> str:
    """``make demo``'s output: ``examples/track_sine.py --out out``, as printed."""
    with tempfile.TemporaryDirectory() as cwd:
        proc = subprocess.run(
            [sys.executable, str(ROOT / "examples" / "track_sine.py"), "--out", "out"],
            capture_output=True,
            text=True,
            cwd=cwd,
            check=True,
        )
    return "```text\n" + proc.stdout + "```\n"


def friction_measured() -> str:
    """paper_friction, 10 s: the observer and dynamics fits against the plant's friction."""
    npz = _run("paper_friction")
    _, observer, dynamics = _fits(npz)
    viscous, coulomb = _friction_truth("paper_friction")
    m_e = max(j.effective_samples for f in (observer, dynamics) for j in f.joints)
    lines = _fit_table(observer, dynamics, viscous, coulomb)
    lines += [
        "",
        _para(
            f"The observer's fit leaves out {observer.stuck} samples where the joints stuck at "
            f"the reversals, and {observer.settling:.3g} s after each (5 × the `chen` observer's "
            f"slowest time constant, {observer.time_constant:.3g} s, along this run). Over 10 s "
            "the residual of either source is too correlated for an interval (the effective "
            f"samples m_e are at most {m_e:.1f}; the note under the table says so); a longer "
            "run gives them."
        ),
    ]
    return "\n".join(lines) + "\n"


@functools.cache
def _heavier() -> tuple[str, str]:
    """The plant's links 2 and 3 30 % heavier: dynamics against regressor; and the plain
    fit of d̂ without the observer's dynamics."""
    from hmpc_pin.experiment.build import Experiment
    from hmpc_pin.experiment.config import load_config
    from hmpc_pin.identification import fit_friction

    viscous, coulomb = _friction_truth("paper_friction")
    exp = Experiment.from_config(load_config("paper_friction"))
    exp.plant = exp.plant.with_scaled_inertias([1.0, 1.3, 1.3])
    run = exp.run()
    dyn = fit_friction(run, source="dynamics", robot=exp.robot)
    reg = fit_friction(run, source="regressor", robot=exp.robot)
    worst = max(
        float(np.max(np.abs(reg.viscous / viscous - 1))),
        float(np.max(np.abs(reg.coulomb / coulomb - 1))),
    )
    ci = dyn.joints[0].viscous_ci
    interval = (
        f"with a 95 % interval of [{_minus(f'{ci[0]:.0f}')}, {_minus(f'{ci[1]:.0f}')}] "
        "that shows the fit is wrong"
        if np.all(np.isfinite(ci))
        else "and no interval (`n/a`: its residual, the missing inertia's torque, is far "
        "too correlated), which says the fit is not to be trusted"
    )
    plain = fit_friction(Experiment.from_config(load_config("paper_friction")).run())
    miss = plain.coulomb[0] / coulomb[0] - 1
    first = _para(
        "Now make the plant's links 2 and 3 30 % heavier than the model, as the sweep does. "
        "The `dynamics` source then blames the friction for the missing inertia: "
        f"a = {dyn.viscous[0]:.3g} instead of {viscous[0]:g} on joint 1, {interval}. "
        f"The `regressor` source recovers every coefficient within {100 * worst:.2f} %:"
    )
    return first + "\n", _para(
        "A plain fit of d̂ against q̇ and sgn q̇, without the observer's dynamics "
        "(`fit_friction(result)` without `observer=`), misses joint 1's Coulomb term by "
        f"{100 * abs(miss):.0f} % ({plain.coulomb[0]:.3g} N·m)."
    ) + "\n"


def friction_heavier() -> str:
    """The plant heavier than the model: the dynamics and regressor sources."""
    return _heavier()[0]


def friction_plain() -> str:
    """A fit of d̂ without the observer's dynamics."""
    return _heavier()[1]


def _feedforward(config: str, after: float | None, duration: float | None, stem: str):
    """The run, ``identify --config`` of it, and the run of the config written."""
    npz = _run(config, duration)
    ff = npz.parent / "ff.toml"
    extra = [] if after is None else ["--after", str(after)]
    _cli("identify", npz, *extra, "--config", config, "--out", ff)
    return npz, _run(str(ff), duration, stem)


def feedforward_table() -> str:
    """paper_friction with the identified friction fed forward: observer and tracking error."""
    before, after = _feedforward("paper_friction", None, None, "paper_friction_ff")
    m0, m1 = _metrics(before), _metrics(after)
    lines = [
        "| joint | RMS d − d̂ [N·m], without → with | tracking RMS after 1 s [rad], "
        "without → with |",
        "|---|---|---|",
    ]
    n = len(m0.rms_error)
    for i in range(n):
        lines.append(
            f"| {i + 1} | {m0.observer_rms[i]:.2g} → {m1.observer_rms[i]:.2g} | "
            f"{_e(m0.rms_error[i])} → {_e(m1.rms_error[i])} |"
        )
    fall = [i for i in range(n) if m1.observer_rms[i] < m0.observer_rms[i]]
    rise = [i for i in range(n) if i not in fall]
    tracking = [i for i in range(n) if m1.rms_error[i] < m0.rms_error[i]]
    text = (
        "Here the observer error is measured against what the observer has to estimate, "
        f"d + τ_f. It falls on {_joints(fall)}"
        + (
            f" and rises on {_joints(rise)} ("
            + "; ".join(f"{m0.observer_rms[i]:.2g} → {m1.observer_rms[i]:.2g} N·m" for i in rise)
            + ")"
            if rise
            else ""
        )
        + "."
    )
    if rise:
        j = rise[-1]
        share1, time, reversals = _reversal_share(after, j)
        share0, _, _ = _reversal_share(before, j)
        text += (
            f" With the feed-forward, {100 * share1:.0f} % of joint {j + 1}'s squared "
            "observer error after 1 s lies within 0.5 s of the reference's reversals "
            f"(t = {' and '.join(f'{x:g}' for x in reversals)} s; windows that cover "
            f"{100 * time:.0f} % of the time; without the feed-forward {100 * share0:.0f} %): "
            "there the Coulomb term fed forward "
            "at the measured velocity switches sign, while the plant's friction at the "
            "standstill is a holding torque anywhere within ±b. What the model misses there "
            "is left to the observer, a jump it follows with its lag; elsewhere the "
            "feed-forward leaves it little."
        )
    text += " The tracking error falls on " + (
        "every joint." if len(tracking) == n else f"{_joints(tracking)}."
    )
    return "\n".join(lines) + "\n\n" + _para(text) + "\n"


def mujoco_friction() -> str:
    """paper_combined_mujoco, 20 s, fitted after the pulses (4.5 s), and fed forward."""
    after = 4.5
    npz = _run("paper_combined_mujoco", 20.0)
    result, observer, dynamics = _fits(npz, after)
    from hmpc_pin.experiment.config import load_config

    mj = load_config("paper_combined_mujoco").plant.mujoco
    viscous = np.broadcast_to(np.asarray(mj.damping, float), (3,))
    coulomb = np.broadcast_to(np.asarray(mj.frictionloss, float), (3,))
    _, ff = _feedforward("paper_combined_mujoco", after, 20.0, "paper_combined_mujoco_ff")
    from hmpc_pin.sim.result import Result

    fed = Result.load(ff)
    late = result.t >= after - 1e-12
    carry0 = np.sqrt(np.mean(result.d_hat[late] ** 2, axis=0))
    carry1 = np.sqrt(np.mean(fed.d_hat[fed.t >= after - 1e-12] ** 2, axis=0))
    e0, e1 = _metrics(npz).rms_error, _metrics(ff).rms_error
    lines = _fit_table(observer, dynamics, viscous, coulomb)
    lines += [
        "",
        _para(
            "With the identified friction fed forward (the last two commands), the estimate "
            "the observer has to carry after the pulses falls from an RMS of "
            f"{_list(carry0, '.3g')} N·m to {_list(carry1, '.2g')} N·m. This is the RMS of "
            f"`d_hat` over t ≥ {after:g} s in the two saved runs. The tracking error after "
            f"1 s goes from {', '.join(map(_e, e0))} rad to {', '.join(map(_e, e1))} rad "
            "(RMS per joint)."
        ),
    ]
    return "\n".join(lines) + "\n"


def _worst_rms(config: str, **kwargs) -> float:
    """The worst joint's RMS tracking error after 1 s of ``config`` [rad] (in-process)."""
    from hmpc_pin.apps.metrics import compute_metrics
    from hmpc_pin.experiment.build import Experiment
    from hmpc_pin.experiment.config import load_config

    result = Experiment.from_config(load_config(config), **kwargs).run()
    return float(compute_metrics(result).rms_error.max())


def mujoco_own_friction() -> str:
    """MuJoCo arms with their own friction: the worst joint's RMS error with and without
    the observer (``hmpc-pin run NAME [--no-ndo]``)."""
    lines = ["| config | NDO | no observer | ratio |", "|---|---|---|---|"]
    for config, label in (
        ("paper_combined_mujoco", "`paper_combined_mujoco` (planar3)"),
        ("ur5_mujoco", "`ur5_mujoco`"),
        ("panda_mujoco", "`panda_mujoco`"),
    ):
        ndo, none = _worst_rms(config), _worst_rms(config, observer=False)
        lines.append(f"| {label} | {_e3(ndo)} rad | {_e3(none)} rad | {none / ndo:.0f}× |")
    return "\n".join(lines) + "\n"


def contact_estimate() -> str:
    """planar3_contact_mujoco with both reactions: the first contact, the flag, and the
    estimate's relative RMS error against MuJoCo's contact force."""
    from dataclasses import replace

    from hmpc_pin.experiment.build import Experiment
    from hmpc_pin.experiment.config import load_config

    config = load_config("planar3_contact_mujoco")
    runs = {}
    for reaction in ("stop", "ignore"):
        cfg = replace(config, collision=replace(config.collision, reaction=reaction))
        runs[reaction] = Experiment.from_config(cfg).run()
    contact = {r: res.meta["first_contact"] for r, res in runs.items()}
    flagged = {r: res.meta["collision"]["detected_at"] for r, res in runs.items()}
    same = len(set(contact.values())) == 1 and len(set(flagged.values())) == 1
    when = (
        f"first contact at {contact['stop']:.2f} s, flagged at {flagged['stop']:.2f} s with "
        "both reactions"
        if same
        else "; ".join(
            f"{r}: first contact at {contact[r]:.2f} s, flagged at {flagged[r]:.2f} s" for r in runs
        )
    )
    lines = [
        _para(
            "Measured on the packaged `planar3_contact_mujoco` (tool driven 1 cm into a padded "
            f"table, no friction or pulses, so the estimate is the contact force): {when}. "
            "Relative RMS error of d̂ against the contact force:"
        ),
        "",
        "| reaction | window | joint 1 | joint 2 | contact force (RMS, joints 1, 2) |",
        "|---|---|---|---|---|",
    ]
    for reaction, settle, what in (("stop", 0.5, "at rest"), ("ignore", 0.1, "force ramping")):
        res = runs[reaction]
        f = res.extra["contact_force"]
        w = res.t >= res.meta["first_contact"] + settle
        rms_f = np.sqrt(np.mean(f[w] ** 2, axis=0))
        rel = np.sqrt(np.mean((res.d_hat[w] - f[w]) ** 2, axis=0)) / rms_f
        lines.append(
            f"| `{reaction}` | t ≥ contact + {settle:g} s ({what}) | {100 * rel[0]:.1f} % | "
            f"{100 * rel[1]:.1f} % | {_plain(rms_f[0])}, {_plain(rms_f[1])} N·m |"
        )
    return "\n".join(lines) + "\n"


def task_space_table() -> str:
    """The end-effector tasks: worst-joint RMS and the task-space errors after 1 s."""
    from hmpc_pin.apps.metrics import compute_metrics, task_metrics
    from hmpc_pin.experiment.build import Experiment
    from hmpc_pin.experiment.config import load_config

    lines = [
        "| config (10 s, inertia-scaled friction and pulses) | worst-joint RMS [rad] | "
        "position RMS [m] | orientation RMS [rad] |",
        "|---|---|---|---|",
    ]
    for config in ("panda_circle", "ur5_circle"):
        result = Experiment.from_config(load_config(config)).run()
        task = task_metrics(result, 1.0)
        worst = float(compute_metrics(result).rms_error.max())
        lines.append(
            f"| `{config}` | {_e(worst)} | {_e3(task.position_rms)} | {_e3(task.orientation_rms)} |"
        )
    return "\n".join(lines) + "\n"


def model_at() -> str:
    """paper_combined with the observer's model at the end (default) and at the start."""
    from dataclasses import replace

    from hmpc_pin.apps.metrics import compute_metrics
    from hmpc_pin.experiment.build import Experiment
    from hmpc_pin.experiment.config import load_config

    base = load_config("paper_combined")
    rms = {}
    for at in ("end", "start"):
        cc = replace(base.controller, observer=replace(base.controller.observer, model_at=at))
        rms[at] = compute_metrics(Experiment.from_config(replace(base, controller=cc)).run())
    end = ", ".join(_e4(x) for x in rms["end"].rms_error)
    start = ", ".join(_e4(x) for x in rms["start"].rms_error)
    return _para(
        '`hmpc-pin init` writes `"start"`. The default is `"end"`, the paper\'s '
        "discretisation (the paper's scenario `hmpc-pin run paper_combined`: "
        f'{end} rad with `"end"`; {start} with `"start"`).'
    )


def _z1_value(rms: float, joint: int) -> str:
    value = _e(rms) if rms < 0.1 else f"{rms:.2g}"
    return f"{value} (joint {joint})"


@functools.cache
def _z1() -> tuple[list, list]:
    """The rows of ``python -m benchmarks.studies.damped_arm``: (first table, second table), each
    row ``(plant, plant joint dynamics, controller compensates, observer, rms, joint)``."""
    from dataclasses import replace

    sys.path.insert(0, str(ROOT))
    from benchmarks.studies import damped_arm
    from hmpc_pin.experiment.init import InitPlan

    base = damped_arm.config(_workdir() / "z1_damped.toml")
    first = []
    plants = [
        ("Pinocchio RK4, 0.1 ms", replace(base.plant, dt=1e-4)),
        ("MuJoCo implicitfast, 1 ms", replace(base.plant, engine="mujoco", dt=0.001)),
    ]
    mj = plants[1][1]
    plants.append(
        (
            "MuJoCo, `friction_timeconst = 0.002`",
            replace(mj, mujoco=replace(mj.mujoco, friction_timeconst=0.002)),
        )
    )
    cases = [
        (False, False, True, "end"),
        (False, False, True, "start"),
        (True, False, True, "start"),
        (True, True, True, "end"),
        (True, True, True, "start"),
        (True, True, False, "-"),
    ]
    for label, pc in plants:
        for plant_jd, ctrl_jd, obs, at in cases:
            cc = base.controller
            if obs:
                cc = replace(cc, observer=replace(cc.observer, model_at=at))
            cfg = replace(
                base,
                plant=replace(pc, joint_dynamics=plant_jd),
                controller=replace(cc, joint_dynamics=ctrl_jd),
            )
            rms, joint = damped_arm.worst_rms(cfg, obs)
            what = f"general ({at})" if obs else "none"
            first.append((label, plant_jd, ctrl_jd, what, rms, joint))
    Ts = InitPlan("z1").periods()[0]
    obs10 = replace(base.controller.observer, bandwidth=10.0 / Ts)
    cc = replace(base.controller, Ts=Ts, observer=obs10)
    second = []
    for label, pc in (plants[0], plants[2]):
        for obs in (True, False):
            rms, joint = damped_arm.worst_rms(replace(base, plant=pc, controller=cc), obs)
            second.append((label, "general (start)" if obs else "none", rms, joint))
    cc50 = replace(cc, N=round(0.1 / Ts))
    rms, joint = damped_arm.worst_rms(replace(base, plant=plants[0][1], controller=cc50))
    second.append((f"{plants[0][0]}, N = {cc50.N}", "general (start)", rms, joint))
    return first, second


def z1_damped() -> str:
    """The damped Z1 at Ts = 10 ms on three plants (``python -m benchmarks.studies.damped_arm``)."""
    first, _ = _z1()
    yes = {True: "yes", False: "no"}
    lines = [
        "| plant | plant has joint dynamics | controller compensates | observer (model at) | "
        "worst RMS [rad] |",
        "|---|---|---|---|---|",
    ]
    for label, plant_jd, ctrl_jd, what, rms, joint in first:
        value = _z1_value(rms, joint)
        if plant_jd and ctrl_jd and what == "general (start)" and "implicitfast" not in label:
            value = value.replace(value.split(" ")[0], f"**{value.split(' ')[0]}**", 1)
        lines.append(f"| {label} | {yes[plant_jd]} | {yes[ctrl_jd]} | {what} | {value} |")
    return "\n".join(lines) + "\n"


def z1_init_period() -> str:
    """The damped Z1 at the period ``hmpc-pin init z1`` picks."""
    _, second = _z1()
    lines = ["| plant | observer (model at) | worst RMS [rad] |", "|---|---|---|"]
    for label, what, rms, joint in second:
        lines.append(f"| {label} | {what} | {_z1_value(rms, joint)} |")
    return "\n".join(lines) + "\n"


def _tv(x: float) -> str:
    """A total variation [N·m/s]: ``22.6``, or ``5.8e5`` from 10⁴ up."""
    return _e(x) if x >= 1e4 else f"{x:.1f}"


def compare_table() -> str:
    """``hmpc-pin compare paper_combined``: the seven controllers (the step's median time is
    machine-dependent: left out of the check)."""
    from hmpc_pin.apps.compare import parse_controllers, run_comparison
    from hmpc_pin.experiment.config import load_config

    config = load_config("paper_combined")
    comp = run_comparison(config, parse_controllers(None, config))
    lines = [
        "| kind | RMS e [rad] (joints 1, 2, 3) | within 0.01 rad from [s] | TV(τ) [N·m/s] | "
        "τ energy > 10 Hz | step median [µs] |",
        "|---|---|---|---|---|---|",
    ]
    for kind, run in comp.runs.items():
        m = run.metrics
        settle = ", ".join("never" if t != t else f"{t:.2f}" for t in m.settling_time)
        lines.append(
            f"| `{kind}` | {', '.join(map(_e, m.rms_error))} | {settle} | "
            f"{', '.join(map(_tv, m.tau_tv))} | {max(m.tau_hf_share):.2f} | "
            f"{run.step_us:.0f} |"
        )
    return "\n".join(lines) + "\n"


def collision_thresholds() -> str:
    """The guide's collision-threshold example: thresholds learned on 60 s of a sine on the
    contact scenario's arm without the table, checked on 60 s of another phase and on the
    contact scenario (the guide's commands, run here)."""
    import tomllib

    from hmpc_pin.data import config_path
    from hmpc_pin.experiment.config.write import write_config
    from hmpc_pin.sim.result import Result

    work = _workdir() / "thresholds"
    work.mkdir()
    src = config_path("planar3_contact_mujoco")
    raw = tomllib.loads(src.read_text(encoding="utf-8"))
    mujoco = {k: v for k, v in raw["plant"]["mujoco"].items() if k != "obstacle"}
    for name, phase in (("planar3_sine_learn", 0.0), ("planar3_sine_other", 1.0)):
        out = work / f"{name}.toml"
        reference = {"kind": "sine", "amplitude": 1.0, "frequency": 0.1, "phase": phase}
        plant = {"engine": "mujoco", "mujoco": mujoco}
        write_config(src, {"reference": reference, "plant": plant}, out, name=name)
        text = out.read_text(encoding="utf-8")  # learn without a watch
        i = text.index("[collision]")
        j = text.index("[", i + 1)
        out.write_text(text[:i] + text[j:], encoding="utf-8")
    learn = _run(str(work / "planar3_sine_learn.toml"), 60.0, "learn")
    other_watch, contact_watch = work / "other_watch.toml", work / "contact_watch.toml"
    _cli("identify", learn, "--thresholds", "--config", work / "planar3_sine_other.toml",
         "--out", other_watch)  # fmt: skip
    _cli("identify", learn, "--thresholds", "--config", "planar3_contact_mujoco",
         "--out", contact_watch)  # fmt: skip
    other = Result.load(_run(str(other_watch), 60.0, "other"))
    contact = Result.load(_run(str(contact_watch), None, "contact"))
    threshold = tomllib.loads(other_watch.read_text(encoding="utf-8"))["collision"]["threshold"]
    peaks = np.abs(Result.load(learn).d_hat).max(axis=0)
    flagged = other.meta["collision"]["detected_at"]
    touched = contact.meta["first_contact"]
    hit = contact.meta["collision"]
    joint = re.sub(r"^joint(\d+)$", r"joint \1", str(hit["joint"]))
    same = (
        hit["detected_at"] is not None
        and touched is not None
        and (hit["detected_at"] - touched < contact.meta["Ts"] - 1e-12)
    )
    return _para(
        f"The learned thresholds are {_list(threshold, '.2g')} N·m; the learning run's peaks "
        f"were {_list(peaks, '.2g')} N·m. Over the other 60 s "
        + (
            'no collision is flagged (`meta["collision"]["detected_at"]` is `None`).'
            if flagged is None
            else f"a collision is flagged at t = {flagged:.2f} s: a false alarm."
        )
        + f" In the contact scenario the table is touched at t = {touched:.2f} s "
        f'(`meta["first_contact"]`), and the collision is flagged at '
        f"t = {hit['detected_at']:.2f} s, on {joint}"
        + (": within the same control period." if same else ".")
    )


@functools.cache
def _latency_error() -> str:
    """The output of ``python -m benchmarks.studies.damped_arm --latency-error --duration 2``."""
    import warnings

    sys.path.insert(0, str(ROOT))
    from benchmarks.studies import damped_arm

    buf = io.StringIO()
    with warnings.catch_warnings(), contextlib.redirect_stdout(buf):
        warnings.simplefilter("ignore")
        damped_arm.main(["--latency-error", "--duration", "2"])
    return buf.getvalue()


def _latency_cell(text: str) -> str:
    text = text.strip()
    stopped = re.fullmatch(r"stopped at ([\d.]+) s", text)
    if stopped:
        return f"stopped at {float(stopped.group(1)):.2g} s"
    mantissa, exponent = f"{float(text):.2e}".split("e")
    return f"{mantissa}e{int(exponent)} rad"


def latency_error_table() -> str:
    """The damped Z1 at Ts = 1 ms with 1 ms declared and the measurements 1, 0.5, 0 ms old,
    per observer bandwidth; the sweep's whole interface model."""
    rows = [
        [c.strip() for c in line.strip().strip("|").split("|")]
        for line in _latency_error().splitlines()
        if re.match(r"\| 1 \| ", line)
    ]
    bandwidths = ["10/Ts", "4/Ts", "1/Ts", "0.5/Ts"]
    cell = {(age, bw): value for _, age, bw, value in rows}
    lines = [
        "| measurements' age | bandwidth " + " | ".join(bandwidths) + " |",
        "|---|---|---|---|---|",
    ]
    for age, label in (("1", "1 ms (declared right)"), ("0.5", "0.5 ms"), ("0", "0 ms")):
        lines.append(
            f"| {label} | " + " | ".join(_latency_cell(cell[age, bw]) for bw in bandwidths) + " |"
        )
    sweep = "1, the sweep's interface model"
    text = _para(
        "A correctly declared 1 ms latency tracks at every bandwidth: the latency-aware "
        "observer and prediction are not the problem. The same holds through the sweep's "
        "whole interface model (2^19-count encoders, finite-difference velocities at 1 kHz, "
        "the 1 ms latency declared, the 100 Hz torque filter): "
        f"{_latency_cell(cell[sweep, '10/Ts'])} at 10/Ts and "
        f"{_latency_cell(cell[sweep, '4/Ts'])} at 4/Ts (same command)."
    )
    return "\n".join(lines) + "\n\n" + text + "\n"


def latency_error_cap() -> str:
    """The stopped run again with a higher QP iteration cap."""
    out = _latency_error()
    found = re.search(
        r"passes t = ([\d.]+) s \(the default cap's stop\): (True|False); there the largest "
        r"\|dq\|/velocity limit is ([\d.]+) \(joint (\d+)\); over the run \(to t = ([\d.]+) s, "
        r"complete (True|False)\) ([\d.]+), max \|d̂\| ([\d.]+) N·m",
        out,
    )
    if found is None:
        raise RuntimeError(f"the benchmark's last line changed: {out.splitlines()[-1]!r}")
    _, passes, ratio, joint, end, complete, speed, d_hat = found.groups()
    if passes != "True":  # the prose below says it does: rewrite it
        raise RuntimeError("with max_iter = 10000 the run no longer passes the default's stop")
    after = (
        f"the same run then stops at {float(end):#.3g} s, after joint speeds of "
        f"{float(speed):.2g} times the limit and |d̂| of {float(d_hat):.3g} N·m"
        if complete == "False"
        else f"the same run then completes, with joint speeds of up to {float(speed):.2g} "
        f"times the limit and |d̂| of {float(d_hat):.3g} N·m"
    )
    return _para(
        "When a run stops this way, its message says that the observer's estimate changed "
        "sign every period before it. The QP that fails then (`PROXQP_MAX_ITER_REACHED`) is "
        "not infeasible: its state limits are soft, and with `controller.max_iter = 10000` "
        "the same run passes the step where the default cap stopped it. Its state is outside "
        f"the velocity limits by then (joint {joint} at {float(ratio):.3g} times its limit), "
        "which costs ProxSuite more iterations than the cap allows. Raising the cap only "
        f"postpones the failure: {after}. Fix the latency or the bandwidth instead."
    )


def _tune(out: Path, trials: int, observers: tuple[str, ...] | None):
    from hmpc_pin.apps.tune import tune
    from hmpc_pin.experiment.config import load_config

    out.mkdir(parents=True, exist_ok=True)
    return tune(
        load_config("panda_sine"),
        out,
        trials=trials,
        samples=4,
        seed=0,
        jobs=1,
        observers=observers,
        holdout=8,
        progress=False,
    )


def _sensing(config) -> str:
    """The sweep's interface model in words."""
    si = config.sweep.interface
    counts = ", ".join(f"{c:g}" for c in np.atleast_1d(si.encoder_counts))
    parts = [
        f"{si.rate:g} Hz",
        f"encoders of {counts} counts/rev",
        f"{si.velocity} velocity",
        f"{1e3 * si.latency:g} ms latency",
    ]
    if si.torque_filter:
        parts.append(f"a {si.torque_filter:g} Hz torque filter")
    if si.q_noise or si.dq_noise:
        parts.append(f"noise σ_q = {si.q_noise:g} rad, σ_q̇ = {si.dq_noise:g} rad/s")
    return ", ".join(parts)


def tuning_table() -> str:
    """``tune panda_sine``: 30 trials with the observer searched, 40 with it kept; the
    held-out comparison on 8 other samples (seed 1)."""
    from hmpc_pin.experiment.config import load_config

    config = load_config("panda_sine")
    searched = _tune(_workdir() / "tune", 30, ("general", "momentum"))
    kept = _tune(_workdir() / "tune_general", 40, None)
    shipped = searched.holdout["shipped"]
    tuned = {"searched": searched.holdout["tuned"], "kept": kept.holdout["tuned"]}
    oc = config.controller.observer
    kind = config.controller.compensation

    def best(result, trials: int) -> str:
        trial = result.study.best_trial
        p = trial.params
        which = f"the `{p['compensation']}` observer with " if "compensation" in p else ""
        return (
            f"trial {trial.number} of {trials}: {which}gain {p['observer_gain']:.4g}, "
            f"Q = diag({p['Q_position']:.4g}, {p['Q_velocity']:.3g}), R = {_e(p['R'])} "
            f"and N = {p['N']}"
        )

    if shipped["bounded"] == 1.0:
        verdict = (
            f"survives its own sweep: on 8 held-out samples (seed 1) every run stays bounded, "
            f"and the torque saturates in {100 * shipped['saturation']:.1f} % of the periods"
        )
    else:
        verdict = (
            f"does not survive its own sweep: on 8 held-out samples (seed 1) "
            f"{100 * shipped['bounded']:.0f} % of the runs stay bounded, and the torque "
            f"saturates in {100 * shipped['saturation']:.1f} % of the periods"
        )
    head = _para(
        f"`panda_sine` as shipped (the `{kind}` observer, c = {oc.gain:g}) {verdict}. The "
        "sweep runs each drawn plant through its interface model (`[sweep.sensing]`, here its "
        f"defaults: {_sensing(config)}). The first search, over the observer as well as the gains, "
        f"picks {best(searched, 30)}; the second, the `{kind}` observer kept, picks "
        f"{best(kept, 40)}. On the 8 held-out samples:"
    )

    def row(label: str, parts: dict) -> str:
        score = _e3(parts["p95_rms"])
        return (
            f"| {label} | {score} | {100 * parts['bounded']:.0f} % | "
            f"{100 * parts['saturation']:.1f} % | {parts['torque_tv']:.0f} |"
        )

    every = all(p["bounded"] == 1.0 for p in (shipped, *tuned.values()))
    table = [
        "| config | p95 score [rad] | bounded | saturated periods | torque TV [N·m/s] |",
        "|---|---|---|---|---|",
        row("panda_sine as shipped", shipped),
        row("tuned, observer searched (30 trials)", tuned["searched"]),
        row(f"tuned, `{kind}` kept (40 trials)", tuned["kept"]),
    ]

    def change(parts: dict) -> str:
        ratio = shipped["p95_rms"] / parts["p95_rms"]
        tv = parts["torque_tv"] / shipped["torque_tv"]
        return (
            f"{max(ratio, 1 / ratio):.3g}× {'lower' if ratio > 1 else 'higher'} at "
            f"{tv:.2g}× the torque's total variation"
        )

    tail = _para(
        ("Every run is bounded, so each score is a true p95 RMS error. " if every else "")
        + "Against the shipped config's, the first search's score is "
        + change(tuned["searched"])
        + f", the second's (`{kind}` kept) "
        + change(tuned["kept"])
        + "."
    )
    return head + "\n\n" + "\n".join(table) + "\n\n" + tail + "\n"


def own_arm_sines() -> str:
    """The hand-tuned packaged arms (``hmpc-pin run <arm>_sine``, 10 s): the worst joint's
    RMS error after 1 s, limits crossed and torque saturated."""
    from hmpc_pin.apps.metrics import compute_metrics
    from hmpc_pin.experiment.build import Experiment
    from hmpc_pin.experiment.config import load_config

    parts, crossed, saturated = [], False, False
    for config, label in (("ur5_sine", "UR5"), ("panda_sine", "Panda"), ("z1_sine", "Z1")):
        m = compute_metrics(Experiment.from_config(load_config(config)).run())
        parts.append(f"{label} {_e(float(m.rms_error.max()))} rad")
        crossed |= m.limit_violation is not None and bool(np.nanmax(m.limit_violation) > 0)
        saturated |= m.saturated_steps is not None and bool(np.max(m.saturated_steps) > 0)
    return _para(
        "Measured over 10 s (`hmpc-pin run <arm>_sine`), worst joint's RMS error after 1 s: "
        + ", ".join(parts)
        + "; "
        + ("a limit crossed" if crossed else "no limit crossed")
        + ", "
        + ("the torque saturated." if saturated else "no torque saturated.")
    )


def any_arm_table() -> str:
    """``python -m benchmarks.studies.any_arm --duration 3``: init and a 3 s run of every
    example-robot-data arm (the step columns are timings: example values)."""
    sys.path.insert(0, str(ROOT))
    from benchmarks.studies import any_arm

    return any_arm.markdown(list(any_arm.rows(3.0))) + "\n"


#: The ROS guide's arm scenarios (tests/ros_test_arm.py): (scenario, duration [s], row label);
#: the settings are the boundary tests' (tests/test_ros_boundary.py).
ROS_SCENARIOS = (
    ("traffic", 3.0, "gripper states, split states, one more node (end of run)"),
    ("nan", 3.0, "NaN in one state, then finite states"),
    ("silent", 3.0, "one state, then silence"),
    ("stall", 5.0, "stalls of 5, 15, 30, 150 ms, then 1 s"),
    ("delay", 3.0, "every state 3 ms late (1.5 periods)"),
    ("interrupt", 3.0, "Ctrl-C"),
    ("deactivate", 6.0, "lifecycle `deactivate`"),
)
ROS_SETTINGS = """
[ros]
rate = 500

[realtime]
max_misses = 200
watchdog = {watchdog}
hold = 3.0
brake_speed = 0.005
"""


def ros_reason() -> str | None:
    """Why the ROS passages cannot run here (no rclpy, no private network namespace)."""
    import importlib.util
    import shutil

    if importlib.util.find_spec("rclpy") is None:
        return "rclpy not installed (extra hmpc_pin[ros])"
    if shutil.which("unshare") is None or shutil.which("ip") is None:
        return "unshare/ip not available: DDS runs only in a private network namespace"
    probe = subprocess.run(["unshare", "-n", "ip", "link", "set", "lo", "up"],
                           capture_output=True, text=True)  # fmt: skip
    if probe.returncode != 0:
        return f"cannot create a private network namespace ({probe.stderr.strip()})"
    return None


def _ros_scenario(scenario: str, duration: float):
    """``tests/ros_test_arm.py SCENARIO CONFIG OUT DURATION`` in a private network
    namespace: its report (``arm.json``) and the controller's run."""
    import json
    import os

    from hmpc_pin.data import config_path
    from hmpc_pin.sim.result import Result

    work = Path(tempfile.mkdtemp(prefix=f"ros_{scenario}_", dir=_workdir()))
    (work / "out").mkdir()
    watchdog = 0.5  # (the boundary tests' choice)
    config = work / "panda_sine.toml"
    config.write_text(
        config_path("panda_sine").read_text(encoding="utf-8")
        + ROS_SETTINGS.format(watchdog=watchdog),
        encoding="utf-8",
    )
    script = ROOT / "tests" / "ros_test_arm.py"
    env = {**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "PYTHONPATH": str(ROOT)}
    command = (f"ip link set lo up && exec {sys.executable} {script} {scenario} {config} "
               f"{work / 'out'} {duration}")  # fmt: skip
    proc = subprocess.run(["unshare", "-n", "bash", "-c", command], env=env, cwd=ROOT,
                          capture_output=True, text=True, timeout=400)  # fmt: skip
    if proc.returncode != 0:
        raise RuntimeError(f"ros_test_arm.py {scenario} exited {proc.returncode}: {proc.stderr}")
    report = json.loads((work / "out" / "arm.json").read_text(encoding="utf-8"))
    saved = work / "out" / "panda_sine_ros.npz"
    return report, (Result.load(saved) if saved.exists() else None)


def ros_stays() -> str:
    """The ROS guide's table: what each stop leaves on the arm (exit, stop, and the
    timings of the brake and the drift, example values)."""
    lines = [
        "| Scenario | Exit | Stop | Brake | Drift over 2 s [rad] | Non-finite commands |",
        "|---|---:|---|---|---:|---:|",
    ]
    for scenario, duration, label in ROS_SCENARIOS:
        report, result = _ros_scenario(scenario, duration)
        ctrl = report["controller"]
        meta = result.meta if result is not None else {}
        stop = meta.get("stop")
        brake = (stop or {}).get("brake") or meta.get("realtime", {}).get("brake") or {}
        if stop is None:
            cause = "—"
        else:
            cause = stop["cause"]
            streaming = re.search(r"stopped streaming after \d+ states", ctrl["stderr"])
            if scenario == "silent" and streaming:  # (elsewhere a count of the timing's)
                cause += f', "{streaming.group(0)}"'
            if scenario == "stall" and stop["cause"] == "watchdog":
                cause += " (at the 1 s stall)" if stop["t"] > 2.3 else " (before it)"
        if len(report["commands"]) == 1:
            braked = "none (one command: G(q))"
        else:
            ended = brake.get("ended", "n/a")
            braked = f"{ended} after {brake['duration']:.2f} s" if "duration" in brake else ended
            if stop is not None and stop["cause"] == "watchdog":
                braked = f"G(q) at once, then {braked} on the resumed states"
        drift = report["drift"]
        lines.append(
            f"| {label} | {ctrl['exit']} | {cause} | {braked} | "
            f"{'0' if drift == 0 else _e(drift)} | {report['nonfinite_commands']} |"
        )
    return "\n".join(lines) + "\n"


@functools.cache
def _sweep(samples: int, controllers: str | None = None):
    """``hmpc-pin sweep paper_combined --samples SAMPLES --seed 0 --jobs 2 [--controllers
    ...]``, in-process (2 local processes: the table is the same for any ``--jobs`` or
    executor, a Dask cluster's too)."""
    from dataclasses import replace

    from hmpc_pin.apps.compare import parse_controllers
    from hmpc_pin.apps.sweep import run_sweep
    from hmpc_pin.experiment.config import load_config

    config = load_config("paper_combined")
    if controllers is not None:
        kinds = parse_controllers(controllers, config)
        config = replace(config, sweep=replace(config.sweep, variants=kinds))
    return run_sweep(config, samples, 0, jobs=2, progress=False)


def _sweep_table(result) -> str:
    """The summary table the command prints (its Markdown table's lines)."""
    lines = result.summary_markdown().splitlines()
    return "\n".join(line for line in lines if line.startswith("|"))


def _sweep_settings(result) -> str:
    """What the sweep drew, in the tutorial's words."""
    sc = result.config.sweep
    q_noise, dq_noise, delay = sc.legacy_measurement()
    return (
        f"masses/inertias ×{sc.mass[0]:g}–{sc.mass[1]:g}, friction and pulses "
        f"×{sc.friction[0]:g}–{sc.friction[1]:g}, noise σ_q = {q_noise:g} rad, "
        f"σ_q̇ = {dq_noise:g} rad/s, {delay} period{'s' if delay != 1 else ''} of delay"
    )


def cluster_sweep() -> str:
    """The cluster tutorial's sweep: ``paper_combined``, 200 samples, seed 0, the config's
    two variants (with and without the observer)."""
    result = _sweep(200)
    summary = result.summary()
    target = result.config.sweep.rms_target
    head = _para(
        "Measured (`hmpc-pin sweep paper_combined --samples 200 --seed 0 --jobs 2`, "
        f"planar3, {result.config.simulation.duration:g} s per run, {len(result.rows)} runs; "
        f"{_sweep_settings(result)}):"
    )
    words = []
    for variant, s in summary.items():
        bounded = (
            "every run stays bounded"
            if s["bounded"] == 1.0
            else (f"{100 * s['bounded']:.1f} % of the runs stay bounded")
        )
        meets = (
            "every one meets"
            if s["pass"] == 1.0
            else "none meets"
            if s["pass"] == 0.0
            else f"{100 * s['pass']:.1f} % meet"
        )
        words.append(f"with `{variant}` {bounded} and {meets} {target:g} rad")
    tail = _para("; ".join(words)[0].upper() + "; ".join(words)[1:] + ".")
    return head + "\n\n" + _sweep_table(result) + "\n\n" + tail + "\n"


CONTROLLERS = (
    "hmpc,hmpc-none,hmpc-momentum,hmpc-ism,hmpc-ism-bl,computed-torque,computed-torque-pid"
)


def controllers_sweep() -> str:
    """The seven controllers over 100 perturbed plants (``paper_combined``, seed 0)."""
    result = _sweep(100, CONTROLLERS)
    summary = result.summary()
    target = result.config.sweep.rms_target
    head = _para(
        "Over perturbed plants the ranking changes where it matters (`hmpc-pin sweep "
        "paper_combined --samples 100 --seed 0 --jobs 2 --controllers "
        f"{CONTROLLERS}`: {_sweep_settings(result)}; worst joint's RMS after "
        f"{result.config.sweep.after:g} s; {len(result.rows)} runs):"
    )
    ratio = summary["hmpc-ism-bl"]["median_rms"] / summary["hmpc"]["median_rms"]
    every = [f"`{v}`" for v, s in summary.items() if s["pass"] == 1.0]
    listed = every[0] if len(every) == 1 else ", ".join(every[:-1]) + " and " + every[-1]
    tail = _para(
        "With measurement noise and delay the boundary-layer ISM loses its nominal edge: its "
        "loop acts on σ, which contains the measured velocity, with gain K/φ = 1/Ts, and it "
        f"ends {ratio:.0f}× worse than the NDO (median). "
        + (
            f"Only {listed} keep every perturbed run within {target:g} rad."
            if every
            else f"No controller keeps every perturbed run within {target:g} rad."
        )
    )
    return head + "\n\n" + _sweep_table(result) + "\n\n" + tail + "\n"


#: Every generated passage, in file order.
BLOCKS: tuple[Block, ...] = (
    Block("demo", "README.md", readme_demo, volatile=(r"in \d+(?:\.\d+)? s;",)),
    Block("friction-measured", TUNING, friction_measured),
    Block("friction-heavier", TUNING, friction_heavier),
    Block("friction-plain", TUNING, friction_plain),
    Block("feedforward", TUNING, feedforward_table),
    Block("mujoco-friction", TUNING, mujoco_friction),
    Block("collision-thresholds", TUNING, collision_thresholds, slow=True),
    Block("tuning", TUNING, tuning_table, slow=True),
    Block("latency-error", "docs/guide/sensing-and-latency.md", latency_error_table, slow=True),
    Block("latency-error-cap", "docs/guide/sensing-and-latency.md", latency_error_cap, slow=True),
    Block("model-at", "docs/guide/joint-dynamics-and-check.md", model_at),
    Block("z1-damped", "docs/guide/joint-dynamics-and-check.md", z1_damped, slow=True),
    Block("z1-init-period", "docs/guide/joint-dynamics-and-check.md", z1_init_period, slow=True),
    Block(
        "compare",
        "docs/concepts/controllers.md",
        compare_table,
        volatile=(r"\| \d+ \|$", r"\| \d+ \|(?= \| `)"),
    ),
    Block("controllers-sweep", "docs/concepts/controllers.md", controllers_sweep, slow=True),
    Block("mujoco-own-friction", "docs/tutorials/mujoco-contacts.md", mujoco_own_friction),
    Block("contact-estimate", "docs/tutorials/mujoco-contacts.md", contact_estimate),
    Block("task-space", "docs/tutorials/end-effector-path.md", task_space_table),
    Block("cluster-sweep", "docs/tutorials/cluster-sweep.md", cluster_sweep, slow=True),
    Block("own-arm-sines", "docs/tutorials/own-arm.md", own_arm_sines),
    Block(
        "any-arm",
        "docs/tutorials/own-arm.md",
        any_arm_table,
        slow=True,
        volatile=(r"\| \d+ \| \d+\.\d \|(?= (?:tracks|misses) \|)",),
    ),
    Block(
        "ros-stays",
        "docs/guide/ros2.md",
        ros_stays,
        slow=True,
        volatile=(r"after \d+\.\d+ s", r"\| (?:\d\.\de[-−]\d+|0) \|(?= \d+ \|)"),
        needs_ros=True,
    ),
)


# --- reading, comparing, writing -----------------------------------------------------------

_NUMBER = re.compile(r"(?<![\w.])[-−+]?\d+(?:\.\d*)?(?:[eE][-−+]?\d+)?(?![\w])")


def passage(text: str, name: str) -> tuple[int, int]:
    """The span of passage ``name`` in ``text`` (between its comments' lines)."""
    start, end = START.format(name=name), END.format(name=name)
    if text.count(start) != 1 or text.count(end) != 1:
        raise ValueError(f"passage {name!r}: expected one {start!r} and one {end!r}")
    i = text.index(start) + len(start) + 1
    j = text.index(end)
    if j < i:
        raise ValueError(f"passage {name!r}: its end comes before its start")
    return i, j


def _ulp(token: str) -> float:
    """One unit of the last printed digit of a number as printed."""
    mantissa, _, exponent = token.replace("−", "-").lower().partition("e")
    decimals = len(mantissa.split(".")[1]) if "." in mantissa else 0
    return 10.0 ** (int(exponent or 0) - decimals)


def agrees(printed: str, regenerated: str, volatile: tuple[str, ...] = ()) -> str | None:
    """``None`` when ``printed`` is ``regenerated`` within the printed precision (module
    docstring; line breaks and runs of spaces count as one space), else the first
    difference in one line."""
    printed, regenerated = (" ".join(x.split()) for x in (printed, regenerated))
    for pattern in volatile:
        printed = re.sub(pattern, "<volatile>", printed)
        regenerated = re.sub(pattern, "<volatile>", regenerated)
    a, b = _NUMBER.split(printed), _NUMBER.split(regenerated)
    na, nb = _NUMBER.findall(printed), _NUMBER.findall(regenerated)
    for k, (x, y) in enumerate(zip(a, b, strict=False)):
        if x != y:
            return f"text differs: {a[k][:70]!r} now {b[k][:70]!r}"
    if len(a) != len(b):
        return "the passage has another number of numbers"
    for x, y in zip(na, nb, strict=True):
        fx, fy = (float(s.replace("−", "-")) for s in (x, y))
        if abs(fx - fy) > _ulp(x) * 1.0000001:
            return f"{x} is now {y}"
    return None


def regenerate(blocks, check: bool) -> list[str]:
    """Run ``blocks``; write them into their files (``check``: compare only). Returns the
    differences found, one line each."""
    problems = []
    for block in blocks:
        if block.needs_ros and (reason := ros_reason()) is not None:
            print(f"{block.name}: left out ({reason})", file=sys.stderr)
            continue
        path = ROOT / block.file
        passage(path.read_text(encoding="utf-8"), block.name)  # marked, before the work
        new = block.write().strip("\n") + "\n"
        text = path.read_text(encoding="utf-8")  # as it is now (edited meanwhile?)
        i, j = passage(text, block.name)
        diff = agrees(text[i:j].strip("\n"), new.strip("\n"), block.volatile)
        if diff is not None and block.needs_ros:  # a scheduling stall of 3 processes: once more
            new = block.write().strip("\n") + "\n"
            diff = agrees(text[i:j].strip("\n"), new.strip("\n"), block.volatile)
        if diff is not None:
            problems.append(f"{block.file} [{block.name}]: {diff}")
            if not check:
                path.write_text(text[:i] + new + text[j:], encoding="utf-8")
        print(f"{block.name}: {'differs' if diff else 'agrees'}", file=sys.stderr)
    return problems


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true", help="compare only; exit 1 on a change")
    parser.add_argument("--only", nargs="+", metavar="NAME", help="these passages only")
    parser.add_argument("--fast", action="store_true", help="leave out the slow passages")
    args = parser.parse_args(argv)
    names = {b.name for b in BLOCKS}
    unknown = set(args.only or ()) - names
    if unknown:
        parser.error(f"unknown passage(s) {sorted(unknown)}; expected some of {sorted(names)}")
    blocks = [
        b
        for b in BLOCKS
        if (args.only is None or b.name in args.only) and not (args.fast and b.slow)
    ]
    problems = regenerate(blocks, args.check)
    for line in problems:
        print(line)
    return 1 if problems and args.check else 0


if __name__ == "__main__":
    raise SystemExit(main())
