// The faults of the library: see errors.hpp.
#include "hmpc/errors.hpp"

#include <utility>

namespace hmpc {

NonFinite::NonFinite(std::string name_, std::vector<Vec> values_, std::optional<double> at_)
    : Error(name_ + " is not finite"), name(std::move(name_)), values(std::move(values_)),
      at(at_) {}

NonFinite::NonFinite(std::string name_, double value)
    : Error(name_ + " is not finite"), name(std::move(name_)), scalar(value) {}

DimensionMismatch::DimensionMismatch(std::string name_, long size_, long expected_,
                                     std::string robot_)
    : Error(name_ + " has " + std::to_string(size_) + " entries but " + robot_),
      name(std::move(name_)), robot(std::move(robot_)), size(size_), expected(expected_) {}

QPNotSolved::QPNotSolved(int joint_, std::string joint_name_, std::string status_,
                         long iterations_)
    : Error("the MPC QP of " + joint_name_ + " was not solved: " + status_),
      joint(joint_), joint_name(std::move(joint_name_)), status(std::move(status_)),
      iterations(iterations_) {}

StateOutOfBound::StateOutOfBound(Vec q_, Vec dq_, double t_, double bound_)
    : Error("the plant state is not finite or beyond the bound"), q(std::move(q_)),
      dq(std::move(dq_)), t(t_), bound(bound_) {}

}  // namespace hmpc
