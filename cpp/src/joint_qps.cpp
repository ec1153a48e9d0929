// The per-joint MPC's QPs, composed of their parts: see joint_qps.hpp.
#include "hmpc/joint_qps.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace hmpc {

namespace pqp = proxsuite::proxqp;

JointQPs::JointQPs(int n_, int N_, int Nc_, bool block_, const CRefMat& H, const CRefVec& v_min,
                   const CRefVec& v_max, const Settings& warm, const Settings& cold)
    : n(n_), N(N_), Nc(Nc_), block(block_), U(RowMat::Zero(Nc_, n_)), slack(Vec::Zero(n_)),
      H_(H), v_min_(v_min), v_max_(v_max), warm_(warm), cold_(cold) {
  if (H.rows() != Nc || H.cols() != Nc || v_min.size() != n || v_max.size() != n)
    throw std::invalid_argument("JointQPs: H must be (Nc, Nc) and v_min, v_max (n,)");
  if ((v_min.array() > v_max.array()).any())
    throw std::invalid_argument("JointQPs: v_min > v_max for some joint");
  g_.setZero(Nc);
  if (block) {
    H_block_ = Mat::Zero(n * Nc, n * Nc);
    Vec lo(n * Nc), hi(n * Nc);
    for (int i = 0; i < n; ++i) {
      H_block_.block(i * Nc, i * Nc, Nc, Nc) = H_;
      lo.segment(i * Nc, Nc).setConstant(v_min_[i]);
      hi.segment(i * Nc, Nc).setConstant(v_max_[i]);
    }
    g_block_.setZero(n * Nc);
    boxes_.emplace_back(std::make_unique<BoxQP>(H_block_, lo, hi, warm_, cold_));
  } else {
    active_set_ = std::make_unique<BoxActiveSet>(H_);
    if (Nc == 1) neg_hinv1_ = active_set_->unconstrained(Vec::Ones(1))[0];  // 0 + 1·(h·1)
    u1_.setZero(1);
    for (int i = 0; i < n; ++i)
      boxes_.emplace_back(std::make_unique<BoxQP>(H_, Vec::Constant(Nc, v_min_[i]),
                                                  Vec::Constant(Nc, v_max_[i]), warm_, cold_));
  }
}

// A new run: the QPs as new, no remembered active set or warm start (a run does not depend
// on the runs before it: the same states give the same answers, bit for bit, as a new
// JointQPs), no slack.
void JointQPs::restart() {
  for (auto& box : boxes_) box->restart();
  if (soft_) soft_->restart();
  slack.setZero();
  stats.constrained_last = false;
  stats.constrained = 0;
}

void JointQPs::save(Memory& m) const {
  m.boxes.clear();
  for (const auto& box : boxes_) m.boxes.push_back(box->results());
  if (soft_) soft_->save(m.soft);
}

void JointQPs::restore(const Memory& m) {
  for (std::size_t i = 0; i < boxes_.size() && i < m.boxes.size(); ++i)
    boxes_[i]->set_results(m.boxes[i]);
  if (soft_ && !m.soft.last.empty()) soft_->restore(m.soft);
}

void JointQPs::set_limits(const CRefMat& Phi, const CRefMat& Gamma, const CRefVec& lower,
                          const CRefVec& upper, const CRefVec& vel, const CRefMat& Hs,
                          const CRefMat& C, const CRefVec& row_scale, double g_slack,
                          double k_slack, const Settings& soft, bool always, const CRefMat& T,
                          const CRefMat& E, const CRefMat& Hp) {
  soft_.reset();
  options.always_constrained = always;
  soft_ = std::make_unique<SoftLimits>(n, N, Nc, H_, v_min_, v_max_, Phi, Gamma, lower, upper,
                                       vel, Hs, C, row_scale, g_slack, k_slack, soft, T, E, Hp,
                                       &stats);
}

void JointQPs::set_max_iter(long max_iter) {
  warm_.max_iter = cold_.max_iter = max_iter;
  for (auto& box : boxes_) box->set_max_iter(max_iter);
  if (soft_) soft_->set_max_iter(max_iter);
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

// Joint i's box QP for the gradient g_ ("joint" layout): the exact shortcuts (BoxActiveSet),
// then ProxSuite (BoxQP); its solution in U.col(i). False when ProxSuite did not report
// solved.
bool JointQPs::box_joint(int i) {
  BoxQP& box = *boxes_[i];
  if (options.shortcut && Nc == 1) {
    // Nc = 1: the unconstrained minimiser −H⁻¹g as BoxActiveSet::unconstrained forms it
    // (0 + 1·(h g), h its −H⁻¹), without its product's dispatch; outside the box, on below.
    const double u = 0.0 + neg_hinv1_ * g_[0];
    if (u >= v_min_[i] && u <= v_max_[i]) {
      U(0, i) = u;
      u1_[0] = u;
      box.remember(0, u1_, nullptr);
      ++stats.unconstrained_solves;
      return true;
    }
  }
  if (options.shortcut) {
    const Vec& u = active_set_->unconstrained(g_);
    if ((u.array() >= v_min_[i]).all() && (u.array() <= v_max_[i]).all()) {
      U.col(i) = u;
      box.remember(0, u, nullptr);
      ++stats.unconstrained_solves;
      return true;
    }
    if (active_set_->solve(g_, v_min_[i], v_max_[i], box.x(), options.active_set_iter,
                           warm_.eps_abs)) {
      box.remember(0, active_set_->u(), &active_set_->z());
      U.col(i) = active_set_->u();
      ++stats.active_set_solves;
      return true;
    }
  }
  bool cold = false;
  const Results* res = box.solve(g_, options.shift ? Nc : 0, cold);
  if (!res) return fail(i, box.failed());
  if (cold) ++stats.cold_solves;
  U.col(i) = res->x;
  return true;
}

bool JointQPs::solve(const CRefRow& G, const CRefVec& q, const CRefVec& dq) {
  if (G.rows() != n || G.cols() != Nc || q.size() != n || dq.size() != n)
    throw std::invalid_argument("JointQPs.solve: G must be (n, Nc) and q, dq (n,)");
  if (block) {
    for (int i = 0; i < n; ++i) g_block_.segment(i * Nc, Nc) = G.row(i).transpose();
    bool cold = false;
    const Results* res = boxes_[0]->solve(g_block_, options.shift ? Nc : 0, cold);
    if (!res) return fail(-1, boxes_[0]->failed());
    if (cold) ++stats.cold_solves;
    for (int i = 0; i < n; ++i) U.col(i) = res->x.segment(i * Nc, Nc);
  } else {
    for (int i = 0; i < n; ++i) {
      g_ = G.row(i).transpose();
      // A joint whose soft QP was answered at the last step with a state limit or the
      // slack active goes straight to its soft QP (enforce_limits): its box QP's answer
      // would only be tested against the limits and, most likely leaving them, discarded.
      if (soft_) {
        soft_->next[i] = soft_->shortcut() && options.soft_active_set_iter >= 0 &&
                         soft_->last[i] && soft_->active[i];
        if (soft_->next[i]) continue;
      }
      if (!box_joint(i)) return false;
    }
  }
  stats.constrained = 0;
  if (soft_ && !enforce_limits(G, q, dq)) return false;
  return true;
}

// Joint i's soft QP (its box-only prediction leaves the limits): the soft shortcut, else
// ProxSuite. False when ProxSuite did not report solved.
bool JointQPs::soft_joint(int i, const CRefRow& G, const CRefVec& q, const CRefVec& dq) {
  SoftLimits& soft = *soft_;
  stats.constrained_last = true;
  soft.prepare(i, G, q, dq);
  ++stats.constrained;
  if (soft.active_set(i, U.col(i), options.soft_active_set_iter)) {
    U.col(i) = soft.y().head(Nc);
    slack[i] = soft.y()[Nc] * soft.k_slack();
    ++stats.soft_active_set_solves;
    soft.last[i] = 1;
    soft.settled(i, soft.binding(), soft.continued());
    return true;
  }
  if (soft.stopped()) {
    // Out of this step's exchanges: the safe fallback; the next step resumes them.
    soft.fallback(i, U(0, i));
    slack[i] = 0.0;
    ++stats.soft_fallbacks;
    soft.last[i] = 1;
    soft.settled(i, false, false);
    return true;
  }
  const Results& res = soft.proxsuite(i, options.soft_active_set_iter);
  if (res.info.status != pqp::QPSolverOutput::PROXQP_SOLVED) return fail(i, res);
  U.col(i) = res.x.head(Nc);
  slack[i] = std::max(res.x[Nc], 0.0) * soft.k_slack();
  soft.last[i] = 1;
  return true;
}

// Whether joint i's box-only prediction (U.col(i)) leaves the limits: the O(1) reach
// bound first (options.soft_reach_test), the O(N) test where it cannot tell.
bool JointQPs::leaves(int i, double q, double dq) {
  if (options.soft_reach_test && soft_->inside(i, q, dq, U.col(i))) {
    ++stats.soft_reach_inside;
    return false;
  }
  return soft_->leaves(i, q, dq, U.col(i));
}

// Re-solve with the soft state constraints the joints whose box-only prediction leaves the
// limits (every joint when always_constrained).
bool JointQPs::enforce_limits(const CRefRow& G, const CRefVec& q, const CRefVec& dq) {
  SoftLimits& soft = *soft_;
  if (stats.constrained_last) {
    slack.setZero();
    stats.constrained_last = false;
  }
  // The step's soft exchanges (options.soft_step_exchanges, else soft_step_work / N; < 0:
  // no bound), spread over the joints whose soft QP this step solves: each joint's share
  // the exchanges left divided by the joints left (rounded up; at least `least` below),
  // what it leaves to the next.
  long left = options.soft_step_exchanges >= 0 ? options.soft_step_exchanges
              : options.soft_step_work >= 0   ? std::max(1L, options.soft_step_work / N)
                                              : -1L;
  int joints_left = 0;
  soft.set_budget(-1);
  if (left >= 0)
    for (int i = 0; i < n; ++i)
      joints_left += soft.next[i] || options.always_constrained ||
                     leaves(i, q[i], dq[i]);
  bool counted = false;  // joint i counted out of joints_left
  // At least a guess's own exchanges (soft_active_set_iter) while the step has them: fewer
  // rarely answer at an activation, and all the joints then fell back (measured, Panda).
  const long least = std::max(options.soft_active_set_iter, 1);
  auto share = [&]() {
    if (left < 0) return;
    if (!counted) counted = true, joints_left = std::max(joints_left - 1, 0);
    soft.set_budget(std::max((left + joints_left) / (joints_left + 1), std::min(left, least)));
  };
  auto spent = [&](long given) {
    if (left >= 0) left -= given - soft.budget();
  };
  for (int i = 0; i < n; ++i) {
    counted = false;
    if (soft.next[i]) {
      share();
      const long given = soft.budget();
      // Box QP skipped (solve): the soft shortcut from the last step's active set; answered
      // with the limits binding, the joint is constrained (its box solution, differing from
      // this one, leaves the limits); answered without, this is the box QP's solution, the
      // joint unconstrained. Not answered: the box QP now, and on as without the skip.
      soft.prepare(i, G, q, dq);
      const bool answered = soft.active_set(i, U.col(i), options.soft_active_set_iter);
      spent(given);
      if (answered) {
        U.col(i) = soft.y().head(Nc);
        slack[i] = soft.y()[Nc] * soft.k_slack();
        soft.settled(i, soft.binding(), soft.continued());
        boxes_[i]->remember(0, U.col(i), nullptr);  // the box QP's next warm start
        if (soft.binding()) {
          stats.constrained_last = true;
          ++stats.constrained;
          ++stats.soft_active_set_solves;
        } else {
          soft.last[i] = 0;
        }
        continue;
      }
      if (soft.stopped()) {
        // Out of this step's exchanges: the box QP's answer, exact when it keeps inside the
        // limits, else made safe (the fallback; the next step resumes the exchanges).
        g_ = G.row(i).transpose();
        if (!box_joint(i)) return false;
        if (!(options.always_constrained || leaves(i, q[i], dq[i]))) {
          soft.last[i] = 0;
          continue;
        }
        soft.fallback(i, U(0, i));
        slack[i] = 0.0;
        ++stats.soft_fallbacks;
        ++stats.constrained;
        stats.constrained_last = true;
        soft.settled(i, false, false);
        continue;
      }
      soft.last[i] = 0;  // its active set failed here: a new activation's guess, if any
      g_ = G.row(i).transpose();
      if (!box_joint(i)) return false;
    }
    if (!(options.always_constrained || leaves(i, q[i], dq[i]))) {
      soft.last[i] = 0;
      continue;
    }
    share();
    const long given = soft.budget();
    const bool ok = soft_joint(i, G, q, dq);
    spent(given);
    if (!ok) return false;
  }
  return true;
}

}  // namespace hmpc
