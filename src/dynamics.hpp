// The Pinocchio part of the native kernels, behind an interface that needs only Eigen:
// _dynamics.cpp (Pinocchio's headers) and _core.cpp (ProxSuite's and pybind11's) compile
// in parallel (hmpc_pin/native/__init__.py).
#pragma once

#include <Eigen/Core>

#include <memory>
#include <string>

namespace hmpc_native {

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

}  // namespace hmpc_native
