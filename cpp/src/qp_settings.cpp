// The ProxSuite settings of a QP and a status's name: see qp_settings.hpp.
#include "hmpc/qp_settings.hpp"

namespace hmpc {

namespace pqp = proxsuite::proxqp;

QPSettings::QPSettings() {
  const pqp::Settings<double> d;  // ProxSuite's defaults
  initial_guess = d.initial_guess;
  eps_abs = d.eps_abs;
  eps_rel = d.eps_rel;
  eps_duality_gap_abs = d.eps_duality_gap_abs;
  eps_duality_gap_rel = d.eps_duality_gap_rel;
  eps_primal_inf = d.eps_primal_inf;
  eps_dual_inf = d.eps_dual_inf;
  max_iter = d.max_iter;
  verbose = d.verbose;
  check_duality_gap = d.check_duality_gap;
}

void QPSettings::apply(pqp::Settings<double>& s) const {
  s.initial_guess = initial_guess;
  s.eps_abs = eps_abs;
  s.eps_rel = eps_rel;
  s.max_iter = max_iter;
  s.verbose = verbose;
  s.check_duality_gap = check_duality_gap;
  s.eps_duality_gap_abs = eps_duality_gap_abs;
  s.eps_duality_gap_rel = eps_duality_gap_rel;
  s.eps_primal_inf = eps_primal_inf;
  s.eps_dual_inf = eps_dual_inf;
}

std::string status_name(pqp::QPSolverOutput status) {
  switch (status) {
    case pqp::QPSolverOutput::PROXQP_SOLVED: return "QPSolverOutput.PROXQP_SOLVED";
    case pqp::QPSolverOutput::PROXQP_MAX_ITER_REACHED: return "QPSolverOutput.PROXQP_MAX_ITER_REACHED";
    case pqp::QPSolverOutput::PROXQP_PRIMAL_INFEASIBLE: return "QPSolverOutput.PROXQP_PRIMAL_INFEASIBLE";
    case pqp::QPSolverOutput::PROXQP_DUAL_INFEASIBLE: return "QPSolverOutput.PROXQP_DUAL_INFEASIBLE";
    case pqp::QPSolverOutput::PROXQP_SOLVED_CLOSEST_PRIMAL_FEASIBLE:
      return "QPSolverOutput.PROXQP_SOLVED_CLOSEST_PRIMAL_FEASIBLE";
    case pqp::QPSolverOutput::PROXQP_NOT_RUN: return "QPSolverOutput.PROXQP_NOT_RUN";
  }
  return "QPSolverOutput.UNKNOWN";
}

}  // namespace hmpc
