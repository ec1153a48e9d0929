// The closed loop (hmpc_pin.sim.compiled_loop): the per-step loop of
// hmpc_pin.sim.simulate.simulate, many control periods per call, over the ports of
// interfaces.hpp: the controller is a Controller port (the hierarchical MPC's compiled step,
// StepController of step.hpp, with its Measurement and Reference ports; or a Python
// controller as a whole), the plant a Plant port (the compiled RK4 plant of rk4_plant.hpp,
// or a Python plant). Per step k, as the per-step oracle loop does:
//   τ, d̂ = controller(t_k, q, q̇) (timed) →
//   record q, q̇, τ, d, d̂ → recorded(k) → (k = K: stop) → τ finite →
//   clip to the effort limit (count, largest excess) → record τ applied → plant period →
//   d recorded made the disturbance applied at the period's start (the Plant port's
//   applied_disturbance) → state finite and within the bound.
// run() returns the step where it stopped: k1 (the chunk ran) or the last step K (recorded).
// Around the chunk's steps the controller's chunk hooks are called (interfaces.hpp:
// reserve(k1 − k0) before, give_back() after, also when a fault stops the chunk).
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
  // plant: the plant (the caller keeps it alive); n: the joints. The controller:
  // set_controller().
  ClosedLoop(Plant* plant, int n, const double* t, int K,
             std::array<double*, 6> records,
             std::int64_t* step_ns, std::int64_t* sat_steps, double* sat_excess,
             const CRefVec& limit, bool has_limit, double bound, double Ts);

  // The controller is `c` (called with the plant's state; the caller keeps it alive).
  void set_controller(Controller* c) { controller = c; }

  // Steps k0 .. k1-1 from the plant's state (q, v) (updated in place).
  long run(RefVec q, RefVec v, long k0, long k1);

  std::function<void()> interrupted;  // called before every step (may throw)
  std::function<void(long)> recorded;  // called with k once step k is recorded (may throw)
  Plant* plant;
  int n, K;
  const double* t_arr;
  std::array<double*, 6> rec;
  std::int64_t *step_ns, *sat_steps;
  double* sat_excess;
  Vec limit;
  bool has_limit;
  double bound;
  double Ts;
  Controller* controller = nullptr;
  long k = 0;         // the step being run
  long last = -1;     // the last recorded step
  long advances = 0;  // plant periods integrated by run()
  long started = 0;   // steps begun by run()
  long stepped = 0;   // controller steps that succeeded

 private:
  void steps(RefVec q, RefVec v, long k0, long k1);
  bool record_and_advance(RefVec q, RefVec v);
  Vec tau, d, dh, qn, vn;
};

}  // namespace hmpc
