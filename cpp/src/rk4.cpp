// The RK4 plant's period: see rk4.hpp.
#include "hmpc/rk4.hpp"

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <utility>

namespace hmpc {

RK4::RK4(const std::string& model) : dyn(std::make_unique<Dynamics>(model)), n(dyn->n) {
  allocate();
}

RK4::RK4(int n_, AbaFunction aba) : aba_fn(std::move(aba)), n(n_) {
  if (!aba_fn) throw std::invalid_argument("RK4: give a serialized model or an aba callable");
  allocate();
}

void RK4::allocate() {
  for (Vec* x : {&q2, &v2, &q3, &v3, &q4, &v4, &a1, &a2, &a3, &a4, &u, &joint.b, &joint.f, &fc_,
                 &qa_, &va_, &qs_, &vs_, &ue_, &col_, &phi_, &vscale_, &fa_, &fb_, &wa_, &wb_,
                 &G_, &qG_, &start_coulomb})
    x->setZero(n);
  mode_.assign(n, 2);
  start_rest.assign(n, 0);
  stuck_.reserve(n);
  free_.reserve(n);
  W_.setZero(n, n);
}

void RK4::set_friction_in_disturbance(const CRefVec& a, const CRefVec& b) {
  if (a.size() != n || b.size() != n || !a.allFinite() || !b.allFinite())
    throw std::invalid_argument("RK4.set_friction_in_disturbance: expected (n,) finite values");
  memo_valid_ = false;
  wa_ = a;
  wb_ = b;
  wf_ = (a.array() != 0.0).any() || (b.array() != 0.0).any();
}

// The Coulomb levels of this period (joint F plus the fused b); whether any is to be located.
bool RK4::coulomb_in(const CRefVec& b, bool friction) {
  if (!stick_slip) return false;
  fc_ = joint.f;
  if (friction) fc_ += b;
  return (fc_.array() > 0.0).any();
}

// q̈ at the fraction th of the step with the modes held: u = base − (a q̇ + b s) − (B q̇ + F s),
// s the mode of a slipping joint (0 for a stuck one), then, with stuck joints S, their
// holding torque φ_S ((M⁻¹)_SS φ_S = −q̈_S, M⁻¹'s columns by ABA's linearity in τ) added,
// q̈_S = 0 and φ into phi_.
template <class Base>
void RK4::accel(const Base& base, double th, const Vec& q, const Vec& v, Vec& out) {
  base(th, q, v, u);
  for (int i = 0; i < n; ++i) {
    const double s = (mode_[i] == 1 || mode_[i] == -1) ? static_cast<double>(mode_[i]) : 0.0;
    if (fused_) u[i] -= fa_[i] * v[i] + fb_[i] * s;
    if (joint.any) u[i] -= joint.b[i] * v[i] + joint.f[i] * s;
  }
  stuck_.clear();
  for (int i = 0; i < n; ++i)
    if (mode_[i] == 0) stuck_.push_back(i);
  const int m = static_cast<int>(stuck_.size());
  if (m == 0) {
    aba(q, v, u, out);
    return;
  }
  if (memo_hit(q, v)) {  // the last call's (the end of a step is the next one's start)
    out = memo_out_;
    for (int i : stuck_) phi_[i] = memo_phi_[i];
    return;
  }
  if (dyn && m >= 2) constrained(q, v, out);
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
bool RK4::memo_hit(const Vec& q, const Vec& v) const {
  const auto same = [this](const Vec& a, const Vec& b) {
    return std::memcmp(a.data(), b.data(), sizeof(double) * static_cast<size_t>(n)) == 0;
  };
  return memo_valid_ && mode_ == memo_mode_ && same(u, memo_u_) && same(q, memo_q_) &&
         same(v, memo_v_);
}

// accel's stuck joints' algebra by ABA's columns: q̈ = ABA(q, v, u), then φ_S.
void RK4::columns(const Vec& q, const Vec& v, Vec& out) {
  aba(q, v, u, out);
  const int m = static_cast<int>(stuck_.size());
  const double scale = 1.0 + u.cwiseAbs().maxCoeff();
  for (int k = 0; k < m; ++k) {
    ue_ = u;
    ue_[stuck_[k]] += scale;
    aba(q, v, ue_, col_);
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
void RK4::constrained(const Vec& q, const Vec& v, Vec& out) {
  const Mat& M = dyn->mass_matrix(q);
  const Vec& hv = dyn->nle(q, v);
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
template <class Base>
void RK4::trial(const Base& base, double ta, double L, double h) {
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
template <class Base>
double RK4::event_value(const Base& base, double th) {
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
template <class Base>
void RK4::choose_modes(const Base& base, double th) {
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
bool RK4::at_rest(const RefVec& q, const RefVec& v) {
  if (!dyn) return false;
  for (int i = 0; i < n; ++i)
    if (!(fc_[i] > 0.0 && v[i] == 0.0)) return false;
  if (!g_valid_ || (qG_.array() != q.array()).any()) {
    G_ = dyn->nle(q, v);
    qG_ = q;
    g_valid_ = true;
  }
  return true;
}

// Every joint stuck at (qa_, va_ = 0), fraction th: the holding torques φ = G(q) − u (u the
// torque there, its Coulomb-viscous terms 0 at rest) into phi_; whether each is within ±F_i.
template <class Base>
bool RK4::hold(const Base& base, double th) {
  base(th, qa_, va_, u);
  bool in = true;
  for (int i = 0; i < n; ++i) {
    phi_[i] = G_[i] - u[i];
    in = in && !(std::abs(phi_[i]) > fc_[i]);
  }
  return in;
}

// The period's start (modes and φ at (qa_, va_)): start_rest, start_coulomb (rk4.hpp).
void RK4::record_start() {
  first_ = false;
  for (int i = 0; i < n; ++i) {
    start_rest[i] = fc_[i] > 0.0 && va_[i] == 0.0;
    const double b = fused_ && start_rest[i] ? fb_[i] : 0.0;
    if (b == 0.0) start_coulomb[i] = 0.0;
    else if (mode_[i] == 0) start_coulomb[i] = b == fc_[i] ? phi_[i] : phi_[i] * (b / fc_[i]);
    else start_coulomb[i] = -b * mode_[i];
  }
}

// One step of h from (q, v) with the Coulomb terms' sign changes located (see rk4.hpp).
template <class Base>
void RK4::coulomb_step(RefVec q, RefVec v, double h, const Base& base) {
  qa_ = q;
  va_ = v;
  if (at_rest(q, v) && hold(base, 0.0)) {  // the rest shortcut (rk4.hpp)
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
    ++events;
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

void RK4::set_joint_dynamics(const CRefVec& damping, const CRefVec& friction) {
  memo_valid_ = false;
  joint.set(damping, friction, n, "RK4.set_joint_dynamics");
}

// u −= B v + F sgn v (sgn 0 = 0), when there are joint dynamics.
template <class V>
void RK4::joint_terms(const V& v) {
  if (!joint.any) return;
  for (int i = 0; i < n; ++i) u[i] -= joint.torque(i, v[i]);
}

template <class Q, class V>
void RK4::aba(const Q& q, const V& v, const Vec& tau, Vec& out) {
  if (dyn) {
    out = dyn->aba(q, v, tau);
    return;
  }
  Vec qc = q, vc = v;
  out = aba_fn(qc, vc, tau);
  if (out.size() != n) throw std::invalid_argument("RK4: aba returned a vector of wrong size");
}

void RK4::aba_into(const CRefVec& q, const CRefVec& v, const Vec& tau, Vec& out) {
  aba(q, v, tau, out);
}

// Stage torque: the held torque plus the time-only terms T_row, minus the friction
// a·q̇ + b·sgn(q̇) (sgn(0) = 0) when `friction`.
template <class Row>
void RK4::torque(const Row& T_row, const Vec& v, const CRefVec& a, const CRefVec& b,
                 bool friction) {
  u = T_row.transpose();
  if (friction)
    for (int i = 0; i < n; ++i) u[i] -= joint_torque(a[i], b[i], v[i]);
  joint_terms(v);
}

void RK4::period(RefVec q, RefVec v, const CRefRow& T, const CRefVec& a, const CRefVec& b,
                 bool friction, double h) {
  memo_valid_ = false;
  const int S = static_cast<int>(T.rows() / 3);
  if (T.rows() != 3 * S || T.cols() != n || q.size() != n || v.size() != n)
    throw std::invalid_argument("RK4.period: shapes do not match the model");
  std::fill(start_rest.begin(), start_rest.end(), 0);
  start_coulomb.setZero();
  if (coulomb_in(b, friction)) {
    fused_ = friction;
    fa_ = a;
    fb_ = b;
    first_ = true;
    for (int s = 0; s < S; ++s) {
      // the time-only terms at the fraction th of step s: its rows, the parabola between
      const auto base = [&T, s, S](double th, const Vec&, const Vec&, Vec& out) {
        if (th == 0.0) {
          out = T.row(s).transpose();
        } else if (th == 0.5) {
          out = T.row(S + s).transpose();
        } else if (th == 1.0) {
          out = T.row(2 * S + s).transpose();
        } else {
          const double l0 = 2.0 * (th - 0.5) * (th - 1.0), lm = -4.0 * th * (th - 1.0),
                       l1 = 2.0 * th * (th - 0.5);
          out = l0 * T.row(s).transpose() + lm * T.row(S + s).transpose() +
                l1 * T.row(2 * S + s).transpose();
        }
      };
      coulomb_step(q, v, h, base);
    }
    return;
  }
  const double hh = 0.5 * h, h6 = h / 6.0;
  Vec vq = v;  // v as a Vec for the stage torque
  for (int s = 0; s < S; ++s) {
    vq = v;
    torque(T.row(s), vq, a, b, friction);
    aba(q, v, u, a1);
    q2 = q + hh * v;
    v2 = v + hh * a1;
    torque(T.row(S + s), v2, a, b, friction);
    aba(q2, v2, u, a2);
    q3 = q + hh * v2;
    v3 = v + hh * a2;
    torque(T.row(S + s), v3, a, b, friction);
    aba(q3, v3, u, a3);
    q4 = q + h * v3;
    v4 = v + h * a3;
    torque(T.row(2 * S + s), v4, a, b, friction);
    aba(q4, v4, u, a4);
    q += h6 * v + (2.0 * h6) * v2 + (2.0 * h6) * v3 + h6 * v4;
    v += h6 * a1 + (2.0 * h6) * a2 + (2.0 * h6) * a3 + h6 * a4;
  }
}

// τ + d(t, q, q̇) into u (d given copies of the stage state).
template <class Q, class V>
void RK4::torque_with(const DisturbanceFunction& dist, const CRefVec& tau, double t, const Q& q,
                      const V& v) {
  Vec qc = q, vc = v;
  Vec d = dist(t, qc, vc);
  if (d.size() != n) throw std::invalid_argument("the disturbance returned a vector of wrong size");
  u = tau + d;
  joint_terms(v);
}

void RK4::period_with(RefVec q, RefVec v, const CRefVec& tau, double t, double h, int S,
                      const DisturbanceFunction& dist) {
  memo_valid_ = false;
  if (q.size() != n || v.size() != n || tau.size() != n)
    throw std::invalid_argument("RK4.period_with: shapes do not match the model");
  std::fill(start_rest.begin(), start_rest.end(), 0);
  start_coulomb.setZero();
  if (coulomb_in(wb_, wf_)) {
    // the function's own friction term added back; accel subtracts the stick-slip one
    fused_ = wf_;
    fa_ = wa_;
    fb_ = wb_;
    first_ = true;
    for (int s = 0; s < S; ++s) {
      const double t0 = t + s * h;
      const auto base = [&](double th, const Vec& qs, const Vec& vs, Vec& out) {
        const double ts = th == 0.5 ? t0 + 0.5 * h : (th == 1.0 ? t0 + h : t0 + th * h);
        Vec d = dist(ts, qs, vs);
        if (d.size() != n)
          throw std::invalid_argument("the disturbance returned a vector of wrong size");
        out = tau + d;
        if (wf_)
          for (int i = 0; i < n; ++i) out[i] += joint_torque(wa_[i], wb_[i], vs[i]);
      };
      coulomb_step(q, v, h, base);
    }
    return;
  }
  const double hh = 0.5 * h, h6 = h / 6.0;
  for (int s = 0; s < S; ++s) {
    const double t0 = t + s * h, tm = t0 + hh, t1 = t0 + h;
    torque_with(dist, tau, t0, q, v);
    aba(q, v, u, a1);
    q2 = q + hh * v;
    v2 = v + hh * a1;
    torque_with(dist, tau, tm, q2, v2);
    aba(q2, v2, u, a2);
    q3 = q + hh * v2;
    v3 = v + hh * a2;
    torque_with(dist, tau, tm, q3, v3);
    aba(q3, v3, u, a3);
    q4 = q + h * v3;
    v4 = v + h * a3;
    torque_with(dist, tau, t1, q4, v4);
    aba(q4, v4, u, a4);
    q += h6 * v + (2.0 * h6) * v2 + (2.0 * h6) * v3 + h6 * v4;
    v += h6 * a1 + (2.0 * h6) * a2 + (2.0 * h6) * a3 + h6 * a4;
  }
}

}  // namespace hmpc
