// The RK4 plant as the loop's Plant port (interfaces.hpp), compiled: the arm's state
// (q, q̇) at t_k = t0 + k·Ts, advanced one control period per call by the RK4 period of
// rk4.hpp with the torque τ held, and its disturbance d(t, q, q̇) (Eq 1: τ + d) either
//   fused: the time-only terms tabulated by the caller at the stage times of each period
//     (rows t_s, then t_s + h/2, then t_s + h, s = 0..S−1: 3S rows per period, set a chunk of
//     periods at a time with set_table), plus one Coulomb–viscous friction −(a q̇ + b sgn q̇);
//   or a Disturbance port (a Python callable) called at every stage.
// disturbance_now() is d at (t_k, q, q̇): the table's first row of period k minus the
// friction, or the port's value; applied_disturbance(d), after a period, adds the Coulomb
// torque the disturbance applied at its start to the joints that started it at rest (RK4's
// start_coulomb: with the stick-slip law, the disturbance's share of a stuck joint's holding
// torque, or its breakaway sign). hmpc_pin.sim.plants.RK4Plant owns one and steps it, and
// the compiled loop (loop.hpp) calls it like any other plant.
#pragma once

#include "hmpc/interfaces.hpp"
#include "hmpc/rk4.hpp"

#include <memory>

namespace hmpc {

class RK4Plant : public Plant {
 public:
  // rk4: the compiled period (shared with its owner); Ts = substeps·h [s]; (a, b): the
  // fused friction's coefficients, applied when `friction`.
  RK4Plant(std::shared_ptr<RK4> rk4, double Ts, int substeps, const CRefVec& a,
           const CRefVec& b, bool friction);

  // Start at (q0, q̇0) at time t0 [s], period 0 (the table is cleared).
  void reset(const CRefVec& q0, const CRefVec& dq0, double t0);

  // The time-only terms of periods k0 .. k0 + P.rows()/(3S) − 1 (copied).
  void set_table(const CRefRow& P, long k0);
  // The first period after the table (k0 when there is none).
  long table_end() const;

  // The disturbance as a port called at every stage (nullptr: the fused one); the caller
  // keeps it alive.
  void set_disturbance(Disturbance* d);

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
  const RowMat* rows_of(long period) const;  // nullptr: no table
  Vec a, b;
  bool friction;
  Disturbance* disturbance = nullptr;
  RowMat table, T;
  long table_k0 = 0;
};

}  // namespace hmpc
