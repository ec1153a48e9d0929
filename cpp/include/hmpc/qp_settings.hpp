// The ProxSuite settings this package chooses for a QP (QPSettings) and the name of a
// ProxSuite status (status_name), shared by the joint QPs' parts (box_qp.hpp,
// soft_limits.hpp).
#pragma once

#include <proxsuite/proxqp/settings.hpp>
#include <proxsuite/proxqp/status.hpp>

#include <string>

namespace hmpc {

// The ProxSuite settings this package chooses for a QP, each a typed field, set on the QP
// after its construction and before init (the others keep ProxSuite's defaults). A
// default-constructed QPSettings holds ProxSuite's own defaults;
// hmpc_pin.mpc.condensed.qp_settings() chooses the package's values, in one place.
struct QPSettings {
  QPSettings();
  proxsuite::proxqp::InitialGuessStatus initial_guess;
  double eps_abs, eps_rel;                          // primal/dual residual tolerances
  double eps_duality_gap_abs, eps_duality_gap_rel;  // duality-gap test (check_duality_gap)
  double eps_primal_inf, eps_dual_inf;              // infeasibility tolerances
  long max_iter;
  bool verbose, check_duality_gap;
  void apply(proxsuite::proxqp::Settings<double>& s) const;
};

// "QPSolverOutput.PROXQP_SOLVED" etc., as ProxSuite's Python binding prints the status.
std::string status_name(proxsuite::proxqp::QPSolverOutput status);

}  // namespace hmpc
