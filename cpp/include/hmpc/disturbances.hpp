// The disturbances of the paper as compiled Disturbance ports (interfaces.hpp), each the one
// implementation of its law (hmpc_pin.sim.disturbances hands them over):
//   GaussianPulses          Eq 33: d_i = a_i exp(k_i (t − b_i)²), k_i = −1/(2σ_i²), of t
//                           alone (time_only);
//   CoulombViscousFriction  Eq 32 with the physical sign: d_i = −(a_i q̇_i + b_i sgn q̇_i),
//                           sgn 0 = 0 (friction; joint_dynamics.hpp's law);
//   DisturbanceSum          Eq 34: the sum of its terms (any ports, compiled or Python), in
//                           their order; none: d = 0.
// Oracle: tests/reference/disturbances.py (tests/test_compiled_ports.py).
#pragma once

#include "hmpc/interfaces.hpp"

#include <vector>

namespace hmpc {

class GaussianPulses : public Disturbance {
 public:
  // a [N·m], b [s], σ [s], n each.
  GaussianPulses(const CRefVec& amplitude, const CRefVec& center, const CRefVec& sigma);
  Vec at(double t, const Vec& q, const Vec& dq) override;
  Kind kind() const override { return Kind::time_only; }
  void at_times(const CRefVec& ts, Eigen::Ref<RowMat> out) override;
  const int n;

 private:
  Vec a_, b_, k_;
};

class CoulombViscousFriction : public Disturbance {
 public:
  // a [N·m·s/rad], b [N·m], n each.
  CoulombViscousFriction(const CRefVec& viscous, const CRefVec& coulomb);
  Vec at(double t, const Vec& q, const Vec& dq) override;
  Kind kind() const override { return Kind::friction; }
  void coefficients(Vec& a, Vec& b) const override;
  const int n;

 private:
  Vec a_, b_;
};

class DisturbanceSum : public Disturbance {
 public:
  // The terms (the caller keeps them alive), for n joints.
  DisturbanceSum(std::vector<Disturbance*> terms, int n);
  Vec at(double t, const Vec& q, const Vec& dq) override;
  std::vector<Disturbance*> terms() override { return terms_; }
  const int n;

 private:
  std::vector<Disturbance*> terms_;
};

}  // namespace hmpc
