// The joint QPs' knobs (JointQPsOptions) and counters (JointQPsStats), as ProxSuite's
// Settings and Info: plain structs, bound to Python field by field
// (hmpc_pin._core.JointQPsOptions, JointQPsStats).
#pragma once

namespace hmpc {

struct JointQPsOptions {
  bool shortcut = true;  // "joint" layout: the exact shortcuts (off for tests)
  // ProxSuite's warm start shifted one step along the horizon (primal and dual); off: the
  // last solution as it stands (measured faster in a closed loop,
  // benchmarks/studies/long_horizon_active.py).
  bool shift = false;
  int active_set_iter = 4;  // "joint" layout: active-set exchanges (< 0: no active-set shortcut)
  // Soft QPs: primal-dual exchanges of the soft active-set shortcut per guess (< 0: ProxSuite
  // for every soft QP).
  int soft_active_set_iter = 8;
  // Soft QPs: the shortcut's exchanges per step over all joints (< 0: soft_step_work's). A
  // joint reached with none left answers the safe fallback (SoftLimits::fallback: the
  // box-only answer, its first input clipped to the accelerations that keep the next state
  // inside the limits, else the box's end nearest them), counted in soft_fallbacks, and
  // resumes its exchanges where they stopped at the next step. The step's exchanges are
  // spread over the joints whose soft QP it solves: each gets the exchanges left divided by
  // the joints left (rounded up), so that one joint's long activation cannot starve the
  // others. Under a bound the guesses are stages spread over steps (SoftLimits::bounded): a
  // stage out of its own exchanges hands over to the next; ProxSuite only for a joint whose
  // stages all failed within the step's exchanges.
  int soft_step_exchanges = -1;
  // Soft QPs: the step's work when soft_step_exchanges < 0, in exchanges × horizon steps (an
  // exchange costs O(N)): at most max(1, soft_step_work / N) exchanges per step (< 0: no
  // bound; opt-in: 1600, 16 exchanges at N = 100, leaves Panda's worst step at 1 kHz near
  // its period, BENCHMARKS.md "1 kHz").
  long soft_step_work = -1;
  // Soft QPs for every joint at every step (set by JointQPs::set_limits).
  bool always_constrained = false;
  // Soft limits: before the O(N) test of a joint's box-only prediction, the O(1) bound of
  // its reach (SoftLimits::inside); where the bound keeps every predicted state inside the
  // limits the test's answer (inside) is known without it (off: the test at every joint,
  // for tests; the answers are the same either way).
  bool soft_reach_test = true;
};

struct JointQPsStats {
  long cold_solves = 0;             // box QPs solved again by their cold twin
  long unconstrained_solves = 0;    // box QPs answered by −H⁻¹g inside the box
  long active_set_solves = 0;       // box QPs answered by the active-set shortcut
  long soft_active_set_solves = 0;  // soft QPs answered by the soft active-set shortcut
  // Guesses of the soft shortcut that did not answer: a pivot of the wrong sign (dependent
  // rows), the exchanges exhausted, the KKT test failed without an exchange to make.
  long soft_fail_pivot = 0, soft_fail_exchanges = 0, soft_fail_kkt = 0;
  long soft_exchanges = 0;  // the soft shortcut's exchanges (KKT solves), over all steps
  long soft_fallbacks = 0;  // soft QPs answered by the fallback (soft_step_exchanges spent)
  long soft_reach_inside = 0;  // limit tests answered by the reach bound alone (inside)
  long constrained = 0;           // joints whose soft QP was solved at the last step
  bool constrained_last = false;  // whether any was
};

}  // namespace hmpc
