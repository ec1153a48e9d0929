"""The worst step at 1 kHz with a long horizon: Panda, Ts = 1 ms, N = Nc = 100, the default
soft joint limits (the URDF's position and velocity limits as soft state constraints).

Three variants, timed in alternating blocks (A, B, C, A, B, C, …), each block restarting
its controller:

- ``closed loop``: the states of a closed loop started 0.2 rad off on every joint (the
  plant is the feedback-linearised arm, q̈ = v exactly, Eq 24, so that only the controller is
  timed; recorded once and replayed, the answers being exact); the first steps open an
  activation of every joint's soft QP;
- ``stalled arm``: the arm held still 0.2 rad off its reference at every step (stalled
  against something, or a plan it cannot follow): every joint's soft QP at every step;
- ``on the reference``: the reference's own states (no soft QP).

Per block: the median step, the worst step by the wall clock and the worst step by the
thread's CPU time (``time.thread_time_ns``: less of the preemption, which on a loaded
machine makes most of the wall clock's worst). Over blocks: the costliest step, the largest
over the steps of each step's median over blocks (a step costly in every block, such as an
activation's first, not one preempted once). The other figures are the medians over
blocks, the ratios the medians over blocks of the per-block ratios to ``on the
reference``'s median step (the costliest step's: to the median of those medians). Also
printed: how the soft QPs were answered (the soft active-set shortcut, whose answers pass
the soft QP's KKT test, or ProxSuite) and the shortcut's guesses that did not answer.

With ``--soft-step-exchanges K``: the soft exchanges bounded to K per step
(``JointQPs.soft_step_exchanges``; spread over the joints, a joint reached with none left
answers the fallback, counted, and resumes at the next step); ``--soft-step-work W``: the
bound W // N (``JointQPs.soft_step_work``); printed beside the counters: the fallbacks,
the exchanges and the most in a step.

Then the three ways to hold a 1 kHz deadline, for both scenarios (the closed loop, the
stalled arm), in the same alternating blocks: (a) the synchronous step as above (the
exchanges as set by the options), (b) the same with the soft exchanges bounded
(``--bounded-work``, default 1600: 16 exchanges at N = 100), (c) the threaded law
(:class:`~hmpc_pin.realtime.franka.threaded.InnerLawThreaded` at period = Ts = 1 ms, the
observer and Eq 4 every cycle, the MPC in its compiled planner thread), paced at 1 kHz (a
sleep, then a spin of the last 200 µs), once per staleness bound of ``--max-ages`` (in
periods; 0: the package's default). The threaded law's closed loop runs on the same plant
(q̈ = v, v the acceleration the law used), the stalled arm on the same held state. Per
variant: the worst step (wall, thread CPU; the median over blocks); for (c) the torque
cycle's compute (law.step; worst and p99.9 over the blocks' cycles; the cycles before
the first plan brake, counted), the planner's solve times (worst by its clock and by
its thread's CPU time, p99), the age of
the plan used (max, p99.9) [ms], the cycles that braked (the law's fallbacks) and the
plans published; tracking: the worst joint's RMS error over the closed loop's steps
against (a)'s (the same plant, same start), and for the stalled arm the RMS of the used
acceleration's difference from (a)'s at the same state, relative to (a)'s RMS.

Run: ``python benchmarks/studies/worst_step.py [--blocks 7] [--steps 100]
[--soft-step-exchanges 16] [--soft-step-work 1600] [--bounded-work 1600]
[--max-ages 2 0] [--no-compare]``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks._fixtures import HOMES, PANDA_LOCKED, load_arm  # noqa: E402
from benchmarks.studies.long_horizon_soft import OFFSET, closed_loop, replay_v  # noqa: E402
from benchmarks.studies.long_horizon_soft import controller as _controller  # noqa: E402
from hmpc_pin.compensation.observers import DisturbanceObserver  # noqa: E402
from hmpc_pin.realtime.franka.threaded import InnerLawThreaded  # noqa: E402

TS, N = 0.001, 100  # [s], horizon


def _stats(ctrl) -> np.ndarray:
    """(soft QPs solved, answered by the shortcut, failed guesses: pivot, exchanges, KKT;
    fallbacks, exchanges, the most exchanges in a step)."""
    s = ctrl.qps._core.stats
    return np.array([0, s.soft_active_set_solves, s.soft_fail_pivot, s.soft_fail_exchanges,
                     s.soft_fail_kkt, s.soft_fallbacks, s.soft_exchanges, 0])  # fmt: skip


def threaded_block(law: InnerLawThreaded, ref, t: np.ndarray, q0, dq0, stalled: bool) -> dict:
    """One paced run of the threaded law from (q0, dq0) at the times t: per cycle the
    compute of law.step [µs] (wall, thread CPU), the used plan's age [ms] (NaN: braked),
    the acceleration used and the state; the planner's solve times [µs] of the plans used."""
    wall, cpu = time.perf_counter_ns, time.thread_time_ns
    planner = law.planner
    law.reset(q0, dq0)
    K = len(t)
    w, c, age, vs, qs = np.empty(K), np.empty(K), np.empty(K), np.empty((K, len(q0))), []
    solves: dict[float, float] = {}
    q, dq = q0.copy(), dq0.copy()
    braked = law.fallbacks
    start = wall()
    for k in range(K):
        due = start + k * 1_000_000  # paced at 1 kHz: sleep, then spin the last 200 µs
        if due - wall() > 300_000:
            time.sleep((due - wall() - 200_000) * 1e-9)
        while wall() < due:
            pass
        qs.append(q.copy())
        c0, w0 = cpu(), wall()
        law.step(float(t[k]), q, dq, ref)
        w1, c1 = wall(), cpu()
        w[k], c[k] = (w1 - w0) / 1e3, (c1 - c0) / 1e3
        fell = law.fallbacks != braked
        braked = law.fallbacks
        age[k] = np.nan if fell else planner.last_age * 1e3
        if not fell:
            solves[round(float(t[k]) - planner.last_age, 9)] = planner.last_solve * 1e6
        vs[k] = law._v
        if not stalled:  # the feedback-linearised arm, q̈ = v (Eq 24), as (a)'s closed loop
            q, dq = q + TS * dq + 0.5 * TS * TS * vs[k], dq + TS * vs[k]
    return {"wall": w, "cpu": c, "age": age, "v": vs, "q": np.array(qs),
            "solves": np.array(list(solves.values())), "max_solve": planner.max_solve * 1e6,
            "max_solve_cpu": planner.max_solve_cpu * 1e6,
            "published": planner.published, "fallbacks": law.fallbacks}  # fmt: skip


def alternate(
    variants: dict, blocks: int, threaded: dict | None = None
) -> dict[str, dict[str, np.ndarray]]:
    """Per variant, per block: step times [µs] by the wall clock and the thread's CPU time,
    and the soft-QP counters summed over the block. ``threaded``: name → (law, reference,
    states, stalled), run once per block after the others (:func:`threaded_block`)."""
    wall, cpu = time.perf_counter_ns, time.thread_time_ns
    out: dict = {name: {"wall": [], "cpu": [], "stats": []} for name in variants}
    for name in threaded or {}:
        out[name] = []
    for _ in range(blocks):
        for name, (law, ref, (t, q, dq), stalled) in (threaded or {}).items():
            out[name].append(threaded_block(law, ref, t, q[0], dq[0], stalled))
        for name, (ctrl, ref, (t, q, dq)) in variants.items():
            calls = [(float(t[i]), q[i].copy(), dq[i].copy()) for i in range(len(t))]
            ctrl.reset(q[0], dq[0])
            step = ctrl.step
            w, c = np.empty(len(calls)), np.empty(len(calls))
            before = _stats(ctrl)
            solved = most = 0
            core = ctrl.qps._core
            for j, (ti, qi, dqi) in enumerate(calls):
                e0 = core.stats.soft_exchanges
                c0, w0 = cpu(), wall()
                step(ti, qi, dqi, ref)
                w1, c1 = wall(), cpu()
                w[j], c[j] = (w1 - w0) / 1e3, (c1 - c0) / 1e3
                solved += ctrl.qps.constrained
                most = max(most, core.stats.soft_exchanges - e0)
            stats = _stats(ctrl) - before
            stats[0], stats[7] = solved, most
            out[name]["wall"].append(w)
            out[name]["cpu"].append(c)
            out[name]["stats"].append(stats)
    return {
        name: d if isinstance(d, list) else {k: np.array(v) for k, v in d.items()}
        for name, d in out.items()
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--blocks", type=int, default=7)
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument(
        "--soft-step-work",
        type=int,
        default=None,
        help="JointQPsOptions.soft_step_work (exchanges × N per step; default: the package's)",
    )
    parser.add_argument(
        "--soft-step-exchanges",
        type=int,
        default=None,
        help="JointQPsOptions.soft_step_exchanges (default: the package's)",
    )
    parser.add_argument(
        "--bounded-work",
        type=int,
        default=1600,
        help="(b): JointQPsOptions.soft_step_work of the bounded synchronous step",
    )
    parser.add_argument(
        "--max-ages",
        type=float,
        nargs="+",
        default=[2.0, 0.0],
        help="(c): the threaded law's staleness bounds, in periods (0: the package's default)",
    )
    parser.add_argument("--no-compare", action="store_true", help="only the first table")
    args = parser.parse_args()
    print("command: python benchmarks/studies/worst_step.py " + " ".join(sys.argv[1:]))
    print(f"load average at start: {' '.join(f'{x:.2f}' for x in os.getloadavg())}\n")
    arm = load_arm("panda", "panda", HOMES["panda"], "general", PANDA_LOCKED)
    robot, ref = arm.robot, arm.reference()

    def controller(robot, Ts, N):
        ctrl = _controller(robot, Ts, N)
        if args.soft_step_exchanges is not None:
            ctrl.qps._core.options.soft_step_exchanges = args.soft_step_exchanges
        if args.soft_step_work is not None:
            ctrl.qps._core.options.soft_step_work = args.soft_step_work
        return ctrl

    loop_ctrl = controller(robot, TS, N)
    opts = loop_ctrl.qps._core.options
    budget = opts.soft_step_exchanges
    if budget < 0 and opts.soft_step_work >= 0:
        budget = max(1, opts.soft_step_work // N)
    states, _, _ = closed_loop(loop_ctrl, ref, TS, args.steps)
    t = states[0]
    q_ref, dq_ref = ref.sample_many(t)
    stalled = (t, np.repeat(q_ref[:1] + OFFSET, len(t), axis=0), np.zeros_like(dq_ref))
    variants = {
        "closed loop": (loop_ctrl, ref, states),
        "stalled arm": (controller(robot, TS, N), ref, stalled),
        "on the reference": (controller(robot, TS, N), ref, (t, q_ref, dq_ref)),
    }
    threaded: dict = {}
    if not args.no_compare:
        for scenario, states_ in (("closed loop", states), ("stalled arm", stalled)):
            bounded = controller(robot, TS, N)
            bounded.qps._core.options.soft_step_work = args.bounded_work
            variants[f"{scenario}, bounded"] = (bounded, ref, states_)
            for m in args.max_ages:
                law = InnerLawThreaded(
                    controller(robot, TS, N),
                    DisturbanceObserver(robot.nq, TS, 100.0, "general"),
                    TS,
                    None,
                    max_age=m * TS if m > 0 else None,
                )
                threaded[f"{scenario}, threaded, max_age {m:g}"] = (
                    law, ref, states_, scenario == "stalled arm")  # fmt: skip
    res = alternate(variants, args.blocks, threaded)
    base = np.median(res["on the reference"]["wall"], axis=1)
    print(f"Panda, Ts = {TS * 1e3:g} ms, N = Nc = {N}, default soft limits, {OFFSET} rad off: "
          f"{args.steps} steps per block, {args.blocks} blocks, soft exchanges per step "
          f"{'unbounded' if budget < 0 else f'at most {budget}'}\n")  # fmt: skip
    print("| variant | median step [µs] | / on the reference | worst step, wall [µs] | "
          "worst step, thread CPU [µs] | costliest step, wall [µs] | costliest / on the reference "
          "|")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    first = ("closed loop", "stalled arm", "on the reference")
    for name, r in ((k, res[k]) for k in first):
        med = np.median(r["wall"], axis=1)
        worst_w = r["wall"].max(axis=1)
        worst_c = r["cpu"].max(axis=1)
        costliest = np.median(r["wall"], axis=0).max()
        print(f"| {name} | {np.median(med):.0f} | {np.median(med / base):.2f} | "
              f"{np.median(worst_w):.0f} | {np.median(worst_c):.0f} | {costliest:.0f} | "
              f"{costliest / np.median(base):.1f} |")  # fmt: skip
    print()
    for name, r in ((k, res[k]) for k in first):
        s = r["stats"].sum(axis=0)
        if s[0]:
            print(f"{name}: soft QPs solved {s[0]}, by the shortcut {s[1]}, by ProxSuite "
                  f"{s[0] - s[1] - s[5]}; guesses that did not answer: pivot {s[2]}, exchanges "
                  f"{s[3]}, KKT {s[4]}; fallbacks {s[5]}; exchanges {s[6]}, at most "
                  f"{r['stats'][:, 7].max()} in a step")  # fmt: skip
    if not args.no_compare:
        compare(res, threaded, variants, ref, budget, args)
    print(f"\nload average at end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    for law, *_ in threaded.values():
        law.close()
    return 0


def _pct(x: np.ndarray, p: float, fmt: str) -> str:
    """The p-th percentile of x formatted, or "none" (no sample: no plan used)."""
    return format(np.percentile(x, p), fmt) if x.size else "none"


def _rms_tracking(q: np.ndarray, t: np.ndarray, ref) -> float:
    """The worst joint's RMS error [rad] of the states q (steps, n) at the times t."""
    q_ref = ref.sample_many(t)[0]
    return float(np.sqrt(np.mean((q - q_ref) ** 2, axis=0)).max())


def compare(res: dict, threaded: dict, variants: dict, ref, budget: int, args) -> None:
    """The second table: (a), (b), (c) per scenario (module doc)."""
    print(f"\nThe 1 ms deadline three ways, in the same blocks: (a) the synchronous step "
          f"(soft exchanges {'unbounded' if budget < 0 else f'at most {budget}'}), (b) bounded "
          f"(soft_step_work {args.bounded_work}: {max(1, args.bounded_work // N)} exchanges), "
          f"(c) the threaded law (period = Ts = 1 ms), max_age in periods "
          f"(default: the package's)\n")  # fmt: skip
    print("| scenario | variant | worst step / cycle, wall [µs] | thread CPU [µs] | "
          "cycle p99.9 [µs] | worst / (a)'s | planner solve worst wall / CPU, p99 wall [µs] | "
          "plan age max / p99.9 [ms] | braked cycles | plans published | tracking / (a)'s | "
          "fallbacks (soft) |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for scenario in ("closed loop", "stalled arm"):
        a = res[scenario]
        a_worst = np.median(a["wall"].max(axis=1))
        t, q, dq = variants[scenario][2]
        ctrl = variants[scenario][0]
        v_a = replay_v(ctrl, ref, (t, q, dq))
        rms_a = _rms_tracking(q, t, ref) if scenario == "closed loop" else None
        for tag, name in (("(a)", scenario), ("(b)", f"{scenario}, bounded")):
            r = res[name]
            worst = np.median(r["wall"].max(axis=1))
            fb = r["stats"][:, 5].sum()
            track = "1" if tag == "(a)" else "–"
            print(f"| {scenario} | {tag} synchronous{', bounded' if tag == '(b)' else ''} | "
                  f"{worst:.0f} | {np.median(r['cpu'].max(axis=1)):.0f} | "
                  f"{np.percentile(r['wall'], 99.9):.0f} | {worst / a_worst:.2f} | – | – | – | – "
                  f"| {track} | {fb} of {r['stats'][:, 0].sum()} |")  # fmt: skip
        for name in (k for k in threaded if k.startswith(scenario)):
            law = threaded[name][0]
            blocks = res[name]
            w = np.concatenate([b["wall"] for b in blocks])
            worst = np.median([b["wall"].max() for b in blocks])
            solves = np.concatenate([b["solves"] for b in blocks])
            ages = np.concatenate([b["age"] for b in blocks])
            used = ages[np.isfinite(ages)]
            braked = sum(b["fallbacks"] for b in blocks)
            published = sum(b["published"] for b in blocks)
            if rms_a is not None:
                track = np.median([_rms_tracking(b["q"], t, ref) for b in blocks]) / rms_a
            else:
                dv = [np.sqrt(np.mean((b["v"] - v_a) ** 2)) for b in blocks]
                track = np.median(dv) / np.sqrt(np.mean(v_a**2))
            print(f"| {scenario} | (c) threaded, max_age {law.max_age * 1e3:g} ms | {worst:.0f} | "
                  f"{np.median([b['cpu'].max() for b in blocks]):.0f} | "
                  f"{np.percentile(w, 99.9):.0f} | {worst / a_worst:.2f} | "
                  f"{max(b['max_solve'] for b in blocks):.0f} / "
                  f"{max(b['max_solve_cpu'] for b in blocks):.0f}, {_pct(solves, 99, '.0f')} "
                  f"| {_pct(used, 100, '.0f')} / {_pct(used, 99.9, '.1f')} | {braked} of "
                  f"{len(ages)} | {published} | {track:.3g} | "
                  f"{law._qps.soft_fallbacks} |")  # fmt: skip
    print(
        "\ntracking / (a)'s: closed loop, the worst joint's RMS error over the run against "
        "(a)'s; stalled arm, RMS(v − v(a)) / RMS(v(a)); (b) replays (a)'s states (no loop of "
        "its own). worst: the median over blocks of "
        "each block's worst; p99.9 over all cycles."
    )


if __name__ == "__main__":
    raise SystemExit(main())
