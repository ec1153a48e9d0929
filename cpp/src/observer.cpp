// The NDO of Eq (13): see observer.hpp.
#include "hmpc/observer.hpp"

#include "hmpc/small_dense.hpp"

#include <limits>
#include <stdexcept>

namespace hmpc {

NDO::NDO(const CRefMat& cY_, double Ts, bool implicit_)
    : n(static_cast<int>(cY_.rows())), implicit(implicit_), cY(cY_), TcY(Ts * cY_),
      z(Vec::Zero(cY_.rows())), d_hat(Vec::Zero(cY_.rows())) {
  if (cY.rows() != cY.cols()) throw std::invalid_argument("NDO: cY must be square");
  symmetric_ = !implicit || (cY - cY.transpose()).isZero(0.0);
  diagonal_ = Mat(cY.diagonal().asDiagonal()) == cY;
  p_.setZero(n);
  rhs_.setZero(n);
  w_.setZero(n);
  A_.setZero(n, n);
  F_.setZero(n, n);
  perm_.setZero(n);
}

void NDO::reset(const CRefVec& dq0) {
  if (dq0.size() != n) throw std::invalid_argument("NDO.reset: dq0 of wrong size");
  z.noalias() = -(cY * dq0);
  d_hat.setZero();
}

void NDO::update(const CRefMat& M, const CRefVec& nle, const CRefVec& dq,
                 const CRefVec& tau_prev) {
  if (diagonal_) p_ = cY.diagonal().cwiseProduct(dq);
  else p_.noalias() = cY * dq;
  rhs_ = nle - tau_prev;
  rhs_ -= p_;
  rhs_ -= z;
  if (implicit) A_ = M + TcY;
  else A_ = M;
  w_ = rhs_;
  if (symmetric_ && cholesky(A_, F_)) {
    cholesky_solve(F_, w_);
  } else {
    F_ = A_;
    if (!lu_factor(F_, perm_)) F_.setConstant(std::numeric_limits<double>::quiet_NaN());
    lu_solve(F_, perm_, w_);
  }
  if (diagonal_) z += TcY.diagonal().cwiseProduct(w_);
  else z.noalias() += TcY * w_;
  d_hat = z + p_;
}

}  // namespace hmpc
