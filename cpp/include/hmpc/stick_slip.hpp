// Coulomb friction by stick-slip events within the RK4 plant's steps (rk4.hpp), the one
// implementation. The known Coulomb terms (the joint friction F and the fused friction's b)
// make the dynamics discontinuous where q̇_i = 0, and RK4 with sgn evaluated per stage
// converges at first order there. Here the sign of each joint's Coulomb term is a mode held
// over a step (s_i = sgn q̇_i at its start), so that the step integrates a smooth field; the
// velocity sign changes are located as events: after a trial step, a joint whose q̇_i
// changed sign (or, for a stuck joint, whose holding torque left [−F_i, F_i]) triggers a
// search for the earliest event time (Illinois regula falsi on the RK4 step's length, to
// 1e-13 of the step), the step is split there, the crossing velocity set to 0 and the modes
// chosen again. A joint with q̇_i = 0 sticks (the usual stick-slip law): its Coulomb torque
// takes the value φ_i in [−F_i, F_i] that keeps q̈_i = 0 (with the other stuck joints, φ_S
// solves (M⁻¹)_SS φ_S = −(M⁻¹ u)_S), and it slips, with s_i = −sgn φ_i, when that value
// would exceed F_i (joints leave the stuck set one at a time, largest |φ_i|/F_i first; a
// joint that would slip against its acceleration stays stuck). Time-only terms are
// interpolated within a step by the parabola through their three stage rows (the caller's
// StageTorque). Where no joint changes sign or sticks, the step is the classical one with
// sgn q̇ of the step's start, bit for bit the per-stage sgn when no stage crosses zero; a
// disturbance given as a function (RK4::period_with) keeps its own terms as they are, but
// for the friction set_friction_in_disturbance names.
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
// What a period applied (RK4::start_rest, start_coulomb): the Coulomb torque of the fused
// (or named, set_friction_in_disturbance) friction at the period's start for a joint at
// rest, which sgn 0 = 0 of the state does not tell: b_i/(F_i + b_i) of its holding torque
// φ_i (F_i the joint's own friction, b_i the disturbance's: the holding torque shared in
// proportion to the two levels) while it sticks, −b_i s_i when it breaks away with sign s_i.
// Oracle: tests/reference/rk4.py.
#pragma once

#include "hmpc/types.hpp"

#include <vector>

namespace hmpc {

class RK4;

// The torque at the fraction θ of a step at the stage state (q, q̇), without the
// Coulomb-viscous terms: a non-owning reference to the caller's callable (no allocation).
class StageTorque {
 public:
  template <class F>
  explicit StageTorque(const F& f)
      : obj_(&f), call_([](const void* o, double th, const Vec& q, const Vec& v, Vec& out) {
          (*static_cast<const F*>(o))(th, q, v, out);
        }) {}
  void operator()(double th, const Vec& q, const Vec& v, Vec& out) const {
    call_(obj_, th, q, v, out);
  }

 private:
  const void* obj_;
  void (*call_)(const void*, double, const Vec&, const Vec&, Vec&);
};

class StickSlip {
 public:
  // The RK4 whose dynamics (ABA, M, C q̇ + G), joint friction and records this uses.
  explicit StickSlip(RK4& rk4);
  void allocate(int n);

  // The friction −(a q̇ + b sgn q̇) inside a disturbance function (RK4's).
  void set_friction_in_disturbance(const CRefVec& a, const CRefVec& b);
  const Vec& wa() const { return wa_; }
  const Vec& wb() const { return wb_; }
  bool wf() const { return wf_; }

  // The Coulomb levels of this period (joint F plus, with friction, b); whether any is to
  // be located (always false with RK4::stick_slip off).
  bool coulomb_in(const CRefVec& b, bool friction);
  // A period with the fused friction (a, b) (fused: subtracted at every stage) begins.
  void begin(bool fused, const CRefVec& a, const CRefVec& b);
  // One step of h from (q, v) with the Coulomb terms' sign changes located.
  void step(RefVec q, RefVec v, double h, const StageTorque& base);
  // The last stuck-joint solve not to be reused (the dynamics or the friction changed).
  void forget() { memo_valid_ = false; }

 private:
  void accel(const StageTorque& base, double th, const Vec& q, const Vec& v, Vec& out);
  void trial(const StageTorque& base, double ta, double L, double h);
  double event_value(const StageTorque& base, double th);
  void choose_modes(const StageTorque& base, double th);
  bool hold(const StageTorque& base, double th);
  bool at_rest(const RefVec& q, const RefVec& v);
  void constrained(const Vec& q, const Vec& v, Vec& out);
  void columns(const Vec& q, const Vec& v, Vec& out);
  bool memo_hit(const Vec& q, const Vec& v) const;
  void record_start();

  RK4& rk4_;
  int n = 0;
  // Coulomb levels, modes (±1 slipping, 0 stuck, 2 no Coulomb term), the fused friction of
  // this period, the step's start and trial states, stuck-joint algebra.
  Vec q2, v2, q3, v3, q4, v4, a1, a2, a3, a4, u;
  Vec fc_, qa_, va_, qs_, vs_, ue_, col_, phi_, vscale_, fa_, fb_, wa_, wb_;
  std::vector<int> mode_, stuck_, free_;
  Mat W_;
  bool fused_ = false;
  bool wf_ = false;     // set_friction_in_disturbance given
  bool first_ = false;  // the next step starts a period (record_start)
  // a1 is q̈ at (qa_, va_) with the modes held: the trials from there skip their first stage
  bool a1_ready_ = false;
  // the last stuck-joint solve of accel: its torque, state, modes, q̈ and φ
  bool memo_valid_ = false;
  Vec memo_u_, memo_q_, memo_v_, memo_out_, memo_phi_;
  std::vector<int> memo_mode_;
  Vec G_, qG_;  // G(q) at q = qG_ (the rest shortcut)
  bool g_valid_ = false;
};

}  // namespace hmpc
