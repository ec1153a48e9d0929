// The RK4 plant as a Plant port: see rk4_plant.hpp.
#include "hmpc/rk4_plant.hpp"

#include "hmpc/joint_dynamics.hpp"

#include <stdexcept>
#include <utility>

namespace hmpc {

RK4Plant::RK4Plant(std::shared_ptr<RK4> r, double Ts_, int substeps_)
    : rk4(std::move(r)), n(rk4 ? rk4->n : 0), substeps(substeps_), Ts(Ts_),
      h(Ts_ / substeps_) {
  if (!rk4 || substeps < 1 || !(Ts > 0.0))
    throw std::invalid_argument("RK4Plant: shapes do not match");
  q.setZero(n);
  v.setZero(n);
  a.setZero(n);
  b.setZero(n);
  T.setZero(3 * substeps, n);
  P.setZero(3 * substeps, n);
  part.setZero(3 * substeps, n);
  times.setZero(3 * substeps);
}

void RK4Plant::reset(const CRefVec& q0, const CRefVec& dq0, double t0_) {
  if (q0.size() != n || dq0.size() != n)
    throw std::invalid_argument("RK4Plant.reset: the state is not of n values");
  q = q0;
  v = dq0;
  t0 = t0_;
  k = 0;
  rows_k = -1;
}

void RK4Plant::set_disturbance(Disturbance* d) {
  std::vector<Disturbance*> terms = d ? d->terms() : std::vector<Disturbance*>{};
  std::vector<Disturbance*> fused_terms;
  Vec ta, tb, sa = Vec::Zero(n), sb = Vec::Zero(n);
  int frictions = 0;
  bool fusable = true;
  for (Disturbance* term : terms) {
    const auto kind = term->kind();
    if (kind == Disturbance::Kind::friction) {
      term->coefficients(ta, tb);
      if (ta.size() != n || tb.size() != n)
        throw std::invalid_argument("RK4Plant: a friction's coefficients are not of n values");
      sa += ta;
      sb += tb;
      ++frictions;
    } else if (kind == Disturbance::Kind::time_only) {
      fused_terms.push_back(term);
    } else {
      fusable = false;
    }
  }
  fusable = fusable && frictions <= 1;
  general = fusable ? nullptr : d;
  time_only = fusable ? std::move(fused_terms) : std::vector<Disturbance*>{};
  friction = fusable && frictions == 1;
  a = friction ? sa : Vec::Zero(n);
  b = friction ? sb : Vec::Zero(n);
  // a friction inside a disturbance called per stage follows the fused one's law
  rk4->set_friction_in_disturbance(fusable ? Vec::Zero(n) : sa, fusable ? Vec::Zero(n) : sb);
  rows_k = -1;
}

void RK4Plant::stage_rows() {
  if (rows_k == k) return;
  const int S = substeps;
  const double t = this->t();
  for (int s = 0; s < S; ++s) {
    const double ts = t + s * h;
    times[s] = ts;
    times[S + s] = ts + 0.5 * h;
    times[2 * S + s] = ts + h;
  }
  for (std::size_t i = 0; i < time_only.size(); ++i) {
    RowMat& out = i == 0 ? P : part;
    time_only[i]->at_times(times, out);
    if (i > 0) P += part;
  }
  rows_k = k;
}

void RK4Plant::advance(const Vec& tau, Vec& q_out, Vec& dq_out) {
  if (tau.size() != n) throw std::invalid_argument("RK4Plant.advance: τ is not of n values");
  if (general) {
    rk4->period_with(q, v, tau, t(), h, substeps,
                     [this](double ts, const Vec& qs, const Vec& vs) {
                       return general->at(ts, qs, vs);
                     });
  } else {
    const long rows = 3L * substeps;
    if (time_only.empty()) {
      for (long r = 0; r < rows; ++r) T.row(r) = tau.transpose();
    } else {
      stage_rows();
      for (long r = 0; r < rows; ++r) T.row(r) = tau.transpose() + P.row(r);
    }
    rk4->period(q, v, T, a, b, friction, h);
  }
  ++k;
  q_out = q;
  dq_out = v;
}

Vec RK4Plant::disturbance_now() {
  if (general) {
    Vec d = general->at(t(), q, v);
    if (d.size() != n)
      throw std::invalid_argument("the disturbance returned a vector of wrong size");
    return d;
  }
  Vec d = Vec::Zero(n);
  if (!time_only.empty()) {
    stage_rows();
    d = P.row(0).transpose();
  }
  if (friction)
    for (int i = 0; i < n; ++i) d[i] -= joint_torque(a[i], b[i], v[i]);
  return d;
}

void RK4Plant::applied_disturbance(RefVec d) {
  if (d.size() != n)
    throw std::invalid_argument("RK4Plant.applied_disturbance: d is not of n values");
  for (int i = 0; i < n; ++i)
    if (rk4->start_rest[i]) d[i] += rk4->start_coulomb[i];
}

}  // namespace hmpc
