"""Monte Carlo robustness sweep: many perturbed runs of one experiment, summarised.

For each of K samples, plant perturbations are drawn from the ``[sweep]`` table of the
config (:class:`~hmpc_pin.experiment.config.sweep.SweepConfig`): link mass and inertia
factors (plant model only), friction and disturbance amplitude factors, a noise seed. Each
sample is run once per controller *variant* (``[sweep] variants``: controller ×
compensation pairs, by default the config's pair and the same controller without
compensation; :func:`resolve_variants`), with the same draws and the same noise sequence
for every variant (common random numbers), and summarised as: fraction of runs bounded,
median and 95th-percentile RMS tracking error, worst case.

Reproducibility: sample ``i`` draws from ``np.random.SeedSequence(seed).spawn(K)[i]``,
and every run is a pure function of ``(config, params, variant)``
(:func:`run_sample`), so the table is bit-identical whatever the number of jobs, the
executor or the order in which runs finish.

Executors: ``"local"`` (:class:`concurrent.futures.ProcessPoolExecutor`, ``jobs``
processes; ``jobs = 1`` runs in this process) and ``"dask"``
(``dask.distributed``: an existing scheduler address, or a local cluster of ``jobs``
worker processes; optional extra ``hmpc_pin[cluster]``).
"""

from __future__ import annotations

import csv
import io
import math
import multiprocessing
import os
import signal
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..controllers.registry import controller_spec
from ..controllers.wrappers import MeasuredController
from ..exceptions import ConfigError, SimulationError
from ..experiment.build import Experiment, load_robot_config, reuse_robots, with_controller
from ..experiment.combos import OBSERVERS
from ..experiment.config import ExperimentConfig
from ..experiment.config.sweep import CONDITION_PARTS
from ..sim.sensing import SensedController
from .cluster import dask_client, dask_modules
from .metrics import task_metrics

__all__ = [
    "SampleParams",
    "SweepResult",
    "check_options",
    "draw_samples",
    "resolve_variants",
    "run_sample",
    "run_sweep",
    "torque_effort",
    "variant_config",
]


def variant_config(config: ExperimentConfig, variant: str) -> ExperimentConfig:
    """The config of one sweep variant (:class:`~hmpc_pin.experiment.config.sweep.SweepConfig`):
    ``"ndo"`` the config's pair (its compensation must be an observer), ``"no-ndo"`` the
    config's controller without compensation, any other name a controller × compensation
    (:func:`~hmpc_pin.experiment.build.with_controller`).

    Raises:
        ConfigError: ``"ndo"`` on a config whose compensation is no observer, or an
            unknown name.
    """
    source = str(config.source) if config.source else None
    if variant == "ndo":
        if config.controller.compensation not in OBSERVERS:
            raise ConfigError(
                "sweep.variants",
                f"'ndo' is the config's controller with its observer, but {config.name} runs "
                f"{config.controller.label}; name the pair instead (e.g. "
                f"'{config.controller.kind}+chen')",
                source=source,
            )
        return config
    if variant == "no-ndo":
        return with_controller(config, observer=False)
    try:
        return with_controller(config, variant)
    except ConfigError as exc:
        raise ConfigError("sweep.variants", exc.message, source=source) from None


def resolve_variants(config: ExperimentConfig) -> tuple[str, ...]:
    """The variants of ``config.sweep`` (default: the config's pair and, when it has a
    compensation, the same controller without), each a different controller.

    Raises:
        ConfigError: Two variants are the same controller × compensation.
    """
    variants = config.sweep.variants
    if variants is None:
        cc = config.controller
        variants = (cc.label,) if cc.compensation == "none" else (cc.label, f"{cc.kind}+none")
    seen: dict[str, str] = {}
    for variant in variants:
        label = variant_config(config, variant).controller.label
        if label in seen:
            raise ConfigError(
                "sweep.variants",
                f"{variant!r} and {seen[label]!r} are the same controller ({label}) on "
                f"{config.name}; give each once",
                source=str(config.source) if config.source else None,
            )
        seen[label] = variant
    return tuple(variants)


EXECUTORS = ("local", "dask")


@dataclass(frozen=True)
class SampleParams:
    """The draws of one sample (factors are multipliers of the config's nominal values).

    Attributes:
        index: Sample number, 0..K-1.
        mass: Per plant link, factor on its mass and rotational inertia.
        friction: Per joint, factor on the viscous and Coulomb friction coefficients.
        disturbance: Per joint, factor on the Gaussian pulse amplitude.
        noise_seed: Seed of the measurement-noise generator of this sample.
    """

    index: int
    mass: tuple[float, ...]
    friction: tuple[float, ...]
    disturbance: tuple[float, ...]
    noise_seed: int


def draw_samples(config: ExperimentConfig, samples: int, seed: int) -> list[SampleParams]:
    """Draw ``samples`` parameter sets; sample ``i`` uses ``SeedSequence(seed).spawn(samples)[i]``.

    Every sample draws the same number of values in the same order (a range ``[1, 1]``
    draws exactly 1.0), so sample ``i`` does not depend on ``samples``.
    """
    n = load_robot_config(config.robot).nq
    sc = config.sweep
    out = []
    for i, child in enumerate(np.random.SeedSequence(seed).spawn(samples)):
        rng = np.random.default_rng(child)
        mass = rng.uniform(sc.mass[0], sc.mass[1], n)
        friction = rng.uniform(sc.friction[0], sc.friction[1], n)
        disturbance = rng.uniform(sc.disturbance[0], sc.disturbance[1], n)
        noise_seed = int(rng.integers(0, 2**63 - 1))
        out.append(
            SampleParams(
                i,
                tuple(map(float, mass)),
                tuple(map(float, friction)),
                tuple(map(float, disturbance)),
                noise_seed,
            )
        )
    return out


def perturbed_config(config: ExperimentConfig, params: SampleParams) -> ExperimentConfig:
    """``config`` with the friction and pulse amplitudes of ``params`` applied (the friction
    factor also to the MuJoCo plant's joint ``frictionloss`` and ``damping``)."""
    dc = config.disturbance
    friction, pulse = dc.friction, dc.pulse
    if friction is not None:
        k = np.array(params.friction)
        friction = replace(friction, viscous=k * friction.viscous, coulomb=k * friction.coulomb)
    if pulse is not None:
        pulse = replace(pulse, amplitude=np.array(params.disturbance) * pulse.amplitude)
    config = replace(config, disturbance=replace(dc, friction=friction, pulse=pulse))
    mc = config.plant.mujoco
    if mc is not None:  # the MuJoCo arm's own friction: the same factor per joint
        k = np.array(params.friction)
        mc = replace(mc, frictionloss=k * mc.frictionloss, damping=k * mc.damping)
        config = replace(config, plant=replace(config.plant, mujoco=mc))
    return config


def _told_latency(config: ExperimentConfig, condition: str) -> ExperimentConfig:
    """``config`` with ``[controller] latency`` set to the modelled latency (latency plus
    whole-period delay) when ``known_latency`` and the controller is ``hmpc`` (the 0.3
    keys: unchanged)."""
    sc, cc = config.sweep, config.controller
    if sc.legacy or not sc.known_latency or not controller_spec(cc.kind).mpc:
        return config
    if "latency" not in CONDITION_PARTS[condition]:
        return config
    si = sc.interface
    latency = si.latency + si.delay * cc.Ts
    return replace(config, controller=replace(cc, latency=latency))


def _measured(
    experiment: Experiment, config: ExperimentConfig, params: SampleParams, condition: str
) -> None:
    """Put the interface model of ``condition`` between ``experiment``'s controller and
    plant."""
    sc = config.sweep
    parts = CONDITION_PARTS[condition]
    rng = np.random.default_rng(params.noise_seed)
    ctrl = experiment.controller
    if sc.legacy:  # the 0.3 model: white noise and a delay in whole periods
        q_noise, dq_noise, delay = sc.legacy_measurement()
        on = "sensing" in parts
        experiment.controller = MeasuredController(
            ctrl,
            q_noise=q_noise if on else 0.0,
            dq_noise=dq_noise if on else 0.0,
            delay=delay if "latency" in parts else 0,
            rng=rng,
        )
        return
    model = sc.interface.model(experiment.robot.nq, parts)
    if not model.ideal:
        experiment.controller = SensedController(ctrl, model, rng)


def run_sample(
    config: ExperimentConfig, params: SampleParams, variant: str, condition: str = "all"
) -> dict:
    """Run one perturbed sample with one controller variant under one condition; return
    its table row.

    Under ``"plant"`` and ``"all"`` the plant's links are scaled by ``params.mass`` (the
    controller keeps the nominal model), friction and pulse amplitudes by
    ``params.friction`` / ``params.disturbance``; under ``"sensing"``, ``"latency"`` and
    ``"all"`` the controller sees the arm through the interface model of
    ``config.sweep`` (:class:`~hmpc_pin.sim.sensing.SensedController`, or with the 0.3 keys
    :class:`~hmpc_pin.controllers.wrappers.MeasuredController`), noise seeded by
    ``params.noise_seed``.

    Returns:
        A dict (one CSV row): the draws, ``complete``, ``bounded``, ``t_end``, RMS error
        after ``sweep.after`` per joint and its max over joints (``rms_max``), ``max_error``
        and the failure ``message`` ("" if the run completed); for a pose task also
        ``position_rms`` [m] and ``orientation_rms`` [rad] after ``sweep.after``. A run
        that stops early (divergence, non-finite state, solver failure) is a row with
        ``complete=False``, not an exception. Also the torque's effort
        (:func:`torque_effort`): ``saturation`` and ``torque_tv``.
    """
    sc = config.sweep
    if condition not in CONDITION_PARTS:
        raise ConfigError(
            "condition", f"expected one of {tuple(CONDITION_PARTS)}, got {condition!r}"
        )
    perturb = condition in ("plant", "all")
    base = perturbed_config(config, params) if perturb else config
    with reuse_robots():  # the worker's runs share the config's URDF, parsed once
        experiment = Experiment.from_config(_told_latency(variant_config(base, variant), condition))
    if perturb:
        experiment.plant = experiment.plant.with_scaled_inertias(params.mass)
    _measured(experiment, config, params, condition)
    try:
        result = experiment.run()
    except SimulationError as exc:
        if exc.result is None:
            raise
        result = exc.result
    names = experiment.robot.joint_names
    e = result.error[result.t >= sc.after - 1e-12]
    if len(e):
        rms = np.sqrt(np.mean(e * e, axis=0))
        max_error = float(np.abs(e).max())
    else:
        rms, max_error = np.full(len(names), np.nan), math.nan
    bounded = bool(result.complete and max_error <= sc.error_bound)
    row = {
        "sample": params.index,
        "variant": variant,
        "condition": condition,
        "noise_seed": params.noise_seed,
    }
    row.update({f"mass_{i + 1}": v for i, v in enumerate(params.mass)})
    row.update({f"friction_{j}": v for j, v in zip(names, params.friction, strict=True)})
    row.update({f"disturbance_{j}": v for j, v in zip(names, params.disturbance, strict=True)})
    row.update(complete=bool(result.complete), bounded=bounded, t_end=float(result.t[-1]))
    row.update({f"rms_{j}": float(v) for j, v in zip(names, rms, strict=True)})
    row.update(rms_max=float(np.max(rms)), max_error=max_error, message=result.message)
    row.update(torque_effort(result))
    task = task_metrics(result, sc.after)  # a pose task: its task-space errors too
    if task is not None:
        row.update(position_rms=task.position_rms, orientation_rms=task.orientation_rms)
    return row


def torque_effort(result) -> dict[str, float]:
    """How hard a run drove its actuators.

    Returns:
        ``saturation``: the fraction of control periods in which the plant clipped the
        torque on some joint (:math:`\\tau \\ne \\tau_\\mathrm{applied}`); ``torque_tv``:
        the commanded torque's total variation per second, summed over joints,
        :math:`\\sum_i \\sum_k |\\tau_{i,k+1} - \\tau_{i,k}| / t_\\mathrm{end}` [N·m/s]
        (chattering shows as a large value).
    """
    tau, applied = result.tau, result.tau_applied
    ok = np.all(np.isfinite(tau), axis=1)
    clipped = np.any(np.abs(tau - applied) > 1e-9 * (1 + np.abs(tau)), axis=1) & ok
    span = float(result.t[-1] - result.t[0]) if len(result.t) > 1 else 0.0
    tv = float(np.abs(np.diff(tau[ok], axis=0)).sum() / span) if span > 0 else 0.0
    return {"saturation": float(np.mean(clipped)) if len(clipped) else 0.0, "torque_tv": tv}


@dataclass
class SweepResult:
    """Rows of a sweep (sorted by sample, then variant in config order) and its settings."""

    config: ExperimentConfig
    samples: int
    seed: int
    rows: list[dict]
    wall_time: float = math.nan
    jobs: int = 1
    executor: str = "local"
    interrupted: bool = False  # Ctrl-C stopped it: ``rows`` holds the runs that finished

    @property
    def planned_runs(self) -> int:
        """Runs the sweep was asked for: samples × variants × conditions."""
        sc = self.config.sweep
        return self.samples * len(sc.variants) * len(sc.conditions)

    @property
    def finished_samples(self) -> int:
        """Samples every variant of which finished."""
        per_sample: dict[int, int] = {}
        for r in self.rows:
            per_sample[r["sample"]] = per_sample.get(r["sample"], 0) + 1
        sc = self.config.sweep
        per = len(sc.variants) * len(sc.conditions)
        return sum(v == per for v in per_sample.values())

    def variant_rows(self, variant: str, condition: str | None = None) -> list[dict]:
        """The rows of one variant (under one condition; ``None``: the last configured,
        ``"all"`` by default)."""
        condition = self.config.sweep.conditions[-1] if condition is None else condition
        return [
            r
            for r in self.rows
            if r["variant"] == variant and r.get("condition", "all") == condition
        ]

    def summary(self, condition: str | None = None) -> dict[str, dict]:
        """Per variant, under ``condition`` (default: the last configured, ``"all"``):
        runs, fraction bounded, fraction bounded with RMS <= target, median /
        95th-percentile / worst RMS (worst joint, runs not bounded count as inf; empirical
        quantiles, no interpolation), and the worst sample."""
        target = self.config.sweep.rms_target
        out = {}
        for variant in self.config.sweep.variants:
            rows = self.variant_rows(variant, condition)
            if not rows:
                continue
            rms = np.array([r["rms_max"] if r["bounded"] else math.inf for r in rows])
            worst = int(np.argmax(rms))
            q50, q95 = np.quantile(rms, [0.5, 0.95], method="inverted_cdf")
            out[variant] = {
                "runs": len(rows),
                "bounded": float(np.mean([r["bounded"] for r in rows])),
                "pass": float(np.mean(rms <= target)),
                "median_rms": float(q50),
                "p95_rms": float(q95),
                "worst_rms": float(rms[worst]),
                "worst_sample": rows[worst]["sample"],
                "worst_max_error": rows[worst]["max_error"],
                "worst_message": rows[worst]["message"],
            }
        return out

    def csv_text(self) -> str:
        """The table as CSV text (floats written with ``repr``: exact round trip)."""
        buf = io.StringIO()
        writer = csv.DictWriter(buf, fieldnames=list(self.rows[0]), lineterminator="\n")
        writer.writeheader()
        for row in self.rows:
            writer.writerow({k: repr(v) if isinstance(v, float) else v for k, v in row.items()})
        return buf.getvalue()

    def _interrupted_lines(self) -> list[str]:
        if not self.interrupted:
            return []
        return [
            f"**Interrupted** (Ctrl-C): {self.finished_samples} of {self.samples} samples "
            f"finished ({len(self.rows)} of {self.planned_runs} runs); the table holds the "
            "runs that finished.",
            "",
        ]

    def summary_markdown(self) -> str:
        """The summary as a Markdown section (settings, one table row per variant)."""
        cfg, sc = self.config, self.config.sweep
        if sc.legacy:
            q_noise, dq_noise, delay = sc.legacy_measurement()
            sensing = (
                f"noise σ_q = {q_noise:g} rad, σ_q̇ = {dq_noise:g} rad/s; delay {delay} period(s)"
            )
        else:
            si = sc.interface
            counts = ", ".join(f"{c:g}" for c in np.atleast_1d(si.encoder_counts))
            vel = si.velocity + (
                f" low-passed at {si.velocity_filter:g} Hz" if si.velocity_filter else ""
            )
            sensing = (
                f"interface at {si.rate:g} Hz: encoders of {counts} counts/rev, velocity "
                f"{vel}, latency {si.latency * 1e3:g} ms"
                + (f" + {si.delay} period(s)" if si.delay else "")
                + (f", torque filter {si.torque_filter:g} Hz" if si.torque_filter else "")
                + (
                    f", noise σ_q = {si.q_noise:g} rad, σ_q̇ = {si.dq_noise:g} rad/s"
                    if si.q_noise or si.dq_noise
                    else ""
                )
                + ("; hmpc told the latency" if sc.known_latency else "")
            )
        lines = [
            f"# Sweep of {cfg.name}: {self.samples} samples, seed {self.seed}",
            "",
            *self._interrupted_lines(),
            f"Config `{cfg.source}`; plant link mass and inertia ×U({sc.mass[0]:g}, "
            f"{sc.mass[1]:g}), friction ×U({sc.friction[0]:g}, {sc.friction[1]:g}), pulse "
            f"amplitude ×U({sc.disturbance[0]:g}, {sc.disturbance[1]:g}) per joint; "
            f"{sensing}; {cfg.simulation.duration:g} s per run. Conditions: sensing (the "
            "measurement model only), latency (timing only), plant (the drawn plant only), "
            f"all (together). RMS and max error over t ≥ {sc.after:g} s, worst joint. "
            f"Bounded: completed and max |e| ≤ {sc.error_bound:g} rad.",
            "",
            f"| condition | variant | runs | bounded | bounded and RMS ≤ {sc.rms_target:g} | "
            "median RMS [rad] | p95 RMS [rad] | worst RMS [rad] (sample) | worst max "
            "\\|e\\| [rad] |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for condition in sc.conditions:
            for variant, s in self.summary(condition).items():
                lines.append(
                    f"| {condition} | {variant} | {s['runs']} | {100 * s['bounded']:.1f} % | "
                    f"{100 * s['pass']:.1f} % | {s['median_rms']:.3e} | {s['p95_rms']:.3e} | "
                    f"{s['worst_rms']:.3e} ({s['worst_sample']}) | "
                    f"{s['worst_max_error']:.3e} |"
                )
        lines += [
            "",
            f"Wall time {self.wall_time:.1f} s ({self.executor} executor, {self.jobs} jobs).",
        ]
        return "\n".join(lines) + "\n"

    def write(self, out: Path) -> tuple[Path, Path]:
        """Write ``<name>_sweep.csv`` and ``<name>_sweep.md`` to ``out`` (each written to a
        ``.part`` file first and renamed, so no partial table is left behind)."""
        paths = []
        for suffix, text in (("csv", self.csv_text()), ("md", self.summary_markdown())):
            path = Path(out) / f"{self.config.name}_sweep.{suffix}"
            part = path.with_name(path.name + ".part")
            part.write_text(text, encoding="utf-8")
            os.replace(part, path)
            paths.append(path)
        return paths[0], paths[1]


def check_options(
    config: ExperimentConfig,
    samples: int,
    seed: int = 0,
    *,
    jobs: int = 1,
    executor: str = "local",
    scheduler: str | None = None,
) -> ExperimentConfig:
    """Check every option of :func:`run_sweep` against ``config``, each error naming its
    own option, before anything runs or is created (the command line calls it before it
    creates ``--out``).

    Returns:
        ``config`` with its variants resolved (:func:`resolve_variants`).

    Raises:
        ConfigError: ``samples`` < 1, ``seed`` < 0, ``jobs`` < 1 (or not integers), an
            unknown ``executor``, a ``scheduler`` without the dask executor (an option
            that does not apply), bad variants, or a config that does not build.
    """
    for key, value, low in (("--samples", samples, 1), ("--seed", seed, 0), ("--jobs", jobs, 1)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
            raise ConfigError(key, f"expected an integer >= {low}, got {value!r}")
    if executor not in EXECUTORS:
        raise ConfigError("--executor", f"expected one of {EXECUTORS}, got {executor!r}")
    if scheduler is not None and executor != "dask":
        raise ConfigError(
            "--scheduler",
            f"applies to --executor dask only (got --executor {executor}); add "
            "--executor dask or drop it",
        )
    if executor == "dask":
        dask_modules()  # the extra is named before anything is created
    config = replace(config, sweep=replace(config.sweep, variants=resolve_variants(config)))
    nominal = Experiment.from_config(config)  # bad input fails here, once, not in every worker
    if not config.sweep.legacy:  # the interface model fits the arm and the control period
        config.sweep.interface.model(nominal.robot.nq).ticks(config.controller.Ts)
    return config


def run_sweep(
    config: ExperimentConfig,
    samples: int,
    seed: int = 0,
    *,
    jobs: int = 1,
    executor: str = "local",
    scheduler: str | None = None,
    progress: bool = True,
) -> SweepResult:
    """Run ``samples`` perturbed samples × ``config.sweep.variants``; return the table.

    Args:
        config: The experiment (its ``[sweep]`` table gives the distributions).
        samples: Number of samples K >= 1.
        seed: Root seed (an integer >= 0).
        jobs: Worker processes (``"local"``; 1 runs in this process) or local Dask workers.
        executor: ``"local"`` or ``"dask"``.
        scheduler: With ``"dask"``, the address of a running scheduler
            (``"tcp://host:8786"``); ``None`` starts a local cluster of ``jobs`` processes.
        progress: Show a tqdm progress bar (on stderr).

    Returns:
        The :class:`SweepResult`; after Ctrl-C (SIGINT) it holds the runs that finished and
        ``interrupted=True`` (the workers are terminated first; nothing is left running).

    Raises:
        ConfigError: Bad ``samples``/``seed``/``jobs``/``executor``/``scheduler``, an
            unknown variant (:func:`check_options`), or ``"dask"`` without dask installed.
    """
    config = check_options(config, samples, seed, jobs=jobs, executor=executor, scheduler=scheduler)
    params = draw_samples(config, samples, seed)
    tasks = [
        (p, v, c) for p in params for v in config.sweep.variants for c in config.sweep.conditions
    ]

    from tqdm import tqdm

    start = time.perf_counter()
    rows: dict[tuple[int, str, str], dict] = {}
    interrupted = False
    bar = tqdm(total=len(tasks), desc=f"sweep {config.name}", unit="run", disable=not progress)
    try:
        if executor == "local" and jobs == 1:
            for p, v, c in tasks:
                rows[p.index, v, c] = run_sample(config, p, v, c)
                bar.update()
        elif executor == "local":
            _run_pool(config, tasks, jobs, rows, bar)
        else:
            client, cluster = dask_client(jobs, scheduler)
            try:
                from dask.distributed import as_completed

                futures = {
                    client.submit(run_sample, config, p, v, c, pure=False): (p.index, v, c)
                    for p, v, c in tasks
                }
                try:
                    for future in as_completed(list(futures)):
                        rows[futures[future]] = future.result()
                        bar.update()
                except KeyboardInterrupt:
                    client.cancel(list(futures))
                    raise
            finally:
                client.close()
                if cluster is not None:
                    cluster.close()
    except KeyboardInterrupt:  # Ctrl-C: keep every run that finished
        interrupted = True
    finally:
        bar.close()
    ordered = [rows[p.index, v, c] for p, v, c in tasks if (p.index, v, c) in rows]
    return SweepResult(
        config, samples, seed, ordered, time.perf_counter() - start, jobs, executor, interrupted
    )


def _ignore_sigint() -> None:
    """Worker initializer: Ctrl-C reaches the whole process group; only the parent acts on
    it (it terminates the workers), so no worker prints a traceback."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _run_pool(config, tasks, jobs: int, rows: dict, bar) -> None:
    """Run ``tasks`` on ``jobs`` spawned worker processes, filling ``rows`` as they finish.

    On Ctrl-C (``KeyboardInterrupt`` in this process) the pending runs are cancelled and
    the workers terminated and joined before the interrupt goes on, so no worker is left.
    """
    from concurrent.futures import ProcessPoolExecutor, as_completed

    ctx = multiprocessing.get_context("spawn")
    pool = None
    # The resource tracker (started with the pool) and the workers (started by submit)
    # are spawned with SIGINT blocked here: they inherit the block (exec keeps the signal
    # mask), so a Ctrl-C during their start-up prints no traceback from each of them; one
    # arriving meanwhile is delivered to this process at the unblock.
    blocked = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        try:
            pool = ProcessPoolExecutor(jobs, mp_context=ctx, initializer=_ignore_sigint)
            futures = {
                pool.submit(run_sample, config, p, v, c): (p.index, v, c) for p, v, c in tasks
            }
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, blocked)
        for future in as_completed(futures):
            rows[futures[future]] = future.result()
            bar.update()
        pool.shutdown(wait=True)  # (a Ctrl-C here, every row in: stopped as below)
    except BaseException:
        if pool is not None:
            _stop_pool(pool)
        raise


def _stop_pool(pool) -> None:
    """Cancel the pending runs of ``pool``, terminate and join its workers now
    (``shutdown`` alone would wait for the runs in progress), and join the pool's manager
    thread before returning: left running, it closes its wake-up pipe while the
    interpreter's exit hook of :mod:`concurrent.futures` writes to that pipe without a
    lock (CPython 3.11), which printed ``OSError: Bad file descriptor`` after a Ctrl-C."""
    workers = list((getattr(pool, "_processes", None) or {}).values())
    manager = getattr(pool, "_executor_manager_thread", None)
    pool.shutdown(wait=False, cancel_futures=True)
    for proc in workers:
        proc.terminate()
    for proc in workers:
        proc.join(timeout=2.0)
        if proc.is_alive():
            proc.kill()
            proc.join()
    if manager is not None:
        manager.join(timeout=10.0)  # it sees the workers gone and ends at once
