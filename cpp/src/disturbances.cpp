// The compiled disturbances: see disturbances.hpp.
#include "hmpc/disturbances.hpp"

#include "hmpc/joint_dynamics.hpp"

#include <cmath>
#include <stdexcept>
#include <utility>

namespace hmpc {

GaussianPulses::GaussianPulses(const CRefVec& amplitude, const CRefVec& center,
                               const CRefVec& sigma)
    : n(static_cast<int>(amplitude.size())), a_(amplitude), b_(center) {
  if (center.size() != n || sigma.size() != n || n < 1)
    throw std::invalid_argument("GaussianPulses: amplitude, center and sigma of n values each");
  k_.resize(n);
  for (int i = 0; i < n; ++i) k_[i] = -0.5 / (sigma[i] * sigma[i]);
}

Vec GaussianPulses::at(double t, const Vec&, const Vec&) {
  Vec d(n);
  for (int i = 0; i < n; ++i) {
    const double x = t - b_[i];
    d[i] = a_[i] * std::exp(k_[i] * x * x);
  }
  return d;
}

void GaussianPulses::at_times(const CRefVec& ts, Eigen::Ref<RowMat> out) {
  if (out.rows() != ts.size() || out.cols() != n)
    throw std::invalid_argument("GaussianPulses.at_times: out is not (m, n)");
  for (Eigen::Index r = 0; r < ts.size(); ++r)
    for (int i = 0; i < n; ++i) {
      const double x = ts[r] - b_[i];
      out(r, i) = a_[i] * std::exp(k_[i] * x * x);
    }
}

CoulombViscousFriction::CoulombViscousFriction(const CRefVec& viscous, const CRefVec& coulomb)
    : n(static_cast<int>(viscous.size())), a_(viscous), b_(coulomb) {
  if (coulomb.size() != n || n < 1)
    throw std::invalid_argument("CoulombViscousFriction: viscous and coulomb of n values each");
}

Vec CoulombViscousFriction::at(double, const Vec&, const Vec& dq) {
  if (dq.size() != n)
    throw std::invalid_argument("CoulombViscousFriction: q̇ is not of n values");
  Vec d(n);
  for (int i = 0; i < n; ++i) d[i] = -joint_torque(a_[i], b_[i], dq[i]);
  return d;
}

void CoulombViscousFriction::coefficients(Vec& a, Vec& b) const {
  a = a_;
  b = b_;
}

DisturbanceSum::DisturbanceSum(std::vector<Disturbance*> terms, int n_)
    : n(n_), terms_(std::move(terms)) {
  for (const Disturbance* d : terms_)
    if (!d) throw std::invalid_argument("DisturbanceSum: a term is missing");
}

Vec DisturbanceSum::at(double t, const Vec& q, const Vec& dq) {
  if (terms_.empty()) return Vec::Zero(n);
  Vec total = terms_[0]->at(t, q, dq);
  for (std::size_t i = 1; i < terms_.size(); ++i) {
    const Vec d = terms_[i]->at(t, q, dq);
    if (d.size() != total.size())
      throw std::invalid_argument("the disturbance returned a vector of wrong size");
    total += d;
  }
  return total;
}

}  // namespace hmpc
