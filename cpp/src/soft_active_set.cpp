// The soft limits' active-set shortcut: its guesses and primal-dual exchanges (see
// soft_limits.hpp; each exchange's subproblem: banded_kkt.hpp).
#include "hmpc/soft_limits.hpp"

#include <algorithm>
#include <cmath>

namespace hmpc {

// Joint i's soft QP answered by the soft active-set shortcut (exchange) from the last soft
// solution's active set (when the joint's soft QP was solved at the last step) shifted one
// step along the horizon, then as it stands; at a new activation, from the box-only
// solution's (the rows its prediction violates active, the inputs next to them freed).
// On success y() holds the minimiser and the active set is remembered.
bool SoftLimits::active_set(int i, const ColRef& box_u, int iter) {
  if (!shortcut_ || iter < 0) return false;
  const int N = N_, Nc = Nc_;
  p_.lo = v_min_[i];
  p_.hi = v_max_[i];
  kkt_->project(p_.g, p_.gp);
  for (int j = 0; j < N; ++j) {
    p_.bnd_hi[2 * j] = upper_[i] - q_free_[j];
    p_.bnd_lo[2 * j] = lower_[i] - q_free_[j];
    p_.bnd_hi[2 * j + 1] = vel_[i] - v_free_[j];
    p_.bnd_lo[2 * j + 1] = -vel_[i] - v_free_[j];
  }
  if (budget_ >= 0) return bounded(i, box_u, iter);  // under a bound: its stages
  // The last soft solution's active set only while it is the last step's (the joint's soft
  // QP solved at the step before): after a step without, its activation is a new one.
  bool ok = false;
  continued_ = false;
  stopped_ = false;
  if (has_guess_[i] && last[i]) {
    // The two guesses in the order of the one that answered at the last step; at an
    // activation's first continued step, the shifted one first when the state is nearer the
    // last answer's prediction of it (x1 = A x0 + B u0: the plan followed) than the last
    // state (an arm held still, stalled or unable to follow its plan: the problem as it
    // stood, that guess first), so that a stalled arm's step does not spend its exchanges
    // on the shifted set.
    const double a00 = Phi_(0, 0), a01 = Phi_(0, 1), a10 = Phi_(1, 0), a11 = Phi_(1, 1);
    const double lq = last_q_[i], lv = last_v_[i], u0 = last_u0_[i];
    const double pq = a00 * lq + a01 * lv + Gamma_(0, 0) * u0;
    const double pv = a10 * lq + a11 * lv + Gamma_(1, 0) * u0;
    const double moved = std::abs(q_ - pq) + a01 * std::abs(dq_ - pv);
    const double held = std::abs(q_ - lq) + a01 * std::abs(dq_ - lv);
    const int first = shifted_first_[i] >= 0 ? shifted_first_[i] : (moved <= held ? 1 : 0);
    for (int k = 0; k < 2 && !ok; ++k) {
      const int shifted = k == 0 ? first : 1 - first;
      const auto& rows = guess_rows_[i];
      const auto& box = guess_box_[i];
      for (int r = 0; r < 2 * N; ++r) st_.rows[r] = rows[shifted && r + 2 < 2 * N ? r + 2 : r];
      for (int a = 0; a < Nc; ++a) st_.box[a] = box[shifted && a + 1 < Nc ? a + 1 : a];
      st_.slack = guess_slack_[i];
      ok = exchange(i, iter);
      if (ok) shifted_first_[i] = static_cast<signed char>(shifted);
    }
    continued_ = ok;
  }
  // At a new activation, the box-only solution's active set, with the rows its prediction
  // violates and ŝ = 0; further off than a last solution's: more exchanges. (Also trying it
  // after the last solution's failed, or with ŝ free, measured slower where the optimum is a
  // degenerate vertex with ŝ > 0: the exchanges rarely settle there and ProxSuite answers.)
  if (!ok && !(has_guess_[i] && last[i])) {
    box_y_.head(Nc) = box_u;
    box_y_[Nc] = 0.0;
    guess_from(i, box_y_, true);
    shifted_first_[i] = -1;  // a new activation: no guess answered at the last step
    st_.rows = guess_rows_[i];
    st_.box = guess_box_[i];
    st_.slack = guess_slack_[i];
    ok = exchange(i, 4 * iter);
  }
  if (!ok) return false;
  remember_state(i, kkt_->y()[0]);
  guess_rows_[i] = ans_rows_[i] = st_.rows;
  guess_box_[i] = ans_box_[i] = st_.box;
  guess_slack_[i] = ans_slack_[i] = st_.slack;
  return true;
}

// Under a bound on the step's exchanges (budget_ >= 0): the guesses as stages with their
// own exchanges (0: the last answer's active set shifted, 1: as it stood, iter each, in the
// order active_set tries them; 2: infeasible_guess's, 3: the box-only answer's, 4·iter
// each), tried in turn, their exchanges spread over steps: a joint out of the step's
// exchanges keeps its stage, the active set reached and the exchanges the stage has made,
// and resumes there at the next step (measured: resuming a guess's exchanges without a
// stage's own count cycled on a guess that never answers); a stage out of its own
// exchanges (or failing) hands over to the next one, the last to the first. A joint whose
// stages all failed within the step's exchanges returns false (not stopped): ProxSuite.
bool SoftLimits::bounded(int i, const ColRef& box_u, int iter) {
  const int N = N_, Nc = Nc_;
  continued_ = false;
  stopped_ = false;
  const bool answered = has_guess_[i] && last[i];
  int order[4], stages = 0;
  if (answered) {
    int first = shifted_first_[i];
    if (first < 0) {
      const double a00 = Phi_(0, 0), a01 = Phi_(0, 1), a10 = Phi_(1, 0), a11 = Phi_(1, 1);
      const double lq = last_q_[i], lv = last_v_[i], u0 = last_u0_[i];
      const double pq = a00 * lq + a01 * lv + Gamma_(0, 0) * u0;
      const double pv = a10 * lq + a11 * lv + Gamma_(1, 0) * u0;
      const double moved = std::abs(q_ - pq) + a01 * std::abs(dq_ - pv);
      const double held = std::abs(q_ - lq) + a01 * std::abs(dq_ - lv);
      first = moved <= held ? 0 : 1;  // stage 0: shifted
    } else {
      first = first ? 0 : 1;  // shifted_first_ 1 (shifted): stage 0
    }
    order[stages++] = first;
    order[stages++] = 1 - first;
  }
  order[stages++] = 2;
  order[stages++] = 3;
  int pos = 0;
  bool fresh = true;
  if (resume_[i] && last[i]) {
    for (int k = 0; k < stages; ++k)
      if (order[k] == resume_[i] - 1) pos = k, fresh = false;
  }
  if (fresh) spent_[i] = 0;
  resume_[i] = 0;
  for (int tries = 0; tries < stages; ++tries, pos = (pos + 1) % stages) {
    const int stage = order[pos];
    if (fresh) {
      spent_[i] = 0;
      if (stage <= 1) {
        const bool shifted = stage == 0;
        for (int r = 0; r < 2 * N; ++r)
          st_.rows[r] = ans_rows_[i][shifted && r + 2 < 2 * N ? r + 2 : r];
        for (int a = 0; a < Nc; ++a) st_.box[a] = ans_box_[i][shifted && a + 1 < Nc ? a + 1 : a];
        st_.slack = ans_slack_[i];
      } else {
        if (stage == 2 && !infeasible_guess(i, box_u)) continue;
        if (stage == 3) {
          box_y_.head(Nc) = box_u;
          box_y_[Nc] = 0.0;
          guess_from(i, box_y_, true);
        }
        st_.rows = guess_rows_[i];
        st_.box = guess_box_[i];
        st_.slack = guess_slack_[i];
      }
    } else {
      st_.rows = res_rows_[i];
      st_.box = res_box_[i];
      st_.slack = res_slack_[i];
    }
    fresh = true;
    const int cap = stage <= 1 ? iter : 4 * iter;
    const bool ok = exchange(i, std::max(cap - spent_[i], 0));
    spent_[i] += made_;
    if (ok) {
      continued_ = stage <= 1;
      shifted_first_[i] = stage <= 1 ? static_cast<signed char>(stage == 0) : -1;
      remember_state(i, kkt_->y()[0]);
      guess_rows_[i] = ans_rows_[i] = st_.rows;
      guess_box_[i] = ans_box_[i] = st_.box;
      guess_slack_[i] = ans_slack_[i] = st_.slack;
      has_guess_[i] = 1;
      return true;
    }
    if (stopped_) {  // out of the step's exchanges: this stage resumed at the next step
      res_rows_[i] = st_.rows;
      res_box_[i] = st_.box;
      res_slack_[i] = st_.slack;
      resume_[i] = static_cast<signed char>(stage + 1);
      return false;
    }
  }
  // Every stage tried at this step, the step's exchanges not spent: a soft QP the shortcut
  // cannot answer (dependent rows, rounding), left to ProxSuite as without a bound (measured
  // none in the Panda's 1 kHz runs; at N = 10 the fallback instead changed the runs).
  return false;
}

// Up to `exchanges` primal-dual exchanges from the active set st_: solve (BandedKKT), then
// test the soft QP's KKT conditions at its point (test_point). True when the point passes:
// then it is the soft QP's minimiser (a convex QP's KKT point), in y().
bool SoftLimits::exchange(int i, int exchanges) {
  // A dependent bound or row dropped by the KKT solve costs no exchange (at most one drop
  // per active item, so this ends).
  // This step's exchanges (budget_) are counted as `exchanges` are: by the solves that
  // were not a drop.
  exhausted_ = false;
  made_ = 0;
  for (int it = 0; it <= exchanges;) {
    if (budget_ == 0) {
      stopped_ = true;
      return false;
    }
    if (!kkt_->solve(st_, p_)) {
      if (kkt_->dropped()) continue;
      ++stats_->soft_fail_pivot;
      return false;
    }
    ++it;
    ++made_;
    if (budget_ > 0) --budget_;
    ++stats_->soft_exchanges;
    const int verdict = test_point(i);
    if (verdict == 0) return true;
    if (verdict < 0) {
      ++stats_->soft_fail_kkt;
      return false;
    }
  }
  ++stats_->soft_fail_exchanges;
  exhausted_ = true;
  return false;
}

// At a new activation: when some row's limit cannot be met by any input in the box (Γ >= 0:
// the row Γ_r U is least at U = lo, largest at U = hi), the slack the worst such row needs,
// k ŝ = its least violation, is a lower bound on the optimum's. The guess: ŝ there and free,
// the inputs that move the worst row (those before its step) at the bound that reduces its
// violation, the others the box-only answer's; its rows at or beyond their limits (the
// worst one among them) active. False (nothing set) when every row can be met.
bool SoftLimits::infeasible_guess(int i, const ColRef& box_u) {
  if (!gamma_nonneg_) return false;
  const int N = N_, Nc = Nc_;
  const double lo = v_min_[i], hi = v_max_[i];
  double worst = 1e-9 * std::max(1.0, vel_[i]);
  int r_star = -1, side = 0;
  for (int pass = 0; pass < 2; ++pass) {  // upper limits at U = lo, lower at U = hi
    box_y_.head(Nc).setConstant(pass == 0 ? lo : hi);
    gamma_.apply(box_y_.head(Nc), Xs_);
    for (int r = 0; r < 2 * N; ++r) {
      const double v = pass == 0 ? Xs_[r] - p_.bnd_hi[r] : p_.bnd_lo[r] - Xs_[r];
      if (v > worst) worst = v, r_star = r, side = pass == 0 ? 1 : -1;
    }
  }
  if (r_star < 0) return false;
  const int moved = std::min(r_star / 2 + 1, Nc);  // x_j depends on u_0 .. u_{j-1}
  box_y_.head(Nc) = box_u;
  for (int a = 0; a < moved; ++a) box_y_[a] = side > 0 ? lo : hi;
  box_y_[Nc] = worst / k_slack_;
  guess_from(i, box_y_, false);
  return true;
}

// The KKT test of joint i's soft QP at the subproblem's point, to the solver's tolerances
// (eps_abs + eps_rel · the size of the terms), as ProxSuite measures them: every row inside
// its limits (rows normalised as the solver's), every input inside its box, ŝ >= 0; zero
// gradient Hs y + g + Cᵀλ for the free inputs (and ŝ when free); multipliers of the sign
// of their bound (rows: λ/row_scale, the solver's z; inputs and ŝ: −gradient). Violated
// rows and bounds join st_, wrong-signed ones leave it: returns 1. Nothing to exchange:
// 0 when the point passes (y() clamped to the box, binding_ set), −1 when it fails.
int SoftLimits::test_point(int i) {
  const int N = N_, Nc = Nc_;
  const double lo = v_min_[i], hi = v_max_[i];
  Vec& y = kkt_->y();
  const Vec& lam = kkt_->lam();
  const auto u = y.head(Nc);
  const double sh = y[Nc];
  gamma_.apply(u, Xs_);
  rows_was_ = st_.rows;
  box_was_ = st_.box;
  // ProxSuite's tolerances: eps_abs + eps_rel · the size of the terms (dual: Hy, g, Cᵀλ;
  // primal: the rows' values), the relative part for slacks far outside the limits.
  rU_.noalias() = H_ * u;
  double dual = std::max({rU_.cwiseAbs().maxCoeff(), std::abs(Hs_(Nc, Nc) * sh),
                          p_.g.cwiseAbs().maxCoeff()});
  rU_ += p_.g.head(Nc);
  gamma_.apply_transpose(lam, gl_);  // Γᵀλ
  rU_ += gl_;
  const double lam_sum = k_slack_ * lam.cwiseAbs().sum();
  dual = std::max({dual, gl_.cwiseAbs().maxCoeff(), lam_sum});
  double rs = Hs_(Nc, Nc) * sh + p_.g[Nc];
  bool changed = false, bad = false;
  const double ks = k_slack_ * sh;
  double primal = 0.0;
  for (int r = 0; r < 2 * N; ++r)
    primal = std::max(primal, (std::abs(Xs_[r]) + std::abs(ks)) * kkt_->scale(r));
  const double eps = soft_.eps_abs + soft_.eps_rel * std::max(dual, primal);
  const double eps_p = soft_.eps_abs + soft_.eps_rel * primal;
  for (int r = 0; r < 2 * N; ++r) {
    const double scale = kkt_->scale(r);
    const int s = st_.rows[r];
    if (s == 0) {
      if ((Xs_[r] - ks - p_.bnd_hi[r]) * scale > eps_p) {
        st_.rows[r] = 1;
        changed = true;
      } else if ((p_.bnd_lo[r] - Xs_[r] - ks) * scale > eps_p) {
        st_.rows[r] = -1;
        changed = true;
      }
    } else {
      rs -= k_slack_ * s * lam[r];
      if (s * lam[r] / scale < -eps) {
        st_.rows[r] = 0;
        changed = true;
      }
    }
  }
  for (int a = 0; a < Nc; ++a) {
    const int s = st_.box[a];
    if (s == 0) {
      if (u[a] < lo - eps_p) {
        st_.box[a] = -1;
        changed = true;
      } else if (u[a] > hi + eps_p) {
        st_.box[a] = 1;
        changed = true;
      } else if (std::abs(rU_[a]) > eps) {
        bad = true;
      }
    } else if (s * rU_[a] > eps) {  // lower bound: gradient >= 0; upper: <= 0
      st_.box[a] = 0;
      changed = true;
    }
  }
  const signed char slack_was = st_.slack;
  if (st_.slack != 0) {
    if (sh < -eps_p) {
      st_.slack = 0;
      changed = true;
    } else if (std::abs(rs) > eps) {
      bad = true;
    }
  } else if (rs < -eps) {
    st_.slack = 1;
    changed = true;
  }
  if (st_.slack != slack_was) {
    // ŝ enters every row: with its status changing, the rows' and bounds' tests at this
    // point say little about the next one (following them too overshot, measured where
    // the limits become attainable or not): ŝ changes alone.
    st_.rows = rows_was_;
    st_.box = box_was_;
  }
  if (changed) return 1;
  if (bad) return -1;
  binding_ = st_.slack != 0 && sh > eps_p;
  for (int r = 0; r < 2 * N && !binding_; ++r)
    binding_ = st_.rows[r] != 0 && std::abs(lam[r]) / kkt_->scale(r) > eps;
  y.head(Nc) = y.head(Nc).cwiseMax(lo).cwiseMin(hi);
  y[Nc] = std::max(y[Nc], 0.0);
  return 0;
}

// The active set of a solution y = (U, ŝ) of joint i's soft QP (or, with box_only, of its
// box-only solution: the rows its prediction violates, the inputs next to them freed,
// ŝ = 0) remembered as the next guess.
void SoftLimits::guess_from(int i, const Vec& y, bool box_only) {
  const int N = N_, Nc = Nc_;
  const double lo = v_min_[i], hi = v_max_[i];
  const double tol = 1e-6 * std::max(1.0, hi - lo);
  auto& box = guess_box_[i];
  for (int a = 0; a < Nc; ++a) box[a] = y[a] <= lo + tol ? -1 : (y[a] >= hi - tol ? 1 : 0);
  gamma_.apply(y.head(Nc), Xs_);
  const double sh = box_only ? 0.0 : y[Nc];
  const double ks = k_slack_ * sh;
  auto& rows = guess_rows_[i];
  for (int r = 0; r < 2 * N; ++r) {
    const double scale = kkt_->scale(r);
    const double row_tol = box_only ? 0.0 : 1e-6;
    rows[r] = (Xs_[r] - ks - p_.bnd_hi[r]) * scale >= -row_tol
                  ? 1
                  : ((p_.bnd_lo[r] - Xs_[r] - ks) * scale >= -row_tol ? -1 : 0);
  }
  if (box_only) {
    // An input next to a violated state (a violated row of x_a or of x_{a+1}; u_a moves
    // x_{a+1} first) is freed: the limits override the box-only solution's bound there (e.g.
    // at a velocity limit the acceleration drops from its bound to 0; rows of x_a and x_{a+1}
    // fix u_a, so keeping its bound too makes them dependent).
    auto violated = [&](int step) {
      return step >= 1 && step <= N && (rows[2 * (step - 1)] != 0 || rows[2 * (step - 1) + 1] != 0);
    };
    for (int a = 0; a < Nc; ++a)
      if (box[a] != 0 && (violated(a) || violated(a + 1))) box[a] = 0;
  }
  guess_slack_[i] = !box_only && sh > 1e-9 ? 1 : 0;
  has_guess_[i] = 1;
}

}  // namespace hmpc
