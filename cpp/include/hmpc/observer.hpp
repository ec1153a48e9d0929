// The nonlinear disturbance observer of Eq (13), discretised at the control period: the one
// implementation, used on its own (hmpc_pin.compensation.observers.DisturbanceObserver) and
// inside the fused step (step.cpp, HierarchicalStep). The numpy oracle it is tested against is
// tests/reference/observers.py.
//
// With p = cY q̇, L = cY M⁻¹ and b = n_k − τ_{k−1} − p_k, each update is one linear solve:
//   implicit (backward Euler): (M + Ts cY) w = b − z,  z⁺ = z + Ts cY w
//   explicit (forward Euler):   M w = b − z,           z⁺ = z + Ts cY w
// and d̂ = z⁺ + p_k (Eq 13 with z = d̂ − p). The solve (small_dense.hpp) is a Cholesky
// factorisation where the matrix is symmetric (M, and M + Ts cY with a symmetric cY: Y = I,
// the general design), an LU with partial pivoting otherwise (Chen's Y of planar arms) or
// where the Cholesky fails. It is the compiled Compensation port
// (interfaces.hpp): q and v are not used.
#pragma once

#include "hmpc/interfaces.hpp"

#include <Eigen/Core>

namespace hmpc {

class NDO : public Compensation {
 public:
  using Vec = Eigen::VectorXd;
  using Mat = Eigen::MatrixXd;
  using CRefVec = Eigen::Ref<const Vec>;
  using CRefMat = Eigen::Ref<const Mat>;
  using MapVec = Eigen::Map<Vec>;

  // cY: c·Y (n×n) [1/s·kg·m² per rad/s]; Ts [s]. The state z and the estimate are this
  // object's (Python reads views of them).
  NDO(const CRefMat& cY, double Ts, bool implicit);

  // z = −cY q̇₀ (so that d̂ = 0 at the start), d̂ = 0.
  void reset(const CRefVec& dq0);
  // One period: M, n = C q̇ + G and q̇ at the measured state, τ the torque held over the
  // period that just ended. Writes z and the estimate d̂.
  void update(const CRefMat& M, const CRefVec& nle, const CRefVec& dq, const CRefVec& tau_prev);

  // The Compensation port.
  void reset(const CRefVec& q, const CRefVec& dq) override {
    (void)q;
    reset(dq);
  }
  void update(const CRefMat& M, const CRefVec& nle, const CRefVec& q, const CRefVec& dq,
              const CRefVec& tau, const CRefVec& v) override {
    (void)q;
    (void)v;
    update(M, nle, dq, tau);
  }
  CRefVec estimate() const override { return d_hat; }

  int n;
  bool implicit;
  Mat cY, TcY;
  Vec z, d_hat;  // z and the estimate d̂ [N·m]

 private:
  bool symmetric_;  // the matrix solved is symmetric: M, or M + Ts cY with cY = cYᵀ
  bool diagonal_;   // cY is diagonal (Y = I): its products are per joint
  Mat A_, F_;       // the matrix solved, its factors
  Eigen::VectorXi perm_;
  Vec p_, rhs_, w_;
};

}  // namespace hmpc
