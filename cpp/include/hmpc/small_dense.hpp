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

// U = Lᵀ with A = L Lᵀ (Cholesky), U upper triangular into U's upper triangle (its strict
// lower triangle is not read), from A's lower triangle: the columns of U are the rows of L,
// contiguous in memory. False where A is not positive definite (a pivot <= 0 or not
// finite). U must be n×n.
inline bool cholesky(const Eigen::Ref<const Mat>& A, Mat& U) {
  const Eigen::Index n = A.rows();
  double* u = U.data();
  for (Eigen::Index j = 0; j < n; ++j) {
    const double* uj = u + j * n;  // column j of U: row j of L
    double d = A(j, j);
    for (Eigen::Index k = 0; k < j; ++k) d -= uj[k] * uj[k];
    if (!(d > 0.0) || !std::isfinite(d)) return false;
    const double ujj = std::sqrt(d);
    u[j + j * n] = ujj;
    for (Eigen::Index i = j + 1; i < n; ++i) {
      const double* ui = u + i * n;
      double s = A(i, j);
      for (Eigen::Index k = 0; k < j; ++k) s -= ui[k] * uj[k];
      u[j + i * n] = s / ujj;  // L(i, j)
    }
  }
  return true;
}

// x = (Uᵀ U)⁻¹ x in place, U from cholesky().
inline void cholesky_solve(const Mat& U, Vec& x) {
  const Eigen::Index n = U.rows();
  const double* u = U.data();
  double* y = x.data();
  for (Eigen::Index i = 0; i < n; ++i) {  // Uᵀ y = x: row i of Uᵀ is column i of U
    const double* ui = u + i * n;
    double s = y[i];
    for (Eigen::Index k = 0; k < i; ++k) s -= ui[k] * y[k];
    y[i] = s / ui[i];
  }
  for (Eigen::Index i = n - 1; i >= 0; --i) {  // U x = y, by columns
    const double* ui = u + i * n;
    y[i] /= ui[i];
    const double yi = y[i];
    for (Eigen::Index k = 0; k < i; ++k) y[k] -= ui[k] * yi;
  }
}

// (A⁻¹)_jj = ‖U⁻ᵀ e_j‖² for A = Uᵀ U (U from cholesky()); y: a work vector of n.
inline double inverse_diagonal(const Mat& U, Eigen::Index j, Vec& y) {
  const Eigen::Index n = U.rows();
  const double* u = U.data();
  double* w = y.data();
  w[j] = 1.0 / u[j + j * n];
  double sum = w[j] * w[j];
  for (Eigen::Index i = j + 1; i < n; ++i) {  // Uᵀ w = e_j, from row j on (w_i = 0 above)
    const double* ui = u + i * n;
    double s = 0.0;
    for (Eigen::Index k = j; k < i; ++k) s -= ui[k] * w[k];
    w[i] = s / ui[i];
    sum += w[i] * w[i];
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
