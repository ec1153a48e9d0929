// The closed loop (hmpc_pin.sim.compiled_loop): the per-step loop of
// hmpc_pin.sim.simulate.simulate, many control periods per call, over the ports of
// interfaces.hpp: the controller is a Controller port (the hierarchical MPC's compiled step,
// StepController of step.hpp, with its Measurement and Reference ports; or a Python
// controller as a whole), the plant the RK4 plant's period with its fused disturbance
// (time-only terms tabulated by the caller, one Coulomb-viscous friction here) or a
// Disturbance port called at every stage (a Python callable), or a Plant port. Per step k,
// as the Python loop does:
//   τ, d̂ = controller(t_k, q, q̇) (timed) →
//   record q, q̇, τ, d, d̂ → recorded(k) → (k = K: stop) → τ finite →
//   clip to the effort limit (count, largest excess) → record τ applied → RK4 period →
//   state finite and within the bound.
// run() returns the step where it stopped: k1 (the chunk ran) or the last step K (recorded).
// A fault throws (errors.hpp), with `k` the step during which it was detected: the
// controller's step (its fault or its ports', nothing recorded at k), NonFinite (τ not finite, recorded at
// k) or StateOutOfBound (the plant's state over the period from t_k, recorded at k).
// `interrupted` is called before every step (it may throw to stop the run, with `last` the
// last recorded step).
//
// Every array (times, records, timings, saturation counts, measurement history) is the
// caller's memory, written in place; the caller keeps it alive as long as the loop.
#pragma once

#include "hmpc/errors.hpp"
#include "hmpc/interfaces.hpp"
#include "hmpc/rk4.hpp"
#include "hmpc/types.hpp"

#include <array>
#include <cstdint>
#include <functional>
#include <utility>

namespace hmpc {

class ClosedLoop {
 public:
  // t: K+1 instants [s]; records: q, q̇, τ, d, d̂, τ applied, each (K+1)×n row-major;
  // step_ns: K+1 step times [ns]; sat_steps, sat_excess: n each; Ts: the control period [s]
  // (for the time of a fault of the plant).
  // plant: the compiled RK4 period (nullptr: a Plant port, set_plant()); n: the joints.
  // The controller: set_controller().
  ClosedLoop(RK4* plant, int n, const double* t, int K,
             std::array<double*, 6> records,
             std::int64_t* step_ns, std::int64_t* sat_steps, double* sat_excess,
             const CRefVec& limit, bool has_limit, double bound, const CRefVec& a,
             const CRefVec& b, bool friction, double h, int substeps, double Ts);

  // The controller is `c` (called with the plant's state; the caller keeps it alive).
  void set_controller(Controller* c) { controller = c; }

  // The plant is `p` (advanced, and asked its disturbance, from here; the caller keeps it
  // alive; no table, no friction, no disturbance port then).
  void set_plant(Plant* p) { plant_port = p; }

  // The plant's disturbance is `d`, called at every stage and for the record (the caller
  // keeps it alive; no table of time-only terms, no friction then); nullptr: the fused one.
  void set_disturbance(Disturbance* d);

  // Steps k0 .. k1-1 from the plant state (q, v) (updated in place). P: the time-only
  // terms at the stage times of periods k0.. (rows of 3·substeps each; none: 0 rows).
  long run(RefVec q, RefVec v, long k0, long k1, const CRefRow& P);

  std::function<void()> interrupted;  // called before every step (may throw)
  std::function<void(long)> recorded;  // called with k once step k is recorded (may throw)
  RK4* plant;
  int n, K;
  const double* t_arr;
  std::array<double*, 6> rec;
  std::int64_t *step_ns, *sat_steps;
  double* sat_excess;
  Vec limit, fa, fb;
  bool has_limit, friction;
  double bound, h;
  int substeps;
  double Ts;
  Disturbance* disturbance = nullptr;
  Controller* controller = nullptr;
  Plant* plant_port = nullptr;
  long k = 0;         // the step being run
  long last = -1;     // the last recorded step
  long advances = 0;  // plant periods integrated by run()
  long started = 0;   // steps begun by run()
  long stepped = 0;   // controller steps that succeeded

 private:
  bool record_and_advance(RefVec q, RefVec v, const CRefRow& P, long j);
  Vec tau, d, dh, qn, vn;
  RowMat T;
};

}  // namespace hmpc
