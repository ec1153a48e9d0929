// The reference's horizon sampler: the one implementation of sampling the references that
// have a closed form here -- a sine per joint (hmpc_pin.tasks.sine.SineReference) or a
// piecewise polynomial in s = t − origin of its segment (quintic moves, trajectory files,
// waypoints and pose tasks) -- used on its own by the references' sample_many and inside the
// fused step (step.cpp, HMPCCore). Oracle: tests/reference/sampling.py.
#pragma once

#include <Eigen/Core>

namespace hmpc {

class HorizonSampler {
 public:
  using Vec = Eigen::VectorXd;
  using RowMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  using CRefVec = Eigen::Ref<const Vec>;
  using CRefRow = Eigen::Ref<const RowMat>;

  explicit HorizonSampler(int n);

  // q = offset + amplitude·sin(ω t + φ), q̇ = (amplitude·ω)·cos(ω t + φ), each (n,).
  void set_sine(const CRefVec& omega, const CRefVec& phase, const CRefVec& amp,
                const CRefVec& offset, const CRefVec& amp_omega);
  // Breakpoints t_0..t_{K-1} (K), segment origins (K + 1: before t_0, then one per
  // breakpoint), coefficients ((K + 1)·(deg + 1) × 2n): [q | q̇] per power of s, segment by
  // segment; segment k holds for t_{k-1} <= t < t_k.
  void set_ppoly(const CRefVec& times, const CRefVec& knots, const CRefRow& coef, int deg);
  void clear() { kind = 0; }

  // q and q̇ (n each, contiguous) at time t.
  void sample(double t, double* q, double* dq) const;

  int n;
  int kind = 0;  // 0 none, 1 sine, 2 piecewise polynomial

 private:
  Vec omega_, phase_, amp_, offset_, amp_omega_;
  Vec times_, knots_;
  RowMat coef_;
  int deg_ = 0;
  mutable Eigen::RowVectorXd acc_;
};

}  // namespace hmpc
