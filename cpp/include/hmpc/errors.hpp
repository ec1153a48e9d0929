// The faults of the library, as exceptions carrying what a caller needs to say what was
// wrong: the Python bindings translate each, in one place (bindings/python/expose_errors.cpp),
// to the matching class of hmpc_pin.exceptions. Programming errors (wrong shapes given by
// the package itself) stay std::invalid_argument.
#pragma once

#include "hmpc/types.hpp"

#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace hmpc {

// The base of every fault below.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// An input or a result is not finite: `name` ("t", "q", "dq", "reference", "tau",
// "plant state", ...), its value (a scalar, one vector, or several vectors), and the time
// it belongs to when that is not the step's own (`at`).
class NonFinite : public Error {
 public:
  NonFinite(std::string name, std::vector<Vec> values, std::optional<double> at = std::nullopt);
  NonFinite(std::string name, double value);
  std::string name;
  std::vector<Vec> values;
  std::optional<double> scalar, at;
};

// A vector has `size` entries where the robot has `expected` joints; `robot` describes the
// robot ("the robot 'panda' has 7 joints (...)"), as the caller set it.
class DimensionMismatch : public Error {
 public:
  DimensionMismatch(std::string name, long size, long expected, std::string robot);
  std::string name, robot;
  long size, expected;
};

// A joint QP did not report solved: the joint (-1: the block QP of all joints), its name,
// ProxSuite's status and the iterations it ran.
class QPNotSolved : public Error {
 public:
  QPNotSolved(int joint, std::string joint_name, std::string status, long iterations);
  int joint;
  std::string joint_name, status;
  long iterations;
};

// The plant's state after the period ending at `t` [s] is not finite or leaves
// |q|, |q̇| <= bound.
class StateOutOfBound : public Error {
 public:
  StateOutOfBound(Vec q, Vec dq, double t, double bound);
  Vec q, dq;
  double t, bound;
  bool finite() const { return q.allFinite() && dq.allFinite(); }
};

}  // namespace hmpc
