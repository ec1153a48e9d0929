// The RK4 plant as the loop's Plant port (interfaces.hpp), compiled: the arm's state
// (q, q̇) at t_k = t0 + k·Ts, advanced one control period per call by the RK4 period of
// rk4.hpp with the torque τ held, and its disturbance d(t, q, q̇) (Eq 1: τ + d), a
// Disturbance port (a sum's terms read through terms()), either
//   fused, when its terms are of time alone or one Coulomb-viscous friction (kind()): the
//     time-only terms evaluated at the stage times of the period (rows t_s, then t_s + h/2,
//     then t_s + h, s = 0..S−1: 3S rows, one at_times call per term and period, summed in
//     the terms' order) added to the held torque, the friction −(a q̇ + b sgn q̇) evaluated
//     per stage by the period (its Coulomb part by the stick-slip law);
//   or called at every stage (any other term), the friction terms among them named to the
//     period (RK4::set_friction_in_disturbance) so that they follow the same law.
// disturbance_now() is d at (t_k, q, q̇): the first stage row of period k minus the
// friction, or the port's value; applied_disturbance(d), after a period, adds the Coulomb
// torque the disturbance applied at its start to the joints that started it at rest (RK4's
// start_coulomb: with the stick-slip law, the disturbance's share of a stuck joint's holding
// torque, or its breakaway sign). hmpc_pin.sim.plants.RK4Plant owns one and steps it, and
// the compiled loop (loop.hpp) calls it like any other plant.
#pragma once

#include "hmpc/interfaces.hpp"
#include "hmpc/rk4.hpp"

#include <memory>
#include <vector>

namespace hmpc {

class RK4Plant : public Plant {
 public:
  // rk4: the compiled period (shared with its owner); Ts = substeps·h [s]. No disturbance
  // until set_disturbance.
  RK4Plant(std::shared_ptr<RK4> rk4, double Ts, int substeps);

  // Start at (q0, q̇0) at time t0 [s], period 0.
  void reset(const CRefVec& q0, const CRefVec& dq0, double t0);

  // The disturbance (nullptr: none); the caller keeps it and its terms alive.
  void set_disturbance(Disturbance* d);
  // Whether the disturbance is fused into the period (above).
  bool fused() const { return !general; }

  void advance(const Vec& tau, Vec& q_out, Vec& dq_out) override;
  Vec disturbance_now() override;
  void applied_disturbance(RefVec d) override;

  std::shared_ptr<RK4> rk4;
  const int n, substeps;
  const double Ts, h;
  Vec q, v;           // the state at t_k [rad, rad/s]
  long k = 0;         // the period
  double t0 = 0.0;    // the time of period 0 [s]
  double t() const { return t0 + Ts * static_cast<double>(k); }

 private:
  void stage_rows();  // the time-only terms' rows of period k into P (once per period)
  Disturbance* general = nullptr;      // called at every stage (not fused)
  std::vector<Disturbance*> time_only;  // fused: evaluated at the stage times
  Vec a, b;                            // fused: the friction's coefficients
  bool friction = false;               // fused: a friction term
  RowMat P, T, part;                   // the period's time-only rows; stage torques
  Vec times;                           // the period's stage times
  long rows_k = -1;                    // the period P holds (-1: none)
};

}  // namespace hmpc
