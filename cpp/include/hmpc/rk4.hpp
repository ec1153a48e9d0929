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
// and the fused friction's b) make f discontinuous where q̇_i = 0, and RK4 with sgn evaluated
// per stage converges at first order there. With stick_slip the sign of each joint's Coulomb
// term is a mode held over a step (s_i = sgn q̇_i at its start), so that the step integrates
// a smooth field; the velocity sign changes are located as events: after a trial step, a
// joint whose q̇_i changed sign (or, for a stuck joint, whose holding torque left [−F_i, F_i])
// triggers a search for the earliest event time (Illinois regula falsi on the RK4 step's
// length, to 1e-13 of the step), the step is split there, the crossing velocity set to 0 and
// the modes chosen again. A joint with q̇_i = 0 sticks (the usual stick-slip law): its Coulomb
// torque takes the value φ_i in [−F_i, F_i] that keeps q̈_i = 0 (with the other stuck joints,
// φ_S solves (M⁻¹)_SS φ_S = −(M⁻¹ u)_S), and it slips, with s_i = −sgn φ_i, when that value
// would exceed F_i (joints leave the stuck set one at a time, largest |φ_i|/F_i first; a joint
// that would slip against its acceleration stays stuck). Time-only terms are interpolated
// within a step by the parabola through their three stage rows. Where no joint changes sign
// or sticks, the step is the classical one with sgn q̇ of the step's start, bit for bit the
// per-stage sgn when no stage crosses zero; a disturbance given as a function (period_with)
// keeps its own terms as they are, but for the friction set_friction_in_disturbance names.
// stick_slip = false: sgn per stage (earlier versions).
//
// At rest (every joint has a Coulomb level and q̇ = 0 at a step's start) the stuck joints'
// algebra has the closed form φ = G(q) − u (q̈ = M⁻¹(u + φ − G) = 0 for all of them; G(q)
// one RNEA at q̇ = 0, kept while q does not change): when it is within ±F_i at the step's
// start and end (where the event function above is checked) the step leaves the state as
// it is, as the general path's trial does exactly (q̈ = 0 at every stage); otherwise the
// general path runs the step. The first stage of a trial step, q̈ at its start with the
// modes held, is the one choose_modes computed there (and the same for every trial of an
// event's search): it is computed once. With two or more stuck joints (and the compiled
// dynamics) a stage solves the same equations from M(q) and C q̇ + G, M_FF q̈_F = (u − C q̇
// − G)_F and φ_S = M_SF q̈_F + (C q̇ + G − u)_S over the free joints F, in place of one ABA
// per stuck joint; a solve at the torque, state and modes of the last one (the end of a
// step is the next one's start when the torque rows there are equal) is not repeated.
//
// What a period applied (start_rest, start_coulomb): the Coulomb torque of the fused (or
// named, set_friction_in_disturbance) friction at the period's start for a joint at rest,
// which sgn 0 = 0 of the state does not tell: b_i/(F_i + b_i) of its holding torque φ_i
// (F_i the joint's own friction, b_i the disturbance's: the holding torque shared in
// proportion to the two levels) while it sticks, −b_i s_i when it breaks away with sign s_i.
// Oracle: tests/reference/rk4.py.
#pragma once

#include "hmpc/dynamics.hpp"
#include "hmpc/joint_dynamics.hpp"
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
  // torque applied to it then [N·m] (see above; 0 where start_rest[i] is false).
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

  // The Coulomb-aware step (stick_slip): one step of h from (q, v); base(θ, q, v, u) writes
  // the torque at the fraction θ of the step without the Coulomb-viscous terms.
  template <class Base>
  void coulomb_step(RefVec q, RefVec v, double h, const Base& base);
  template <class Base>
  void accel(const Base& base, double th, const Vec& q, const Vec& v, Vec& out);
  template <class Base>
  void trial(const Base& base, double ta, double L, double h);
  template <class Base>
  double event_value(const Base& base, double th);
  template <class Base>
  void choose_modes(const Base& base, double th);
  template <class Base>
  bool hold(const Base& base, double th);
  bool at_rest(const RefVec& q, const RefVec& v);
  void constrained(const Vec& q, const Vec& v, Vec& out);
  void columns(const Vec& q, const Vec& v, Vec& out);
  bool memo_hit(const Vec& q, const Vec& v) const;
  void record_start();
  bool coulomb_in(const CRefVec& b, bool friction);

  Vec q2, v2, q3, v3, q4, v4, a1, a2, a3, a4, u;
  // stick_slip: Coulomb levels, modes (±1 slipping, 0 stuck, 2 no Coulomb term), the fused
  // friction of this period, the step's start and trial states, stuck-joint algebra.
  Vec fc_, qa_, va_, qs_, vs_, ue_, col_, phi_, vscale_, fa_, fb_, wa_, wb_;
  std::vector<int> mode_, stuck_, free_;
  Mat W_;
  bool fused_ = false;
  bool wf_ = false;  // set_friction_in_disturbance given
  bool first_ = false;  // the next Coulomb-aware step starts a period (record_start)
  // a1 is q̈ at (qa_, va_) with the modes held: the trials from there skip their first stage
  bool a1_ready_ = false;
  // the last stuck-joint solve of accel: its torque, state, modes, q̈ and φ
  bool memo_valid_ = false;
  Vec memo_u_, memo_q_, memo_v_, memo_out_, memo_phi_;
  std::vector<int> memo_mode_;
  Vec G_, qG_;          // G(q) at q = qG_ (the rest shortcut)
  bool g_valid_ = false;
};

}  // namespace hmpc
