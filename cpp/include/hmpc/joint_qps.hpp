// The per-joint MPC's quadratic programs (Eq 25–26): the one implementation, used on its
// own (hmpc_pin.mpc.condensed.JointQPs) and inside the fused step (step.cpp, HierarchicalStep),
// composed of named parts:
//   BoxQP (box_qp.hpp)                 a box QP solved by ProxSuite, warm, with its cold twin;
//   BoxActiveSet (box_active_set.hpp)  the box QP answered without ProxSuite when it can be;
//   SoftLimits (soft_limits.hpp)       the soft state limits' QPs and their shortcut, whose
//     subproblems BandedKKT (banded_kkt.hpp) solves with Γ's products by GammaRecursion
//     (gamma_recursion.hpp);
// with its knobs in an Options struct and its counters in a Stats struct
// (joint_qps_options.hpp). The numpy/ProxSuite-Python oracle it is tested against is
// tests/reference/joint_qps.py.
//
// Layouts: "block" (the n box QPs as one block-diagonal BoxQP of n·Nc variables) or "joint"
// (one BoxQP per joint; BoxActiveSet first: the unconstrained minimiser −H⁻¹g when inside
// the box, else a guessed active set refined by a few exchanges, answering only when its
// point passes the box QP's KKT test to the solver's tolerance). A BoxQP is warm-started
// from its last solution (shifted one step along the horizon with options.shift); one that
// does not report solved is solved again by its cold twin. With soft state limits, a joint
// whose box-only prediction X = Φ x0 + Γ U leaves them is solved again with the soft
// constraints (SoftLimits: its shortcut first, then ProxSuite from scratch). Along an
// activation that continues (answered from the last step's active set with the limits
// binding), the next step skips the joint's box QP and goes straight to the soft shortcut
// (the box QP and the test above only if it does not answer).
#pragma once

#include "hmpc/box_active_set.hpp"
#include "hmpc/box_qp.hpp"
#include "hmpc/errors.hpp"
#include "hmpc/joint_qps_options.hpp"
#include "hmpc/qp_settings.hpp"
#include "hmpc/soft_limits.hpp"

#include <Eigen/Core>

#include <memory>
#include <string>
#include <vector>

namespace hmpc {

class JointQPs {
 public:
  using Vec = Eigen::VectorXd;
  using Mat = Eigen::MatrixXd;
  using RowMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  using CRefVec = Eigen::Ref<const Vec>;
  using CRefMat = Eigen::Ref<const Mat>;
  using CRefRow = Eigen::Ref<const RowMat>;
  using MapRow = Eigen::Map<RowMat>;
  using Settings = QPSettings;
  using Options = JointQPsOptions;
  using Stats = JointQPsStats;
  using Results = proxsuite::proxqp::Results<double>;

  static constexpr double BIG = SoftLimits::BIG;  // as hmpc_pin.mpc.condensed.BIG

  // H: one joint's scaled Hessian (Nc×Nc); v_min, v_max (n,) [rad/s²]; warm, cold: the box
  // QPs' and their cold twins' settings. The solution U and the slack are this object's
  // (Python reads views of them).
  JointQPs(int n, int N, int Nc, bool block, const CRefMat& H, const CRefVec& v_min,
           const CRefVec& v_max, const Settings& warm, const Settings& cold);

  // Soft state limits (hmpc_pin.mpc.condensed.JointQPs builds every matrix). T, E, Hp: the
  // banded coordinates of the soft active-set shortcut (CondensedMPC.banded: U = T p,
  // E = Γ T, Hp = Tᵀ H T, each exactly banded; empty T: no shortcut).
  void set_limits(const CRefMat& Phi, const CRefMat& Gamma, const CRefVec& lower,
                  const CRefVec& upper, const CRefVec& vel, const CRefMat& Hs, const CRefMat& C,
                  const CRefVec& row_scale, double g_slack, double k_slack,
                  const Settings& soft, bool always_constrained, const CRefMat& T,
                  const CRefMat& E, const CRefMat& Hp);

  // Solve every joint's QP for the gradients G (n×Nc, one row per joint) at the state
  // (q, q̇) (used by the soft limits only). Writes U and slack. Returns false when a QP did
  // not report solved (failure()).
  bool solve(const CRefRow& G, const CRefVec& q, const CRefVec& dq);

  // The fault of the last solve() that returned false (fail_joint, fail_status, fail_iter,
  // the joint's name from joint_names).
  QPNotSolved failure() const;

  // The iteration cap of every QP (the warm ones, their twins, the soft ones).
  void set_max_iter(long max_iter);

  // Start a new run: every QP as new (no warm start, no remembered active set), slack 0, so
  // that a run gives, bit for bit, the answers of a new JointQPs (the counters go on).
  void restart();

  // The QPs' memory between steps (warm starts, remembered active sets), saved and put back:
  // a dry step (HierarchicalMPC.warm_up) followed by restore() leaves the next step's
  // answers bit for bit those without it.
  struct Memory {
    std::vector<Results> boxes;
    SoftLimits::Memory soft;
  };
  void save(Memory& m) const;
  void restore(const Memory& m);

  int n, N, Nc;
  bool block;
  Options options;
  Stats stats;
  RowMat U;   // (Nc, n) the input sequences of the last solve() [rad/s²]
  Vec slack;  // (n) the slack of each joint at the last solve() [rad]
  int fail_joint = -2;  // the last failure's joint (−1: the block)
  std::string fail_status;
  long fail_iter = 0;
  std::vector<std::string> joint_names;  // for failure() (empty: "joint i")

 private:
  void make_box_qps();
  bool box_joint(int i);
  bool enforce_limits(const CRefRow& G, const CRefVec& q, const CRefVec& dq);
  bool leaves(int i, double q, double dq);
  bool soft_joint(int i, const CRefRow& G, const CRefVec& q, const CRefVec& dq);
  bool fail(int joint, const Results& res);

  Mat H_, H_block_;
  Vec v_min_, v_max_, g_block_, g_;
  Settings warm_, cold_;
  std::vector<std::unique_ptr<BoxQP>> boxes_;
  std::unique_ptr<BoxActiveSet> active_set_;  // "joint" layout
  double neg_hinv1_ = 0.0;  // "joint" layout, Nc = 1: BoxActiveSet's −H⁻¹ (1×1)
  Vec u1_;                  // its unconstrained minimiser, remembered as the warm start
  std::unique_ptr<SoftLimits> soft_;          // with set_limits
};

}  // namespace hmpc
