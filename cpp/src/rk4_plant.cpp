// The RK4 plant as a Plant port: see rk4_plant.hpp.
#include "hmpc/rk4_plant.hpp"

#include "hmpc/joint_dynamics.hpp"

#include <stdexcept>
#include <string>
#include <utility>

namespace hmpc {

RK4Plant::RK4Plant(std::shared_ptr<RK4> r, double Ts_, int substeps_, const CRefVec& a_,
                   const CRefVec& b_, bool friction_)
    : rk4(std::move(r)), n(rk4 ? rk4->n : 0), substeps(substeps_), Ts(Ts_),
      h(Ts_ / substeps_), a(a_), b(b_), friction(friction_) {
  if (!rk4 || substeps < 1 || !(Ts > 0.0) || a.size() != n || b.size() != n)
    throw std::invalid_argument("RK4Plant: shapes do not match");
  q.setZero(n);
  v.setZero(n);
  T.setZero(3 * substeps, n);
}

void RK4Plant::reset(const CRefVec& q0, const CRefVec& dq0, double t0_) {
  if (q0.size() != n || dq0.size() != n)
    throw std::invalid_argument("RK4Plant.reset: the state is not of n values");
  q = q0;
  v = dq0;
  t0 = t0_;
  k = 0;
  table.resize(0, n);
  table_k0 = 0;
}

void RK4Plant::set_table(const CRefRow& P, long k0) {
  const long rows = 3L * substeps;
  if (P.cols() != n || P.rows() % rows != 0 || k0 < 0)
    throw std::invalid_argument("RK4Plant.set_table: rows of 3·substeps per period, n columns");
  if (disturbance)
    throw std::invalid_argument("RK4Plant.set_table: a disturbance port and a table of terms");
  table = P;
  table_k0 = k0;
}

long RK4Plant::table_end() const {
  return table_k0 + static_cast<long>(table.rows()) / (3L * substeps);
}

void RK4Plant::set_disturbance(Disturbance* d) {
  if (d && (friction || table.rows() > 0))
    throw std::invalid_argument("RK4Plant: a disturbance port and a fused disturbance");
  disturbance = d;
}

const RowMat* RK4Plant::rows_of(long period) const {
  if (table.rows() == 0) return nullptr;
  if (period < table_k0 || period >= table_end())
    throw std::out_of_range("RK4Plant: the table of time-only terms does not cover period " +
                            std::to_string(period));
  return &table;
}

void RK4Plant::advance(const Vec& tau, Vec& q_out, Vec& dq_out) {
  if (tau.size() != n) throw std::invalid_argument("RK4Plant.advance: τ is not of n values");
  if (disturbance) {
    rk4->period_with(q, v, tau, t(), h, substeps,
                     [this](double ts, const Vec& qs, const Vec& vs) {
                       return disturbance->at(ts, qs, vs);
                     });
  } else {
    const RowMat* P = rows_of(k);
    const long rows = 3L * substeps, first = (k - table_k0) * rows;
    for (long r = 0; r < rows; ++r) {
      if (P) T.row(r) = tau.transpose() + P->row(first + r);
      else T.row(r) = tau.transpose();
    }
    rk4->period(q, v, T, a, b, friction, h);
  }
  ++k;
  q_out = q;
  dq_out = v;
}

Vec RK4Plant::disturbance_now() {
  if (disturbance) {
    Vec d = disturbance->at(t(), q, v);
    if (d.size() != n)
      throw std::invalid_argument("the disturbance returned a vector of wrong size");
    return d;
  }
  Vec d(n);
  const RowMat* P = rows_of(k);
  if (P) d = P->row((k - table_k0) * 3L * substeps).transpose();
  else d.setZero();
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
