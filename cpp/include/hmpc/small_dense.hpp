// Factorisations of an arm's small dense matrices (n of a few joints), written as plain loops:
// at these sizes Eigen's dynamic-size factorisations and triangular solves cost more in
// their dispatch than in their arithmetic. Used where the step factors a matrix every period:
// the observer's solve (observer.cpp) and the joint-damping zero-order-hold term's diagonal
// of M⁻¹ (joint_dynamics.cpp). Column-major storage (Mat), no allocation once sized.
#pragma once

#include "hmpc/types.hpp"

#include <cmath>
#include <utility>

namespace hmpc {

// L with A = L Lᵀ (Cholesky), L lower triangular into L's lower triangle (its strict upper
// triangle is not read), from A's lower triangle. False where A is not positive definite
// (a pivot <= 0 or not finite). L must be n×n.
inline bool cholesky(const Eigen::Ref<const Mat>& A, Mat& L) {
  const Eigen::Index n = A.rows();
  for (Eigen::Index j = 0; j < n; ++j) {
    double d = A(j, j);
    for (Eigen::Index k = 0; k < j; ++k) d -= L(j, k) * L(j, k);
    if (!(d > 0.0) || !std::isfinite(d)) return false;
    const double ljj = std::sqrt(d);
    L(j, j) = ljj;
    for (Eigen::Index i = j + 1; i < n; ++i) {
      double s = A(i, j);
      for (Eigen::Index k = 0; k < j; ++k) s -= L(i, k) * L(j, k);
      L(i, j) = s / ljj;
    }
  }
  return true;
}

// x = (L Lᵀ)⁻¹ x in place, L from cholesky().
inline void cholesky_solve(const Mat& L, Vec& x) {
  const Eigen::Index n = L.rows();
  for (Eigen::Index i = 0; i < n; ++i) {  // L y = x
    double s = x[i];
    for (Eigen::Index k = 0; k < i; ++k) s -= L(i, k) * x[k];
    x[i] = s / L(i, i);
  }
  for (Eigen::Index i = n - 1; i >= 0; --i) {  // Lᵀ x = y
    double s = x[i];
    for (Eigen::Index k = i + 1; k < n; ++k) s -= L(k, i) * x[k];
    x[i] = s / L(i, i);
  }
}

// (A⁻¹)_jj = ‖L⁻¹ e_j‖² for A = L Lᵀ (L from cholesky()); y: a work vector of n.
inline double inverse_diagonal(const Mat& L, Eigen::Index j, Vec& y) {
  const Eigen::Index n = L.rows();
  y[j] = 1.0 / L(j, j);
  double sum = y[j] * y[j];
  for (Eigen::Index i = j + 1; i < n; ++i) {  // L y = e_j, from row j on (y_i = 0 above)
    double s = 0.0;
    for (Eigen::Index k = j; k < i; ++k) s -= L(i, k) * y[k];
    y[i] = s / L(i, i);
    sum += y[i] * y[i];
  }
  return sum;
}

// A = P⁻¹ L U in place (LU with partial pivoting: L unit lower, U upper, in A), the row
// exchanges in perm (perm[k]: the row exchanged with row k at step k). False where a pivot
// is zero or not finite (A singular to working precision).
inline bool lu_factor(Mat& A, Eigen::VectorXi& perm) {
  const Eigen::Index n = A.rows();
  for (Eigen::Index k = 0; k < n; ++k) {
    Eigen::Index p = k;
    double best = std::abs(A(k, k));
    for (Eigen::Index i = k + 1; i < n; ++i) {
      if (std::abs(A(i, k)) > best) {
        best = std::abs(A(i, k));
        p = i;
      }
    }
    perm[k] = static_cast<int>(p);
    if (!(best > 0.0) || !std::isfinite(best)) return false;
    if (p != k)
      for (Eigen::Index c = 0; c < n; ++c) std::swap(A(k, c), A(p, c));
    const double inv = 1.0 / A(k, k);
    for (Eigen::Index i = k + 1; i < n; ++i) A(i, k) *= inv;
    for (Eigen::Index c = k + 1; c < n; ++c) {
      const double u = A(k, c);
      for (Eigen::Index i = k + 1; i < n; ++i) A(i, c) -= A(i, k) * u;
    }
  }
  return true;
}

// x = A⁻¹ x in place, A and perm from lu_factor().
inline void lu_solve(const Mat& A, const Eigen::VectorXi& perm, Vec& x) {
  const Eigen::Index n = A.rows();
  for (Eigen::Index k = 0; k < n; ++k)
    if (perm[k] != k) std::swap(x[k], x[perm[k]]);
  for (Eigen::Index i = 0; i < n; ++i) {  // L y = P x (unit diagonal)
    double s = x[i];
    for (Eigen::Index k = 0; k < i; ++k) s -= A(i, k) * x[k];
    x[i] = s;
  }
  for (Eigen::Index i = n - 1; i >= 0; --i) {  // U x = y
    double s = x[i];
    for (Eigen::Index k = i + 1; k < n; ++k) s -= A(i, k) * x[k];
    x[i] = s / A(i, i);
  }
}

}  // namespace hmpc
