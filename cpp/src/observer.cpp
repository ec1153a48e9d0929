// The NDO of Eq (13): see observer.hpp.
#include "hmpc/observer.hpp"

#include <stdexcept>

namespace hmpc {

NDO::NDO(const CRefMat& cY_, double Ts, bool implicit_)
    : n(static_cast<int>(cY_.rows())), implicit(implicit_), cY(cY_), TcY(Ts * cY_),
      z(Vec::Zero(cY_.rows())), d_hat(Vec::Zero(cY_.rows())), lu_(cY_.rows()),
      llt_(cY_.rows()) {
  if (cY.rows() != cY.cols()) throw std::invalid_argument("NDO: cY must be square");
  symmetric_ = !implicit || (cY - cY.transpose()).isZero(0.0);
  p_.setZero(n);
  rhs_.setZero(n);
  w_.setZero(n);
}

void NDO::reset(const CRefVec& dq0) {
  if (dq0.size() != n) throw std::invalid_argument("NDO.reset: dq0 of wrong size");
  z.noalias() = -(cY * dq0);
  d_hat.setZero();
}

void NDO::update(const CRefMat& M, const CRefVec& nle, const CRefVec& dq,
                 const CRefVec& tau_prev) {
  p_.noalias() = cY * dq;
  rhs_ = nle - tau_prev;
  rhs_ -= p_;
  rhs_ -= z;
  if (symmetric_) {
    if (implicit) llt_.compute(M + TcY);
    else llt_.compute(M);
    if (llt_.info() == Eigen::Success) {
      w_ = rhs_;
      llt_.solveInPlace(w_);
      z.noalias() += TcY * w_;
      d_hat = z + p_;
      return;
    }
  }
  if (implicit) lu_.compute(M + TcY);
  else lu_.compute(M);
  w_ = lu_.solve(rhs_);
  z.noalias() += TcY * w_;
  d_hat = z + p_;
}

}  // namespace hmpc
