// The arm's own joint dynamics, the one law of the library: joint damping B [N·m·s/rad] and
// Coulomb friction F [N·m], diagonal (the URDF's <dynamics damping friction>),
//   J(q̇) = B q̇ + F sgn q̇   (sgn 0 = 0),
// which the RK4 plant applies at every stage (rk4.hpp), the step compensates (step.hpp) and
// the fused Coulomb-viscous disturbance −(a q̇ + b sgn q̇) shares (loop.hpp); and the
// zero-order-hold terms that make a compensated damped joint reach, over a period of the
// torque held, the velocity the MPC's double integrator predicts (zoh()).
// Oracle: tests/reference/step.py.
#pragma once

#include "hmpc/types.hpp"

#include <Eigen/Core>

namespace hmpc {

// sgn v, with sgn 0 = 0.
inline double sgn(double v) { return (v > 0.0) - (v < 0.0); }

// b v + f sgn v [N·m]: one joint's damping and Coulomb friction torque at velocity v.
inline double joint_torque(double b, double f, double v) { return b * v + f * sgn(v); }

class JointDynamics {
 public:
  // B and F of n joints (zeros: none). Throws std::invalid_argument naming `who` unless both
  // are (n,), finite and >= 0.
  void set(const CRefVec& damping, const CRefVec& friction, int n, const char* who);

  // J_i(v) = b_i v + f_i sgn v [N·m].
  double torque(int i, double v) const { return joint_torque(b[i], f[i], v); }

  // The zero-order-hold terms, per joint, into `extra` [N·m]: with B q̇_k compensated, joint
  // j's velocity over a period Ts of the torque held follows m_j ẇ = −b_j w + m_j v_j + e_j
  // (w = q̇ − q̇_k, m_j = 1/(M⁻¹)_jj its inertia with the others free, a_j = b_j/m_j), so it
  // gains v_j (1 − e^{−a_j Ts})/a_j instead of the v_j Ts the MPC predicts. The extra
  // torque (g_j − 1) m_j v_j, g_j = a_j Ts / (1 − e^{−a_j Ts}), restores v_j Ts
  // (g_j → 1 + a_j Ts/2 as a_j Ts → 0). The Coulomb term f_j sgn(q̇) changes sign where the
  // velocity path from q̇_k to q̇_k + v_j Ts (exponential with a_j, linear without damping)
  // crosses zero, at the fraction s* of the period: f_j sgn(q̇_k) is replaced by f_j σ_j,
  // σ_j the mean sign weighted by e^{−a_j (Ts − t)}, the weight the velocity at the end of
  // the period gives the force at t (σ_j = sgn(q̇_k + v_j Ts) when q̇_k = 0, so that a joint
  // at rest is not left to stick). M: M(q_k); dq: q̇_k; v: the commanded accelerations
  // (n, contiguous). Zeros where M is not positive definite.
  void zoh(const Mat& M, const Vec& dq, const double* v, double Ts, Vec& extra);

  Vec b, f;          // B, F (n each)
  bool any = false;  // whether any of them is non-zero

 private:
  Mat L_;  // Lᵀ of M = L Lᵀ (small_dense.hpp)
  Vec e_;
};

}  // namespace hmpc
