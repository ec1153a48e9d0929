// The compiled Measurement (interfaces.hpp): an arm's interface as hmpc_pin.sim.sensing
// models it, and the plain noise + delay of hmpc_pin.controllers.wrappers.MeasuredController.
//
// Interface model (exact = false). The plant's states at the control instants t_k = k Ts are
// kept (the last `keep` of them); the angle in between is the cubic Hermite interpolant of the
// angles and velocities at the two instants around it, and before the start
// q(t) = q0 + t q̇0. At t_k the interface has sampled the arm at t_k − L − i T_if
// (i = m−1 … 0, m = Ts/T_if; one sample at k = 0): each angle quantised by the encoder,
//   q̃ = Δ round(q/Δ)  (Δ = 2π/N [rad], 0: exact),
// the velocity the backward difference (q̃_i − q̃_{i−1})/T_if of those angles, low-passed
//   y_i = a x_i + (1 − a) y_{i−1}  (libfranka's lowpassFilter, a = T/(T + 1/(2π f_c)))
// (the first sample: the interpolant's velocity), or the interpolant's velocity; then white
// noise q̃ + σ_q ε, q̃̇ + σ_q̇ ε' (ε, ε' standard normal, drawn only when a σ is not 0), and
// the measurement of t_{k−D} handed over (before that, the first). The commanded torque is
// filtered by the same low-pass at the interface rate over the period's m samples, and the
// plant holds their mean (the first command passes and settles the filter).
//
// Plain model (exact = true): the state at t_k as is, noise drawn at every measurement (also
// when both σ are 0), delay D; no torque filter.
//
// Every floating-point operation is the one hmpc_pin.sim.sensing and MeasuredController did
// in numpy, in the same order, so that a run is bit-identical to theirs. The noise comes from
// the caller (`normals`: count standard normal draws per call, 2n per measurement, q's first),
// so that a seeded numpy Generator gives the same stream as before.
#pragma once

#include "hmpc/interfaces.hpp"

#include <functional>
#include <vector>

namespace hmpc {

// count standard normal draws into out.
using NormalSource = std::function<void(double* out, Eigen::Index count)>;

// The settings of SensingMeasurement (each one of hmpc_pin.sim.sensing).
struct SensingSettings {
  bool exact = false;            // the plain model (noise and delay only)
  double Ts = 0.0;               // the control period [s]
  int ticks = 1;                 // m, interface periods per control period
  double Tif = 0.0;              // the interface period T_if [s]
  double latency = 0.0;          // L [s]
  int keep = 3;                  // control instants kept (ceil(L/Ts) + 3)
  bool encoder = false;          // quantise the angle
  Vec encoder_step;              // Δ [rad], one value or one per joint (0: exact)
  bool finite_difference = false;  // the velocity from the quantised angles
  double velocity_gain = 1.0;    // a of the velocity's low-pass (1: none)
  double q_noise = 0.0;          // σ_q [rad]
  double dq_noise = 0.0;         // σ_q̇ [rad/s]
  int delay = 0;                 // D [control periods]
  bool torque_filter = false;    // filter the commanded torque
  double torque_gain = 1.0;      // a of the torque's low-pass
};

class SensingMeasurement : public Measurement {
 public:
  SensingMeasurement(const SensingSettings& settings, NormalSource normals);
  void reset(const CRefVec& q0, const CRefVec& dq0) override;
  void measure(double t, const CRefVec& q, const CRefVec& dq) override;
  void command(RefVec tau) override;
  const SensingSettings s;

 private:
  void take();                         // the measurement of instant k into its delay slot
  void sample(double t);               // one interface sample at t into qr, dr
  struct Segment {
    const Vec &q0, &v0, &q1, &v1;  // the states at the segment's two control instants
    double x;                      // the position within it, in control periods
  };
  Segment segment(double sk) const;    // the history's segment around sk = t/Ts > 0
  void angle(double t, Vec& out) const;
  void velocity(double t, Vec& out) const;
  long slot(long j) const;             // the history slot of control index j (clamped)
  NormalSource normals;
  int n = 0;
  long k = 0, k0 = 0;                  // the newest and the oldest kept control index
  std::vector<Vec> hq, hv;             // the kept states, index j at j % keep
  std::vector<Vec> bq, bv;             // the last D+1 measurements, index j at j % (D+1)
  Vec qx, dqx;                         // the plain model's state at t_k
  Vec qr, dr, qa, qprev, dqfilt, z, tauf, total;
  bool has_prev = false, tau_started = false;
};

}  // namespace hmpc
