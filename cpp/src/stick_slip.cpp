// Coulomb friction by stick-slip events within the RK4 plant's steps: see stick_slip.hpp.
#include "hmpc/stick_slip.hpp"

#include "hmpc/rk4.hpp"

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>

namespace hmpc {

StickSlip::StickSlip(RK4& rk4) : rk4_(rk4) {}

void StickSlip::allocate(int n_) {
  n = n_;
  for (Vec* x : {&q2, &v2, &q3, &v3, &q4, &v4, &a1, &a2, &a3, &a4, &u, &fc_, &qa_, &va_, &qs_,
                 &vs_, &ue_, &col_, &phi_, &vscale_, &fa_, &fb_, &wa_, &wb_, &G_, &qG_})
    x->setZero(n);
  mode_.assign(n, 2);
  stuck_.reserve(n);
  free_.reserve(n);
  W_.setZero(n, n);
}

void StickSlip::set_friction_in_disturbance(const CRefVec& a, const CRefVec& b) {
  if (a.size() != n || b.size() != n || !a.allFinite() || !b.allFinite())
    throw std::invalid_argument("RK4.set_friction_in_disturbance: expected (n,) finite values");
  memo_valid_ = false;
  wa_ = a;
  wb_ = b;
  wf_ = (a.array() != 0.0).any() || (b.array() != 0.0).any();
}

void StickSlip::begin(bool fused, const CRefVec& a, const CRefVec& b) {
  fused_ = fused;
  fa_ = a;
  fb_ = b;
  first_ = true;
}

// The Coulomb levels of this period (joint F plus the fused b); whether any is to be located.
bool StickSlip::coulomb_in(const CRefVec& b, bool friction) {
  if (!rk4_.stick_slip) return false;
  fc_ = rk4_.joint.f;
  if (friction) fc_ += b;
  return (fc_.array() > 0.0).any();
}

// q̈ at the fraction th of the step with the modes held: u = base − (a q̇ + b s) − (B q̇ + F s),
// s the mode of a slipping joint (0 for a stuck one), then, with stuck joints S, their
// holding torque φ_S ((M⁻¹)_SS φ_S = −q̈_S, M⁻¹'s columns by ABA's linearity in τ) added,
// q̈_S = 0 and φ into phi_.
void StickSlip::accel(const StageTorque& base, double th, const Vec& q, const Vec& v, Vec& out) {
  base(th, q, v, u);
  for (int i = 0; i < n; ++i) {
    const double s = (mode_[i] == 1 || mode_[i] == -1) ? static_cast<double>(mode_[i]) : 0.0;
    if (fused_) u[i] -= fa_[i] * v[i] + fb_[i] * s;
    if (rk4_.joint.any) u[i] -= rk4_.joint.b[i] * v[i] + rk4_.joint.f[i] * s;
  }
  stuck_.clear();
  for (int i = 0; i < n; ++i)
    if (mode_[i] == 0) stuck_.push_back(i);
  const int m = static_cast<int>(stuck_.size());
  if (m == 0) {
    rk4_.aba_into(q, v, u, out);
    return;
  }
  if (memo_hit(q, v)) {  // the last call's (the end of a step is the next one's start)
    out = memo_out_;
    for (int i : stuck_) phi_[i] = memo_phi_[i];
    return;
  }
  if (rk4_.dyn && m >= 2) constrained(q, v, out);
  else columns(q, v, out);
  memo_valid_ = true;
  memo_u_ = u;
  memo_q_ = q;
  memo_v_ = v;
  memo_mode_ = mode_;
  memo_out_ = out;
  memo_phi_ = phi_;
}

// Whether (u, q, v) and the modes are bit for bit those of the last stuck-joint solve.
bool StickSlip::memo_hit(const Vec& q, const Vec& v) const {
  const auto same = [this](const Vec& a, const Vec& b) {
    return std::memcmp(a.data(), b.data(), sizeof(double) * static_cast<size_t>(n)) == 0;
  };
  return memo_valid_ && mode_ == memo_mode_ && same(u, memo_u_) && same(q, memo_q_) &&
         same(v, memo_v_);
}

// accel's stuck joints' algebra by ABA's columns: q̈ = ABA(q, v, u), then φ_S.
void StickSlip::columns(const Vec& q, const Vec& v, Vec& out) {
  rk4_.aba_into(q, v, u, out);
  const int m = static_cast<int>(stuck_.size());
  const double scale = 1.0 + u.cwiseAbs().maxCoeff();
  for (int k = 0; k < m; ++k) {
    ue_ = u;
    ue_[stuck_[k]] += scale;
    rk4_.aba_into(q, v, ue_, col_);
    W_.col(k) = (col_ - out) / scale;
  }
  Mat Wss(m, m);
  Vec rhs(m);
  for (int r = 0; r < m; ++r) {
    rhs[r] = -out[stuck_[r]];
    for (int c = 0; c < m; ++c) Wss(r, c) = W_(stuck_[r], c);
  }
  const Vec phi = Wss.partialPivLu().solve(rhs);
  out += W_.leftCols(m) * phi;
  for (int k = 0; k < m; ++k) {
    out[stuck_[k]] = 0.0;
    phi_[stuck_[k]] = phi[k];
  }
}

// accel's stuck joints' algebra, m >= 2 of them, from M(q) (CRBA) and h = C q̇ + G (RNEA)
// in place of m more ABAs: the free joints F solve M_FF q̈_F = (u − h)_F, q̈_S = 0, and the
// holding torques are φ_S = M_SF q̈_F + h_S − u_S (the same equations as accel's).
void StickSlip::constrained(const Vec& q, const Vec& v, Vec& out) {
  const Mat& M = rk4_.dyn->mass_matrix(q);
  const Vec& hv = rk4_.dyn->nle(q, v);
  free_.clear();
  for (int i = 0; i < n; ++i)
    if (mode_[i] != 0) free_.push_back(i);
  const int f = static_cast<int>(free_.size());
  out.setZero(n);
  if (f > 0) {
    Mat Mff(f, f);
    Vec rf(f);
    for (int r = 0; r < f; ++r) {
      rf[r] = u[free_[r]] - hv[free_[r]];
      for (int c = 0; c < f; ++c) Mff(r, c) = M(free_[r], free_[c]);
    }
    const Vec af = Mff.llt().solve(rf);
    for (int r = 0; r < f; ++r) out[free_[r]] = af[r];
  }
  for (int i : stuck_) {
    double s = hv[i] - u[i];
    for (int r = 0; r < f; ++r) s += M(i, free_[r]) * out[free_[r]];
    phi_[i] = s;
  }
}

// One RK4 step of length L from (qa_, va_) at the fraction ta of the step h, the modes held,
// into (qs_, vs_) (a stuck joint's q̈ is 0 at every stage: it stays where it is).
void StickSlip::trial(const StageTorque& base, double ta, double L, double h) {
  const double hh = 0.5 * L, h6 = L / 6.0, tm = ta + hh / h, t1 = ta + L / h;
  if (!a1_ready_) accel(base, ta, qa_, va_, a1);  // else as choose_modes or a trial left it
  a1_ready_ = true;
  q2 = qa_ + hh * va_;
  v2 = va_ + hh * a1;
  accel(base, tm, q2, v2, a2);
  q3 = qa_ + hh * v2;
  v3 = va_ + hh * a2;
  accel(base, tm, q3, v3, a3);
  q4 = qa_ + L * v3;
  v4 = va_ + L * a3;
  accel(base, t1, q4, v4, a4);
  qs_ = qa_ + (h6 * va_ + (2.0 * h6) * v2 + (2.0 * h6) * v3 + h6 * v4);
  vs_ = va_ + (h6 * a1 + (2.0 * h6) * a2 + (2.0 * h6) * a3 + h6 * a4);
}

// The event function at the trial's end (fraction th): the least over joints of s_i q̇_i / scale_i
// (slipping) and (F_i − |φ_i|) / F_i (stuck); < 0 once an event has happened.
double StickSlip::event_value(const StageTorque& base, double th) {
  double G = std::numeric_limits<double>::infinity();
  bool stuck = false;
  for (int i = 0; i < n; ++i) {
    if (mode_[i] == 1 || mode_[i] == -1) G = std::min(G, mode_[i] * vs_[i] / vscale_[i]);
    stuck = stuck || mode_[i] == 0;
  }
  if (stuck) {
    accel(base, th, qs_, vs_, a4);
    for (int i : stuck_) G = std::min(G, (fc_[i] - std::abs(phi_[i])) / fc_[i]);
  }
  return G;
}

// The modes at (qa_, va_), fraction th: the sign of a moving joint's velocity; a joint at rest
// sticks while its holding torque is within ±F_i, else slips against it.
void StickSlip::choose_modes(const StageTorque& base, double th) {
  bool rest = false;
  a1_ready_ = false;
  for (int i = 0; i < n; ++i) {
    mode_[i] = fc_[i] > 0.0 ? (va_[i] > 0.0 ? 1 : (va_[i] < 0.0 ? -1 : 0)) : 2;
    rest = rest || mode_[i] == 0;
  }
  if (!rest) return;
  for (int it = 0; it < 2 * n + 2; ++it) {
    accel(base, th, qa_, va_, a1);
    a1_ready_ = true;  // q̈ at the start with these modes: the trials' first stage
    int worst = -1;
    double ratio = 1.0;
    for (int i : stuck_) {
      const double r = std::abs(phi_[i]) / fc_[i];
      if (r > ratio) {
        ratio = r;
        worst = i;
      }
    }
    if (worst >= 0) {
      mode_[worst] = phi_[worst] > 0.0 ? -1 : 1;
      a1_ready_ = false;
      continue;
    }
    int back = -1;
    for (int i = 0; i < n && back < 0; ++i)
      if ((mode_[i] == 1 || mode_[i] == -1) && va_[i] == 0.0 && mode_[i] * a1[i] < 0.0) back = i;
    if (back < 0 || it > n) break;
    mode_[back] = 0;
    a1_ready_ = false;
  }
}

// Whether every joint has a Coulomb level and is at rest at (q, v) (with the compiled
// dynamics); then G_ = G(q) (one RNEA at q̇ = 0, kept while q stays).
bool StickSlip::at_rest(const RefVec& q, const RefVec& v) {
  if (!rk4_.dyn) return false;
  for (int i = 0; i < n; ++i)
    if (!(fc_[i] > 0.0 && v[i] == 0.0)) return false;
  if (!g_valid_ || (qG_.array() != q.array()).any()) {
    G_ = rk4_.dyn->nle(q, v);
    qG_ = q;
    g_valid_ = true;
  }
  return true;
}

// Every joint stuck at (qa_, va_ = 0), fraction th: the holding torques φ = G(q) − u (u the
// torque there, its Coulomb-viscous terms 0 at rest) into phi_; whether each is within ±F_i.
bool StickSlip::hold(const StageTorque& base, double th) {
  base(th, qa_, va_, u);
  bool in = true;
  for (int i = 0; i < n; ++i) {
    phi_[i] = G_[i] - u[i];
    in = in && !(std::abs(phi_[i]) > fc_[i]);
  }
  return in;
}

// The period's start (modes and φ at (qa_, va_)): RK4::start_rest, start_coulomb.
void StickSlip::record_start() {
  first_ = false;
  for (int i = 0; i < n; ++i) {
    rk4_.start_rest[i] = fc_[i] > 0.0 && va_[i] == 0.0;
    const double b = fused_ && rk4_.start_rest[i] ? fb_[i] : 0.0;
    if (b == 0.0) rk4_.start_coulomb[i] = 0.0;
    else if (mode_[i] == 0) rk4_.start_coulomb[i] = b == fc_[i] ? phi_[i] : phi_[i] * (b / fc_[i]);
    else rk4_.start_coulomb[i] = -b * mode_[i];
  }
}

// One step of h from (q, v) with the Coulomb terms' sign changes located (see stick_slip.hpp).
void StickSlip::step(RefVec q, RefVec v, double h, const StageTorque& base) {
  qa_ = q;
  va_ = v;
  if (at_rest(q, v) && hold(base, 0.0)) {  // the rest shortcut (stick_slip.hpp)
    std::fill(mode_.begin(), mode_.end(), 0);
    const bool first = first_;
    if (first) record_start();
    if (hold(base, 1.0)) return;  // stuck over the step: the state as it is
    first_ = first;               // else the general path, from the step's start
  }
  double ta = 0.0, rem = h;  // the fraction of the step done, the length left [s]
  choose_modes(base, ta);
  if (first_) record_start();
  for (int budget = 4 * n + 8;; --budget) {
    trial(base, ta, rem, h);
    if (budget <= 0) break;
    for (int i = 0; i < n; ++i) vscale_[i] = std::abs(va_[i]) + std::abs(vs_[i]) + 1e-300;
    double Ghi = event_value(base, ta + rem / h);
    if (!(Ghi < 0.0)) break;
    // the earliest event in (0, rem]: Illinois regula falsi on the trial's length
    double lo = 0.0, hi = 1.0, Glo = 1.0;
    for (int i = 0; i < n; ++i)
      if ((mode_[i] == 1 || mode_[i] == -1) && va_[i] != 0.0)
        Glo = std::min(Glo, mode_[i] * va_[i] / vscale_[i]);
    Glo = std::max(Glo, 1e-12);
    int side = 0;
    for (int it = 0; it < 200 && (hi - lo) * rem > 1e-13 * h; ++it) {
      const double w = hi - lo;
      double x = (lo * Ghi - hi * Glo) / (Ghi - Glo);
      x = std::min(std::max(x, lo + 1e-3 * w), hi - 1e-3 * w);
      trial(base, ta, x * rem, h);
      const double Gx = event_value(base, ta + x * rem / h);
      if (Gx > 0.0) {
        lo = x;
        Glo = Gx;
        if (side == -1) Ghi *= 0.5;
        side = -1;
      } else {
        hi = x;
        Ghi = Gx;
        if (side == 1) Glo *= 0.5;
        side = 1;
      }
    }
    trial(base, ta, hi * rem, h);  // just past the event
    qa_ = qs_;
    va_ = vs_;
    for (int i = 0; i < n; ++i)
      if ((mode_[i] == 1 || mode_[i] == -1) && mode_[i] * va_[i] <= 0.0) va_[i] = 0.0;
    ++rk4_.events;
    ta += hi * rem / h;
    rem -= hi * rem;
    choose_modes(base, ta);
    if (rem <= 1e-13 * h) {
      qs_ = qa_;
      vs_ = va_;
      break;
    }
  }
  q = qs_;
  v = vs_;
}

}  // namespace hmpc
