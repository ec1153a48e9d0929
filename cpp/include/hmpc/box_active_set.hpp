// The box QP min ½ uᵀ H u + gᵀ u s.t. lo <= u <= hi (one joint's, H Nc×Nc positive definite,
// the same bounds for every input) answered without a QP solver when it can be: the
// unconstrained minimiser u0 = −H⁻¹ g when it lies inside the box (the exact solution of a
// convex QP whose constraints are inactive), else a guessed active set refined by a few
// primal-dual active-set exchanges, answering only when its point passes the box QP's KKT
// test to a tolerance (then it is the QP's minimiser). JointQPs (joint_qps.hpp) asks it
// before ProxSuite. Oracle: tests/reference/qp_parts.py.
#pragma once

#include <Eigen/Core>

#include <vector>

namespace hmpc {

class BoxActiveSet {
 public:
  using Vec = Eigen::VectorXd;
  using Mat = Eigen::MatrixXd;

  explicit BoxActiveSet(const Mat& H);

  // u0 = −H⁻¹ g into u() (the symmetrised inverse), returned.
  const Vec& unconstrained(const Vec& g) {
    u_.noalias() = neg_Hinv_ * g;
    return u_;
  }

  // The box QP for g (unconstrained(g) called before) from the guesses: the last solution
  // `last`'s active set shifted one step along the horizon (one exchange), then as it stands
  // (`iter` exchanges), then the bounds u0 crosses (4·iter); iter < 0: none. True when a
  // guess's point passes the KKT test to eps (free inputs inside the box with zero gradient,
  // multipliers of the fixed ones of their bound's sign): u() the minimiser, z() the bounds'
  // multipliers (−(H u + g) at the fixed inputs, 0 at the free).
  bool solve(const Vec& g, double lo, double hi, const Vec& last, int iter, double eps);

  // From the active set state() (−1 lower, +1 upper, 0 free), up to `exchanges` exchanges.
  bool exchange(const Vec& g, double lo, double hi, int exchanges, double eps);

  const Vec& u() const { return u_; }
  const Vec& z() const { return r_; }
  std::vector<int>& state() { return state_; }

 private:
  int Nc_;
  Mat H_, neg_Hinv_, HFF_;
  Vec u_, u0_, r_, rhs_;
  std::vector<int> free_, active_, state_;
};

}  // namespace hmpc
