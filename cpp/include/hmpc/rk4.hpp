// The RK4 plant's period (hmpc_pin.sim.plants.RK4Plant), the one implementation: classical
// Runge-Kutta steps of h with the torque held, the disturbance evaluated at every stage,
//   k1 = f(t_s, x), k2 = f(t_s + h/2, x + h/2 k1), k3 = f(t_s + h/2, x + h/2 k2),
//   k4 = f(t_s + h, x + h k3),  x += h/6 (k1 + 2 k2 + 2 k3 + k4),
//   f(t, [q; q̇]) = [q̇; ABA(q, q̇, τ + d(t, q, q̇) − B q̇ − F sgn q̇)].
// B q̇ + F sgn q̇ (sgn 0 = 0) is the arm's own joint damping and Coulomb friction, the URDF's
// <dynamics damping friction> (set_joint_dynamics; none by default), evaluated per stage.
// The disturbance is either fused (period(): time-only terms tabulated by the caller per
// stage time, one Coulomb-viscous friction −(a q̇ + b sgn q̇) here) or any function
// d(t, q, q̇) (period_with()). ABA is Pinocchio's, compiled, or a function given by the
// caller for models the compiled dynamics cannot load (mimic joints).
//
// Coulomb friction (stick_slip, the default): the known Coulomb terms (the joint friction F
// and the fused friction's b) by stick-slip events located within the steps, a joint at
// rest sticking while its holding torque is within ±F_i (StickSlip, stick_slip.hpp, which
// also records what a period applied: start_rest, start_coulomb). stick_slip = false: sgn
// per stage (earlier versions).
// Oracle: tests/reference/rk4.py.
#pragma once

#include "hmpc/dynamics.hpp"
#include "hmpc/joint_dynamics.hpp"
#include "hmpc/stick_slip.hpp"
#include "hmpc/types.hpp"

#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace hmpc {

class RK4 {
 public:
  // q̈ = ABA(q, q̇, τ), for models the compiled dynamics cannot load.
  using AbaFunction = std::function<Vec(const Vec& q, const Vec& v, const Vec& tau)>;
  // d(t, q, q̇) [N·m].
  using DisturbanceFunction = std::function<Vec(double t, const Vec& q, const Vec& v)>;

  // The compiled dynamics of a serialized Pinocchio model.
  explicit RK4(const std::string& model);
  // ABA given by the caller, for n joints.
  RK4(int n, AbaFunction aba);
  RK4(const RK4&) = delete;  // its StickSlip refers to it
  RK4& operator=(const RK4&) = delete;

  // The joint damping B and Coulomb friction F applied at every stage (zeros: none).
  void set_joint_dynamics(const CRefVec& damping, const CRefVec& friction);

  // Advance (q, v) in place over T.rows() / 3 steps of h. T holds, per stage time, the
  // torque without friction: rows t_s (s = 0..S-1), then t_s + h/2, then t_s + h.
  void period(RefVec q, RefVec v, const CRefRow& T, const CRefVec& a, const CRefVec& b,
              bool friction, double h);

  // The Coulomb-viscous friction −(a q̇ + b sgn q̇) that the disturbance function of
  // period_with contains (a user's sum of terms with a friction term): with stick_slip its
  // sign is taken as the fused friction's (the function's own term added back, then the
  // stick-slip one subtracted), so that a friction term follows the same law whether the
  // disturbance is fused or a function. Zeros: none.
  void set_friction_in_disturbance(const CRefVec& a, const CRefVec& b);

  // Advance (q, v) in place over S steps of h from time t with τ held, the disturbance
  // d(t, q, q̇) evaluated at every stage (stage times t_s = t + s·h, t_s + h/2, t_s + h).
  void period_with(RefVec q, RefVec v, const CRefVec& tau, double t, double h, int S,
                   const DisturbanceFunction& dist);

  // q̈ = ABA(q, q̇, τ) into `out`.
  void aba_into(const CRefVec& q, const CRefVec& v, const Vec& tau, Vec& out);

  bool stick_slip = true;  // Coulomb friction by event location and sticking (see above)
  long events = 0;         // events located since construction (sign changes, stick, slip)
  // After period() or period_with(): start_rest[i], whether joint i started the period at
  // rest with a Coulomb level (stick_slip); start_coulomb[i], the disturbance's Coulomb
  // torque applied to it then [N·m] (stick_slip.hpp; 0 where start_rest[i] is false).
  std::vector<char> start_rest;
  Vec start_coulomb;

  std::unique_ptr<Dynamics> dyn;  // null: aba_fn
  AbaFunction aba_fn;
  int n;
  JointDynamics joint;  // the arm's joint damping B and Coulomb friction F (none by default)

 private:
  void allocate();
  template <class V>
  void joint_terms(const V& v);
  template <class Q, class V>
  void aba(const Q& q, const V& v, const Vec& tau, Vec& out);
  template <class Row>
  void torque(const Row& T_row, const Vec& v, const CRefVec& a, const CRefVec& b, bool friction);
  template <class Q, class V>
  void torque_with(const DisturbanceFunction& dist, const CRefVec& tau, double t, const Q& q,
                   const V& v);

  Vec q2, v2, q3, v3, q4, v4, a1, a2, a3, a4, u;
  StickSlip stick_{*this};  // the Coulomb-aware steps (stick_slip)
};

}  // namespace hmpc
