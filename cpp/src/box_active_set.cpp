// The box QP's active-set shortcut: see box_active_set.hpp.
#include "hmpc/box_active_set.hpp"

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace hmpc {

BoxActiveSet::BoxActiveSet(const Mat& H) : Nc_(static_cast<int>(H.rows())), H_(H) {
  if (H.rows() != H.cols()) throw std::invalid_argument("BoxActiveSet: H must be square");
  const Mat Hinv = H_.inverse();
  neg_Hinv_ = -0.5 * (Hinv + Hinv.transpose());
  u_.setZero(Nc_);
  HFF_.setZero(Nc_, Nc_);
  u0_.setZero(Nc_);
  active_.reserve(Nc_);
  r_.setZero(Nc_);
  rhs_.setZero(Nc_);
  free_.reserve(Nc_);
  state_.assign(Nc_, 0);
}

// Guesses of the active set: the last solution's shifted one step along the horizon (right
// in a closed loop, where the plan advances one step per period) with one exchange, then the
// last solution's as it stands (right when the error persists) with up to iter exchanges,
// then the bounds the unconstrained minimiser crosses with 4·iter (free inputs outside the
// box fixed at the bound they cross, fixed inputs whose multiplier has the wrong sign freed).
bool BoxActiveSet::solve(const Vec& g, double lo, double hi, const Vec& last, int iter,
                         double eps) {
  if (iter < 0) return false;
  u0_ = u_;  // the unconstrained minimiser −H⁻¹g
  const double guess_tol = 1e-6 * std::max(1.0, hi - lo);
  // A last solution inside the box (the arm tracking, or a new run) gives no active input to
  // guess: from it, the first exchange reaches the bounds u0 crosses, the third guess below,
  // which has more exchanges than either: straight to it (an activation's first step).
  bool any_active = false;
  for (int j = 0; j < Nc_ && !any_active; ++j)
    any_active = last[j] <= lo + guess_tol || last[j] >= hi - guess_tol;
  for (int shifted = Nc_ > 1 ? 1 : 0; any_active && shifted >= 0; --shifted) {
    for (int j = 0; j < Nc_; ++j) {
      const double c = last[shifted && j + 1 < Nc_ ? j + 1 : j];
      state_[j] = c <= lo + guess_tol ? -1 : (c >= hi - guess_tol ? 1 : 0);
    }
    if (exchange(g, lo, hi, shifted ? std::min(1, iter) : iter, eps)) return true;
  }
  // Failing those (a new error, the first step): the bounds that the unconstrained minimiser
  // u0 crosses, with more exchanges (further off than a last solution's).
  for (int j = 0; j < Nc_; ++j) state_[j] = u0_[j] < lo ? -1 : (u0_[j] > hi ? 1 : 0);
  return exchange(g, lo, hi, 4 * iter, eps);
}

// Each guess fixes its active inputs at their bounds and solves H_FF u_F = −(g_F + H_FA u_A)
// for the free ones (or, with fewer active than free inputs, the same point as
// u = u0 − H⁻¹E_A μ, (H⁻¹)_AA μ = u0_A − u_A from u0 = −H⁻¹g: a Cholesky factorisation of
// the smaller size), then tests the KKT conditions; a violated bound joins the active set,
// a wrong-signed multiplier leaves it.
bool BoxActiveSet::exchange(const Vec& g, double lo, double hi, int exchanges, double eps) {
  const int Nc = Nc_;
  for (int it = 0; it <= exchanges; ++it) {
    free_.clear();
    for (int j = 0; j < Nc; ++j) {
      if (state_[j] == 0) free_.push_back(j);
      else u_[j] = state_[j] < 0 ? lo : hi;
    }
    const int m = static_cast<int>(free_.size()), a = Nc - m;
    if (m > 0 && m <= a) {  // H_FF u_F = −(g_F + H_FA u_A), a Cholesky of size m
      for (int p = 0; p < m; ++p) {
        double s = -g[free_[p]];
        for (int j = 0; j < Nc; ++j)
          if (state_[j] != 0) s -= H_(free_[p], j) * u_[j];
        rhs_[p] = s;
        for (int q = 0; q <= p; ++q) HFF_(p, q) = H_(free_[p], free_[q]);
      }
      Eigen::Ref<Mat> block_ref = HFF_.topLeftCorner(m, m);
      Eigen::LLT<Eigen::Ref<Mat>, Eigen::Lower> llt(block_ref);
      if (llt.info() != Eigen::Success) return false;
      auto sol = rhs_.head(m);
      llt.solveInPlace(sol);
      for (int p = 0; p < m; ++p) u_[free_[p]] = sol[p];
    } else if (m > 0) {  // fewer active inputs: u = u0 − H⁻¹ E_A μ with (H⁻¹)_AA μ = u0_A − u_A
      active_.clear();
      for (int j = 0; j < Nc; ++j)
        if (state_[j] != 0) active_.push_back(j);
      for (int p = 0; p < a; ++p) {
        rhs_[p] = u0_[active_[p]] - u_[active_[p]];
        for (int q = 0; q <= p; ++q) HFF_(p, q) = -neg_Hinv_(active_[p], active_[q]);
      }
      Eigen::Ref<Mat> block_ref = HFF_.topLeftCorner(a, a);
      Eigen::LLT<Eigen::Ref<Mat>, Eigen::Lower> llt(block_ref);
      if (llt.info() != Eigen::Success) return false;
      auto mu = rhs_.head(a);
      llt.solveInPlace(mu);
      for (int p = 0; p < m; ++p) {
        double s = u0_[free_[p]];
        for (int q = 0; q < a; ++q) s += neg_Hinv_(free_[p], active_[q]) * mu[q];
        u_[free_[p]] = s;
      }
    }
    r_.noalias() = H_ * u_;
    r_ += g;
    bool ok = true;
    for (int j = 0; j < Nc; ++j) {
      const int s = state_[j];
      if (s == 0) {
        if (u_[j] < lo - eps) { state_[j] = -1; ok = false; }
        else if (u_[j] > hi + eps) { state_[j] = 1; ok = false; }
        else if (std::abs(r_[j]) > eps) return false;  // stationarity lost to rounding
      } else if (s * r_[j] > eps) {  // lower bound: r >= 0; upper: r <= 0
        state_[j] = 0;
        ok = false;
      }
    }
    if (ok) {
      u_ = u_.cwiseMax(lo).cwiseMin(hi);
      for (int j = 0; j < Nc; ++j) r_[j] = state_[j] == 0 ? 0.0 : -r_[j];
      return true;
    }
  }
  return false;
}

}  // namespace hmpc
