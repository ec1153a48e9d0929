// The reference's horizon sampler: see sampler.hpp.
#include "hmpc/sampler.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace hmpc {

HorizonSampler::HorizonSampler(int n_) : n(n_) { acc_.setZero(2 * n_); }

void HorizonSampler::set_sine(const CRefVec& omega, const CRefVec& phase, const CRefVec& amp,
                              const CRefVec& offset, const CRefVec& amp_omega) {
  for (const CRefVec* x : {&omega, &phase, &amp, &offset, &amp_omega})
    if (x->size() != n) throw std::invalid_argument("sine coefficients of wrong size");
  omega_ = omega;
  phase_ = phase;
  amp_ = amp;
  offset_ = offset;
  amp_omega_ = amp_omega;
  kind = 1;
}

void HorizonSampler::set_ppoly(const CRefVec& times, const CRefVec& knots, const CRefRow& coef,
                               int deg) {
  const Eigen::Index K = times.size();
  if (deg < 0 || knots.size() != K + 1 || coef.rows() != (K + 1) * (deg + 1) ||
      coef.cols() != 2 * n)
    throw std::invalid_argument("piecewise polynomial of wrong shape");
  times_ = times;
  knots_ = knots;
  coef_ = coef;
  deg_ = deg;
  kind = 2;
}

void HorizonSampler::sample(double t, double* q, double* dq) const {
  if (kind == 1) {
    for (int i = 0; i < n; ++i) {
      const double arg = t * omega_[i] + phase_[i];
      q[i] = std::sin(arg) * amp_[i] + offset_[i];
      dq[i] = std::cos(arg) * amp_omega_[i];
    }
    return;
  }
  if (kind != 2) throw std::logic_error("HorizonSampler: no reference set");
  const double* begin = times_.data();
  const double* end = begin + times_.size();
  const Eigen::Index seg = std::upper_bound(begin, end, t) - begin;
  const double s = t - knots_[seg];
  const auto block = coef_.middleRows(seg * (deg_ + 1), deg_ + 1);
  double power = 1.0;
  acc_ = block.row(0);
  for (int k = 1; k <= deg_; ++k) {
    power *= s;
    acc_ += power * block.row(k);
  }
  for (int i = 0; i < n; ++i) {
    q[i] = acc_[i];
    dq[i] = acc_[n + i];
  }
}

}  // namespace hmpc
