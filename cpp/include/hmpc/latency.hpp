// The measurement latency known to the controller: L = m Ts + alpha Ts (0 <= alpha < 1).
// The observer is fed the torque applied over the interval its two measurements span
// (align()), and the MPC and the inverse dynamics start from the state predicted over L
// (predict()). Oracle: tests/reference/latency.py.
#pragma once

#include "hmpc/types.hpp"

#include <vector>

namespace hmpc {

class Latency {
 public:
  // L [s] at the control period Ts [s] for n joints (L = 0: off).
  void set(double L, double Ts, int n);

  // Whether the interval [t_{k-1} - L, t_k - L] between the last two measurements lies
  // after the start, k = steps finished since the start: the observer can be advanced over
  // it.
  bool ready(long steps) const { return steps >= m + 1 + (alpha > 0.0 ? 1 : 0); }

  // The torque applied over [t_{k-1} - L, t_k - L], averaged (the observer's input):
  //   alpha τ_{k-2-m} + (1 - alpha) τ_{k-1-m};  likewise the commanded acceleration.
  void align();

  // The state at t_k predicted from the measurement of t_k - L by the decoupled double
  // integrator q̈ = v with the accelerations commanded over [t_k - L, t_k]: v_{k-1-m} over
  // alpha Ts, then v_{k-m}, ..., v_{k-1} over Ts each (exact for piecewise-constant v).
  void predict(RefVec q, RefVec dq) const;

  // After a step: the torque the observer is to be fed for the period it was applied over,
  // and the commanded acceleration, enter the history.
  void record(const Vec& tau, const Vec& v);

  // Forget the history (a new run).
  void clear();

  bool on = false;
  int m = 0;
  double alpha = 0.0, Ts = 0.0;
  std::vector<Vec> tau_hist;  // tau_hist[j]: torque applied over [t_{k-1-j}, t_{k-j}), j = 0..m+1
  std::vector<Vec> v_hist;    // v_hist[j]: acceleration commanded then, j = 0..m+1
  Vec tau_obs, v_obs;         // the torque and acceleration aligned with the measurement
};

}  // namespace hmpc
