"""``hmpc-pin plot FILE``: the figures of any file a command wrote, each drawn only when
the file holds what it shows.

What a file is is read from its contents, not its name:

- a run (``.npz`` of ``run``, ``realtime``, ``ros`` or a Franka arm, :func:`load_run`):
  tracking (reference and angle), tracking error :math:`|q - r|` (log scale), torque
  (commanded, applied where the plant clipped it, and a Franka arm's desired joint torque
  ``tau_J_d``), disturbance (the true :math:`d` of a simulation, the estimate
  :math:`\\hat d`, a Franka arm's filtered external torque ``tau_ext_hat_filtered``), the
  task-space figure of an end-effector task, and the latency histogram when the run's
  ``<stem>_timing.npz`` lies beside it;
- a timing file (``<stem>_timing.npz`` of ``realtime`` or ``ros``): the latency histogram
  (deadline to torque written, wake-up to torque written, and measurement to torque where
  the stamps allow);
- a Franka arm's per-cycle record (``<stem>_cycles.npz`` of ``franka``): the compute
  time from ``readOnce``'s return to ``writeOnce`` (histogram), the robot's ``Duration``
  of every cycle (lost cycles above one period) and its command success rate;
- a sweep table (``<name>_sweep.csv``): the worst joint's RMS error of every run, per
  condition and variant, the runs that were not bounded marked;
- an identification (the ``.toml`` that ``identify`` wrote, alone or in a config): the
  friction law :math:`f = a\\dot q + b\\,\\mathrm{sgn}\\,\\dot q` fitted per joint over the
  run's friction :math:`\\tau_f - \\hat d` against :math:`\\dot q`, or the collision
  thresholds over the run's :math:`|\\hat d|`; the run is the one the file names, beside
  it, or ``--run``.

Anything else is one :class:`~hmpc_pin.exceptions.ConfigError` naming the file and what
was expected (exit 2). :func:`figures` builds the figures (``name -> Figure``) without
writing them; :func:`plot_file` writes them as ``<stem>_<name>.png``.
"""

from __future__ import annotations

import csv
import re
from pathlib import Path

import numpy as np

from ..exceptions import ConfigError
from .runfile import load_run

__all__ = [
    "CYCLES_ARRAYS",
    "FRANKA_ARRAYS",
    "TIMING_ARRAYS",
    "figures",
    "plot_arguments",
    "plot_file",
    "save",
]

#: The arrays that make an ``.npz`` a timing file (:meth:`RealtimeRun.save_timing
#: <hmpc_pin.realtime.loop.RealtimeRun.save_timing>`).
TIMING_ARRAYS = ("wake", "latency", "compute", "missed")

#: The arrays that make an ``.npz`` a Franka arm's per-cycle record
#: (:attr:`FrankaArm.cycles <hmpc_pin.realtime.franka.FrankaArm.cycles>`).
CYCLES_ARRAYS = ("compute", "duration", "success_rate", "sent", "robot_time")

#: A Franka arm's own torque records, drawn beside the package's (top-level arrays or
#: ``extra_`` ones): the desired joint torque and the filtered external torque [N·m].
FRANKA_ARRAYS = ("tau_J_d", "tau_ext_hat_filtered")

#: The friction figure's samples start here [s] (``identify``'s default ``--after``).
FIT_AFTER = 0.5

_EXPECTED = (
    "expected a run (.npz of `hmpc-pin run`, `realtime`, `ros`, `franka`), its "
    "_timing.npz, a Franka run's _cycles.npz, a _sweep.csv of `hmpc-pin sweep`, or a "
    ".toml written by `hmpc-pin identify`"
)


def _bad(path: Path, what: str) -> ConfigError:
    return ConfigError("FILE", f"{str(path)!r} {what}; {_EXPECTED}")


# --- what a file is --------------------------------------------------------------------


def _kind(path: Path) -> str:
    """``"run"``, ``"timing"``, ``"cycles"``, ``"sweep"`` or ``"fit"`` (a
    :class:`ConfigError` otherwise)."""
    if not path.is_file():
        raise _bad(path, "not found" if not path.exists() else "is not a file")
    try:
        with path.open("rb") as f:
            head = f.read(4096)
    except OSError as exc:
        raise ConfigError("FILE", f"{str(path)!r} cannot be read ({exc.strerror or exc})") from None
    if not head:
        raise _bad(path, "is empty (0 bytes)")
    if head.startswith(b"PK\x03\x04"):
        names = _npz_names(path)
        if "meta" in names and "t" in names:
            return "run"
        if all(a in names for a in TIMING_ARRAYS):
            return "timing"
        if all(a in names for a in CYCLES_ARRAYS):
            return "cycles"
        raise _bad(path, f"is a .npz of neither a run nor its timing (arrays {sorted(names)})")
    try:
        text = head.decode("utf-8")
    except UnicodeDecodeError:
        raise _bad(path, "is neither a .npz archive nor text") from None
    first = text.splitlines()[0] if text else ""
    if first.startswith("t,q_"):
        raise _bad(path, "is a run's CSV table; plot the run's .npz beside it")
    if first.startswith("sample,") and "rms_max" in first.split(","):
        return "sweep"
    if path.suffix == ".toml" or "identify" in text:
        return "fit"
    raise _bad(path, "is text but neither a sweep table nor an identification")


def _npz_names(path: Path) -> set[str]:
    import zipfile

    try:
        with zipfile.ZipFile(path) as z:
            return {n[:-4] if n.endswith(".npy") else n for n in z.namelist()}
    except (zipfile.BadZipFile, OSError) as exc:
        raise _bad(path, f"is truncated or corrupt ({exc})") from None


def _franka(path: Path, result) -> dict[str, np.ndarray]:
    """The Franka arrays of the run (:data:`FRANKA_ARRAYS`) of its shape (K+1, n)."""
    found = {k: result.extra[k] for k in FRANKA_ARRAYS if k in result.extra}
    with np.load(path, allow_pickle=False) as f:
        found.update({k: f[k] for k in FRANKA_ARRAYS if k in f.files and k not in found})
    return {k: v for k, v in found.items() if np.shape(v) == np.shape(result.q)}


def _timing(path: Path, keys=("latency", "compute")) -> dict[str, np.ndarray]:
    try:
        with np.load(path, allow_pickle=False) as f:
            out = {k: np.asarray(f[k]) for k in f.files}
    except (OSError, ValueError) as exc:
        raise _bad(path, f"cannot be read as a timing file ({exc})") from None
    for key in keys:
        if out[key].ndim != 1 or not np.issubdtype(out[key].dtype, np.number):
            raise _bad(path, f"has a {key!r} array of shape {out[key].shape}, expected (C,)")
    return out


# --- the figures -----------------------------------------------------------------------


def _title(result) -> str:
    meta = result.meta
    name = meta.get("experiment") or ""
    label = meta.get("controller")
    tail = "" if meta.get("stop") is None else " — stopped: " + str(meta["stop"].get("cause"))
    return f"{name} ({label}){tail}" if label else f"{name}{tail}"


def _finite(a) -> bool:
    return bool(np.any(np.isfinite(np.asarray(a, dtype=float))))


def _torque(result, franka: dict, title: str):
    from . import plots

    units = plots.joint_units(result)
    clipped = np.any(np.abs(result.tau - result.tau_applied) > 1e-9 * (1 + np.abs(result.tau)))

    # a Franka arm (or a ROS arm with [ros] gravity = "arm") adds G(q) to the command
    label = "commanded τ (without G(q))" if result.gravity_by_arm else "commanded τ"

    def draw(ax, r, i):
        plots._line(ax, r.t, r.tau[:, i], "C0", lw=1.0, label=label)
        if clipped and _finite(r.tau_applied[:, i]):
            plots._line(ax, r.t, r.tau_applied[:, i], "C1--", lw=1.0, label="applied")
        if "tau_J_d" in franka:
            plots._line(ax, r.t, franka["tau_J_d"][:, i], "C2:", lw=1.0, label="τ_J_d (arm)")
        ax.set_ylabel(f"τ{i + 1} [{units[i][2]}]")
        plots._decorate(ax, i)

    return plots._per_joint(result, None, title, draw)


def _disturbance(result, franka: dict, title: str):
    from . import plots

    ext = franka.get("tau_ext_hat_filtered")

    def draw(ax, r, i):
        plots._disturbance(ax, r, i)
        if ext is not None:
            plots._line(ax, r.t, ext[:, i], "C2:", lw=1.0, label="τ_ext filtered (arm)")
            if i == 0:
                ax.legend(loc="upper right", fontsize=8)

    return plots._per_joint(result, None, title, draw)


def _latency(timing: dict, title: str):
    """Histograms [µs] of the cycles' latency and compute time (and the measurement's
    age where recorded); the misses in the title."""
    from . import plots

    series = [
        ("deadline → torque written", timing["latency"]),
        ("wake → torque", timing["compute"]),
    ]
    age = timing.get("age")
    if age is not None and _finite(age):
        series.append(("measurement → torque", age))
    fig = plots._new_figure((7, 4))
    ax = fig.subplots()
    for k, (label, x) in enumerate(series):
        us = np.asarray(x, dtype=float)
        us = us[np.isfinite(us)] * 1e6
        if len(us):
            p99 = np.percentile(us, 99)
            counts, edges = np.histogram(us, bins=60)
            ax.stairs(
                counts,
                edges,
                color=f"C{k}",
                lw=1.2,
                label=f"{label}: median {np.median(us):.0f}, p99 {p99:.0f}, max {us.max():.0f}",
            )
    ax.set_yscale("log")
    ax.set_xlabel("time [µs]")
    ax.set_ylabel("cycles")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    missed = np.asarray(timing.get("missed", ()), dtype=bool)
    ran = int(np.isfinite(np.asarray(timing["latency"], dtype=float)).sum())
    head = f"{title} — " if title else ""
    ax.set_title(plots._wrap(f"{head}{ran} cycles run, {int(missed.sum())} missed deadlines", fig))
    fig.tight_layout()
    return fig


def _cycles(record: dict, title: str):
    """A Franka arm's per-cycle record: the compute time [µs] from ``readOnce``'s return to
    ``writeOnce`` (histogram of the loop's cycles), the robot's ``Duration`` [ms] of every
    cycle against its time (a lost cycle: above one period) and its command success
    rate."""
    from . import plots

    us = np.asarray(record["compute"], dtype=float)
    us = us[np.isfinite(us)] * 1e6
    duration = np.asarray(record["duration"], dtype=float) * 1e3
    rate = np.asarray(record["success_rate"], dtype=float)
    t = np.asarray(record.get("robot_time", np.arange(len(duration)) * 1e-3), dtype=float)
    t = t - (t[np.isfinite(t)][0] if np.isfinite(t).any() else 0.0)
    fig = plots._new_figure((7, 7))
    ax_c, ax_d, ax_r = fig.subplots(3, 1)
    if len(us):
        counts, edges = np.histogram(us, bins=60)
        ax_c.stairs(
            counts,
            edges,
            color="C0",
            lw=1.2,
            label=f"readOnce → writeOnce: median {np.median(us):.0f}, "
            f"p99 {np.percentile(us, 99):.0f}, max {us.max():.0f}",
        )
        ax_c.legend(fontsize=8)
    ax_c.set_yscale("log")
    ax_c.set_xlabel("compute [µs]")
    ax_c.set_ylabel("cycles")
    ax_d.plot(t, duration, "C1.", ms=2, label="Duration since the last state")
    ax_d.set_ylabel("Duration [ms]")
    ax_r.plot(t, rate, "C2", lw=1.0, label="control_command_success_rate")
    ax_r.set_ylabel("success rate")
    ax_r.set_xlabel("robot time [s]")
    for ax in (ax_c, ax_d, ax_r):
        ax.grid(alpha=0.3)
    periods = np.rint(duration[1:][np.isfinite(duration[1:])]).astype(int)
    lost = int(np.sum(np.maximum(periods - 1, 0)))
    sent = int(np.asarray(record.get("sent", ()), dtype=bool).sum())
    ax_c.set_title(
        plots._wrap(f"{title} — {len(duration)} robot cycles, {sent} commands, {lost} lost", fig)
    )
    fig.tight_layout()
    return fig


def _sweep_rows(path: Path) -> list[dict]:
    with path.open(encoding="utf-8", newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        raise _bad(path, "is a sweep table without rows")
    try:
        for r in rows:
            r["rms_max"] = float(r["rms_max"])
            r["bounded"] = r["bounded"] == "True"
            r["condition"] = r.get("condition") or "all"
    except (KeyError, ValueError) as exc:
        raise _bad(path, f"has a row without a number in {exc}") from None
    return rows


def _sweep(rows: list[dict], title: str):
    """Per condition (one panel each), per variant (one column): every run's worst-joint
    RMS error [rad] on a log axis, bounded runs as dots, the others as red crosses."""
    from . import plots

    conditions = list(dict.fromkeys(r["condition"] for r in rows))
    variants = list(dict.fromkeys(r["variant"] for r in rows))
    fig = plots._new_figure((max(5.0, 1.4 * len(variants) + 2), 2.6 * len(conditions) + 0.8))
    axes = fig.subplots(len(conditions), 1, sharex=True, squeeze=False)[:, 0]
    for ax, condition in zip(axes, conditions, strict=True):
        for x, variant in enumerate(variants):
            sel = [r for r in rows if r["condition"] == condition and r["variant"] == variant]
            styles = ((True, {"c": "C0", "marker": "o"}), (False, {"c": "C3", "marker": "x"}))
            for bounded, style in styles:
                y = [r["rms_max"] for r in sel if r["bounded"] is bounded]
                y = [v if np.isfinite(v) and v > 0 else np.nan for v in y]
                if y:
                    ax.scatter(
                        np.full(len(y), float(x)),
                        y,
                        s=14,
                        **style,
                        label=("bounded" if bounded else "not bounded") if x == 0 else None,
                    )
            share = np.mean([r["bounded"] for r in sel]) if sel else np.nan
            ax.annotate(
                f"{100 * share:.0f} % bounded",
                (x, 1.0),
                xycoords=("data", "axes fraction"),
                ha="center",
                va="bottom",
                fontsize=7,
            )
        plots._log_y(ax)
        ax.set_ylabel(f"{condition}: RMS [rad]")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7, loc="lower right")
    axes[-1].set_xticks(range(len(variants)), variants)
    axes[-1].set_xlim(-0.5, len(variants) - 0.5)
    fig.suptitle(plots._wrap(title, fig))
    fig.tight_layout()
    return fig


def _fit_tables(path: Path) -> tuple[str, dict, str]:
    """``("friction", {"viscous", "coulomb"}, run)`` or ``("collision", {"threshold"}, run)``
    of an identification file, ``run`` the file it names (``""``: none)."""
    import tomllib

    text = path.read_text(encoding="utf-8")
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise _bad(path, f"is not valid TOML ({exc})") from None
    found = re.search(r"identif\w+ by `hmpc-pin identify[^`]*` from (\S+)", text)
    run = found.group(1) if found else ""
    friction = (raw.get("controller") or {}).get("friction")
    if isinstance(friction, dict) and "viscous" in friction and "coulomb" in friction:
        return "friction", friction, run
    collision = raw.get("collision")
    if isinstance(collision, dict) and "threshold" in collision:
        return "collision", collision, run
    raise _bad(path, "holds neither a [controller.friction] nor a [collision] table")


def _per_joint_values(table: dict, key: str, n: int, path: Path) -> np.ndarray:
    v = np.atleast_1d(np.asarray(table[key], dtype=float))
    if v.size == 1:
        v = np.full(n, float(v[0]))
    if v.shape != (n,):
        raise ConfigError("FILE", f"{str(path)!r}: {key} has {v.size} values, the run {n} joints")
    return v


def _friction(result, table: dict, path: Path, title: str):
    """Per joint: the run's friction against q̇ (from the observer, τ_f − d̂; from the
    plant, −d, where a simulation knows it) and the fitted law a q̇ + b sgn q̇."""
    from . import plots

    n = result.q.shape[1]
    a = _per_joint_values(table, "viscous", n, path)
    b = _per_joint_values(table, "coulomb", n, path)
    ff = result.extra.get("friction_feedforward")
    observed = (0.0 if ff is None else ff) - result.d_hat
    keep = result.t >= FIT_AFTER - 1e-12  # the start-up transient: not what was fitted
    units = plots.joint_units(result)
    fig = plots._new_figure((6, 2.2 * n + 0.8))
    axes = fig.subplots(n, 1, squeeze=False)[:, 0]
    for i, ax in enumerate(axes):
        v = result.dq[keep, i]
        if _finite(result.d[:, i]):
            ax.scatter(v, -result.d[keep, i], s=3, c="0.7", label="plant −d")
        ax.scatter(v, observed[keep, i], s=3, c="C0", label="observer τ_f − d̂")
        span = np.nanmax(np.abs(v)) if _finite(v) else 1.0
        grid = np.linspace(-span, span, 401)
        ax.plot(
            grid,
            a[i] * grid + b[i] * np.sign(grid),
            "C3",
            lw=1.5,
            label=f"fit a = {a[i]:.4g}, b = {b[i]:.4g}",
        )
        ax.set_ylabel(f"f{i + 1} [{units[i][2]}]")
        ax.legend(fontsize=7, loc="upper left")
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel(f"velocity q̇ [{units[0][1]}]")
    fig.suptitle(plots._wrap(f"friction identified: {title} (run after {FIT_AFTER:g} s)", fig))
    fig.tight_layout()
    return fig


def _thresholds(result, table: dict, path: Path, title: str):
    """Per joint: the run's |d̂| over time and the learned threshold."""
    from . import plots

    n = result.q.shape[1]
    thr = _per_joint_values(table, "threshold", n, path)
    units = plots.joint_units(result)

    def draw(ax, r, i):
        plots._line(ax, r.t, np.abs(r.d_hat[:, i]), "C0", lw=1.0, label="|d̂|")
        ax.axhline(thr[i], color="C3", ls="--", lw=1.2, label="threshold")
        ax.set_ylabel(f"|d̂{i + 1}| [{units[i][2]}]")
        plots._decorate(ax, i)

    return plots._per_joint(result, None, f"collision thresholds: {title}", draw)


def _fit_run(path: Path, named: str, run: Path | None) -> Path:
    if run is not None:
        return run
    if not named:
        raise ConfigError(
            "--run", f"{str(path)!r} does not name the run it was fitted from; pass --run RUN.npz"
        )
    candidate = path.parent / named
    if not candidate.is_file():
        raise ConfigError(
            "--run",
            f"{str(path)!r} was fitted from {named!r}, which is not beside it; pass --run RUN.npz",
        )
    return candidate


def figures(path: Path, run: Path | None = None) -> tuple[str, dict]:
    """The figures of the file at ``path``, not yet written.

    Args:
        path: Any file :mod:`this module <hmpc_pin.apps.plot>` reads.
        run: For an identification: the run it was fitted from (default: the file it
            names, in its folder).

    Returns:
        ``(kind, {name: Figure})``, kind one of ``"run"``, ``"timing"``, ``"sweep"``,
        ``"fit"``; only the figures whose arrays the file holds.

    Raises:
        ConfigError: Not such a file (one line: what it is instead, what was expected).
    """
    from . import plots

    path = Path(path)
    kind = _kind(path)
    out: dict = {}
    if kind == "timing":
        out["latency"] = _latency(_timing(path), path.stem.removesuffix("_timing"))
    elif kind == "cycles":
        out["fci"] = _cycles(_timing(path, CYCLES_ARRAYS[:3]), path.stem)
    elif kind == "sweep":
        out["rms"] = _sweep(_sweep_rows(path), f"sweep {path.stem.removesuffix('_sweep')}")
    elif kind == "fit":
        what, table, named = _fit_tables(path)
        result = load_run(_fit_run(path, named, run), "--run")
        title = path.name
        out[what] = (_friction if what == "friction" else _thresholds)(result, table, path, title)
    else:
        result = load_run(path, "FILE")
        franka = _franka(path, result)
        title = _title(result)
        if _finite(result.q) and _finite(result.q_ref):
            out["tracking"] = plots._per_joint(result, None, title, plots._tracking)
            label = "with NDO" if result.meta.get("observer") else "run"
            out["error"] = plots._error({label: result}, None, title)
        if _finite(result.tau):
            out["torque"] = _torque(result, franka, title)
        if _finite(result.d_hat) or _finite(result.d) or franka:
            out["disturbance"] = _disturbance(result, franka, title)
        if result.ee_pos is not None:
            out["task_space"] = plots.plot_task_space(result, None, title)
        timing = path.with_name(path.stem + "_timing.npz")
        if timing.is_file() and _kind(timing) == "timing":
            out["latency"] = _latency(_timing(timing), title)
    return kind, out


def save(path: Path, figs: dict, folder: Path) -> list[Path]:
    """Write ``figs`` (:func:`figures` of ``path``) as ``folder/<stem>_<name>.png``."""
    from . import plots

    path = Path(path)
    stem = path.stem if path.suffix in (".npz", ".csv", ".toml") else path.name
    return [plots._save(fig, Path(folder) / f"{stem}_{name}.png") for name, fig in figs.items()]


def plot_file(path: Path, out: Path | None = None, run: Path | None = None) -> list[Path]:
    """Write the figures of ``path`` (:func:`figures`) as ``out/<stem>_<name>.png``
    (``out``: the file's folder by default) and return their paths."""
    path = Path(path)
    _, figs = figures(path, run)
    return save(path, figs, path.parent if out is None else Path(out))


def plot_arguments(plt) -> None:
    """The ``plot`` subcommand's description and arguments."""
    plt.description = (
        "Draw the figures of a file a command wrote: a run of `run`, `realtime`, `ros`, "
        "`franka` (tracking, tracking error, torque, disturbance estimate; the latency "
        "histogram from its _timing.npz beside it), a _timing.npz, the _cycles.npz of "
        "`franka` (compute per cycle, Duration, success rate), a _sweep.csv (every run's RMS "
        "error per variant), or the .toml of `identify` (the fit over its run). Each "
        "figure only when the file holds its arrays. Exit 2 with one line for any other file."
    )
    plt.add_argument("file", type=Path, help="a .npz, _sweep.csv or identify .toml")
    plt.add_argument("--out", type=Path, default=None, help="output directory [the file's folder]")
    plt.add_argument(
        "--run",
        type=Path,
        default=None,
        help="for an identify .toml: the run it was fitted from [the one it names]",
    )
