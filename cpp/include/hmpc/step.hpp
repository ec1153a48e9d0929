// The hierarchical MPC's step (hmpc_pin.controllers.hierarchical.HierarchicalMPC.step),
// composed of the components: the reference behind its port (interfaces.hpp: a compiled
// one of references.hpp, or a Python reference through its trampoline), the gradient map, the
// dynamics (dynamics.hpp, or the caller's model for models it cannot load), the
// compensation behind its port (interfaces.hpp: the NDO of observer.hpp, or a Python
// compensation through its trampoline), the joint QPs (joint_qps.hpp), and the inverse
// dynamics τ = M v + C q̇ + G − d̂ (Eq 4). The rules of what the compensation is given --
// the observer's model at the period's end or start, the torque beyond the joint dynamics,
// with a latency the measured interval -- are here only, for every compensation.
//
// Crocoddyl's model/data split: the step's memory (the stack [q; q̇; r_1..r_N; ṙ_1..ṙ_N],
// v, τ, d̂, M, C q̇ + G) is a StepData (step_data.hpp) the step shares with its caller; the
// step holds it, the joint QPs and the compensation as long as it lives.
#pragma once

#include "hmpc/dynamics.hpp"
#include "hmpc/errors.hpp"
#include "hmpc/interfaces.hpp"
#include "hmpc/joint_dynamics.hpp"
#include "hmpc/latency.hpp"
#include "hmpc/observer.hpp"
#include "hmpc/step_data.hpp"
#include "hmpc/types.hpp"

#include <Eigen/Cholesky>

#include <functional>
#include <memory>
#include <optional>
#include <string>

namespace hmpc {

class JointQPs;

class HierarchicalStep {
 public:
  // model: a serialized Pinocchio model (none: M and nle come from the `model` function);
  // F: the condensed MPC's gradient map ((2 + 2N)×Nc, rows [q; q̇; r_1; ṙ_1; ..; r_N; ṙ_N],
  // CondensedMPC.FT), kept in the stack's order; qps: the joint QPs; comp: the compensation
  // this step advances (none: d̂ stays what reset() set); data: the step's memory (n joints,
  // horizon N).
  HierarchicalStep(const std::optional<std::string>& model, const CRefRow& F, int N,
           std::shared_ptr<JointQPs> qps, std::shared_ptr<Compensation> comp,
           std::shared_ptr<StepData> data);

  // The horizon offsets j·Ts, j = 1..N [s] at which fill() samples the compiled reference.
  void set_offsets(const CRefVec& offsets);

  // The reference whose horizon fill() samples (the caller keeps it alive; none: fill()
  // refuses).
  void set_reference(Reference* r) { reference = r; }

  // The stack's state and horizon rows for time t (through the Reference port).
  // Throws NonFinite (t, or q before a wrong-sized q̇) or DimensionMismatch (q or q̇ of a
  // size other than n); nothing changed then.
  void fill(double t, const CRefVec& q, const CRefVec& dq);
  // A whole step at time t: fill(), then step().
  void step_t(double t, const CRefVec& q, const CRefVec& dq);

  // The measurement latency L [s] at the control period Ts [s] (L = 0: off).
  void set_latency(double L, double Ts) { latency.set(L, Ts, n); }
  // Whether the compensation can be advanced over the interval between the last two
  // measurements.
  bool observer_ready() const { return latency.on ? latency.ready(steps) : started; }

  // The joint damping B [N·m·s/rad] and Coulomb friction F [N·m] to compensate (zeros:
  // none); Ts > 0 also applies their zero-order-hold terms (JointDynamics::zoh(), in
  // finish()).
  void set_joint_dynamics(const CRefVec& damping, const CRefVec& friction, double Ts);
  void set_observer_model(bool at_start) {
    obs_start = at_start;
    has_prev = false;
  }
  void set_effort(const CRefVec& limit);

  // Start a run: the estimate (the compensation's, after its own reset).
  void reset(const CRefVec& dhat0);

  // The first half of a step from the stack S: the gradients, and M, C q̇ + G (evaluate()).
  // t [s]: the step's time (for the fault's message). Throws NonFinite (an input is not
  // finite: nothing changed).
  void prepare(const CRefRow& S, double t);
  // The second half: the joint QPs for the gradients, then τ = M v + C q̇ + G − d̂ (Eq 4)
  // with d̂ in dhat. Throws QPNotSolved (a QP did not report solved).
  void finish();
  // One control step at time t [s] from the stack S = [q; q̇; r_1..r_N; ṙ_1..ṙ_N]
  // ((2 + 2N)×n), with the compensation (or none) advanced here. Throws as prepare(),
  // finish(), or what the compensation throws.
  void step(const CRefRow& S, double t);

  // The torque held over the period that just ended, as the plant applied it.
  const Vec& applied_torque();

  std::unique_ptr<Dynamics> dyn;  // null: M and nle come from `model`
  // Without compiled dynamics: writes M(q) and C(q, q̇) q̇ + G(q) at (q, q̇) into M_out,
  // nle_out (e.g. Pinocchio's Python API for mimic joints).
  std::function<void(const Vec& q, const Vec& dq)> model;
  int n, N, Nc;
  // Gradient map, rows in stack order [q; q̇; r_1..r_N; ṙ_1..ṙ_N]; rows used.
  RowMat FT;  // (2 + 2N)×Nc
  Eigen::Index grad_rows;
  Mat Gt;  // Nc×n: one column per joint (the memory of G, n×Nc row-major)
  std::shared_ptr<JointQPs> qps;
  std::shared_ptr<Compensation> comp_held;
  std::shared_ptr<StepData> data;
  JointQPs* qp;
  Compensation* comp;  // advanced by step(); null: none
  Vec effort;
  bool started = false;
  // The step's memory (data's): the stack [q; q̇; r_1..r_N; ṙ_1..ṙ_N], v, τ, d̂, and the
  // model's M, C q̇ + G (+ B q̇ + F sgn q̇ once evaluate() added them) without compiled
  // dynamics.
  RowMat &stack, &v, &tau, &dhat, &M_out, &nle_out;
  Vec applied, qv, dqv;
  const Mat* M = nullptr;    // M(q) of the last prepare (the dynamics' own, or none)
  const Vec* nle = nullptr;  // C q̇ + G of the last prepare
  bool external = false;     // the last prepare took M, nle from the caller (M_out, nle_out)
  Mat Mx;                    // the caller's M, C q̇ + G of the last evaluate()
  Vec nx, vprev;
  Reference* reference = nullptr;  // the horizon's (set_reference)
  Vec offsets;  // horizon offsets j·Ts, j = 1..N [s]
  // The measurement latency (off: the step is exactly the latency-free one).
  Latency latency;
  // Where the observer's model (M, C q̇ + G of Eq 13) is evaluated over the period that
  // just ended (set_observer_model): at its end, the new measurement (false, Eq 13's
  // backward Euler), or at its start, the state the torque held over it was computed from
  // (true; with latency, the previous measurement). At the start, the observer's residual
  // is what the held torque's model missed over the period, the correction Eq (4) needs for
  // the next one; at the end it is that residual minus the model's change over the period,
  // which Eq (4) then applies with the wrong sign (guide "Joint dynamics", observer model).
  bool obs_start = false;
  bool has_prev = false;  // with latency: prev_M, prev_nle hold the previous measurement's
  Mat prev_M;
  Vec prev_nle;
  long steps = 0;  // finished steps since reset
  // The arm's joint damping B and Coulomb friction F (the URDF's <dynamics>), compensated:
  // C q̇ + G becomes C q̇ + G + B q̇ + F sgn q̇ (for the observer and Eq 4), and with
  // zoh_Ts > 0 the commanded acceleration of a damped joint is scaled so that over a period
  // of the torque held the damped joint reaches the velocity the MPC's double integrator
  // predicts (finish()).
  JointDynamics joint;
  Vec nle_j, extra;  // C q̇ + G + B q̇ + F sgn q̇; the zero-order-hold terms
  // J = B q̇_k + F σ + ZOH gain: the joint-dynamics torque of the last finish(). The observer
  // is given the applied torque minus J and C q̇ + G without the joint terms: what the
  // joint dynamics took over the period J was designed to cancel, the model of Eq (13) is
  // the plain rigid body again (its Euler model of a damped joint would be wrong by g_j).
  Vec jtau;
  const Vec* nle0 = nullptr;  // C q̇ + G alone of the last prepare (compiled dynamics)
  double zoh_Ts = 0.0;
  // The robot as faults name it ("the robot 'panda' has 7 joints (...)").
  std::string robot = "the model";
  double t_now = 0.0;  // the time of the step being run [s]

 private:
  // The NonFinite fault of a stack with a non-finite entry: q, q̇, the first reference row
  // of the horizon that is not finite, or (none of those) the stack as a whole.
  [[noreturn]] void non_finite(const CRefRow& S) const;
  void sample_horizon(double t);
  // M, C q̇ + G (nle0) and C q̇ + G + B q̇ + F sgn q̇ (nle) at (q, q̇): the compiled dynamics,
  // else the caller's model (then Eq 4 reads M_out, nle_out, the joint terms added there).
  void evaluate(const Vec& q, const Vec& dq);
  void record();
  void step_latency(const CRefRow& S);
};

// The step as the loop's Controller port (interfaces.hpp): the controller sees the plant
// through the Measurement port `measurement` (none: the plant's state as is; its
// hand_over: the measurement of the first step was taken at its reset), samples its horizon
// through the core's Reference port (step_t), and the measurement's command() filters the
// torque; the chunk hooks go to the measurement. The caller keeps the core and the ports
// alive.
class StepController : public Controller {
 public:
  explicit StepController(HierarchicalStep* core);
  void step(double t, const Vec& q, const Vec& dq, Vec& tau, Vec& dhat) override;
  void reserve(long steps) override {
    if (measurement) measurement->reserve(steps);
  }
  void give_back() override {
    if (measurement) measurement->give_back();
  }

  HierarchicalStep* core;
  Measurement* measurement = nullptr;
};

}  // namespace hmpc
