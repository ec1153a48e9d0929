// The references with a closed form: see references.hpp.
#include "hmpc/references.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace hmpc {

void SampledReference::horizon(double t, const CRefVec& offsets, Eigen::Ref<RowMat> S) {
  const Eigen::Index N = offsets.size();
  if (S.rows() != 2 + 2 * N || S.cols() != n)
    throw std::invalid_argument("Reference.horizon: the stack is not (2 + 2N)×n");
  for (Eigen::Index j = 0; j < N; ++j) sample(t + offsets[j], &S(2 + j, 0), &S(2 + N + j, 0));
}

SineReference::SineReference(const CRefVec& omega, const CRefVec& phase, const CRefVec& amp,
                             const CRefVec& offset, const CRefVec& amp_omega)
    : SampledReference(static_cast<int>(omega.size())), omega_(omega), phase_(phase), amp_(amp),
      offset_(offset), amp_omega_(amp_omega) {
  for (const CRefVec* x : {&phase, &amp, &offset, &amp_omega})
    if (x->size() != n) throw std::invalid_argument("sine coefficients of wrong size");
}

void SineReference::sample(double t, double* q, double* dq) const {
  for (int i = 0; i < n; ++i) {
    const double arg = t * omega_[i] + phase_[i];
    q[i] = std::sin(arg) * amp_[i] + offset_[i];
    dq[i] = std::cos(arg) * amp_omega_[i];
  }
}

void SineReference::horizon(double t, const CRefVec& offsets, Eigen::Ref<RowMat> S) {
  const Eigen::Index N = offsets.size();
  if (S.rows() != 2 + 2 * N || S.cols() != n)
    throw std::invalid_argument("Reference.horizon: the stack is not (2 + 2N)×n");
  // One reference may serve steps in several threads: its turns are shared, behind a lock.
  const std::lock_guard<std::mutex> lock(turns_mutex_);
  if (offsets_.size() != N || offsets_ != offsets) {  // the turns of these offsets
    offsets_ = offsets;
    cos_.resize(N, n);
    sin_.resize(N, n);
    for (int i = 0; i < n; ++i)
      for (Eigen::Index j = 0; j < N; ++j) {
        cos_(j, i) = std::cos(omega_[i] * offsets[j]);
        sin_(j, i) = std::sin(omega_[i] * offsets[j]);
      }
    s_.resize(n);
    c_.resize(n);
  }
  for (int i = 0; i < n; ++i) {
    const double arg = t * omega_[i] + phase_[i];
    s_[i] = std::sin(arg);
    c_[i] = std::cos(arg);
  }
  // sin(a + b) = sin a cos b + cos a sin b, cos(a + b) = cos a cos b − sin a sin b; row by
  // row of the stack (contiguous over the joints)
  const double *s = s_.data(), *c = c_.data(), *a = amp_.data(), *o = offset_.data(),
               *aw = amp_omega_.data();
  for (Eigen::Index j = 0; j < N; ++j) {
    const double* cb = &cos_(j, 0);
    const double* sb = &sin_(j, 0);
    double* q = &S(2 + j, 0);
    double* dq = &S(2 + N + j, 0);
    for (int i = 0; i < n; ++i) {
      q[i] = (s[i] * cb[i] + c[i] * sb[i]) * a[i] + o[i];
      dq[i] = (c[i] * cb[i] - s[i] * sb[i]) * aw[i];
    }
  }
}

PolynomialReference::PolynomialReference(const CRefVec& times, const CRefVec& knots,
                                         const CRefRow& coef, int deg)
    : SampledReference(static_cast<int>(coef.cols() / 2)), times_(times), knots_(knots),
      coef_(coef), deg_(deg) {
  const Eigen::Index K = times.size();
  if (deg < 0 || knots.size() != K + 1 || coef.rows() != (K + 1) * (deg + 1) ||
      coef.cols() != 2 * n || n < 1)
    throw std::invalid_argument("piecewise polynomial of wrong shape");
  acc_.setZero(2 * n);
}

void PolynomialReference::sample(double t, double* q, double* dq) const {
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
