// The ports of the loop: abstract parts the closed loop (loop.hpp) calls without knowing
// whether they are compiled (measurement.hpp) or written in Python (a subclass of the bound
// port, reached through the trampolines of bindings/python/trampolines.hpp).
//
// Measurement: what the controller is handed at each control instant t_k, and what the arm's
// interface does to the torque the controller commands.
//   reset(q0, q̇0)      the start of a run at (q0, q̇0) [rad, rad/s]: the measurement handed
//                      over at t_0 (qm, dqm);
//   measure(t_k, q, q̇) the plant's state at t_k, k >= 1: the measurement handed over at t_k;
//   command(τ)         the interface's filter of the commanded torque τ [N·m], in place
//                      (none by default).
// Its callers go through restart(q0, q̇0) (reset, once, by the controller's reset) and
// hand_over(t_k, q, q̇) (before every step: the measurement of reset at the first step after
// it, else measure's), so that whether a step was measured lives in the port (`started`);
// the step's Controller port (StepController, step.hpp) then calls command on the step's
// torque. The chunk hooks: reserve(m) before m steps of the closed loop (a measurement that
// draws noise may draw theirs at once), give_back() after them (the draws not used given
// back: the noise's source is where a draw per measurement leaves it); none by default.
//
// Disturbance: the torque d(t, q, q̇) [N·m] acting on the plant (Eq 1: τ + d), evaluated at
// every RK4 stage of a period and, for the record, at each t_k. It says what it is, so
// that the RK4 plant (rk4_plant.hpp) can fuse it into its period: kind() general (called at
// every stage), time_only (d of t alone: at_times(t_1..t_m) gives m rows at once, the
// plant's stage times of a period) or friction (−(a q̇ + b sgn q̇), sgn 0 = 0: coefficients()
// gives (a, b), whose Coulomb part the plant integrates by its stick-slip law); terms() lists
// a sum's terms (a single term: itself). The compiled ones (disturbances.hpp: the Gaussian
// pulses of Eq 33, the Coulomb-viscous friction of Eq 32, their sum) implement it; a Python
// callable, or a Python time-only term, plugs in through a trampoline.
//
// Reference: the MPC's horizon for a step at t, r(t + o_j) and ṙ(t + o_j) at the offsets
// o_j = j Ts, j = 1..N, written into rows 2..2N+1 of the step's stack
// [q; q̇; r_1..r_N; ṙ_1..ṙ_N] ((2 + 2N)×n). The references with a closed form (a sine, a
// piecewise polynomial: references.hpp) implement it compiled; any other (sampled in Python)
// plugs in through a trampoline.
//
// Compensation: the disturbance estimate d̂ [N·m] the step cancels (Eq 4:
// τ = M v + C q̇ + G − d̂), advanced once per control period by the step (step.hpp), which
// decides -- once, for every compensation -- where its model is evaluated (observer model,
// at the period's end or start) and, with a measurement latency, over which interval:
//   reset(q, q̇)               restart at the measured state (q, q̇) [rad, rad/s]: d̂ is
//                             then estimate() (zeros for the NDO);
//   update(M, n, q, q̇, τ, v)  one period: M [kg·m²] and n = C q̇ + G [N·m] of the model
//                             the step chose, (q, q̇) the measured state, τ [N·m] the torque
//                             applied over the period beyond the joint dynamics' J, v
//                             [rad/s²] the acceleration commanded over it; afterwards
//                             estimate() is d̂_k;
//   estimate()                d̂ now, n values.
// The NDO of Eq 13 (observer.hpp) implements it; a Python compensation (momentum observer,
// ISM, a user class) plugs in through a trampoline (bindings/python/trampolines.hpp).
//
// Controller: the torque τ_k [N·m] for the plant's state at t_k and the disturbance estimate
// d̂_k [N·m] of that step. The hierarchical MPC's compiled step implements it
// (StepController, step.hpp: the step behind its Measurement and Reference ports); any other
// controller (computed torque, a wrapper) plugs in here as a whole. reserve(m) and
// give_back() around m steps of the closed loop: the Measurement's chunk hooks, passed on.
//
// Plant: the arm, advanced over one control period with the torque τ [N·m] held (its new
// state into q, q̇), and the disturbance acting on it, for the record:
//   disturbance_now()       d(t_k, q, q̇) [N·m] at the state now (sgn 0 = 0 in a Coulomb
//                           term);
//   applied_disturbance(d)  after advance: d, disturbance_now() of the period's start,
//                           made the disturbance the plant applied at that start where the
//                           two differ (a joint at rest held by a Coulomb term: its holding
//                           torque with the period's torque, or its breakaway sign), in
//                           place; unchanged by default.
// The RK4 plant implements it compiled (rk4_plant.hpp); any other plant (semi-implicit
// Euler, MuJoCo) plugs in here from Python.
#pragma once

#include "hmpc/types.hpp"

#include <vector>

namespace hmpc {

class Compensation {
 public:
  virtual ~Compensation() = default;
  virtual void reset(const CRefVec& q, const CRefVec& dq) = 0;
  virtual void update(const CRefMat& M, const CRefVec& nle, const CRefVec& q, const CRefVec& dq,
                      const CRefVec& tau, const CRefVec& v) = 0;
  virtual CRefVec estimate() const = 0;
};

class Measurement {
 public:
  virtual ~Measurement() = default;
  virtual void reset(const CRefVec& q0, const CRefVec& dq0) = 0;
  virtual void measure(double t, const CRefVec& q, const CRefVec& dq) = 0;
  virtual void command(RefVec tau) { (void)tau; }
  virtual void reserve(long steps) { (void)steps; }
  virtual void give_back() {}
  // reset(q0, q̇0): a run starts; the first hand_over hands over its measurement.
  void restart(const CRefVec& q0, const CRefVec& dq0) {
    started = false;
    reset(q0, dq0);
  }
  // The measurement handed over at t_k (into qm, dqm): reset's at the first step after it,
  // measure(t, q, q̇)'s afterwards.
  void hand_over(double t, const CRefVec& q, const CRefVec& dq) {
    if (started) measure(t, q, dq);
    started = true;
  }
  Vec qm, dqm;           // the measurement handed over now [rad, rad/s]
  bool started = false;  // a step was handed a measurement since restart
};

class Plant {
 public:
  virtual ~Plant() = default;
  virtual void advance(const Vec& tau, Vec& q, Vec& dq) = 0;
  virtual Vec disturbance_now() = 0;
  virtual void applied_disturbance(RefVec d) { (void)d; }
};

class Controller {
 public:
  virtual ~Controller() = default;
  virtual void step(double t, const Vec& q, const Vec& dq, Vec& tau, Vec& dhat) = 0;
  virtual void reserve(long steps) { (void)steps; }
  virtual void give_back() {}
};

class Reference {
 public:
  virtual ~Reference() = default;
  virtual void horizon(double t, const CRefVec& offsets, Eigen::Ref<RowMat> stack) = 0;
};

class Disturbance {
 public:
  enum class Kind { general, time_only, friction };
  virtual ~Disturbance() = default;
  virtual Vec at(double t, const Vec& q, const Vec& dq) = 0;
  virtual Kind kind() const { return Kind::general; }
  // time_only: d at each of ts into the rows of out (m×n).
  virtual void at_times(const CRefVec& ts, Eigen::Ref<RowMat> out) {
    const Vec none;
    for (Eigen::Index i = 0; i < ts.size(); ++i) out.row(i) = at(ts[i], none, none).transpose();
  }
  // friction: (a, b) of −(a q̇ + b sgn q̇), n each.
  virtual void coefficients(Vec& a, Vec& b) const {
    (void)a;
    (void)b;
  }
  // The summed terms (a single term: itself).
  virtual std::vector<Disturbance*> terms() { return {this}; }
};

}  // namespace hmpc
