// Pinocchio behind an interface that needs only Eigen: only dynamics.cpp includes Pinocchio's
// headers, so that the other units compile without them.
#pragma once

#include <Eigen/Core>

#include <memory>
#include <string>

namespace hmpc {

// A Pinocchio model (passed as its serialized string) and its data.
class Dynamics {
 public:
  using Vec = Eigen::VectorXd;
  using Mat = Eigen::MatrixXd;
  using CRefVec = Eigen::Ref<const Vec>;

  explicit Dynamics(const std::string& serialized);
  ~Dynamics();
  Dynamics(Dynamics&&) noexcept;
  Dynamics& operator=(Dynamics&&) noexcept;

  int n = 0;  // nq == nv

  // M(q), both triangles filled (CRBA, LOCAL convention).
  const Mat& mass_matrix(const CRefVec& q);
  // C(q, q̇) q̇ + G(q) (RNEA).
  const Vec& nle(const CRefVec& q, const CRefVec& v);
  // q̈ = ABA(q, q̇, τ) (LOCAL convention).
  const Vec& aba(const CRefVec& q, const CRefVec& v, const CRefVec& tau);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hmpc
