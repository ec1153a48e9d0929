// Γ's products by the recursion: see gamma_recursion.hpp.
#include "hmpc/gamma_recursion.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace hmpc {

// X = Γ u (2N): by the recursion x_{j+1} = A x_j + B u_min(j, Nc−1), x_0 = 0 (Eq 24), in
// O(N), when set found Γ to be that recursion; else the dense product.
void GammaRecursion::apply(const Eigen::Ref<const Vec>& u, Vec& X) const {
  if (!rec_) {
    X.noalias() = Gamma_ * u;
    return;
  }
  double x = 0.0, v = 0.0;
  for (int j = 0; j < N_; ++j) {
    const double uj = u[std::min(j, Nc_ - 1)];
    const double xn = a_[0] * x + a_[1] * v + b_[0] * uj;
    v = a_[2] * x + a_[3] * v + b_[1] * uj;
    x = xn;
    X[2 * j] = x;
    X[2 * j + 1] = v;
  }
}

// out = Γᵀ λ (Nc) by the adjoint recursion μ_j = λ_j + Aᵀ μ_{j+1} (μ_{N+1} = 0), the input
// u_min(j−1, Nc−1) collecting Bᵀ μ_j (j = N .. 1), in O(N); else the dense product.
void GammaRecursion::apply_transpose(const Vec& lam, Vec& out) const {
  if (!rec_) {
    out.noalias() = Gamma_.transpose() * lam;
    return;
  }
  out.setZero();
  double m0 = 0.0, m1 = 0.0;
  for (int j = N_; j >= 1; --j) {
    const double n0 = lam[2 * (j - 1)] + a_[0] * m0 + a_[2] * m1;
    m1 = lam[2 * (j - 1) + 1] + a_[1] * m0 + a_[3] * m1;
    m0 = n0;
    out[std::min(j - 1, Nc_ - 1)] += b_[0] * m0 + b_[1] * m1;
  }
}

// Whether Γ is the recursion of apply with A = the first two rows of Φ and B = the first
// column's first two entries: every entry of the recursion's columns within 1e-12 of its
// row's largest |Γ| (the rows are the constraints, normalised per row); else the dense
// products are kept.
bool GammaRecursion::set(const Eigen::Ref<const Mat>& Phi, const Eigen::Ref<const Mat>& Gamma) {
  if (Phi.cols() != 2 || Gamma.rows() % 2 != 0 || Phi.rows() != Gamma.rows() ||
      Gamma.rows() < 2 || Gamma.cols() < 1)
    throw std::invalid_argument("GammaRecursion: Phi must be (2N, 2) and Gamma (2N, Nc)");
  Gamma_ = Gamma;
  N_ = static_cast<int>(Gamma.rows() / 2);
  Nc_ = static_cast<int>(Gamma.cols());
  a_[0] = Phi(0, 0);
  a_[1] = Phi(0, 1);
  a_[2] = Phi(1, 0);
  a_[3] = Phi(1, 1);
  b_[0] = Gamma_(0, 0);
  b_[1] = Gamma_(1, 0);
  const Vec row_max = Gamma_.cwiseAbs().rowwise().maxCoeff();
  rec_ = true;
  Vec e = Vec::Zero(Nc_), col(2 * N_);
  bool same = true;
  for (int c = 0; c < Nc_ && same; ++c) {
    e.setZero();
    e[c] = 1.0;
    apply(e, col);
    for (int r = 0; r < 2 * N_ && same; ++r)
      same = std::abs(col[r] - Gamma_(r, c)) <= 1e-12 * row_max[r];
  }
  rec_ = same;
  return same;
}

}  // namespace hmpc
