// The per-joint MPC's soft QPs (joint_qps.hpp): the soft active-set shortcut, its KKT
// system in banded coordinates and its exchanges (the rest of JointQPs: joint_qps.cpp).
#include "hmpc/joint_qps.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace hmpc {

namespace pqp = proxsuite::proxqp;

// X = Γ u (2N): by the recursion x_{j+1} = A x_j + B u_min(j, Nc−1), x_0 = 0 (Eq 24), in
// O(N), when set_limits found Γ to be that recursion (gamma_rec_); else the dense product.
void JointQPs::gamma_u(const Eigen::Ref<const Vec>& u, Vec& X) const {
  if (!gamma_rec_) {
    X.noalias() = Gamma_ * u;
    return;
  }
  double x = 0.0, v = 0.0;
  for (int j = 0; j < N; ++j) {
    const double uj = u[std::min(j, Nc - 1)];
    const double xn = ga_[0] * x + ga_[1] * v + gb_[0] * uj;
    v = ga_[2] * x + ga_[3] * v + gb_[1] * uj;
    x = xn;
    X[2 * j] = x;
    X[2 * j + 1] = v;
  }
}

// out = Γᵀ λ (Nc) by the adjoint recursion μ_j = λ_j + Aᵀ μ_{j+1} (μ_{N+1} = 0), the input
// u_min(j−1, Nc−1) collecting Bᵀ μ_j (j = N .. 1), in O(N); else the dense product.
void JointQPs::gamma_t(const Vec& lam, Vec& out) const {
  if (!gamma_rec_) {
    out.noalias() = Gamma_.transpose() * lam;
    return;
  }
  out.setZero();
  double m0 = 0.0, m1 = 0.0;
  for (int j = N; j >= 1; --j) {
    const double n0 = lam[2 * (j - 1)] + ga_[0] * m0 + ga_[2] * m1;
    m1 = lam[2 * (j - 1) + 1] + ga_[1] * m0 + ga_[3] * m1;
    m0 = n0;
    out[std::min(j - 1, Nc - 1)] += gb_[0] * m0 + gb_[1] * m1;
  }
}

// Whether Γ is the recursion of gamma_u with A = the first two rows of Φ and B = the first
// column's first two entries: every entry of the recursion's columns within 1e-12 of its
// row's largest |Γ| (the rows are the constraints, normalised per row); else the dense
// products are kept.
bool JointQPs::gamma_is_recursion() {
  ga_[0] = Phi_(0, 0);
  ga_[1] = Phi_(0, 1);
  ga_[2] = Phi_(1, 0);
  ga_[3] = Phi_(1, 1);
  gb_[0] = Gamma_(0, 0);
  gb_[1] = Gamma_(1, 0);
  const Vec row_max = Gamma_.cwiseAbs().rowwise().maxCoeff();
  gamma_rec_ = true;
  Vec e = Vec::Zero(Nc), col(2 * N);
  bool same = true;
  for (int c = 0; c < Nc && same; ++c) {
    e.setZero();
    e[c] = 1.0;
    gamma_u(e, col);
    for (int r = 0; r < 2 * N && same; ++r)
      same = std::abs(col[r] - Gamma_(r, c)) <= 1e-12 * row_max[r];
  }
  gamma_rec_ = same;
  return same;
}

// The soft QP's variables y = (U, ŝ), s = k ŝ, with the active set st_rows_ (each row r of
// X = Φ x0 + Γ U, interleaved q_1, q̇_1, …: −1 at its lower limit, +1 at its upper, 0 free),
// st_box_ (each input at v_min, v_max or free) and st_slack_ (1: ŝ free, 0: ŝ = 0). Solves
// the equality-constrained QP
//     min ½ yᵀ Hs y + gᵀ y  s.t.  Γ_r U − st_r k ŝ = b_r (active rows), u_a = bound (active box)
// in the banded coordinates U = T p (Hp = Tᵀ H T, E = Γ T banded; CondensedMPC.banded): its
// KKT matrix [1, ·, cᵀ; ·, Hp, Eᵀ; c, E, 0], ŝ (when free) first, each active row placed
// right after the last p it involves, has an envelope of a few entries per row (with ŝ
// free, the rows' reach back to it), so its LDLᵀ without pivoting (quasi-definite: positive
// pivots for ŝ and p, negative for the rows) costs O(N) (O(N · active rows) with ŝ free). Writes y_soft_ and the row multipliers lam_ (Hs y + g + Cᵀλ = 0,
// physical rows). False if a pivot has the wrong sign or is negligible: dropped_ when that
// pivot's bound or row, dependent on the rows before it, has been left out of the active set.
bool JointQPs::soft_kkt(int i) {
  dropped_ = false;
  item_kind_.clear();
  item_ref_.clear();
  first_.clear();
  // A free ŝ first: rows tied through it (e.g. two rows at the largest violation) are
  // dependent in p alone. Each active row's envelope then reaches back to it.
  const bool slack_free = st_slack_ != 0;
  if (slack_free) {
    item_kind_.push_back(3);
    item_ref_.push_back(Nc);
    first_.push_back(0);
  }
  for (int a = 0; a < Nc; ++a) {
    pidx_[a] = static_cast<int>(item_kind_.size());
    item_kind_.push_back(0);
    item_ref_.push_back(a);
    first_.push_back(pidx_[std::max(a - wH_, 0)]);
    if (st_box_[a] != 0) {
      item_kind_.push_back(1);
      item_ref_.push_back(a);
      first_.push_back(pidx_[t_first_[a]]);
    }
    for (int r : rows_by_last_[a]) {
      if (st_rows_[r] == 0) continue;
      item_kind_.push_back(2);
      item_ref_.push_back(r);
      first_.push_back(slack_free ? 0 : pidx_[e_first_[r]]);
    }
  }
  const int m = static_cast<int>(item_kind_.size());
  start_.resize(m + 1);
  start_[0] = 0;
  for (int k = 0; k < m; ++k) start_[k + 1] = start_[k] + (k - first_[k] + 1);
  L_.assign(start_[m], 0.0);
  auto at = [&](int k, int col) -> double& { return L_[start_[k] + col - first_[k]]; };
  for (int k = 0; k < m; ++k) {
    const int ref = item_ref_[k];
    switch (item_kind_[k]) {
      case 0:
        for (int c = std::max(ref - wH_, 0); c <= ref; ++c) at(k, pidx_[c]) = Hp_(ref, c);
        x_[k] = -gp_[ref];
        break;
      case 1:
        for (int c = t_first_[ref]; c <= ref; ++c) at(k, pidx_[c]) = T_(ref, c);
        x_[k] = st_box_[ref] < 0 ? v_min_[i] : v_max_[i];
        break;
      case 2:
        for (int c = e_first_[ref]; c <= e_last_[ref]; ++c) at(k, pidx_[c]) = E_(ref, c);
        if (slack_free) at(k, 0) = -k_slack_ * st_rows_[ref];
        x_[k] = st_rows_[ref] > 0 ? bnd_hi_[ref] : bnd_lo_[ref];
        break;
      default:
        at(k, k) = Hs_(Nc, Nc);
        x_[k] = -g_soft_[Nc];
    }
  }
  // Envelope LDLᵀ (row k holds L(k, first_[k] .. k−1) and, at k, the diagonal).
  for (int k = 0; k < m; ++k) {
    const int fk = first_[k];
    double* Lk = L_.data() + start_[k] - fk;
    double size = std::abs(Lk[k]);
    for (int j = fk; j < k; ++j) {
      const int fj = first_[j];
      const double* Lj = L_.data() + start_[j] - fj;
      double s = Lk[j];
      for (int c = std::max(fk, fj); c < j; ++c) s -= w_[c] * Lj[c];
      w_[j] = s;
      Lk[j] = s / D_[j];
    }
    double d = Lk[k];
    for (int c = fk; c < k; ++c) {
      d -= Lk[c] * w_[c];
      size += std::abs(Lk[c] * w_[c]);
    }
    const double sign = item_kind_[k] == 0 || item_kind_[k] == 3 ? 1.0 : -1.0;
    if (!(sign * d > 1e-13 * size)) {  // NaN too
      // A bound or row dependent on those before it (e.g. an input at its bound between two
      // active velocity rows, which fix it to 0): one item of the dependency leaves the
      // active set, the next exchange tests it. A row whose dependency holds an input at its
      // bound frees the last such input (the rows are the limits, and with both kept the
      // exchanges re-add the dropped row at every step: a cycle); otherwise the item itself.
      if (item_kind_[k] == 0 || item_kind_[k] == 3) return false;
      int drop = k;
      if (item_kind_[k] == 2 && std::isfinite(d)) {
        // The dependency a_k = Σ_j ρ_j a_j: K_{<k} [0; ρ] = [a_k; 0], so ρ is the constraint
        // part of K_{<k}⁻¹ b_k = L⁻ᵀ (row k of L), b_k the column of item k.
        z_.resize(D_.size());
        for (int j = 0; j < k; ++j) z_[j] = j >= fk ? Lk[j] : 0.0;
        for (int j = k - 1; j > 0; --j) {
          const int fj = first_[j];
          const double* Lj = L_.data() + start_[j] - fj;
          const double zj = z_[j];
          if (zj != 0.0)
            for (int c = fj; c < j; ++c) z_[c] -= Lj[c] * zj;
        }
        double big = 0.0;
        for (int j = 0; j < k; ++j)
          if (item_kind_[j] == 1 || item_kind_[j] == 2) big = std::max(big, std::abs(z_[j]));
        for (int j = k - 1; j >= 0; --j)
          if (item_kind_[j] == 1 && std::abs(z_[j]) > 1e-9 * big) {
            drop = j;
            break;
          }
      }
      if (item_kind_[drop] == 1) st_box_[item_ref_[drop]] = 0;
      else st_rows_[item_ref_[drop]] = 0;
      dropped_ = true;
      return false;
    }
    D_[k] = d;
  }
  soft_solve();
  lam_.setZero();
  mu_.setZero();
  y_soft_[Nc] = 0.0;
  for (int k = 0; k < m; ++k) {
    if (item_kind_[k] == 1) mu_[item_ref_[k]] = x_[k];
    else if (item_kind_[k] == 2) lam_[item_ref_[k]] = x_[k];
    else if (item_kind_[k] == 3) y_soft_[Nc] = x_[k];
  }
  for (int a = 0; a < Nc; ++a) {  // U = T p
    double u = 0.0;
    for (int c = t_first_[a]; c <= a; ++c) u += T_(a, c) * x_[pidx_[c]];
    y_soft_[a] = u;
  }
  if (!(std::isfinite(y_soft_.sum()) && std::isfinite(lam_.sum()))) return false;
  // Iterative refinement against the KKT system in U (the solver's H, Γ): U = T p is a
  // second difference of p, whose rounding would otherwise reach the gradient's tolerance.
  for (int refine = 0; refine < 2; ++refine) {
    const auto u = y_soft_.head(Nc);
    rU_.noalias() = H_ * u;
    rU_ += g_soft_.head(Nc);
    gamma_t(lam_, gl_);
    rU_ += gl_;
    rU_ += mu_;
    gamma_u(u, Xs_);
    double rs = Hs_(Nc, Nc) * y_soft_[Nc] + g_soft_[Nc];
    for (int r = 0; r < 2 * N; ++r) rs -= k_slack_ * st_rows_[r] * lam_[r];
    for (int k = 0; k < m; ++k) {
      const int ref = item_ref_[k];
      switch (item_kind_[k]) {
        case 0: {
          double t = 0.0;  // (Tᵀ r)_ref
          for (int a = ref; a < Nc && a <= ref + wT_; ++a)
            if (t_first_[a] <= ref) t += T_(a, ref) * rU_[a];
          x_[k] = -t;
          break;
        }
        case 1: x_[k] = (st_box_[ref] < 0 ? v_min_[i] : v_max_[i]) - y_soft_[ref]; break;
        case 2:
          x_[k] = (st_rows_[ref] > 0 ? bnd_hi_[ref] : bnd_lo_[ref]) -
                  (Xs_[ref] - k_slack_ * st_rows_[ref] * y_soft_[Nc]);
          break;
        default: x_[k] = -rs;
      }
    }
    // Refined only while the residual (the gradient's in U, the rows' as the solver scales
    // them, the bounds', ŝ's when free) exceeds 1e-3 of the solver's absolute tolerance.
    double res = rU_.cwiseAbs().maxCoeff();
    for (int k = 0; k < m; ++k) {
      const int ref = item_ref_[k];
      if (item_kind_[k] == 1) res = std::max(res, std::abs(x_[k]));
      else if (item_kind_[k] == 2)
        res = std::max(res, std::abs(x_[k]) * row_scale_[(ref % 2 == 0 ? 0 : 2 * N) + ref / 2]);
      else if (item_kind_[k] == 3) res = std::max(res, std::abs(rs));
    }
    if (!(res > 1e-3 * soft_.eps_abs)) break;
    soft_solve();
    for (int k = 0; k < m; ++k) {
      const int ref = item_ref_[k];
      if (item_kind_[k] == 1) mu_[ref] += x_[k];
      else if (item_kind_[k] == 2) lam_[ref] += x_[k];
      else if (item_kind_[k] == 3) y_soft_[Nc] += x_[k];
    }
    for (int a = 0; a < Nc; ++a) {
      double du = 0.0;
      for (int c = t_first_[a]; c <= a; ++c) du += T_(a, c) * x_[pidx_[c]];
      y_soft_[a] += du;
    }
  }
  return std::isfinite(y_soft_.sum()) && std::isfinite(lam_.sum());
}

// x_ ← K⁻¹ x_ with the envelope LDLᵀ of soft_kkt.
void JointQPs::soft_solve() {
  const int m = static_cast<int>(item_kind_.size());
  for (int k = 0; k < m; ++k) {  // L z = b
    const int fk = first_[k];
    const double* Lk = L_.data() + start_[k] - fk;
    double s = x_[k];
    for (int c = fk; c < k; ++c) s -= Lk[c] * x_[c];
    x_[k] = s;
  }
  for (int k = 0; k < m; ++k) x_[k] /= D_[k];
  for (int k = m - 1; k >= 0; --k) {  // Lᵀ x = z
    const int fk = first_[k];
    const double* Lk = L_.data() + start_[k] - fk;
    const double xk = x_[k];
    for (int c = fk; c < k; ++c) x_[c] -= Lk[c] * xk;
  }
}

// Up to `exchanges` primal-dual exchanges from the active set st_*: solve (soft_kkt), then
// test the soft QP's KKT conditions at its point to the solver's tolerances (eps_abs +
// eps_rel · the size of the terms), as ProxSuite measures them: every row inside its limits (rows normalised as the solver's),
// every input inside its box, ŝ >= 0; zero gradient Hs y + g + Cᵀλ for the free inputs
// (and ŝ when free); multipliers of the sign of their bound (rows: λ/row_scale, the solver's
// z; inputs and ŝ: −gradient). Violated rows and bounds join the active set, wrong-signed
// ones leave it. True when the point passes: then it is the soft QP's minimiser (a convex
// QP's KKT point), in y_soft_.
bool JointQPs::soft_exchange(int i, int exchanges) {
  const double lo = v_min_[i], hi = v_max_[i];
  // A dependent bound or row dropped by soft_kkt costs no exchange (at most one drop per
  // active item, so this ends).
  for (int it = 0; it <= exchanges;) {
    if (!soft_kkt(i)) {
      if (dropped_) continue;
      ++soft_fail_pivot;
      return false;
    }
    ++it;
    const auto u = y_soft_.head(Nc);
    const double sh = y_soft_[Nc];
    gamma_u(u, Xs_);
    rows_was_ = st_rows_;
    box_was_ = st_box_;
    // ProxSuite's tolerances: eps_abs + eps_rel · the size of the terms (dual: Hy, g, Cᵀλ;
    // primal: the rows' values), the relative part for slacks far outside the limits.
    rU_.noalias() = H_ * u;
    double dual = std::max({rU_.cwiseAbs().maxCoeff(), std::abs(Hs_(Nc, Nc) * sh),
                            g_soft_.cwiseAbs().maxCoeff()});
    rU_ += g_soft_.head(Nc);
    gamma_t(lam_, gl_);  // Γᵀλ
    rU_ += gl_;
    const double lam_sum = k_slack_ * lam_.cwiseAbs().sum();
    dual = std::max({dual, gl_.cwiseAbs().maxCoeff(), lam_sum});
    double rs = Hs_(Nc, Nc) * sh + g_soft_[Nc];
    bool changed = false, bad = false;
    const double ks = k_slack_ * sh;
    double primal = 0.0;
    for (int r = 0; r < 2 * N; ++r)
      primal = std::max(primal, (std::abs(Xs_[r]) + std::abs(ks)) *
                                    row_scale_[(r % 2 == 0 ? 0 : 2 * N) + r / 2]);
    const double eps = soft_.eps_abs + soft_.eps_rel * std::max(dual, primal);
    const double eps_p = soft_.eps_abs + soft_.eps_rel * primal;
    for (int r = 0; r < 2 * N; ++r) {
      const double scale = row_scale_[(r % 2 == 0 ? 0 : 2 * N) + r / 2];
      const int s = st_rows_[r];
      if (s == 0) {
        if ((Xs_[r] - ks - bnd_hi_[r]) * scale > eps_p) {
          st_rows_[r] = 1;
          changed = true;
        } else if ((bnd_lo_[r] - Xs_[r] - ks) * scale > eps_p) {
          st_rows_[r] = -1;
          changed = true;
        }
      } else {
        rs -= k_slack_ * s * lam_[r];
        if (s * lam_[r] / scale < -eps) {
          st_rows_[r] = 0;
          changed = true;
        }
      }
    }
    for (int a = 0; a < Nc; ++a) {
      const int s = st_box_[a];
      if (s == 0) {
        if (u[a] < lo - eps_p) {
          st_box_[a] = -1;
          changed = true;
        } else if (u[a] > hi + eps_p) {
          st_box_[a] = 1;
          changed = true;
        } else if (std::abs(rU_[a]) > eps) {
          bad = true;
        }
      } else if (s * rU_[a] > eps) {  // lower bound: gradient >= 0; upper: <= 0
        st_box_[a] = 0;
        changed = true;
      }
    }
    const signed char slack_was = st_slack_;
    if (st_slack_ != 0) {
      if (sh < -eps_p) {
        st_slack_ = 0;
        changed = true;
      } else if (std::abs(rs) > eps) {
        bad = true;
      }
    } else if (rs < -eps) {
      st_slack_ = 1;
      changed = true;
    }
    if (st_slack_ != slack_was) {
      // ŝ enters every row: with its status changing, the rows' and bounds' tests at this
      // point say little about the next one (following them too overshot, measured where
      // the limits become attainable or not): ŝ changes alone.
      st_rows_ = rows_was_;
      st_box_ = box_was_;
    }
    if (!changed) {
      if (bad) {
        ++soft_fail_kkt;
        return false;
      }
      soft_binding_ = st_slack_ != 0 && sh > eps_p;
      for (int r = 0; r < 2 * N && !soft_binding_; ++r)
        soft_binding_ = st_rows_[r] != 0 &&
                        std::abs(lam_[r]) / row_scale_[(r % 2 == 0 ? 0 : 2 * N) + r / 2] > eps;
      y_soft_.head(Nc) = y_soft_.head(Nc).cwiseMax(lo).cwiseMin(hi);
      y_soft_[Nc] = std::max(y_soft_[Nc], 0.0);
      return true;
    }
  }
  ++soft_fail_exchanges;
  return false;
}

// The active set of a solution y = (U, ŝ) of joint i's soft QP (or, with
// box_only, of its box-only solution: the rows its prediction violates, the inputs next to
// them freed, ŝ = 0) remembered as the next guess.
void JointQPs::soft_guess_from(int i, const Vec& y, bool box_only) {
  const double lo = v_min_[i], hi = v_max_[i];
  const double tol = 1e-6 * std::max(1.0, hi - lo);
  auto& box = guess_box_[i];
  for (int a = 0; a < Nc; ++a) box[a] = y[a] <= lo + tol ? -1 : (y[a] >= hi - tol ? 1 : 0);
  gamma_u(y.head(Nc), Xs_);
  const double sh = box_only ? 0.0 : y[Nc];
  const double ks = k_slack_ * sh;
  auto& rows = guess_rows_[i];
  for (int r = 0; r < 2 * N; ++r) {
    const double scale = row_scale_[(r % 2 == 0 ? 0 : 2 * N) + r / 2];
    const double row_tol = box_only ? 0.0 : 1e-6;
    rows[r] = (Xs_[r] - ks - bnd_hi_[r]) * scale >= -row_tol
                  ? 1
                  : ((bnd_lo_[r] - Xs_[r] - ks) * scale >= -row_tol ? -1 : 0);
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

// After joint i's soft QP was answered (binding: ŝ > 0 or a row's multiplier nonzero, to
// the solver's tolerance; continued: by the shortcut from the last step's active set):
// whether the next step goes straight to the soft QP, without the box QP (solve,
// enforce_limits). Only when the activation continues (a closed loop, where the next
// step's problem is this one a period on) and the limits bind: the box QP's answer would
// then most likely leave them and be discarded. The choice is for speed only: either way
// the answer is the soft QP's, exact.
void JointQPs::soft_settled(int i, bool binding, bool continued) {
  soft_active_[i] = binding && continued ? 1 : 0;
}

// Joint i's soft QP answered by the soft active-set shortcut (soft_exchange) from the last
// soft solution's active set (when the joint's soft QP was solved at the last step) shifted
// one step along the horizon, then as it stands; at a new activation, from the box-only
// solution's (the rows its prediction violates active, the inputs next to them freed).
// On success y_soft_ holds the minimiser and the active set is remembered.
bool JointQPs::soft_active_set(int i) {
  if (!soft_shortcut_ || soft_active_set_iter < 0) return false;
  gp_.setZero();  // gp = Tᵀ g
  for (int a = 0; a < Nc; ++a)
    for (int c = t_first_[a]; c <= a; ++c) gp_[c] += T_(a, c) * g_soft_[a];
  for (int j = 0; j < N; ++j) {
    bnd_hi_[2 * j] = upper_[i] - q_free_[j];
    bnd_lo_[2 * j] = lower_[i] - q_free_[j];
    bnd_hi_[2 * j + 1] = vel_[i] - v_free_[j];
    bnd_lo_[2 * j + 1] = -vel_[i] - v_free_[j];
  }
  // The last soft solution's active set only while it is the last step's (the joint's soft
  // QP solved at the step before): after a step without, its activation is a new one.
  bool ok = false;
  soft_continued_ = false;
  if (has_guess_[i] && soft_last_[i]) {
    for (int shifted = 1; shifted >= 0 && !ok; --shifted) {
      const auto& rows = guess_rows_[i];
      const auto& box = guess_box_[i];
      for (int r = 0; r < 2 * N; ++r) st_rows_[r] = rows[shifted && r + 2 < 2 * N ? r + 2 : r];
      for (int a = 0; a < Nc; ++a) st_box_[a] = box[shifted && a + 1 < Nc ? a + 1 : a];
      st_slack_ = guess_slack_[i];
      ok = soft_exchange(i, soft_active_set_iter);
    }
    soft_continued_ = ok;
  }
  // At a new activation, the box-only solution's active set, with the rows its prediction
  // violates and ŝ = 0; further off than a last solution's: more exchanges. (Also trying it
  // after the last solution's failed, or with ŝ free, measured slower where the optimum is a
  // degenerate vertex with ŝ > 0: the exchanges rarely settle there and ProxSuite answers.)
  if (!ok && !(has_guess_[i] && soft_last_[i])) {
    y_soft_.head(Nc) = U.col(i);
    y_soft_[Nc] = 0.0;
    soft_guess_from(i, y_soft_, true);
    st_rows_ = guess_rows_[i];
    st_box_ = guess_box_[i];
    st_slack_ = guess_slack_[i];
    ok = soft_exchange(i, 4 * soft_active_set_iter);
  }
  if (!ok) return false;
  guess_rows_[i] = st_rows_;
  guess_box_[i] = st_box_;
  guess_slack_[i] = st_slack_;
  return true;
}

}  // namespace hmpc
