// The per-joint MPC's QPs: see joint_qps.hpp.
#include "hmpc/joint_qps.hpp"

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace hmpc {

namespace pqp = proxsuite::proxqp;

QPSettings::QPSettings() {
  const pqp::Settings<double> d;  // ProxSuite's defaults
  initial_guess = d.initial_guess;
  eps_abs = d.eps_abs;
  eps_rel = d.eps_rel;
  eps_duality_gap_abs = d.eps_duality_gap_abs;
  eps_duality_gap_rel = d.eps_duality_gap_rel;
  eps_primal_inf = d.eps_primal_inf;
  eps_dual_inf = d.eps_dual_inf;
  max_iter = d.max_iter;
  verbose = d.verbose;
  check_duality_gap = d.check_duality_gap;
}

void QPSettings::apply(pqp::Settings<double>& s) const {
  s.initial_guess = initial_guess;
  s.eps_abs = eps_abs;
  s.eps_rel = eps_rel;
  s.max_iter = max_iter;
  s.verbose = verbose;
  s.check_duality_gap = check_duality_gap;
  s.eps_duality_gap_abs = eps_duality_gap_abs;
  s.eps_duality_gap_rel = eps_duality_gap_rel;
  s.eps_primal_inf = eps_primal_inf;
  s.eps_dual_inf = eps_dual_inf;
}

std::string status_name(pqp::QPSolverOutput status) {
  switch (status) {
    case pqp::QPSolverOutput::PROXQP_SOLVED: return "QPSolverOutput.PROXQP_SOLVED";
    case pqp::QPSolverOutput::PROXQP_MAX_ITER_REACHED: return "QPSolverOutput.PROXQP_MAX_ITER_REACHED";
    case pqp::QPSolverOutput::PROXQP_PRIMAL_INFEASIBLE: return "QPSolverOutput.PROXQP_PRIMAL_INFEASIBLE";
    case pqp::QPSolverOutput::PROXQP_DUAL_INFEASIBLE: return "QPSolverOutput.PROXQP_DUAL_INFEASIBLE";
    case pqp::QPSolverOutput::PROXQP_SOLVED_CLOSEST_PRIMAL_FEASIBLE:
      return "QPSolverOutput.PROXQP_SOLVED_CLOSEST_PRIMAL_FEASIBLE";
    case pqp::QPSolverOutput::PROXQP_NOT_RUN: return "QPSolverOutput.PROXQP_NOT_RUN";
  }
  return "QPSolverOutput.UNKNOWN";
}

namespace {

// A box-constrained dense QP, initialised and solved once: update() before any solve()
// crashes ProxSuite 0.8.0 with warm starts (measured here).
std::unique_ptr<JointQPs::DenseQP> new_box_qp(const JointQPs::Mat& H, const JointQPs::Vec& g,
                                              const JointQPs::Vec& lo, const JointQPs::Vec& hi,
                                              const QPSettings& options) {
  auto qp = std::make_unique<JointQPs::DenseQP>(H.rows(), 0, 0, true);
  options.apply(qp->settings);
  qp->init(H, g, std::nullopt, std::nullopt, std::nullopt, std::nullopt, std::nullopt, lo, hi);
  qp->solve();
  return qp;
}

}  // namespace

JointQPs::JointQPs(int n_, int N_, int Nc_, bool block_, const CRefMat& H, const CRefVec& v_min,
                   const CRefVec& v_max, const Settings& warm, const Settings& cold, double* U_,
                   double* slack_)
    : n(n_), N(N_), Nc(Nc_), block(block_), U(U_, Nc_, n_), slack(slack_, n_), H_(H),
      v_min_(v_min), v_max_(v_max), warm_(warm), cold_(cold) {
  if (H.rows() != Nc || H.cols() != Nc || v_min.size() != n || v_max.size() != n)
    throw std::invalid_argument("JointQPs: H must be (Nc, Nc) and v_min, v_max (n,)");
  if ((v_min.array() > v_max.array()).any())
    throw std::invalid_argument("JointQPs: v_min > v_max for some joint");
  g_.setZero(Nc);
  u_.setZero(Nc);
  HFF_.setZero(Nc, Nc);
  u0_.setZero(Nc);
  active_.reserve(Nc);
  r_.setZero(Nc);
  rhs_.setZero(Nc);
  free_.reserve(Nc);
  state_.assign(Nc, 0);
  // Each box QP's bounds, kept for its cold twin (made on first use).
  if (block) {
    H_block_ = Mat::Zero(n * Nc, n * Nc);
    Vec lo(n * Nc), hi(n * Nc);
    for (int i = 0; i < n; ++i) {
      H_block_.block(i * Nc, i * Nc, Nc, Nc) = H_;
      lo.segment(i * Nc, Nc).setConstant(v_min_[i]);
      hi.segment(i * Nc, Nc).setConstant(v_max_[i]);
    }
    box_lo_.push_back(lo);
    box_hi_.push_back(hi);
    g_block_.setZero(n * Nc);
    qps_.emplace_back(new_box_qp(H_block_, g_block_, lo, hi, warm_));
  } else {
    const Mat Hinv = H_.inverse();
    neg_Hinv_ = -0.5 * (Hinv + Hinv.transpose());
    for (int i = 0; i < n; ++i) {
      box_lo_.push_back(Vec::Constant(Nc, v_min_[i]));
      box_hi_.push_back(Vec::Constant(Nc, v_max_[i]));
      qps_.emplace_back(new_box_qp(H_, Vec::Zero(Nc), box_lo_[i], box_hi_[i], warm_));
    }
  }
  cold_qps_.resize(qps_.size());
}

void JointQPs::set_limits(const CRefMat& Phi, const CRefMat& Gamma, const CRefVec& lower,
                          const CRefVec& upper, const CRefVec& vel, const CRefMat& Hs,
                          const CRefMat& C, const CRefVec& row_scale, double g_slack,
                          double k_slack, const Settings& soft, bool always, const CRefMat& T,
                          const CRefMat& E, const CRefMat& Hp) {
  if (Phi.rows() != 2 * N || Phi.cols() != 2 || Gamma.rows() != 2 * N || Gamma.cols() != Nc ||
      lower.size() != n || upper.size() != n || vel.size() != n || Hs.rows() != Nc + 1 ||
      Hs.cols() != Nc + 1 || C.rows() != 4 * N || C.cols() != Nc + 1 || row_scale.size() != 4 * N)
    throw std::invalid_argument("JointQPs.set_limits: shapes do not match the horizon");
  Phi_ = Phi;
  Gamma_ = Gamma;
  lower_ = lower;
  upper_ = upper;
  vel_ = vel;
  Hs_ = Hs;
  C_ = C;
  row_scale_ = row_scale;
  g_slack_ = g_slack;
  k_slack_ = k_slack;
  soft_ = soft;
  always_constrained = always;
  mid_ = 0.5 * (lower_ + upper_);
  half_ = 0.5 * (upper_ - lower_);
  g_soft_.setZero(Nc + 1);
  l_soft_.setZero(4 * N);
  u_soft_.setZero(4 * N);
  X_.setZero(2 * N);
  q_free_.setZero(N);
  v_free_.setZero(N);
  soft_qps_.clear();
  for (int i = 0; i < n; ++i) {
    auto qp = std::make_unique<DenseQP>(Nc + 1, 0, 4 * N, true);
    soft_.apply(qp->settings);
    g_soft_.head(Nc).setZero();
    g_soft_[Nc] = g_slack_;
    soft_bounds(i, Vec::Zero(N), Vec::Zero(N));
    Vec lo(Nc + 1), hi(Nc + 1);
    lo.head(Nc).setConstant(v_min_[i]);
    hi.head(Nc).setConstant(v_max_[i]);
    lo[Nc] = 0.0;
    hi[Nc] = BIG;
    qp->init(Hs_, g_soft_, std::nullopt, std::nullopt, C_, l_soft_, u_soft_, lo, hi);
    qp->solve();
    soft_qps_.push_back(std::move(qp));
  }
  limits = true;
  soft_shortcut_ = false;
  if (T.size() == 0) return;
  if (T.rows() != Nc || T.cols() != Nc || E.rows() != 2 * N || E.cols() != Nc ||
      Hp.rows() != Nc || Hp.cols() != Nc)
    throw std::invalid_argument("JointQPs.set_limits: T, Hp must be (Nc, Nc) and E (2N, Nc)");
  T_ = T;
  E_ = E;
  Hp_ = Hp;
  // The bands: T lower triangular, each row of E one contiguous run of columns, Hp of lower
  // bandwidth wH_ (every entry outside them exactly zero, as CondensedMPC.banded makes them).
  wH_ = 0;
  for (int a = 0; a < Nc; ++a)
    for (int c = 0; c < a; ++c)
      if (Hp_(a, c) != 0.0) wH_ = std::max(wH_, a - c);
  t_first_.assign(Nc, 0);
  wT_ = 0;
  for (int a = 0; a < Nc; ++a) {
    int f = a;
    for (int c = 0; c < Nc; ++c) {
      if (T_(a, c) == 0.0) continue;
      if (c > a) throw std::invalid_argument("JointQPs.set_limits: T must be lower triangular");
      f = std::min(f, c);
    }
    t_first_[a] = f;
    wT_ = std::max(wT_, a - f);
  }
  e_first_.assign(2 * N, 0);
  e_last_.assign(2 * N, 0);
  rows_by_last_.assign(Nc, {});
  for (int r = 0; r < 2 * N; ++r) {
    int f = -1, l = -1;
    for (int c = 0; c < Nc; ++c)
      if (E_(r, c) != 0.0) {
        if (f < 0) f = c;
        l = c;
      }
    if (f < 0) throw std::invalid_argument("JointQPs.set_limits: a row of E is zero");
    e_first_[r] = f;
    e_last_[r] = l;
    rows_by_last_[l].push_back(r);
  }
  guess_rows_.assign(n, std::vector<signed char>(2 * N, 0));
  guess_box_.assign(n, std::vector<signed char>(Nc, 0));
  guess_slack_.assign(n, 0);
  has_guess_.assign(n, 0);
  st_rows_.assign(2 * N, 0);
  st_box_.assign(Nc, 0);
  pidx_.assign(Nc, 0);
  const int items = 2 * Nc + 2 * N + 1;
  item_kind_.reserve(items);
  item_ref_.reserve(items);
  first_.reserve(items);
  start_.reserve(items + 1);
  D_.assign(items, 0.0);
  w_.assign(items, 0.0);
  x_.assign(items, 0.0);
  y_soft_.setZero(Nc + 1);
  lam_.setZero(2 * N);
  rU_.setZero(Nc);
  mu_.setZero(Nc);
  gl_.setZero(Nc);
  gp_.setZero(Nc);
  bnd_lo_.setZero(2 * N);
  bnd_hi_.setZero(2 * N);
  Xs_.setZero(2 * N);
  soft_shortcut_ = true;
}

void JointQPs::set_max_iter(long max_iter) {
  warm_.max_iter = cold_.max_iter = soft_.max_iter = max_iter;
  for (auto* list : {&qps_, &cold_qps_, &soft_qps_})
    for (auto& qp : *list)
      if (qp) qp->settings.max_iter = max_iter;
}

QPNotSolved JointQPs::failure() const {
  std::string name = "all-joint block";
  if (fail_joint >= 0)
    name = fail_joint < static_cast<int>(joint_names.size()) ? joint_names[fail_joint]
                                                             : "joint " + std::to_string(fail_joint);
  return QPNotSolved(fail_joint < 0 ? -1 : fail_joint, name, fail_status, fail_iter);
}

bool JointQPs::fail(int joint, const Results& res) {
  fail_joint = joint;
  fail_status = status_name(res.info.status);
  fail_iter = res.info.iter;
  return false;
}

// Joint i's box QP answered without ProxSuite. Guesses of the active set: the last
// solution's shifted one step along the horizon (right in a closed loop, where the plan
// advances one step per period) with one active-set exchange, then the last solution's as it
// stands (right when the error persists) with up to active_set_iter exchanges (free inputs
// outside the box fixed at the bound they cross, fixed inputs whose multiplier has the wrong
// sign freed). Each guess fixes its active inputs at their bounds and solves
// H_FF u_F = −(g_F + H_FA u_A) for the free ones (or, with fewer active than free inputs,
// the same point as u = u0 − H⁻¹E_A μ, (H⁻¹)_AA μ = u0_A − u_A from u0 = −H⁻¹g: a
// Cholesky factorisation of the smaller size); it answers when that point satisfies the
// box QP's KKT conditions to the solver's tolerance eps_abs: free inputs inside the box
// with a zero gradient (H u + g)_F, multipliers z = −(H u + g) of the fixed inputs with the sign of their bound. It is then the
// QP's minimiser (a convex QP's KKT point), u_ on return, with its multipliers remembered.
bool JointQPs::active_set(int i) {
  if (active_set_iter < 0) return false;
  u0_ = u_;  // the unconstrained minimiser −H⁻¹g
  const Vec& x = qps_[i]->results.x;
  const double lo = v_min_[i], hi = v_max_[i];
  const double guess_tol = 1e-6 * std::max(1.0, hi - lo);
  for (int shifted = Nc > 1 ? 1 : 0; shifted >= 0; --shifted) {
    for (int j = 0; j < Nc; ++j) {
      const double c = x[shifted && j + 1 < Nc ? j + 1 : j];
      state_[j] = c <= lo + guess_tol ? -1 : (c >= hi - guess_tol ? 1 : 0);
    }
    if (exchange(i, shifted ? std::min(1, active_set_iter) : active_set_iter)) return true;
  }
  return false;
}

// The active set state_ (−1 lower, +1 upper, 0 free) and up to `exchanges` exchanges.
bool JointQPs::exchange(int i, int exchanges) {
  const double lo = v_min_[i], hi = v_max_[i];
  const double eps = warm_.eps_abs;
  for (int it = 0; it <= exchanges; ++it) {
    free_.clear();
    for (int j = 0; j < Nc; ++j) {
      if (state_[j] == 0) free_.push_back(j);
      else u_[j] = state_[j] < 0 ? lo : hi;
    }
    const int m = static_cast<int>(free_.size()), a = Nc - m;
    if (m > 0 && m <= a) {  // H_FF u_F = −(g_F + H_FA u_A), a Cholesky of size m
      for (int p = 0; p < m; ++p) {
        double s = -g_[free_[p]];
        for (int j = 0; j < Nc; ++j)
          if (state_[j] != 0) s -= H_(free_[p], j) * u_[j];
        rhs_[p] = s;
        for (int q = 0; q <= p; ++q) HFF_(p, q) = H_(free_[p], free_[q]);
      }
      Eigen::Ref<Mat> block_ref = HFF_.topLeftCorner(m, m);
      Eigen::LLT<Eigen::Ref<Mat>, Eigen::Lower> llt(block_ref);
      if (llt.info() != Eigen::Success) return false;
      auto sol = rhs_.head(m);
      llt.solveInPlace(sol);
      for (int p = 0; p < m; ++p) u_[free_[p]] = sol[p];
    } else if (m > 0) {  // fewer active inputs: u = u0 − H⁻¹ E_A μ with (H⁻¹)_AA μ = u0_A − u_A
      active_.clear();
      for (int j = 0; j < Nc; ++j)
        if (state_[j] != 0) active_.push_back(j);
      for (int p = 0; p < a; ++p) {
        rhs_[p] = u0_[active_[p]] - u_[active_[p]];
        for (int q = 0; q <= p; ++q) HFF_(p, q) = -neg_Hinv_(active_[p], active_[q]);
      }
      Eigen::Ref<Mat> block_ref = HFF_.topLeftCorner(a, a);
      Eigen::LLT<Eigen::Ref<Mat>, Eigen::Lower> llt(block_ref);
      if (llt.info() != Eigen::Success) return false;
      auto mu = rhs_.head(a);
      llt.solveInPlace(mu);
      for (int p = 0; p < m; ++p) {
        double s = u0_[free_[p]];
        for (int q = 0; q < a; ++q) s += neg_Hinv_(free_[p], active_[q]) * mu[q];
        u_[free_[p]] = s;
      }
    }
    r_.noalias() = H_ * u_;
    r_ += g_;
    bool ok = true;
    for (int j = 0; j < Nc; ++j) {
      const int s = state_[j];
      if (s == 0) {
        if (u_[j] < lo - eps) { state_[j] = -1; ok = false; }
        else if (u_[j] > hi + eps) { state_[j] = 1; ok = false; }
        else if (std::abs(r_[j]) > eps) return false;  // stationarity lost to rounding
      } else if (s * r_[j] > eps) {  // lower bound: r >= 0; upper: r <= 0
        state_[j] = 0;
        ok = false;
      }
    }
    if (ok) {
      u_ = u_.cwiseMax(lo).cwiseMin(hi);
      for (int j = 0; j < Nc; ++j) r_[j] = state_[j] == 0 ? 0.0 : -r_[j];
      remember(i, 0, u_, &r_);
      return true;
    }
  }
  return false;
}

// Box QP k's last solution set to x (multipliers z, or 0) at its variables offset..offset+Nc,
// so that its next warm start (shifted) begins there.
void JointQPs::remember(int k, int offset, const Vec& x, const Vec* z) {
  auto& res = qps_[k]->results;
  res.x.segment(offset, Nc) = x;
  if (z) res.z.segment(offset, Nc) = *z;
  else res.z.segment(offset, Nc).setZero();
}

// Box QP k with gradient g; on a failed warm solve, its cold twin.
const JointQPs::Results* JointQPs::solve_box(int k, const Vec& g, int joint) {
  DenseQP& qp = *qps_[k];
  if (shift && Nc > 1) {  // warm start from the last solution, one step on
    auto& x = qp.results.x;
    auto& z = qp.results.z;
    const int blocks = static_cast<int>(x.size()) / Nc;
    for (int b = 0; b < blocks; ++b) {
      const int o = b * Nc;
      for (int j = 0; j + 1 < Nc; ++j) {
        x[o + j] = x[o + j + 1];
        z[o + j] = z[o + j + 1];
      }
    }
  }
  qp.update(std::nullopt, g, std::nullopt, std::nullopt, std::nullopt, std::nullopt,
            std::nullopt, std::nullopt, std::nullopt);
  qp.solve();
  if (qp.results.info.status == pqp::QPSolverOutput::PROXQP_SOLVED) return &qp.results;
  if (!cold_qps_[k]) {
    const Mat& Hq = block ? H_block_ : H_;
    auto twin = std::make_unique<DenseQP>(Hq.rows(), 0, 0, true);
    cold_.apply(twin->settings);
    twin->init(Hq, g, std::nullopt, std::nullopt, std::nullopt, std::nullopt, std::nullopt,
                box_lo_[k], box_hi_[k]);
    twin->solve();
    cold_qps_[k] = std::move(twin);
  } else {
    cold_qps_[k]->update(std::nullopt, g, std::nullopt, std::nullopt, std::nullopt, std::nullopt,
                         std::nullopt, std::nullopt, std::nullopt);
    cold_qps_[k]->solve();
  }
  const auto& res = cold_qps_[k]->results;
  if (res.info.status != pqp::QPSolverOutput::PROXQP_SOLVED) {
    fail(joint, res);
    return nullptr;
  }
  ++cold_solves;
  // Restart the warm QP from this solution, so that the next steps warm-start from it.
  Vec x = res.x, y = res.y;
  qp.solve(x, y, std::nullopt);
  if (qp.results.info.status == pqp::QPSolverOutput::PROXQP_SOLVED) return &qp.results;
  return &res;
}

bool JointQPs::solve(const CRefRow& G, const CRefVec& q, const CRefVec& dq) {
  if (G.rows() != n || G.cols() != Nc || q.size() != n || dq.size() != n)
    throw std::invalid_argument("JointQPs.solve: G must be (n, Nc) and q, dq (n,)");
  if (block) {
    for (int i = 0; i < n; ++i) g_block_.segment(i * Nc, Nc) = G.row(i).transpose();
    const auto* res = solve_box(0, g_block_, -1);
    if (!res) return false;
    for (int i = 0; i < n; ++i) U.col(i) = res->x.segment(i * Nc, Nc);
  } else {
    for (int i = 0; i < n; ++i) {
      g_ = G.row(i).transpose();
      if (shortcut) {
        u_.noalias() = neg_Hinv_ * g_;
        if ((u_.array() >= v_min_[i]).all() && (u_.array() <= v_max_[i]).all()) {
          U.col(i) = u_;
          remember(i, 0, u_, nullptr);
          ++unconstrained_solves;
          continue;
        }
        if (active_set(i)) {
          U.col(i) = u_;
          ++active_set_solves;
          continue;
        }
      }
      const auto* res = solve_box(i, g_, i);
      if (!res) return false;
      U.col(i) = res->x;
    }
  }
  constrained = 0;
  if (limits && !enforce_limits(G, q, dq)) return false;
  return true;
}

// Row bounds of joint i's soft QP for the free responses of q and q̇.
void JointQPs::soft_bounds(int i, const Vec& q_free, const Vec& v_free) {
  for (int j = 0; j < N; ++j) {
    l_soft_[j] = -BIG;
    u_soft_[j] = (upper_[i] - q_free[j]) * row_scale_[j];
    l_soft_[N + j] = (lower_[i] - q_free[j]) * row_scale_[N + j];
    u_soft_[N + j] = BIG;
    l_soft_[2 * N + j] = -BIG;
    u_soft_[2 * N + j] = (vel_[i] - v_free[j]) * row_scale_[2 * N + j];
    l_soft_[3 * N + j] = (-vel_[i] - v_free[j]) * row_scale_[3 * N + j];
    u_soft_[3 * N + j] = BIG;
  }
}

// Re-solve with the soft state constraints the joints whose box-only prediction leaves the
// limits (every joint when always_constrained).
bool JointQPs::enforce_limits(const CRefRow& G, const CRefVec& q, const CRefVec& dq) {
  if (constrained_last) {
    slack.setZero();
    constrained_last = false;
  }
  for (int i = 0; i < n; ++i) {
    bool outside = always_constrained;
    if (!outside) {
      X_.noalias() = Phi_.col(0) * q[i] + Phi_.col(1) * dq[i];
      X_.noalias() += Gamma_ * U.col(i);
      const double m = mid_[i];
      for (int j = 0; j < N && !outside; ++j)
        outside = std::abs(X_[2 * j] - m) > half_[i] || std::abs(X_[2 * j + 1]) > vel_[i];
    }
    if (!outside) continue;
    constrained_last = true;
    for (int j = 0; j < N; ++j) {
      q_free_[j] = Phi_(2 * j, 0) * q[i] + Phi_(2 * j, 1) * dq[i];
      v_free_[j] = Phi_(2 * j + 1, 0) * q[i] + Phi_(2 * j + 1, 1) * dq[i];
    }
    g_soft_.head(Nc) = G.row(i).transpose();
    g_soft_[Nc] = g_slack_;
    ++constrained;
    if (soft_active_set(i)) {
      U.col(i) = y_soft_.head(Nc);
      slack[i] = y_soft_[Nc] * k_slack_;
      ++soft_active_set_solves;
      continue;
    }
    soft_bounds(i, q_free_, v_free_);
    DenseQP& qp = *soft_qps_[i];
    qp.update(std::nullopt, g_soft_, std::nullopt, std::nullopt, std::nullopt, l_soft_, u_soft_,
              std::nullopt, std::nullopt);
    qp.solve();
    if (qp.results.info.status != pqp::QPSolverOutput::PROXQP_SOLVED) return fail(i, qp.results);
    U.col(i) = qp.results.x.head(Nc);
    slack[i] = std::max(qp.results.x[Nc], 0.0) * k_slack_;
    if (soft_shortcut_ && soft_active_set_iter >= 0) soft_guess_from(i, qp.results.x, false);
  }
  return true;
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
      // active velocity rows): left out of the active set, the next exchange tests it.
      if (item_kind_[k] == 1) st_box_[item_ref_[k]] = 0;
      else if (item_kind_[k] == 2) st_rows_[item_ref_[k]] = 0;
      else return false;
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
    rU_.noalias() += Gamma_.transpose() * lam_;
    rU_ += mu_;
    Xs_.noalias() = Gamma_ * u;
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
  for (int it = 0; it <= exchanges; ++it) {
    if (!soft_kkt(i)) {
      if (dropped_) continue;
      ++soft_fail_pivot;
      return false;
    }
    const auto u = y_soft_.head(Nc);
    const double sh = y_soft_[Nc];
    Xs_.noalias() = Gamma_ * u;
    // ProxSuite's tolerances: eps_abs + eps_rel · the size of the terms (dual: Hy, g, Cᵀλ;
    // primal: the rows' values), the relative part for slacks far outside the limits.
    rU_.noalias() = H_ * u;
    double dual = std::max({rU_.cwiseAbs().maxCoeff(), std::abs(Hs_(Nc, Nc) * sh),
                            g_soft_.cwiseAbs().maxCoeff()});
    rU_ += g_soft_.head(Nc);
    gl_.noalias() = Gamma_.transpose() * lam_;  // Γᵀλ
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
    if (!changed) {
      if (bad) {
        ++soft_fail_kkt;
        return false;
      }
      y_soft_.head(Nc) = y_soft_.head(Nc).cwiseMax(lo).cwiseMin(hi);
      y_soft_[Nc] = std::max(y_soft_[Nc], 0.0);
      return true;
    }
  }
  ++soft_fail_exchanges;
  return false;
}

// The active set of a solution y = (U, ŝ) of joint i's soft QP (or, with
// box_only, of its box-only solution: the rows its prediction violates)
// remembered as the next guess.
void JointQPs::soft_guess_from(int i, const Vec& y, bool box_only) {
  const double lo = v_min_[i], hi = v_max_[i];
  const double tol = 1e-6 * std::max(1.0, hi - lo);
  auto& box = guess_box_[i];
  for (int a = 0; a < Nc; ++a) box[a] = y[a] <= lo + tol ? -1 : (y[a] >= hi - tol ? 1 : 0);
  Xs_.noalias() = Gamma_ * y.head(Nc);
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
  guess_slack_[i] = !box_only && sh > 1e-9 ? 1 : 0;
  has_guess_[i] = 1;
}

// Joint i's soft QP answered by the soft active-set shortcut (soft_exchange) from the last
// soft solution's active set shifted one step along the horizon, then as it stands; or,
// without one, from the box-only solution's (with the rows its prediction violates).
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
  const bool first = !has_guess_[i];
  if (first) {  // the box-only solution's active set, with the rows its prediction violates
    y_soft_.head(Nc) = U.col(i);
    y_soft_[Nc] = 0.0;
    soft_guess_from(i, y_soft_, true);
  }
  bool ok = false;
  for (int shifted = first ? 0 : 1; shifted >= 0 && !ok; --shifted) {
    const auto& rows = guess_rows_[i];
    const auto& box = guess_box_[i];
    for (int r = 0; r < 2 * N; ++r) st_rows_[r] = rows[shifted && r + 2 < 2 * N ? r + 2 : r];
    for (int a = 0; a < Nc; ++a) st_box_[a] = box[shifted && a + 1 < Nc ? a + 1 : a];
    st_slack_ = guess_slack_[i];
    // From the box-only solution the active set is further off: more exchanges.
    ok = soft_exchange(i, first ? 4 * soft_active_set_iter : soft_active_set_iter);
  }
  if (!ok) return false;
  guess_rows_[i] = st_rows_;
  guess_box_[i] = st_box_;
  guess_slack_[i] = st_slack_;
  return true;
}

}  // namespace hmpc
