// The closed loop: see loop.hpp.
#include "hmpc/loop.hpp"

#include "hmpc/joint_dynamics.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

namespace hmpc {

ClosedLoop::ClosedLoop(RK4* p, int n_, const double* t, int K_,
                       std::array<double*, 6> records, std::int64_t* step_ns_,
                       std::int64_t* sat_steps_, double* sat_excess_, const CRefVec& limit_,
                       bool has_limit_, double bound_, const CRefVec& a, const CRefVec& b,
                       bool friction_, double h_, int substeps_, double Ts_)
    : plant(p), n(n_), K(K_), t_arr(t), rec(records), step_ns(step_ns_),
      sat_steps(sat_steps_), sat_excess(sat_excess_), limit(limit_), fa(a), fb(b),
      has_limit(has_limit_), friction(friction_), bound(bound_), h(h_), substeps(substeps_),
      Ts(Ts_) {
  if ((p && p->n != n) || limit.size() != n ||
      fa.size() != n || fb.size() != n || substeps < 1)
    throw std::invalid_argument("ClosedLoop: shapes do not match");
  tau.setZero(n);
  d.setZero(n);
  dh.setZero(n);
  T.setZero(3 * substeps, n);
}

void ClosedLoop::set_disturbance(Disturbance* d) {
  if (d && friction)
    throw std::invalid_argument("ClosedLoop: a disturbance port and a fused friction");
  disturbance = d;
}

long ClosedLoop::run(RefVec q, RefVec v, long k0, long k1, const CRefRow& P) {
  if (q.size() != n || v.size() != n || k0 < 0 || k1 > K + 1 || k0 > k1)
    throw std::invalid_argument("ClosedLoop.run: bad state or steps");
  if (!controller) throw std::invalid_argument("ClosedLoop.run: no controller");
  if (!plant && !plant_port) throw std::invalid_argument("ClosedLoop.run: no plant");
  if (plant_port && (disturbance || friction || P.rows() > 0))
    throw std::invalid_argument("ClosedLoop.run: a plant port carries its own disturbance");
  const int rows = 3 * substeps;
  if (P.rows() > 0 && disturbance)
    throw std::invalid_argument("ClosedLoop.run: a disturbance port and a table of terms");
  if (P.rows() > 0 && (P.rows() < (k1 - k0) * rows || P.cols() != n))
    throw std::invalid_argument("ClosedLoop.run: the table of time-only terms is too short");
  for (k = k0; k < k1; ++k) {
    if (interrupted) interrupted();
    ++started;
    const auto start = std::chrono::steady_clock::now();
    controller->step(t_arr[k], q, v, tau, dh);
    step_ns[k] = std::chrono::duration_cast<std::chrono::nanoseconds>(
                     std::chrono::steady_clock::now() - start)
                     .count();
    if (tau.size() != n || dh.size() != n)
      throw std::invalid_argument("the controller's torque or estimate is not of n values");
    ++stepped;
    if (!record_and_advance(q, v, P, k - k0)) return k;
  }
  return k1;
}

// Step k's records, then (k < K) the torque's check and clip and the plant's period; false
// at the last step.
bool ClosedLoop::record_and_advance(RefVec q, RefVec v, const CRefRow& P, long j) {
  const double* t = t_arr;
  const int rows = 3 * substeps;
  const bool pulses = P.rows() > 0;
  // d(t_k, q, q̇): the time-only terms at the period's first stage, minus the friction
  if (plant_port) {
    d = plant_port->disturbance_now();
  } else if (disturbance) {
    d = disturbance->at(t[k], Vec(q), Vec(v));
    if (d.size() != n)
      throw std::invalid_argument("the disturbance returned a vector of wrong size");
  } else {
    if (pulses) d = P.row(j * rows).transpose();
    else d.setZero();
    if (friction)
      for (int i = 0; i < n; ++i) d[i] -= joint_torque(fa[i], fb[i], v[i]);
  }
  double* rq = rec[0] + k * n;
  double* rdq = rec[1] + k * n;
  double* rtau = rec[2] + k * n;
  double* rd = rec[3] + k * n;
  double* rdh = rec[4] + k * n;
  for (int i = 0; i < n; ++i) {
    rq[i] = q[i];
    rdq[i] = v[i];
    rtau[i] = tau[i];
    rd[i] = d[i];
    rdh[i] = dh[i];
  }
  last = k;
  if (recorded) recorded(k);
  if (k == K) return false;
  if (!tau.allFinite()) throw NonFinite("tau", {tau}, t[k]);
  if (has_limit) {
    for (int i = 0; i < n; ++i) {
      const double excess = std::abs(tau[i]) - limit[i];
      if (excess > 0.0) {
        ++sat_steps[i];
        sat_excess[i] = std::max(sat_excess[i], excess);
        tau[i] = std::min(std::max(tau[i], -limit[i]), limit[i]);
      }
    }
  }
  double* rap = rec[5] + k * n;
  for (int i = 0; i < n; ++i) rap[i] = tau[i];
  if (plant_port) {
    plant_port->advance(tau, qn, vn);
    if (qn.size() != n || vn.size() != n)
      throw std::invalid_argument("the plant's state is not of n values");
    q = qn;
    v = vn;
  } else if (disturbance) {
    plant->period_with(q, v, tau, t[k], h, substeps,
                       [this](double ts, const Vec& qs, const Vec& vs) {
                         return disturbance->at(ts, qs, vs);
                       });
  } else {
    for (int r = 0; r < rows; ++r) {
      if (pulses) T.row(r) = tau.transpose() + P.row(j * rows + r);
      else T.row(r) = tau.transpose();
    }
    plant->period(q, v, T, fa, fb, friction, h);
  }
  ++advances;
  bool inside = true;
  for (int i = 0; i < n && inside; ++i)
    inside = std::abs(q[i]) <= bound && std::abs(v[i]) <= bound;
  if (!inside) throw StateOutOfBound(q, v, t[k] + Ts, bound);
  return true;
}

}  // namespace hmpc
