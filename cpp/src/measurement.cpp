// The compiled Measurement: see measurement.hpp.
#include "hmpc/measurement.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

namespace hmpc {

SensingMeasurement::SensingMeasurement(const SensingSettings& settings, NormalSource source)
    : s(settings), normals(std::move(source)) {
  if (s.delay < 0 || s.keep < 1 || s.ticks < 1 || (!s.exact && !(s.Ts > 0.0 && s.Tif > 0.0)))
    throw std::invalid_argument(
        "SensingMeasurement: expected delay >= 0, keep >= 1, ticks >= 1, Ts > 0, Tif > 0");
}

long SensingMeasurement::slot(long j) const {
  const long len = k - k0 + 1;
  const long i = std::min(std::max(j - k0, 0L), len - 1);
  return (k0 + i) % s.keep;
}

void SensingMeasurement::reset(const CRefVec& q0, const CRefVec& dq0) {
  n = static_cast<int>(q0.size());
  if (dq0.size() != n) throw std::invalid_argument("SensingMeasurement: q0 and dq0 differ");
  if (s.encoder && s.encoder_step.size() != 1 && s.encoder_step.size() != n)
    throw std::invalid_argument("SensingMeasurement: one encoder step or one per joint");
  const auto D = static_cast<std::size_t>(s.delay) + 1;
  bq.assign(D, Vec::Zero(n));
  bv.assign(D, Vec::Zero(n));
  z.setZero(2 * n);
  k = k0 = 0;
  if (s.exact) {
    qx = q0;
    dqx = dq0;
  } else {
    hq.assign(static_cast<std::size_t>(s.keep), Vec::Zero(n));
    hv.assign(static_cast<std::size_t>(s.keep), Vec::Zero(n));
    hq[0] = q0;
    hv[0] = dq0;
    has_prev = false;
    dqfilt = dq0;
    qr.setZero(n);
    dr.setZero(n);
    qa.setZero(n);
  }
  tau_started = false;
  take();
}

void SensingMeasurement::measure(double, const CRefVec& q, const CRefVec& dq) {
  if (q.size() != n || dq.size() != n)
    throw std::invalid_argument("SensingMeasurement.measure: the state has another size "
                                "than at reset");
  if (s.exact) {
    qx = q;
    dqx = dq;
  } else {  // push the state of t_{k+1}, dropping the oldest kept one when full
    if (k - k0 + 1 == s.keep) ++k0;
    const auto j = static_cast<std::size_t>((k + 1) % s.keep);
    hq[j] = q;
    hv[j] = dq;
  }
  ++k;
  take();
}

void SensingMeasurement::take() {
  const auto at = static_cast<std::size_t>(k % (s.delay + 1));
  Vec& q = bq[at];
  Vec& v = bv[at];
  if (s.exact) {
    q = qx;
    v = dqx;
  } else {
    const double t_now = static_cast<double>(k) * s.Ts;
    const double t_meas = t_now - s.latency;
    const int count = k == 0 ? 1 : s.ticks;
    for (int i = count - 1; i >= 0; --i) sample(t_meas - static_cast<double>(i) * s.Tif);
    q = qr;
    v = dr;
  }
  if (s.exact || s.q_noise != 0.0 || s.dq_noise != 0.0) {
    if (!normals) throw std::invalid_argument("SensingMeasurement: noise without a source");
    normals(z.data(), 2 * n);
    for (int i = 0; i < n; ++i) {
      q[i] = q[i] + s.q_noise * z[i];
      v[i] = v[i] + s.dq_noise * z[n + i];
    }
  }
  const auto out = static_cast<std::size_t>((k > s.delay ? k - s.delay : 0) % (s.delay + 1));
  qm = bq[out];
  dqm = bv[out];
}

void SensingMeasurement::sample(double t) {
  angle(t, qa);
  if (s.encoder) {
    const bool one = s.encoder_step.size() == 1;
    for (int i = 0; i < n; ++i) {
      const double step = s.encoder_step[one ? 0 : i];
      qr[i] = step == 0.0 ? qa[i] : step * std::nearbyint(qa[i] / step);
    }
  } else {
    qr = qa;
  }
  if (!s.finite_difference) {
    velocity(t, dr);
    return;
  }
  if (!has_prev) {  // the first sample: no difference yet
    velocity(t, dr);
    dqfilt = dr;
  } else {
    const double a = s.velocity_gain;
    const double b = 1.0 - a;
    for (int i = 0; i < n; ++i) {
      const double x = (qr[i] - qprev[i]) / s.Tif;
      dr[i] = a * x + b * dqfilt[i];
    }
    dqfilt = dr;
  }
  qprev = qr;
  has_prev = true;
}

// The interpolation segment of the history around sk = t/Ts > 0 (k >= 1): the states at the
// control indices j and j + 1 (j <= k − 1: beyond t_k the last segment extrapolates) and the
// position x = sk − j within it.
SensingMeasurement::Segment SensingMeasurement::segment(double sk) const {
  const long j = std::min(static_cast<long>(std::floor(sk)), k - 1);
  const auto a = static_cast<std::size_t>(slot(j)), b = static_cast<std::size_t>(slot(j + 1));
  return {hq[a], hv[a], hq[b], hv[b], sk - static_cast<double>(j)};
}

void SensingMeasurement::angle(double t, Vec& out) const {
  const double sk = t / s.Ts;
  if (sk <= 0 || k == 0) {
    const long j = slot(0);
    const Vec& q0 = hq[static_cast<std::size_t>(j)];
    const Vec& v0 = hv[static_cast<std::size_t>(j)];
    const double before = std::min(t, 0.0);
    for (int i = 0; i < n; ++i) out[i] = q0[i] + before * v0[i];
    return;
  }
  const Segment g = segment(sk);
  const double x = g.x;
  const double h = s.Ts;
  const double x2 = x * x, x3 = x * x * x;
  const double c0 = 2.0 * x3 - 3.0 * x2 + 1.0;
  const double c1 = (x3 - 2.0 * x2 + x) * h;
  const double c2 = -2.0 * x3 + 3.0 * x2;
  const double c3 = (x3 - x2) * h;
  for (int i = 0; i < n; ++i)
    out[i] = c0 * g.q0[i] + c1 * g.v0[i] + c2 * g.q1[i] + c3 * g.v1[i];
}

void SensingMeasurement::velocity(double t, Vec& out) const {
  const double sk = t / s.Ts;
  if (sk <= 0 || k == 0) {
    out = hv[static_cast<std::size_t>(slot(0))];
    return;
  }
  const Segment g = segment(sk);
  const double x = g.x;
  const double h = s.Ts;
  const double x2 = x * x;
  const double a = 6.0 * x2 - 6.0 * x;
  const double b = 3.0 * x2 - 4.0 * x + 1.0;
  const double c = -6.0 * x2 + 6.0 * x;
  const double d = 3.0 * x2 - 2.0 * x;
  for (int i = 0; i < n; ++i)
    out[i] = a * g.q0[i] / h + b * g.v0[i] + c * g.q1[i] / h + d * g.v1[i];
}

void SensingMeasurement::command(RefVec tau) {
  if (!s.torque_filter) return;
  if (!tau_started) {  // the filter starts settled at the first command
    tauf = tau;
    tau_started = true;
    return;
  }
  const double a = s.torque_gain;
  const double b = 1.0 - a;
  total.setZero(tau.size());
  for (int r = 0; r < s.ticks; ++r)
    for (Eigen::Index i = 0; i < tau.size(); ++i) {
      tauf[i] = a * tau[i] + b * tauf[i];
      total[i] += tauf[i];
    }
  const auto m = static_cast<double>(s.ticks);
  for (Eigen::Index i = 0; i < tau.size(); ++i) tau[i] = total[i] / m;
}

}  // namespace hmpc
