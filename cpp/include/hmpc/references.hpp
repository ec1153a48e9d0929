// The references with a closed form, as compiled Reference ports (interfaces.hpp): the one
// implementation of sampling them, used by the references' own sample_many
// (hmpc_pin.tasks.base.CompiledSampling) and by the step (step.hpp) for its horizon.
//   SineReference        q = o + a sin(ω t + φ), q̇ = (a ω) cos(ω t + φ), per joint
//                        (hmpc_pin.tasks.sine.SineReference);
//   PolynomialReference  segment i = the number of breakpoints <= t,
//                        [q q̇] = Σ_k c_{i,k} s^k, s = t − origin_i (quintic moves,
//                        trajectory files, waypoints, pose tasks).
// Oracle: tests/reference/sampling.py.
#pragma once

#include "hmpc/interfaces.hpp"

#include <mutex>

namespace hmpc {

// A reference sampled point by point: its horizon is its samples at t + o_j.
class SampledReference : public Reference {
 public:
  explicit SampledReference(int n_) : n(n_) {}
  // q and q̇ (n each, contiguous) at time t [s].
  virtual void sample(double t, double* q, double* dq) const = 0;
  void horizon(double t, const CRefVec& offsets, Eigen::Ref<RowMat> stack) override;
  const int n;
};

class SineReference : public SampledReference {
 public:
  // ω [rad/s], φ [rad], a [rad], o [rad], a ω [rad/s] (the velocity's amplitude), n each.
  SineReference(const CRefVec& omega, const CRefVec& phase, const CRefVec& amp,
                const CRefVec& offset, const CRefVec& amp_omega);
  void sample(double t, double* q, double* dq) const override;
  // The horizon by angle addition: sin/cos(ω t + φ) once per joint, turned by the angles
  // ω o_j, whose sin/cos are computed once per offsets (kept while the offsets stay).
  void horizon(double t, const CRefVec& offsets, Eigen::Ref<RowMat> stack) override;

 private:
  Vec omega_, phase_, amp_, offset_, amp_omega_;
  Vec offsets_;             // the offsets the turns below are of
  RowMat cos_, sin_;        // cos/sin(ω_i o_j), N×n (row j: offset j's, by joint)
  Vec s_, c_;               // sin/cos(ω_i t + φ_i) of the horizon being sampled
  std::mutex turns_mutex_;  // guards the three above
};

class PolynomialReference : public SampledReference {
 public:
  // Breakpoints t_0..t_{K-1} (K) [s], segment origins (K + 1: before t_0, then one per
  // breakpoint) [s], coefficients ((K + 1)·(deg + 1) × 2n): [q | q̇] per power of s, segment
  // by segment; segment k holds for t_{k-1} <= t < t_k.
  PolynomialReference(const CRefVec& times, const CRefVec& knots, const CRefRow& coef, int deg);
  void sample(double t, double* q, double* dq) const override;

 private:
  Vec times_, knots_;
  RowMat coef_;
  int deg_;
  mutable Eigen::RowVectorXd acc_;
};

}  // namespace hmpc
