// The products with the prediction matrix Γ of one joint (Eq 24, X = Φ x0 + Γ U, rows
// x_1 .. x_N interleaved q, q̇): X = Γ u by the recursion x_{j+1} = A x_j + B u_min(j, Nc−1),
// x_0 = 0, and Γᵀ λ by its adjoint, each in O(N) where the dense products cost N·Nc, when Γ
// is that recursion (A the first two rows of Φ, B the first column's first two entries:
// every entry within 1e-12 of its row's largest |Γ|); else the dense products. The soft
// limits' shortcut (soft_limits.hpp, banded_kkt.hpp) uses it. Oracle: the dense products
// (tests/reference/qp_parts.py).
#pragma once

#include <Eigen/Core>

namespace hmpc {

class GammaRecursion {
 public:
  using Vec = Eigen::VectorXd;
  using Mat = Eigen::MatrixXd;

  GammaRecursion() = default;
  // Phi (2N×2), Gamma (2N×Nc). Returns recursion().
  bool set(const Eigen::Ref<const Mat>& Phi, const Eigen::Ref<const Mat>& Gamma);

  // X = Γ u (2N).
  void apply(const Eigen::Ref<const Vec>& u, Vec& X) const;
  // out = Γᵀ λ (Nc).
  void apply_transpose(const Vec& lam, Vec& out) const;
  // Whether the products are the recursions (else the dense products).
  bool recursion() const { return rec_; }
  int rows() const { return 2 * N_; }  // 2N
  int cols() const { return Nc_; }     // Nc

 private:
  Mat Gamma_;
  int N_ = 0, Nc_ = 0;
  bool rec_ = false;
  double a_[4] = {0.0, 0.0, 0.0, 0.0}, b_[2] = {0.0, 0.0};
};

}  // namespace hmpc
