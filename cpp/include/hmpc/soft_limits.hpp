// The per-joint MPC's soft state limits (hmpc_pin.mpc.condensed, module docstring): per
// joint, the QP over y = (U, ŝ) with the limits on X = Φ x0 + Γ U as soft rows (slack
// s = k ŝ), solved by ProxSuite from scratch (made once; Nc + 1 variables, 4N rows) or,
// first, by the soft active-set shortcut: the last step's soft solution's active set,
// shifted one step along the horizon or as it stands (first the one that answered at the
// last step, else the shifted one unless the arm is nearer its last state than the plan's
// prediction of it: held still); at a new activation, the box-only
// solution's with the rows it violates and the inputs next to them freed; refined by
// primal-dual exchanges, each subproblem solved by BandedKKT (banded_kkt.hpp), answering
// only when its point passes the soft QP's KKT test to the solver's tolerance. JointQPs
// (joint_qps.hpp) decides which joints need it (leaves) and composes the answers.
#pragma once

#include "hmpc/banded_kkt.hpp"
#include "hmpc/gamma_recursion.hpp"
#include "hmpc/joint_qps_options.hpp"
#include "hmpc/qp_settings.hpp"

#include <Eigen/Core>
#include <proxsuite/proxqp/results.hpp>

#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

namespace proxsuite::proxqp::dense {
template <typename T>
struct QP;  // proxsuite/proxqp/dense/dense.hpp, included by the sources only
}  // namespace proxsuite::proxqp::dense

namespace hmpc {

class SoftLimits {
 public:
  using Vec = Eigen::VectorXd;
  using Mat = Eigen::MatrixXd;
  using RowMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  using CRefVec = Eigen::Ref<const Vec>;
  using CRefMat = Eigen::Ref<const Mat>;
  using CRefRow = Eigen::Ref<const RowMat>;
  using ColRef = Eigen::Ref<const Vec, 0, Eigen::InnerStride<>>;
  using DenseQP = proxsuite::proxqp::dense::QP<double>;
  using Results = proxsuite::proxqp::Results<double>;

  static constexpr double BIG = 1e10;  // as hmpc_pin.mpc.condensed.BIG

  // The shapes as JointQPs::set_limits; H (Nc×Nc), v_min, v_max (n): the box QPs'; stats:
  // where the shortcut's failures are counted (alive as long as this). Empty T: no shortcut.
  SoftLimits(int n, int N, int Nc, const Mat& H, const Vec& v_min, const Vec& v_max,
             const CRefMat& Phi, const CRefMat& Gamma, const CRefVec& lower,
             const CRefVec& upper, const CRefVec& vel, const CRefMat& Hs, const CRefMat& C,
             const CRefVec& row_scale, double g_slack, double k_slack, const QPSettings& soft,
             const CRefMat& T, const CRefMat& E, const CRefMat& Hp, JointQPsStats* stats);
  ~SoftLimits();

  // A new run: the soft QPs ProxSuite solved remade, nothing remembered.
  void restart();
  void set_max_iter(long max_iter);
  // Whether the soft active-set shortcut is on (banded data given).
  bool shortcut() const { return shortcut_; }

  // Whether joint i's box-only prediction X = Φ x0 + Γ U (x0 = (q_i, q̇_i), U its column u)
  // leaves the limits: X by the recursion x_{j+1} = A x_j + B u_min(j, Nc−1) (Eq 24; A, B the
  // first rows of Φ and Γ), O(N) where Γ U costs N·Nc (inline: on the step's path).
  bool leaves(int i, double q, double dq, const ColRef& U) const {
    const double a00 = Phi_(0, 0), a01 = Phi_(0, 1), a10 = Phi_(1, 0), a11 = Phi_(1, 1);
    const double b0 = Gamma_(0, 0), b1 = Gamma_(1, 0);
    const double m = mid_[i];
    double x = q, v = dq;
    bool outside = false;
    for (int j = 0; j < N_ && !outside; ++j) {
      const double u = U[j < Nc_ - 1 ? j : Nc_ - 1];
      const double xn = a00 * x + a01 * v + b0 * u;
      v = a10 * x + a11 * v + b1 * u;
      x = xn;
      outside = std::abs(x - m) > half_[i] || std::abs(v) > vel_[i];
    }
    return outside;
  }
  // Whether joint i's box-only prediction provably keeps inside the limits, in O(Nc): the
  // reach of the recursion of leaves() bounded from constants computed once (reach_),
  // |x_j − m| <= c0 |q − m| + c1 |m| + c2 |q̇| + c3 max|U| and |v_j| <= d0 |q| + d1 |q̇| +
  // d3 max|U| over every j, each below its limit by a relative margin of 1e-9 (far above
  // the rounding of leaves()' recursion). True: leaves() answers false; false: unknown.
  bool inside(int i, double q, double dq, const ColRef& U) const {
    double umax = 0.0;
    for (int k = 0; k < Nc_; ++k) umax = std::max(umax, std::abs(U[k]));
    const double m = mid_[i], aq = std::abs(q - m), am = std::abs(m), adq = std::abs(dq);
    const double p = reach_[0] * aq + reach_[1] * am + reach_[2] * adq + reach_[3] * umax;
    const double pscale = reach_[0] * (aq + am) + reach_[2] * adq + reach_[3] * umax + am;
    const double v = reach_[4] * std::abs(q) + reach_[5] * adq + reach_[7] * umax;
    const double vscale = reach_[4] * std::abs(q) + v;
    // written so that a NaN anywhere answers false (unknown)
    return p + 1e-9 * (pscale + half_[i]) < half_[i] && v + 1e-9 * (vscale + vel_[i]) < vel_[i];
  }
  // Joint i's soft QP's gradient (G's row i, ŝ's) and the free responses of its state.
  void prepare(int i, const CRefRow& G, const CRefVec& q, const CRefVec& dq);
  // The soft active-set shortcut for joint i (after prepare; box_u: its box-only solution,
  // the guess at a new activation) with `iter` exchanges per guess. True: y() the minimiser
  // (binding(), continued() as soft_settled takes them), its active set remembered.
  bool active_set(int i, const ColRef& box_u, int iter);
  // ProxSuite's answer for joint i (after prepare); then, when the shortcut is on
  // (iter >= 0), its active set remembered as the next guess.
  const Results& proxsuite(int i, int iter);
  // The exchanges the next active_set may make (< 0: no bound; JointQPs gives each joint
  // its share of the step's); budget() what is left of them; stopped(): the last
  // active_set ran out of them, or, under a bound, out of its guess's own exchanges (its
  // active set kept: the next step resumes it).
  void set_budget(long exchanges) { budget_ = exchanges; }
  long budget() const { return budget_; }
  bool stopped() const { return stopped_; }
  // The fallback answer for joint i (after prepare) when the exchanges ran out: its first
  // input u0 (its box-only answer) clipped to the accelerations that keep the next state
  // x1 = A x0 + B u0 inside the position and velocity limits (the velocity's alone when
  // both cannot hold), then to the box (with no input in the box keeping them: the box's
  // end nearest them, braking at the most the box allows).
  void fallback(int i, double& u0) const;
  // After joint i's soft QP was answered: whether the next step goes straight to it.
  void settled(int i, bool binding, bool continued) { active[i] = binding && continued ? 1 : 0; }

  const Vec& y() const { return kkt_->y(); }
  bool binding() const { return binding_; }
  bool continued() const { return continued_; }
  double k_slack() const { return k_slack_; }

  // What the next step starts from (the active sets and states remembered, the flags
  // below, ProxSuite's warm starts), saved and put back (a dry step: JointQPs::save).
  struct Memory {
    std::vector<signed char> last, next, active, guess_slack, has_guess, shifted_first, resume,
        used;
    std::vector<std::vector<signed char>> guess_rows, guess_box, res_rows, res_box, ans_rows,
        ans_box;
    std::vector<signed char> res_slack, ans_slack;
    std::vector<int> spent;
    Vec last_q, last_v, last_u0;
    std::vector<Results> qps;
  };
  void save(Memory& m) const;
  void restore(const Memory& m);

  // Per joint: its soft QP solved at the last step (last); its last soft solution with a
  // state limit or the slack active (active; else it is the box QP's solution); its soft
  // QP solved without the box QP at this step (next, set by JointQPs::solve).
  std::vector<signed char> last, active, next;

 private:
  void make_qp(int i);
  void bounds(int i, const Vec& q_free, const Vec& v_free);
  bool exchange(int i, int exchanges);
  int test_point(int i);
  void guess_from(int i, const Vec& y, bool box_only);
  bool infeasible_guess(int i, const ColRef& box_u);
  bool bounded(int i, const ColRef& box_u, int iter);

  int n_, N_, Nc_;
  Mat H_, Phi_, Gamma_, Hs_, C_;
  Vec v_min_, v_max_, lower_, upper_, vel_, row_scale_, mid_, half_;
  // inside()'s constants over j = 1..N of x_j = A^j x0 + Σ_{k<j} A^(j−1−k) B u_k: c0..c3 =
  // max |A^j_00|, max |A^j_00 − 1|, max |A^j_01|, Σ_{k<N} |(A^k B)_0|; d0, d1, (unused), d3
  // likewise for the velocity row (A^j_10, A^j_11, (A^k B)_1).
  double reach_[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  double g_slack_, k_slack_;
  QPSettings soft_;
  JointQPsStats* stats_;
  std::vector<std::unique_ptr<DenseQP>> qps_;
  std::vector<signed char> used_;  // per joint: its soft QP solved by ProxSuite since made
  Vec l_soft_, u_soft_, q_free_, v_free_;
  SoftProblem p_;  // p_.g: the soft QP's gradient
  // The shortcut: Γ's products, the KKT solver, the active sets remembered per joint.
  bool shortcut_ = false;
  GammaRecursion gamma_;
  std::unique_ptr<BandedKKT> kkt_;
  std::vector<std::vector<signed char>> guess_rows_, guess_box_;
  std::vector<signed char> guess_slack_, has_guess_;
  // Per joint: the state (q, q̇) and first input of its last remembered soft answer (which
  // guess active_set tries first); q_, dq_: the state of the joint prepared.
  Vec last_q_, last_v_, last_u0_;
  std::vector<signed char> shifted_first_;  // the guess that answered at the last step (1:
                                            // shifted, 0: as it stood, −1: none)
  double q_ = 0.0, dq_ = 0.0;
  long budget_ = -1;
  bool stopped_ = false;
  bool exhausted_ = false;     // the last exchange() ran out of its guess's exchanges
  bool gamma_nonneg_ = false;  // every entry of Γ >= 0 (infeasible_guess)
  // Per joint, under a bound (bounded()): the stage stopped at the last step + 1 (0: none),
  // the exchanges it made, the active set it reached; the last answer's active set.
  std::vector<signed char> resume_;
  std::vector<int> spent_;
  std::vector<std::vector<signed char>> res_rows_, res_box_, ans_rows_, ans_box_;
  std::vector<signed char> res_slack_, ans_slack_;
  int made_ = 0;  // the last exchange()'s exchanges
  void remember_state(int i, double u0) {
    last_q_[i] = q_;
    last_v_[i] = dq_;
    last_u0_[i] = u0;
  }
  SoftActiveSet st_;
  std::vector<signed char> rows_was_, box_was_;
  bool continued_ = false;  // the last active_set answered from the last step's set
  bool binding_ = false;    // its answer with ŝ > 0 or a row's multiplier nonzero
  Vec box_y_, rU_, gl_, Xs_;
};

}  // namespace hmpc
