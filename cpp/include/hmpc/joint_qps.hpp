// The per-joint MPC's quadratic programs (Eq 25–26), solved by ProxSuite: the one
// implementation, used on its own (hmpc_pin.mpc.condensed.JointQPs) and inside the fused
// step (step.cpp, HMPCCore). The numpy/ProxSuite-Python oracle it is tested against is
// tests/reference/joint_qps.py.
//
// Layouts: "block" (the n box QPs as one block-diagonal QP of n·Nc variables) or "joint"
// (one QP per joint; a joint whose unconstrained minimiser −H⁻¹g lies inside its box takes
// it without a solver call, the exact solution of a convex QP with inactive constraints;
// failing that, the active set guessed from the last solution shifted one step along the
// horizon or as it stands, or from the bounds −H⁻¹g crosses, refined by a few primal-dual
// active-set exchanges, answers when
// its point passes the KKT test of the box QP to the solver's tolerance). A box QP sent to
// ProxSuite is warm-started from its last primal and dual solution (shifted one step along
// the horizon when `shift` is on).
// A warm-started box QP that does not report solved is solved again by its cold twin
// (made on first use), and the warm QP restarted from that solution. With soft state limits,
// a joint whose box-only prediction X = Φ x0 + Γ U leaves them is solved again with the soft
// constraints (hmpc_pin.mpc.condensed, module docstring): first by the soft active-set
// shortcut (the last step's soft solution's active set, shifted one step along the horizon
// or as it stands; at a new activation, the box-only solution's with the rows it violates
// and the inputs next to them freed, refined by primal-dual
// exchanges; each equality-constrained QP solved in the banded coordinates p of
// hmpc_pin.mpc.condensed.CondensedMPC.banded, U = T p, by an envelope LDLᵀ of its KKT
// matrix in O(N)), answering only when its point passes the soft QP's KKT test to the
// solver's tolerance; failing that, ProxSuite, from scratch. Along an activation that
// continues (answered from the last step's active set with the limits binding), the next
// step skips the joint's box QP and goes straight to the soft shortcut (the box QP and the
// test above only if it does not answer).
#pragma once

#include "hmpc/errors.hpp"

#include <Eigen/Core>
#include <proxsuite/proxqp/dense/dense.hpp>

#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace hmpc {

// The ProxSuite settings this package chooses for a QP, each a typed field, set on the QP
// after its construction and before init (the others keep ProxSuite's defaults). A
// default-constructed QPSettings holds ProxSuite's own defaults;
// hmpc_pin.mpc.condensed.qp_settings() chooses the package's values, in one place.
struct QPSettings {
  QPSettings();
  proxsuite::proxqp::InitialGuessStatus initial_guess;
  double eps_abs, eps_rel;                          // primal/dual residual tolerances
  double eps_duality_gap_abs, eps_duality_gap_rel;  // duality-gap test (check_duality_gap)
  double eps_primal_inf, eps_dual_inf;              // infeasibility tolerances
  long max_iter;
  bool verbose, check_duality_gap;
  void apply(proxsuite::proxqp::Settings<double>& s) const;
};

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
  using DenseQP = proxsuite::proxqp::dense::QP<double>;
  using Results = proxsuite::proxqp::Results<double>;

  static constexpr double BIG = 1e10;  // as hmpc_pin.mpc.condensed.BIG

  // H: one joint's scaled Hessian (Nc×Nc); v_min, v_max (n,) [rad/s²]; warm, cold: the box
  // QPs' and their cold twins' settings; U (Nc×n, row-major) and slack (n): the caller's
  // buffers, written in place.
  JointQPs(int n, int N, int Nc, bool block, const CRefMat& H, const CRefVec& v_min,
           const CRefVec& v_max, const Settings& warm, const Settings& cold, double* U,
           double* slack);

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
  // not report solved (fail_joint: the joint, −1 for the block; fail_status, fail_iter).
  bool solve(const CRefRow& G, const CRefVec& q, const CRefVec& dq);

  // The fault of the last solve() that returned false (fail_joint, fail_status, fail_iter,
  // the joint's name from joint_names).
  QPNotSolved failure() const;

  // The iteration cap of every QP (the warm ones, their twins, the soft ones).
  void set_max_iter(long max_iter);

  // Start a new run: every QP as new (no warm start, no remembered active set), slack 0, so
  // that a run gives, bit for bit, the answers of a new JointQPs (the counters go on).
  void restart();

  int n, N, Nc;
  bool block;
  bool shortcut = true;  // "joint" layout: the exact shortcuts (off for tests)
  // ProxSuite's warm start shifted one step along the horizon (primal and dual); off: the
  // last solution as it stands (measured faster in a closed loop, benchmarks/long_horizon_active.py).
  bool shift = false;
  int active_set_iter = 4;  // "joint" layout: active-set exchanges (< 0: no active-set shortcut)
  // Soft QPs: primal-dual exchanges of the soft active-set shortcut per guess (< 0: ProxSuite
  // for every soft QP).
  int soft_active_set_iter = 8;
  bool limits = false;
  bool always_constrained = false;
  MapRow U;
  Eigen::Map<Vec> slack;
  long cold_solves = 0;
  long unconstrained_solves = 0;
  long active_set_solves = 0;
  long soft_active_set_solves = 0;  // soft QPs answered by the soft active-set shortcut
  // Guesses of the soft shortcut that did not answer: a pivot of the wrong sign (dependent
  // rows), the exchanges exhausted, the KKT test failed without an exchange to make.
  long soft_fail_pivot = 0, soft_fail_exchanges = 0, soft_fail_kkt = 0;
  long constrained = 0;
  bool constrained_last = false;
  int fail_joint = -2;
  std::string fail_status;
  long fail_iter = 0;
  std::vector<std::string> joint_names;  // for failure() (empty: "joint i")

 private:
  void make_box_qps();
  void make_soft_qp(int i);
  const Results* solve_box(int k, const Vec& g, int joint);
  bool enforce_limits(const CRefRow& G, const CRefVec& q, const CRefVec& dq);
  void soft_bounds(int i, const Vec& q_free, const Vec& v_free);
  bool fail(int joint, const Results& res);
  bool active_set(int i);
  bool exchange(int i, int exchanges);
  void remember(int k, int offset, const Vec& x, const Vec* z);
  bool soft_active_set(int i);
  bool soft_exchange(int i, int exchanges);
  bool soft_kkt(int i);
  void soft_solve();
  void soft_guess_from(int i, const Vec& y, bool box_only);
  void soft_settled(int i, bool binding, bool continued);
  void soft_prepare(int i, const CRefRow& G, const CRefVec& q, const CRefVec& dq);
  bool box_joint(int i);
  void gamma_u(const Eigen::Ref<const Vec>& u, Vec& X) const;
  void gamma_t(const Vec& lam, Vec& out) const;
  bool gamma_is_recursion();

  Mat H_, H_block_, neg_Hinv_;
  Vec v_min_, v_max_, g_block_, g_;
  Settings warm_, cold_, soft_;
  std::vector<std::unique_ptr<DenseQP>> qps_, cold_qps_, soft_qps_;
  std::vector<Vec> box_lo_, box_hi_;  // each box QP's bounds (its cold twin's too)
  Mat Phi_, Gamma_, Hs_, C_;
  Vec lower_, upper_, vel_, row_scale_, mid_, half_, g_soft_, l_soft_, u_soft_, X_, u_;
  Vec q_free_, v_free_;
  // The active-set shortcut's workspace.
  Mat HFF_;
  Vec r_, rhs_, u0_;
  std::vector<int> free_, active_, state_;
  double g_slack_ = 0.0, k_slack_ = 0.0;
  // The soft active-set shortcut: banded data (rows of E in Γ's order, x_1 .. x_N
  // interleaved q, q̇), the active sets (−1 lower, +1 upper, 0 inactive; the slack: 1 free,
  // 0 at its bound 0) remembered per joint, and the envelope LDLᵀ's workspace.
  bool soft_shortcut_ = false;
  Mat T_, E_, Hp_;
  int wH_ = 0, wT_ = 0;
  std::vector<int> t_first_, e_first_, e_last_;
  std::vector<std::vector<int>> rows_by_last_;
  std::vector<std::vector<signed char>> guess_rows_, guess_box_;
  std::vector<signed char> guess_slack_, has_guess_;
  std::vector<signed char> soft_last_;  // per joint: its soft QP solved at the last step
  std::vector<signed char> soft_used_;  // per joint: its soft QP solved by ProxSuite since made
  // Per joint: its last soft solution with a state limit or the slack active (else it is
  // the box QP's solution); its soft QP solved without the box QP at this step.
  std::vector<signed char> soft_active_, soft_next_;
  bool soft_continued_ = false;  // the last soft_active_set answered from the last step's set
  bool soft_binding_ = false;    // its answer with ŝ > 0 or a row's multiplier nonzero
  std::vector<signed char> st_rows_, st_box_, rows_was_, box_was_;
  signed char st_slack_ = 0;
  // Γ as the recursion x_{j+1} = A x_j + B u_min(j, Nc−1) (gamma_u, gamma_t): A (row-major), B.
  bool gamma_rec_ = false;
  double ga_[4] = {0.0, 0.0, 0.0, 0.0}, gb_[2] = {0.0, 0.0};
  bool dropped_ = false;
  std::vector<int> item_kind_, item_ref_, first_, start_, pidx_;
  std::vector<double> L_, D_, w_, x_, z_;
  Vec y_soft_, lam_, mu_, gl_, rU_, gp_, bnd_lo_, bnd_hi_, Xs_;

};

std::string status_name(proxsuite::proxqp::QPSolverOutput status);

}  // namespace hmpc
