// The closed loop: see loop.hpp.
#include "hmpc/loop.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

namespace hmpc {

ClosedLoop::ClosedLoop(Plant* p, int n_, const double* t, int K_,
                       std::array<double*, 6> records, std::int64_t* step_ns_,
                       std::int64_t* sat_steps_, double* sat_excess_, const CRefVec& limit_,
                       bool has_limit_, double bound_, double Ts_)
    : plant(p), n(n_), K(K_), t_arr(t), rec(records), step_ns(step_ns_),
      sat_steps(sat_steps_), sat_excess(sat_excess_), limit(limit_), has_limit(has_limit_),
      bound(bound_), Ts(Ts_) {
  if (limit.size() != n) throw std::invalid_argument("ClosedLoop: shapes do not match");
  tau.setZero(n);
  d.setZero(n);
  dh.setZero(n);
}

long ClosedLoop::run(RefVec q, RefVec v, long k0, long k1) {
  if (q.size() != n || v.size() != n || k0 < 0 || k1 > K + 1 || k0 > k1)
    throw std::invalid_argument("ClosedLoop.run: bad state or steps");
  if (!controller) throw std::invalid_argument("ClosedLoop.run: no controller");
  if (!plant) throw std::invalid_argument("ClosedLoop.run: no plant");
  controller->reserve(k1 - k0);  // the chunk's measurements, drawn at once where they may be
  try {
    steps(q, v, k0, k1);
  } catch (...) {
    controller->give_back();
    throw;
  }
  controller->give_back();
  return k == k1 ? k1 : k;
}

void ClosedLoop::steps(RefVec q, RefVec v, long k0, long k1) {
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
    if (!record_and_advance(q, v)) return;
  }
}

// Step k's records, then (k < K) the torque's check and clip and the plant's period; false
// at the last step.
bool ClosedLoop::record_and_advance(RefVec q, RefVec v) {
  const double* t = t_arr;
  d = plant->disturbance_now();  // d(t_k, q, q̇)
  if (d.size() != n) throw std::invalid_argument("the plant's disturbance is not of n values");
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
  plant->advance(tau, qn, vn);
  if (qn.size() != n || vn.size() != n)
    throw std::invalid_argument("the plant's state is not of n values");
  Eigen::Map<Vec> applied(rd, n);  // d as applied at the period's start
  plant->applied_disturbance(applied);
  q = qn;
  v = vn;
  ++advances;
  bool inside = true;
  for (int i = 0; i < n && inside; ++i)
    inside = std::abs(q[i]) <= bound && std::abs(v[i]) <= bound;
  if (!inside) throw StateOutOfBound(q, v, t[k] + Ts, bound);
  return true;
}

}  // namespace hmpc
