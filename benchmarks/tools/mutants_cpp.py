"""Kill rate of one-line mutations of the compiled core (cpp/): apply each, rebuild, run the
tests of its area, revert.

The list was written from cpp/ and bindings/ alone (no test read), committed before any ran.
Same format as benchmarks/tools/one_line_mutants.py: (group, file, old line part, new line part,
tests). The extension is rebuilt by CMake in BUILD (configured once, see --configure) and
the module copied beside the package (the worktree's hmpc_pin/_core*.so). Run from the
repository root:

    .venv/bin/python benchmarks/tools/mutants_cpp.py [--only SUBSTRING] [--index I,J,...]

``--check`` checks that every mutant's text is in its file, once, without building (the
runner, shared with one_line_mutants.py, is benchmarks/tools/mutation.py).
"""

from __future__ import annotations

import glob
import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks.tools import mutation  # noqa: E402
from benchmarks.tools.mutation import Mutant, run_tests  # noqa: E402

BUILD = Path(os.environ.get("HMPC_MUT_BUILD", ROOT / "build" / "direct"))

# The tests of each area (chosen after the list was committed; the fastest file first: -x)
QP = ["tests/test_qp_parts.py", "tests/test_joint_mpc.py"]
PLANT = [
    "tests/test_plant_step.py",
    "tests/test_joint_dynamics.py",
    "tests/test_simulate_compiled.py",
]
OBS = ["tests/test_observers.py"]
CTRL = [
    "tests/test_latency.py",
    "tests/test_joint_dynamics.py",
    "tests/test_controller.py",
    "tests/test_native.py",
]

#: (group, file, old line part, new line part, tests); rationale in the comment above each
MUTANTS: list[Mutant] = [
    # ---- box_qp
    # the cold twin kept across runs: a run depends on the runs before it (missed reset)
    ("cpp", "cpp/src/box_qp.cpp", "  cold_qp_.reset();\n}", "}", QP),
    # a cold solve not reported as such (Stats.cold_solves never counts)
    (
        "cpp",
        "cpp/src/box_qp.cpp",
        "  cold = true;\n  // Restart",
        "  cold = false;\n  // Restart",
        QP,
    ),
    # ---- box_active_set
    # wrong sign of the unconstrained minimiser −H⁻¹g
    (
        "cpp",
        "cpp/src/box_active_set.cpp",
        "neg_Hinv_ = -0.5 * (Hinv + Hinv.transpose());",
        "neg_Hinv_ = 0.5 * (Hinv + Hinv.transpose());",
        QP,
    ),
    # wrong sign of the active inputs' term in H_FF u_F = −(g_F + H_FA u_A)
    (
        "cpp",
        "cpp/src/box_active_set.cpp",
        "if (state_[j] != 0) s -= H_(free_[p], j) * u_[j];",
        "if (state_[j] != 0) s += H_(free_[p], j) * u_[j];",
        QP,
    ),
    # multiplier sign test inverted: wrong-signed bounds kept, a non-optimal point accepted
    (
        "cpp",
        "cpp/src/box_active_set.cpp",
        "} else if (s * r_[j] > eps) {",
        "} else if (s * r_[j] < -eps) {",
        QP,
    ),
    # z() returned with the wrong sign (the warm start's multipliers)
    (
        "cpp",
        "cpp/src/box_active_set.cpp",
        "r_[j] = state_[j] == 0 ? 0.0 : -r_[j];",
        "r_[j] = state_[j] == 0 ? 0.0 : r_[j];",
        QP,
    ),
    # μ's right-hand side with the wrong sign (the small-active-set branch)
    (
        "cpp",
        "cpp/src/box_active_set.cpp",
        "rhs_[p] = u0_[active_[p]] - u_[active_[p]];",
        "rhs_[p] = u_[active_[p]] - u0_[active_[p]];",
        QP,
    ),
    # off by one: `exchanges` exchanges become exchanges − 1 (none at iter 0)
    (
        "cpp",
        "cpp/src/box_active_set.cpp",
        "for (int it = 0; it <= exchanges; ++it) {",
        "for (int it = 0; it < exchanges; ++it) {",
        QP,
    ),
    # ---- gamma_recursion
    # the recursion's input index one step ahead (set() then rejects the recursion)
    (
        "cpp",
        "cpp/src/gamma_recursion.cpp",
        "const double uj = u[std::min(j, Nc_ - 1)];",
        "const double uj = u[std::min(j + 1, Nc_ - 1)];",
        QP,
    ),
    # Aᵀ's off-diagonal taken from A (a_[1] ↔ a_[2]) in the adjoint recursion Γᵀλ
    (
        "cpp",
        "cpp/src/gamma_recursion.cpp",
        "m1 = lam[2 * (j - 1) + 1] + a_[1] * m0 + a_[3] * m1;",
        "m1 = lam[2 * (j - 1) + 1] + a_[2] * m0 + a_[3] * m1;",
        QP,
    ),
    # only Γ's first column checked: a Γ that is not the recursion accepted
    (
        "cpp",
        "cpp/src/gamma_recursion.cpp",
        "for (int c = 0; c < Nc_ && same; ++c) {",
        "for (int c = 0; c < 1 && same; ++c) {",
        QP,
    ),
    # ---- banded_kkt
    # Hp's bandwidth one short: its outermost band dropped from the envelope
    (
        "cpp",
        "cpp/src/banded_kkt.cpp",
        "if (Hp_(a, c) != 0.0) wH_ = std::max(wH_, a - c);",
        "if (Hp_(a, c) != 0.0) wH_ = std::max(wH_, a - c - 1);",
        QP,
    ),
    # ŝ's pivot expected negative: a free slack always fails the factorisation
    (
        "cpp",
        "cpp/src/banded_kkt.cpp",
        "const double sign = item_kind_[k] == 0 || item_kind_[k] == 3 ? 1.0 : -1.0;",
        "const double sign = item_kind_[k] == 0 ? 1.0 : -1.0;",
        QP,
    ),
    # wrong sign of ŝ's coefficient in an active row
    (
        "cpp",
        "cpp/src/banded_kkt.cpp",
        "if (slack_free) at(k, 0) = -k_ * st.rows[ref];",
        "if (slack_free) at(k, 0) = k_ * st.rows[ref];",
        QP,
    ),
    # an input fixed at the wrong bound (lower ↔ upper) in the KKT right-hand side
    (
        "cpp",
        "cpp/src/banded_kkt.cpp",
        "x_[k] = st.box[ref] < 0 ? p.lo : p.hi;",
        "x_[k] = st.box[ref] > 0 ? p.lo : p.hi;",
        QP,
    ),
    # U = T p without T's diagonal (c < a)
    (
        "cpp",
        "cpp/src/banded_kkt.cpp",
        "for (int c = t_first_[a]; c <= a; ++c) u += T_(a, c) * x_[pidx_[c]];",
        "for (int c = t_first_[a]; c < a; ++c) u += T_(a, c) * x_[pidx_[c]];",
        QP,
    ),
    # no iterative refinement at all
    (
        "cpp",
        "cpp/src/banded_kkt.cpp",
        "for (int refine = 0; refine < 2; ++refine) {",
        "for (int refine = 0; refine < 0; ++refine) {",
        QP,
    ),
    # the first dependent bound freed instead of the last
    (
        "cpp",
        "cpp/src/banded_kkt.cpp",
        "for (int j = k - 1; j >= 0; --j)",
        "for (int j = 0; j < k; ++j)",
        QP,
    ),
    # ---- soft_limits (ProxSuite path, the limit test)
    # the upper velocity row's bound with the free response's sign flipped
    (
        "cpp",
        "cpp/src/soft_limits.cpp",
        "u_soft_[2 * N + j] = (vel_[i] - v_free[j]) * row_scale_[2 * N + j];",
        "u_soft_[2 * N + j] = (vel_[i] + v_free[j]) * row_scale_[2 * N + j];",
        QP,
    ),
    # Φ's columns swapped in the velocity's free response
    (
        "cpp",
        "cpp/src/soft_limits.cpp",
        "v_free_[j] = Phi_(2 * j + 1, 0) * q[i] + Phi_(2 * j + 1, 1) * dq[i];",
        "v_free_[j] = Phi_(2 * j + 1, 1) * q[i] + Phi_(2 * j + 1, 0) * dq[i];",
        QP,
    ),
    # the slack ŝ held at 0 (upper bound 0): the soft QP becomes hard
    ("cpp", "cpp/src/soft_limits.cpp", "  hi[Nc] = BIG;", "  hi[Nc] = 0.0;", QP),
    # a new run keeps `last` (the soft QP was solved at the last step) from the run before
    ("cpp", "cpp/src/soft_limits.cpp", "  std::fill(last.begin(), last.end(), 0);\n", "", QP),
    # a new run keeps the soft QPs ProxSuite warm-started in the run before
    (
        "cpp",
        "cpp/src/soft_limits.cpp",
        "    if (used_[i]) make_qp(i);",
        "    if (used_[i] && false) make_qp(i);",
        QP,
    ),
    # the limit test without the velocity limit (dropped term)
    (
        "cpp",
        "cpp/include/hmpc/soft_limits.hpp",
        "outside = std::abs(x - m) > half_[i] || std::abs(v) > vel_[i];",
        "outside = std::abs(x - m) > half_[i];",
        QP,
    ),
    # the limit test's last step of the horizon not checked (off by one)
    (
        "cpp",
        "cpp/include/hmpc/soft_limits.hpp",
        "for (int j = 0; j < N_ && !outside; ++j) {",
        "for (int j = 0; j < N_ - 1 && !outside; ++j) {",
        QP,
    ),
    # the warm-start flag: straight to the soft QP when binding OR continued
    (
        "cpp",
        "cpp/include/hmpc/soft_limits.hpp",
        "active[i] = binding && continued ? 1 : 0;",
        "active[i] = binding || continued ? 1 : 0;",
        QP,
    ),
    # ---- soft_active_set
    # the lower velocity bound's sign lost (−v_max → +v_max)
    (
        "cpp",
        "cpp/src/soft_active_set.cpp",
        "p_.bnd_lo[2 * j + 1] = -vel_[i] - v_free_[j];",
        "p_.bnd_lo[2 * j + 1] = vel_[i] - v_free_[j];",
        QP,
    ),
    # ŝ's stationarity with the rows' multipliers added instead of subtracted
    (
        "cpp",
        "cpp/src/soft_active_set.cpp",
        "rs -= k_slack_ * s * lam[r];",
        "rs += k_slack_ * s * lam[r];",
        QP,
    ),
    # the rows' multiplier sign test inverted
    (
        "cpp",
        "cpp/src/soft_active_set.cpp",
        "if (s * lam[r] / scale < -eps) {",
        "if (s * lam[r] / scale > eps) {",
        QP,
    ),
    # the inputs' bound multiplier sign test inverted
    (
        "cpp",
        "cpp/src/soft_active_set.cpp",
        "} else if (s * rU_[a] > eps) {",
        "} else if (s * rU_[a] < -eps) {",
        QP,
    ),
    # the box-only guess given as many exchanges as a last solution's (4·iter → iter)
    (
        "cpp",
        "cpp/src/soft_active_set.cpp",
        "ok = exchange(i, 4 * iter);",
        "ok = exchange(i, iter);",
        QP,
    ),
    # ---- joint_qps
    # the unconstrained minimiser accepted when inside EITHER bound
    (
        "cpp",
        "cpp/src/joint_qps.cpp",
        "if ((u.array() >= v_min_[i]).all() && (u.array() <= v_max_[i]).all()) {",
        "if ((u.array() >= v_min_[i]).all() || (u.array() <= v_max_[i]).all()) {",
        QP,
    ),
    # a step's slack not cleared when the last step was constrained (missed reset)
    (
        "cpp",
        "cpp/src/joint_qps.cpp",
        "    slack.setZero();\n    stats.constrained_last = false;",
        "    stats.constrained_last = false;",
        QP,
    ),
    # restart() keeps the last run's slack (missed reset)
    (
        "cpp",
        "cpp/src/joint_qps.cpp",
        "  slack.setZero();\n  stats.constrained_last = false;\n  stats.constrained = 0;",
        "  stats.constrained_last = false;\n  stats.constrained = 0;",
        QP,
    ),
    # the skip of the box QP when the soft QP was last OR active (flag)
    (
        "cpp",
        "cpp/src/joint_qps.cpp",
        "soft_->last[i] && soft_->active[i];",
        "soft_->last[i] || soft_->active[i];",
        QP,
    ),
    # the soft QP only when always_constrained AND leaving (|| → &&)
    (
        "cpp",
        "cpp/src/joint_qps.cpp",
        # (the joint's own test after its box QP: the out-of-exchanges branch repeats it)
        "    }\n    if (!(options.always_constrained || leaves(i, q[i], dq[i]))) {",
        "    }\n    if (!(options.always_constrained && leaves(i, q[i], dq[i]))) {",
        QP,
    ),
    # ---- stick_slip
    # RK4's weights of a2 and a3 swapped (2, 1 → wrong rule) in the velocity update
    (
        "cpp",
        "cpp/src/stick_slip.cpp",
        "vs_ = va_ + (h6 * a1 + (2.0 * h6) * a2 + (2.0 * h6) * a3 + h6 * a4);",
        "vs_ = va_ + (h6 * a1 + (2.0 * h6) * a2 + h6 * a3 + h6 * a4);",
        PLANT,
    ),
    # the stage time in seconds, not as a fraction of the step
    (
        "cpp",
        "cpp/src/stick_slip.cpp",
        "tm = ta + hh / h, t1 = ta + L / h;",
        "tm = ta + hh, t1 = ta + L / h;",
        PLANT,
    ),
    # break-away tested on one side only (abs dropped)
    (
        "cpp",
        "cpp/src/stick_slip.cpp",
        "G = std::min(G, (fc_[i] - std::abs(phi_[i])) / fc_[i]);",
        "G = std::min(G, (fc_[i] - phi_[i]) / fc_[i]);",
        PLANT,
    ),
    # the joint breaking away slides the wrong way
    (
        "cpp",
        "cpp/src/stick_slip.cpp",
        "mode_[worst] = phi_[worst] > 0.0 ? -1 : 1;",
        "mode_[worst] = phi_[worst] > 0.0 ? 1 : -1;",
        PLANT,
    ),
    # the rest test's gravity cached across configurations (stale cache)
    (
        "cpp",
        "cpp/src/stick_slip.cpp",
        "if (!g_valid_ || (qG_.array() != q.array()).any()) {",
        "if (!g_valid_) {",
        PLANT,
    ),
    # the rest shortcut's hold test without abs: held against a push either way
    (
        "cpp",
        "cpp/src/stick_slip.cpp",
        "in = in && !(std::abs(phi_[i]) > fc_[i]);",
        "in = in && !(phi_[i] > fc_[i]);",
        PLANT,
    ),
    # the Coulomb torque at the start recorded with the wrong sign
    (
        "cpp",
        "cpp/src/stick_slip.cpp",
        "else rk4_.start_coulomb[i] = -b * mode_[i];",
        "else rk4_.start_coulomb[i] = b * mode_[i];",
        PLANT,
    ),
    # the step's done fraction advanced in seconds
    ("cpp", "cpp/src/stick_slip.cpp", "ta += hi * rem / h;", "ta += hi * rem;", PLANT),
    # ---- rk4
    # stage 3 given the end-of-step torque instead of the midpoint's
    (
        "cpp",
        "cpp/src/rk4.cpp",
        "torque(T.row(S + s), v3, a, b, friction);",
        "torque(T.row(2 * S + s), v3, a, b, friction);",
        PLANT,
    ),
    # the midpoint time of the disturbance at the end of the step
    ("cpp", "cpp/src/rk4.cpp", "tm = t0 + hh, t1 = t0 + h;", "tm = t0 + h, t1 = t0 + h;", PLANT),
    # the disturbance subtracted
    ("cpp", "cpp/src/rk4.cpp", "  u = tau + d;", "  u = tau - d;", PLANT),
    # the fused friction added instead of subtracted
    (
        "cpp",
        "cpp/src/rk4.cpp",
        "for (int i = 0; i < n; ++i) u[i] -= joint_torque(a[i], b[i], v[i]);",
        "for (int i = 0; i < n; ++i) u[i] += joint_torque(a[i], b[i], v[i]);",
        PLANT,
    ),
    # ---- rk4_plant
    # the reported disturbance with the fused friction's sign flipped
    (
        "cpp",
        "cpp/src/rk4_plant.cpp",
        "    for (int i = 0; i < n; ++i) d[i] -= joint_torque(a[i], b[i], v[i]);",
        "    for (int i = 0; i < n; ++i) d[i] += joint_torque(a[i], b[i], v[i]);",
        PLANT,
    ),
    # ---- observer
    # the implicit observer's matrix M − T cY
    (
        "cpp",
        "cpp/src/observer.cpp",
        "if (implicit) A_ = M + TcY;",
        "if (implicit) A_ = M - TcY;",
        OBS,
    ),
    # reset with z = + cY q̇0 (d̂ starts at 2 cY q̇0, not 0)
    ("cpp", "cpp/src/observer.cpp", "z.noalias() = -(cY * dq0);", "z.noalias() = cY * dq0;", OBS),
    # the observer's residual with nle − τ flipped
    ("cpp", "cpp/src/observer.cpp", "rhs_ = nle - tau_prev;", "rhs_ = tau_prev - nle;", OBS),
    # ---- step
    # the gradient's rows one short of the reference horizon
    (
        "cpp",
        "cpp/include/hmpc/stack_map.hpp",
        "return FT.bottomRows(N).isZero(0.0) ? N + 2 : 2 + 2 * N;",
        "return FT.bottomRows(N).isZero(0.0) ? N + 1 : 2 + 2 * N;",
        CTRL,
    ),
    # the estimate added to the torque instead of subtracted
    (
        "cpp",
        "cpp/src/step.cpp",
        "  t -= dhat.row(0).transpose();",
        "  t += dhat.row(0).transpose();",
        CTRL,
    ),
    # reset keeps has_prev: the first update after reset uses the last run's model
    ("cpp", "cpp/src/step.cpp", "  has_prev = false;\n", "", CTRL),
    # obs_start ignored: the observer fed the model at the new state
    (
        "cpp",
        "cpp/src/step.cpp",
        "const Mat& Mo = obs_start ? prev_M : *M;",
        "const Mat& Mo = *M;",
        CTRL,
    ),
    # the joint torque J not taken out of the applied torque the observer sees
    ("cpp", "cpp/src/step.cpp", "    if (joint.any) applied -= jtau;\n", "", CTRL),
    # the latency's record of the torque fed without the effort clip
    (
        "cpp",
        "cpp/src/step.cpp",
        "Vec fed = tau.row(0).transpose().cwiseMax(-effort).cwiseMin(effort);",
        "Vec fed = tau.row(0).transpose();",
        CTRL,
    ),
    # ---- joint_dynamics (the hold's ZOH correction)
    # g = x / (1 − e^{−x}) written as x / (e^{x} − 1)
    ("cpp", "cpp/src/joint_dynamics.cpp", "x / -std::expm1(-x);", "x / std::expm1(x);", CTRL),
    # the crossing fraction p ↔ 1 − p
    (
        "cpp",
        "cpp/src/joint_dynamics.cpp",
        "const double p = a / (a - c);",
        "const double p = c / (c - a);",
        CTRL,
    ),
    # ---- latency
    # the history interpolated with α and 1 − α swapped
    (
        "cpp",
        "cpp/src/latency.cpp",
        "tau_obs = (1.0 - alpha) * tau_hist[m] + alpha * tau_hist[m + 1];",
        "tau_obs = alpha * tau_hist[m] + (1.0 - alpha) * tau_hist[m + 1];",
        CTRL,
    ),
]


def build() -> bool:
    proc = subprocess.run(["nice", "cmake", "--build", str(BUILD), "-j2"], cwd=ROOT,
                          capture_output=True, text=True)  # fmt: skip
    if proc.returncode != 0:
        sys.stderr.write(proc.stdout[-3000:] + proc.stderr[-3000:])
        return False
    (so,) = glob.glob(str(BUILD / "_core*.so"))
    tmp = ROOT / "hmpc_pin" / (Path(so).name + ".tmp")
    shutil.copy2(so, tmp)
    os.replace(tmp, ROOT / "hmpc_pin" / Path(so).name)  # a new inode: running processes keep theirs
    return True


def run(mutant: Mutant, tests: list[str] | None = None) -> tuple[str, str]:
    """Rebuild with ``mutant`` applied, then run its tests (or ``tests``)."""
    if not build():
        return "nobuild", ""
    killed, tail = run_tests([tests or mutant[4]], timeout=900.0, nice=True)
    return ("killed" if killed else "SURVIVED"), tail


def main(argv: list[str] | None = None) -> int:
    parser = mutation.parser(__doc__)
    parser.add_argument(
        "--tests",
        nargs="*",
        default=None,
        help="run these tests for every mutant picked (in place of its own)",
    )
    args = parser.parse_args(argv)
    indices = mutation.picked(MUTANTS, args)
    try:
        return mutation.campaign(MUTANTS, indices, lambda m: run(m, args.tests), args.check)
    finally:
        if not args.check:
            build()  # the clean module back


if __name__ == "__main__":
    raise SystemExit(main())
