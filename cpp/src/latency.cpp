// The measurement latency known to the controller: see latency.hpp.
#include "hmpc/latency.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace hmpc {

void Latency::set(double L, double Ts_, int n) {
  if (!(std::isfinite(L) && L >= 0.0 && std::isfinite(Ts_) && Ts_ > 0.0))
    throw std::invalid_argument("set_latency: expected L >= 0 and Ts > 0");
  Ts = Ts_;
  on = L > 0.0;
  const double periods = L / Ts;
  m = static_cast<int>(std::floor(periods + 1e-9));
  alpha = periods - m;
  if (alpha < 1e-9) alpha = 0.0;
  tau_hist.assign(m + 2, Vec::Zero(n));
  v_hist.assign(m + 2, Vec::Zero(n));
  tau_obs.setZero(n);
  v_obs.setZero(n);
}

void Latency::align() {
  tau_obs = (1.0 - alpha) * tau_hist[m] + alpha * tau_hist[m + 1];
  v_obs = (1.0 - alpha) * v_hist[m] + alpha * v_hist[m + 1];
}

void Latency::predict(RefVec q, RefVec dq) const {
  auto seg = [&](const Vec& a, double h) {
    q += h * dq + (0.5 * h * h) * a;
    dq += h * a;
  };
  if (alpha > 0.0) seg(v_hist[m], alpha * Ts);
  for (int j = m - 1; j >= 0; --j) seg(v_hist[j], Ts);
}

void Latency::record(const Vec& tau, const Vec& v) {
  std::rotate(tau_hist.rbegin(), tau_hist.rbegin() + 1, tau_hist.rend());
  std::rotate(v_hist.rbegin(), v_hist.rbegin() + 1, v_hist.rend());
  tau_hist[0] = tau;
  v_hist[0] = v;
}

void Latency::clear() {
  for (Vec& x : tau_hist) x.setZero();
  for (Vec& x : v_hist) x.setZero();
}

}  // namespace hmpc
