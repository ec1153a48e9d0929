// The soft state limits' QPs by ProxSuite and the limit test: see soft_limits.hpp (the
// shortcut: soft_active_set.cpp).
#include "hmpc/soft_limits.hpp"

#include <proxsuite/proxqp/dense/dense.hpp>

#include <algorithm>
#include <cmath>
#include <optional>
#include <stdexcept>

namespace hmpc {

SoftLimits::SoftLimits(int n, int N, int Nc, const Mat& H, const Vec& v_min, const Vec& v_max,
                       const CRefMat& Phi, const CRefMat& Gamma, const CRefVec& lower,
                       const CRefVec& upper, const CRefVec& vel, const CRefMat& Hs,
                       const CRefMat& C, const CRefVec& row_scale, double g_slack,
                       double k_slack, const QPSettings& soft, const CRefMat& T,
                       const CRefMat& E, const CRefMat& Hp, JointQPsStats* stats)
    : n_(n), N_(N), Nc_(Nc), H_(H), Phi_(Phi), Gamma_(Gamma), Hs_(Hs), C_(C), v_min_(v_min),
      v_max_(v_max), lower_(lower), upper_(upper), vel_(vel), row_scale_(row_scale),
      g_slack_(g_slack), k_slack_(k_slack), soft_(soft), stats_(stats) {
  if (Phi.rows() != 2 * N || Phi.cols() != 2 || Gamma.rows() != 2 * N || Gamma.cols() != Nc ||
      lower.size() != n || upper.size() != n || vel.size() != n || Hs.rows() != Nc + 1 ||
      Hs.cols() != Nc + 1 || C.rows() != 4 * N || C.cols() != Nc + 1 || row_scale.size() != 4 * N)
    throw std::invalid_argument("JointQPs.set_limits: shapes do not match the horizon");
  mid_ = 0.5 * (lower_ + upper_);
  half_ = 0.5 * (upper_ - lower_);
  {  // inside()'s constants: A^j and the sums of |A^k B| along the horizon
    const double a00 = Phi_(0, 0), a01 = Phi_(0, 1), a10 = Phi_(1, 0), a11 = Phi_(1, 1);
    double p00 = 1.0, p01 = 0.0, p10 = 0.0, p11 = 1.0;  // A^j
    double s0 = 0.0, s1 = 0.0;                          // Σ_{k<j} |(A^k B)|
    for (int j = 1; j <= N; ++j) {
      // (A^(j−1) B) adds to the sums of x_j
      s0 += std::abs(p00 * Gamma_(0, 0) + p01 * Gamma_(1, 0));
      s1 += std::abs(p10 * Gamma_(0, 0) + p11 * Gamma_(1, 0));
      const double n00 = a00 * p00 + a01 * p10, n01 = a00 * p01 + a01 * p11;
      const double n10 = a10 * p00 + a11 * p10, n11 = a10 * p01 + a11 * p11;
      p00 = n00, p01 = n01, p10 = n10, p11 = n11;
      reach_[0] = std::max(reach_[0], std::abs(p00));
      reach_[1] = std::max(reach_[1], std::abs(p00 - 1.0));
      reach_[2] = std::max(reach_[2], std::abs(p01));
      reach_[3] = std::max(reach_[3], s0);
      reach_[4] = std::max(reach_[4], std::abs(p10));
      reach_[5] = std::max(reach_[5], std::abs(p11));
      reach_[7] = std::max(reach_[7], s1);
    }
  }
  p_.g.setZero(Nc + 1);
  l_soft_.setZero(4 * N);
  u_soft_.setZero(4 * N);
  q_free_.setZero(N);
  v_free_.setZero(N);
  qps_.resize(n);
  used_.assign(n, 0);
  for (int i = 0; i < n; ++i) make_qp(i);
  last.assign(n, 0);
  next.assign(n, 0);
  active.assign(n, 0);
  if (T.size() == 0) return;
  if (T.rows() != Nc || T.cols() != Nc || E.rows() != 2 * N || E.cols() != Nc ||
      Hp.rows() != Nc || Hp.cols() != Nc)
    throw std::invalid_argument("JointQPs.set_limits: T, Hp must be (Nc, Nc) and E (2N, Nc)");
  kkt_ = std::make_unique<BandedKKT>(T, E, Hp, H_, gamma_, row_scale_, k_slack_, Hs_(Nc, Nc),
                                     soft_.eps_abs);
  guess_rows_.assign(n, std::vector<signed char>(2 * N, 0));
  guess_box_.assign(n, std::vector<signed char>(Nc, 0));
  guess_slack_.assign(n, 0);
  has_guess_.assign(n, 0);
  last_q_.setZero(n);
  last_v_.setZero(n);
  last_u0_.setZero(n);
  shifted_first_.assign(n, -1);
  resume_.assign(n, 0);
  spent_.assign(n, 0);
  res_rows_.assign(n, std::vector<signed char>(2 * N, 0));
  ans_rows_.assign(n, std::vector<signed char>(2 * N, 0));
  res_box_.assign(n, std::vector<signed char>(Nc, 0));
  ans_box_.assign(n, std::vector<signed char>(Nc, 0));
  res_slack_.assign(n, 0);
  ans_slack_.assign(n, 0);
  st_.rows.assign(2 * N, 0);
  st_.box.assign(Nc, 0);
  p_.gp.setZero(Nc);
  p_.bnd_lo.setZero(2 * N);
  p_.bnd_hi.setZero(2 * N);
  box_y_.setZero(Nc + 1);
  rU_.setZero(Nc);
  gl_.setZero(Nc);
  Xs_.setZero(2 * N);
  gamma_.set(Phi_, Gamma_);
  gamma_nonneg_ = (Gamma_.array() >= 0.0).all();
  shortcut_ = true;
}

SoftLimits::~SoftLimits() = default;

// Joint i's soft QP as new: initialised with its rows at x0 = 0 and solved once at g = 0
// (ŝ's gradient g_slack); the gradient p_.g kept, l_soft_ and u_soft_ overwritten.
void SoftLimits::make_qp(int i) {
  const int Nc = Nc_, N = N_;
  auto& qp = qps_[i];
  const Vec g = p_.g;
  qp = std::make_unique<DenseQP>(Nc + 1, 0, 4 * N, true);
  soft_.apply(qp->settings);
  p_.g.head(Nc).setZero();
  p_.g[Nc] = g_slack_;
  bounds(i, Vec::Zero(N), Vec::Zero(N));
  Vec lo(Nc + 1), hi(Nc + 1);
  lo.head(Nc).setConstant(v_min_[i]);
  hi.head(Nc).setConstant(v_max_[i]);
  lo[Nc] = 0.0;
  hi[Nc] = BIG;
  qp->init(Hs_, p_.g, std::nullopt, std::nullopt, C_, l_soft_, u_soft_, lo, hi);
  qp->solve();
  p_.g = g;
  used_[i] = 0;
}

void SoftLimits::restart() {
  // The soft QPs ProxSuite solved in the last run made again (their init factorises a KKT
  // matrix of Nc + 1 + 4N rows, about 18 ms at N = 100: here, never in a step).
  for (int i = 0; i < n_; ++i)
    if (used_[i]) make_qp(i);
  std::fill(has_guess_.begin(), has_guess_.end(), 0);
  std::fill(shifted_first_.begin(), shifted_first_.end(), -1);
  std::fill(resume_.begin(), resume_.end(), 0);
  std::fill(last.begin(), last.end(), 0);
  std::fill(active.begin(), active.end(), 0);  // no box QP skipped at the start
  std::fill(next.begin(), next.end(), 0);
}

void SoftLimits::save(Memory& m) const {
  m.last = last;
  m.next = next;
  m.active = active;
  m.guess_slack = guess_slack_;
  m.has_guess = has_guess_;
  m.shifted_first = shifted_first_;
  m.resume = resume_;
  m.used = used_;
  m.guess_rows = guess_rows_;
  m.guess_box = guess_box_;
  m.res_rows = res_rows_;
  m.res_box = res_box_;
  m.ans_rows = ans_rows_;
  m.ans_box = ans_box_;
  m.res_slack = res_slack_;
  m.ans_slack = ans_slack_;
  m.spent = spent_;
  m.last_q = last_q_;
  m.last_v = last_v_;
  m.last_u0 = last_u0_;
  m.qps.clear();
  for (const auto& qp : qps_) m.qps.push_back(qp->results);
}

void SoftLimits::restore(const Memory& m) {
  last = m.last;
  next = m.next;
  active = m.active;
  guess_slack_ = m.guess_slack;
  has_guess_ = m.has_guess;
  shifted_first_ = m.shifted_first;
  resume_ = m.resume;
  used_ = m.used;
  guess_rows_ = m.guess_rows;
  guess_box_ = m.guess_box;
  res_rows_ = m.res_rows;
  res_box_ = m.res_box;
  ans_rows_ = m.ans_rows;
  ans_box_ = m.ans_box;
  res_slack_ = m.res_slack;
  ans_slack_ = m.ans_slack;
  spent_ = m.spent;
  last_q_ = m.last_q;
  last_v_ = m.last_v;
  last_u0_ = m.last_u0;
  for (std::size_t i = 0; i < qps_.size() && i < m.qps.size(); ++i) qps_[i]->results = m.qps[i];
}

void SoftLimits::set_max_iter(long max_iter) {
  soft_.max_iter = max_iter;
  for (auto& qp : qps_)
    if (qp) qp->settings.max_iter = max_iter;
}

// Row bounds of joint i's soft QP for the free responses of q and q̇.
void SoftLimits::bounds(int i, const Vec& q_free, const Vec& v_free) {
  const int N = N_;
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

void SoftLimits::prepare(int i, const CRefRow& G, const CRefVec& q, const CRefVec& dq) {
  for (int j = 0; j < N_; ++j) {
    q_free_[j] = Phi_(2 * j, 0) * q[i] + Phi_(2 * j, 1) * dq[i];
    v_free_[j] = Phi_(2 * j + 1, 0) * q[i] + Phi_(2 * j + 1, 1) * dq[i];
  }
  p_.g.head(Nc_) = G.row(i).transpose();
  p_.g[Nc_] = g_slack_;
  q_ = q[i];
  dq_ = dq[i];
}

void SoftLimits::fallback(int i, double& u0) const {
  const double a00 = Phi_(0, 0), a01 = Phi_(0, 1), a10 = Phi_(1, 0), a11 = Phi_(1, 1);
  const double b0 = Gamma_(0, 0), b1 = Gamma_(1, 0);  // both > 0
  const double q1 = a00 * q_ + a01 * dq_, v1 = a10 * q_ + a11 * dq_;  // x1 at u0 = 0
  const double vlo = (-vel_[i] - v1) / b1, vhi = (vel_[i] - v1) / b1;
  double lo = std::max(vlo, (lower_[i] - q1) / b0), hi = std::min(vhi, (upper_[i] - q1) / b0);
  if (lo > hi) lo = vlo, hi = vhi;  // the velocity limit's alone
  // Into the limits' interval, then the box: where they meet, into both; else the box's
  // end nearest the interval (not the box-only answer, which may drive further out).
  u0 = std::min(std::max(u0, lo), hi);
  u0 = std::min(std::max(u0, v_min_[i]), v_max_[i]);
}

const SoftLimits::Results& SoftLimits::proxsuite(int i, int iter) {
  bounds(i, q_free_, v_free_);
  DenseQP& qp = *qps_[i];
  used_[i] = 1;
  qp.update(std::nullopt, p_.g, std::nullopt, std::nullopt, std::nullopt, l_soft_, u_soft_,
            std::nullopt, std::nullopt);
  qp.solve();
  if (qp.results.info.status != proxsuite::proxqp::QPSolverOutput::PROXQP_SOLVED)
    return qp.results;
  if (shortcut_ && iter >= 0) {
    guess_from(i, qp.results.x, false);
    ans_rows_[i] = guess_rows_[i];
    ans_box_[i] = guess_box_[i];
    ans_slack_[i] = guess_slack_[i];
    remember_state(i, qp.results.x[0]);
    shifted_first_[i] = -1;
    settled(i, false, false);
  }
  return qp.results;
}

}  // namespace hmpc
