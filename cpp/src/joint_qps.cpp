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
  } else {
    const Mat Hinv = H_.inverse();
    neg_Hinv_ = -0.5 * (Hinv + Hinv.transpose());
    for (int i = 0; i < n; ++i) {
      box_lo_.push_back(Vec::Constant(Nc, v_min_[i]));
      box_hi_.push_back(Vec::Constant(Nc, v_max_[i]));
    }
  }
  make_box_qps();
}

// The box QPs as new (each initialised and solved once at g = 0, new_box_qp), their cold
// twins to be made on first use.
void JointQPs::make_box_qps() {
  qps_.clear();
  if (block) {
    g_block_.setZero(n * Nc);
    qps_.emplace_back(new_box_qp(H_block_, g_block_, box_lo_[0], box_hi_[0], warm_));
  } else {
    for (int i = 0; i < n; ++i)
      qps_.emplace_back(new_box_qp(H_, Vec::Zero(Nc), box_lo_[i], box_hi_[i], warm_));
  }
  cold_qps_.clear();
  cold_qps_.resize(qps_.size());
}

// Joint i's soft QP as new: initialised with its rows at x0 = 0 and solved once at g = 0
// (ŝ's gradient g_slack); g_soft_ kept, l_soft_ and u_soft_ overwritten.
void JointQPs::make_soft_qp(int i) {
  auto& qp = soft_qps_[i];
  const Vec g = g_soft_;
  qp = std::make_unique<DenseQP>(Nc + 1, 0, 4 * N, true);
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
  g_soft_ = g;
  soft_used_[i] = 0;
}

// A new run: the QPs as new, no remembered active set or warm start (a run does not depend
// on the runs before it: the same states give the same answers, bit for bit, as a new
// JointQPs), no slack.
void JointQPs::restart() {
  make_box_qps();
  // The soft QPs ProxSuite solved in the last run made again (their init factorises a KKT
  // matrix of Nc + 1 + 4N rows, about 18 ms at N = 100: here, never in a step).
  for (int i = 0; i < static_cast<int>(soft_qps_.size()); ++i)
    if (soft_used_[i]) make_soft_qp(i);
  std::fill(has_guess_.begin(), has_guess_.end(), 0);
  std::fill(soft_last_.begin(), soft_last_.end(), 0);
  std::fill(soft_active_.begin(), soft_active_.end(), 0);  // no box QP skipped at the start
  std::fill(soft_next_.begin(), soft_next_.end(), 0);
  slack.setZero();
  constrained_last = false;
  constrained = 0;
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
  soft_qps_.resize(n);
  soft_used_.assign(n, 0);
  for (int i = 0; i < n; ++i) make_soft_qp(i);
  limits = true;
  soft_shortcut_ = false;
  soft_last_.assign(n, 0);
  soft_next_.assign(n, 0);
  soft_active_.assign(n, 0);
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
  gamma_is_recursion();
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
// stands (right when the error persists) with up to active_set_iter exchanges, then the
// bounds the unconstrained minimiser crosses with 4·active_set_iter (free inputs
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
  // Failing those (a new error, the first step): the bounds that the unconstrained minimiser
  // u0 crosses, with more exchanges (further off than a last solution's).
  for (int j = 0; j < Nc; ++j) state_[j] = u0_[j] < lo ? -1 : (u0_[j] > hi ? 1 : 0);
  return exchange(i, 4 * active_set_iter);
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

// Joint i's box QP for the gradient g_ ("joint" layout): the exact shortcuts, then
// ProxSuite; its solution in U.col(i). False when ProxSuite did not report solved.
bool JointQPs::box_joint(int i) {
  if (shortcut) {
    u_.noalias() = neg_Hinv_ * g_;
    if ((u_.array() >= v_min_[i]).all() && (u_.array() <= v_max_[i]).all()) {
      U.col(i) = u_;
      remember(i, 0, u_, nullptr);
      ++unconstrained_solves;
      return true;
    }
    if (active_set(i)) {
      U.col(i) = u_;
      ++active_set_solves;
      return true;
    }
  }
  const auto* res = solve_box(i, g_, i);
  if (!res) return false;
  U.col(i) = res->x;
  return true;
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
      // A joint whose soft QP was answered at the last step with a state limit or the
      // slack active goes straight to its soft QP (enforce_limits): its box QP's answer
      // would only be tested against the limits and, most likely leaving them, discarded.
      if (limits) {
        soft_next_[i] = soft_shortcut_ && soft_active_set_iter >= 0 && soft_last_[i] &&
                        soft_active_[i];
        if (soft_next_[i]) continue;
      }
      if (!box_joint(i)) return false;
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

// Joint i's soft QP's gradient and the free responses of its state (x_1 .. x_N).
void JointQPs::soft_prepare(int i, const CRefRow& G, const CRefVec& q, const CRefVec& dq) {
  for (int j = 0; j < N; ++j) {
    q_free_[j] = Phi_(2 * j, 0) * q[i] + Phi_(2 * j, 1) * dq[i];
    v_free_[j] = Phi_(2 * j + 1, 0) * q[i] + Phi_(2 * j + 1, 1) * dq[i];
  }
  g_soft_.head(Nc) = G.row(i).transpose();
  g_soft_[Nc] = g_slack_;
}

// Re-solve with the soft state constraints the joints whose box-only prediction leaves the
// limits (every joint when always_constrained).
bool JointQPs::enforce_limits(const CRefRow& G, const CRefVec& q, const CRefVec& dq) {
  if (constrained_last) {
    slack.setZero();
    constrained_last = false;
  }
  for (int i = 0; i < n; ++i) {
    if (soft_next_[i]) {
      // Box QP skipped (solve): the soft shortcut from the last step's active set; answered
      // with the limits binding, the joint is constrained (its box solution, differing from
      // this one, leaves the limits); answered without, this is the box QP's solution, the
      // joint unconstrained. Not answered: the box QP now, and on as without the skip.
      soft_prepare(i, G, q, dq);
      if (soft_active_set(i)) {
        U.col(i) = y_soft_.head(Nc);
        slack[i] = y_soft_[Nc] * k_slack_;
        soft_settled(i, soft_binding_, soft_continued_);
        remember(i, 0, U.col(i), nullptr);  // the box QP's next warm start
        if (soft_binding_) {
          constrained_last = true;
          ++constrained;
          ++soft_active_set_solves;
        } else {
          soft_last_[i] = 0;
        }
        continue;
      }
      soft_last_[i] = 0;  // its active set failed here: a new activation's guess, if any
      g_ = G.row(i).transpose();
      if (!box_joint(i)) return false;
    }
    bool outside = always_constrained;
    if (!outside) {
      // X = Φ x0 + Γ U by the recursion x_{j+1} = A x_j + B u_min(j, Nc−1) (Eq 24; A, B
      // the first rows of Φ and Γ): O(N) where Γ U costs N·Nc.
      const double a00 = Phi_(0, 0), a01 = Phi_(0, 1), a10 = Phi_(1, 0), a11 = Phi_(1, 1);
      const double b0 = Gamma_(0, 0), b1 = Gamma_(1, 0);
      const double m = mid_[i];
      double x = q[i], v = dq[i];
      for (int j = 0; j < N && !outside; ++j) {
        const double u = U(std::min(j, Nc - 1), i);
        const double xn = a00 * x + a01 * v + b0 * u;
        v = a10 * x + a11 * v + b1 * u;
        x = xn;
        outside = std::abs(x - m) > half_[i] || std::abs(v) > vel_[i];
      }
    }
    if (!outside) {
      soft_last_[i] = 0;
      continue;
    }
    constrained_last = true;
    soft_prepare(i, G, q, dq);
    ++constrained;
    if (soft_active_set(i)) {
      U.col(i) = y_soft_.head(Nc);
      slack[i] = y_soft_[Nc] * k_slack_;
      ++soft_active_set_solves;
      soft_last_[i] = 1;
      soft_settled(i, soft_binding_, soft_continued_);
      continue;
    }
    soft_bounds(i, q_free_, v_free_);
    DenseQP& qp = *soft_qps_[i];
    soft_used_[i] = 1;
    qp.update(std::nullopt, g_soft_, std::nullopt, std::nullopt, std::nullopt, l_soft_, u_soft_,
              std::nullopt, std::nullopt);
    qp.solve();
    if (qp.results.info.status != pqp::QPSolverOutput::PROXQP_SOLVED) return fail(i, qp.results);
    U.col(i) = qp.results.x.head(Nc);
    slack[i] = std::max(qp.results.x[Nc], 0.0) * k_slack_;
    soft_last_[i] = 1;
    if (soft_shortcut_ && soft_active_set_iter >= 0) {
      soft_guess_from(i, qp.results.x, false);
      soft_settled(i, false, false);
    }
  }
  return true;
}

}  // namespace hmpc
