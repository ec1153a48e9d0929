// Pinocchio behind an Eigen-only interface: see dynamics.hpp.
#include "hmpc/dynamics.hpp"

#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/multibody.hpp>
#include <pinocchio/serialization.hpp>

#include <stdexcept>

namespace hmpc {

struct Dynamics::Impl {
  pinocchio::Model model;
  pinocchio::Data data;
};

Dynamics::Dynamics(const std::string& serialized) : impl_(std::make_unique<Impl>()) {
  impl_->model.loadFromString(serialized);
  if (impl_->model.nq != impl_->model.nv)
    throw std::invalid_argument("native kernels need nq == nv (no free-flyer, no "
                                "quaternion joints); use backend = \"python\"");
  impl_->data = pinocchio::Data(impl_->model);
  n = impl_->model.nv;
}

Dynamics::~Dynamics() = default;
Dynamics::Dynamics(Dynamics&&) noexcept = default;
Dynamics& Dynamics::operator=(Dynamics&&) noexcept = default;

const Dynamics::Mat& Dynamics::mass_matrix(const CRefVec& q) {
  auto& data = impl_->data;
  pinocchio::crba(impl_->model, data, q, pinocchio::Convention::LOCAL);
  data.M.triangularView<Eigen::StrictlyLower>() =
      data.M.transpose().triangularView<Eigen::StrictlyLower>();
  return data.M;
}

const Dynamics::Vec& Dynamics::nle(const CRefVec& q, const CRefVec& v) {
  return pinocchio::nonLinearEffects(impl_->model, impl_->data, q, v);
}

const Dynamics::Vec& Dynamics::aba(const CRefVec& q, const CRefVec& v, const CRefVec& tau) {
  return pinocchio::aba(impl_->model, impl_->data, q, v, tau, pinocchio::Convention::LOCAL);
}

}  // namespace hmpc
