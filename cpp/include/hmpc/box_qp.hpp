// One box-constrained QP, min ½ xᵀ H x + gᵀ x s.t. lo <= x <= hi, solved by ProxSuite and
// warm-started from its last primal and dual solution (shifted one step along the horizon
// when asked), with a cold twin (made on first use) that solves it again from scratch when
// the warm solve does not report solved; the warm QP then restarts from the twin's solution.
// Crocoddyl's BoxQP plays the same part there. JointQPs (joint_qps.hpp) holds one per joint
// ("joint" layout) or one for all joints ("block"). Oracle: the box QP by enumeration of
// its active sets (tests/reference/qp_parts.py).
#pragma once

#include "hmpc/qp_settings.hpp"

#include <Eigen/Core>
#include <proxsuite/proxqp/results.hpp>

#include <memory>

namespace proxsuite::proxqp::dense {
template <typename T>
struct QP;  // proxsuite/proxqp/dense/dense.hpp, included by the sources only
}  // namespace proxsuite::proxqp::dense

namespace hmpc {

class BoxQP {
 public:
  using Vec = Eigen::VectorXd;
  using Mat = Eigen::MatrixXd;
  using DenseQP = proxsuite::proxqp::dense::QP<double>;
  using Results = proxsuite::proxqp::Results<double>;

  // H (m×m), lo, hi (m): the QP's data; warm, cold: the warm QP's and the twin's settings.
  BoxQP(const Mat& H, const Vec& lo, const Vec& hi, const QPSettings& warm,
        const QPSettings& cold);
  ~BoxQP();

  // The QP as new: initialised and solved once at g = 0 (update() before any solve()
  // crashes ProxSuite 0.8.0 with warm starts, measured here); the twin to be made again.
  void restart();

  // Solve for the gradient g. shift_block > 0: the warm start shifted one step along each
  // block of that length first. Returns the solution (the warm QP's, or the twin's when the
  // warm one did not report solved; cold set then), or null when the twin did not report
  // solved either (failed() holds its results).
  const Results* solve(const Vec& g, int shift_block, bool& cold);
  const Results& failed() const;

  // The last solution set to x (multipliers z, or 0) at the variables offset..offset+x.size(),
  // so that the next warm start begins there (a solution found without ProxSuite).
  // (Inline, as x(): on the step's path, through the warm QP's results.)
  void remember(int offset, const Vec& x, const Vec* z) {
    const auto m = x.size();
    res_->x.segment(offset, m) = x;
    if (z) res_->z.segment(offset, m) = *z;
    else res_->z.segment(offset, m).setZero();
  }
  const Vec& x() const { return res_->x; }
  // The warm start (the warm QP's results), saved and put back (JointQPs::save, restore).
  const Results& results() const { return *res_; }
  void set_results(const Results& r) { *res_ = r; }

  // The iteration cap, of this QP, its twin and the QPs restart() makes.
  void set_max_iter(long max_iter);

 private:
  Mat H_;
  Vec lo_, hi_;
  QPSettings warm_, cold_;
  std::unique_ptr<DenseQP> qp_, cold_qp_;
  Results* res_ = nullptr;  // qp_->results
};

}  // namespace hmpc
