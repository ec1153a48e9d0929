// The step's data (Crocoddyl's model/data split): the memory one control step of the
// hierarchical MPC (step.hpp, HierarchicalStep) reads and writes, allocated here once per controller
// and kept across the steps it builds (a new compensation rebuilds the step, not its data).
// Python reads it through views of this memory (hmpc_pin._core.StepData: q, dq, q_ref,
// dq_ref, v, tau, d_hat, M, nle), never through offsets of its own.
#pragma once

#include "hmpc/types.hpp"

namespace hmpc {

struct StepData {
  // n joints, horizon of N steps.
  StepData(int n_, int N_)
      : n(n_), N(N_), stack(RowMat::Zero(2 + 2 * N_, n_)), v(RowMat::Zero(1, n_)),
        tau(RowMat::Zero(1, n_)), dhat(RowMat::Zero(1, n_)), M(RowMat::Zero(n_, n_)),
        nle(RowMat::Zero(1, n_)) {}

  int n, N;
  // [q; q̇; r_1..r_N; ṙ_1..ṙ_N] ((2 + 2N)×n, one column per joint): the state the step
  // starts from (the measurement, or with a latency its prediction) [rad, rad/s] and the
  // reference horizon r(t + jTs), ṙ(t + jTs), j = 1..N [rad, rad/s].
  RowMat stack;
  RowMat v;     // (1, n) commanded acceleration of the last step [rad/s²]
  RowMat tau;   // (1, n) commanded torque of the last step, Eq (4) [N·m]
  RowMat dhat;  // (1, n) disturbance estimate d̂ [N·m]
  RowMat M;     // (n, n) M(q) from the caller's model (without compiled dynamics) [kg·m²]
  RowMat nle;   // (1, n) its C q̇ + G (+ B q̇ + F sgn q̇ once the step added them) [N·m]

  auto q() { return stack.row(0); }
  auto dq() { return stack.row(1); }
  auto q_ref() { return stack.middleRows(2, N); }   // (N, n): r_1..r_N
  auto dq_ref() { return stack.bottomRows(N); }     // (N, n): ṙ_1..ṙ_N
};

}  // namespace hmpc
