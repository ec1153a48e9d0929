// The closed loop (hmpc_pin.sim.compiled_loop): the per-step loop of
// hmpc_pin.sim.simulate.simulate, many control periods per call, when every part has a
// compiled form: the controller's fused step with its compiled reference (HMPCCore.step_t),
// (or the step from a Reference port's horizon), optionally behind a Measurement port (interfaces.hpp: compiled, measurement.hpp, or a
// Python subclass), and the plant through its Plant port (the compiled RK4 plant of
// rk4_plant.hpp, or a Python plant). Per step k, as the per-step oracle loop does:
//   (k >= 1: measure(t_k, q, q̇)) → τ = step(t_k, measured state) → command(τ) →
//   record q, q̇, τ, d, d̂ → recorded(k) → (k = K: stop) → τ finite →
//   clip to the effort limit (count, largest excess) → record τ applied → plant period →
//   state finite and within the bound.
// run() returns the step where it stopped: k1 (the chunk ran) or the last step K (recorded).
// A fault throws (errors.hpp), with `k` the step during which it was detected: the
// controller's step (its fault, nothing recorded at k), NonFinite (τ not finite, recorded at
// k) or StateOutOfBound (the plant's state over the period from t_k, recorded at k).
// `interrupted` is called before every step (it may throw to stop the run, with `last` the
// last recorded step).
//
// Every array (times, records, timings, saturation counts, measurement history) is the
// caller's memory, written in place; the caller keeps it alive as long as the loop.
#pragma once

#include "hmpc/errors.hpp"
#include "hmpc/interfaces.hpp"
#include "hmpc/step.hpp"
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
  // core: the controller's compiled step (nullptr: a Controller port, set_controller());
  // plant: the plant (the caller keeps it alive); n: the joints.
  ClosedLoop(HMPCCore* core, Plant* plant, int n, const double* t, int K,
             std::array<double*, 6> records,
             std::int64_t* step_ns, std::int64_t* sat_steps, double* sat_excess,
             const CRefVec& limit, bool has_limit, double bound, double Ts);

  // The controller is `c` as a whole (called with the plant's state; no compiled step, no
  // measurement or reference port then; the caller keeps it alive).
  void set_controller(Controller* c) { controller = c; }

  // The controller sees the plant through `m` (reset by the caller with the controller; the
  // caller keeps it alive); nullptr: the plant's state as is.
  void set_measurement(Measurement* m);

  // The controller's reference is `r` (its horizon written into the step's stack, then the
  // step from the stack; the caller keeps it alive); nullptr: the compiled one (step_t).
  void set_reference(Reference* r) { reference = r; }

  // Steps k0 .. k1-1 from the plant's state (q, v) (updated in place).
  long run(RefVec q, RefVec v, long k0, long k1);

  std::function<void()> interrupted;  // called before every step (may throw)
  std::function<void(long)> recorded;  // called with k once step k is recorded (may throw)
  HMPCCore* core;
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
  Measurement* measurement = nullptr;
  Reference* reference = nullptr;
  Controller* controller = nullptr;
  long k = 0;         // the step being run
  long last = -1;     // the last recorded step
  long advances = 0;  // plant periods integrated by run()
  long started = 0;   // steps begun by run()
  long stepped = 0;   // controller steps that succeeded

 private:
  void compiled_step(const RefVec& q, const RefVec& v);
  bool record_and_advance(RefVec q, RefVec v);
  Vec qm, dqm, tau, d, dh, qn, vn;
};

}  // namespace hmpc
