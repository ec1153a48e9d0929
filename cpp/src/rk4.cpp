// The RK4 plant's period: see rk4.hpp.
#include "hmpc/rk4.hpp"

#include <algorithm>
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
  for (Vec* x : {&q2, &v2, &q3, &v3, &q4, &v4, &a1, &a2, &a3, &a4, &u, &joint.b, &joint.f,
                 &start_coulomb})
    x->setZero(n);
  start_rest.assign(n, 0);
  stick_.allocate(n);
}

void RK4::set_friction_in_disturbance(const CRefVec& a, const CRefVec& b) {
  stick_.set_friction_in_disturbance(a, b);
}

void RK4::set_joint_dynamics(const CRefVec& damping, const CRefVec& friction) {
  stick_.forget();
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
  stick_.forget();
  const int S = static_cast<int>(T.rows() / 3);
  if (T.rows() != 3 * S || T.cols() != n || q.size() != n || v.size() != n)
    throw std::invalid_argument("RK4.period: shapes do not match the model");
  std::fill(start_rest.begin(), start_rest.end(), 0);
  start_coulomb.setZero();
  if (stick_.coulomb_in(b, friction)) {
    stick_.begin(friction, a, b);
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
      stick_.step(q, v, h, StageTorque(base));
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
  stick_.forget();
  if (q.size() != n || v.size() != n || tau.size() != n)
    throw std::invalid_argument("RK4.period_with: shapes do not match the model");
  std::fill(start_rest.begin(), start_rest.end(), 0);
  start_coulomb.setZero();
  if (stick_.coulomb_in(stick_.wb(), stick_.wf())) {
    // the function's own friction term added back; the stick-slip step subtracts its own
    const bool wf = stick_.wf();
    const Vec& wa = stick_.wa();
    const Vec& wb = stick_.wb();
    stick_.begin(wf, wa, wb);
    for (int s = 0; s < S; ++s) {
      const double t0 = t + s * h;
      const auto base = [&](double th, const Vec& qs, const Vec& vs, Vec& out) {
        const double ts = th == 0.5 ? t0 + 0.5 * h : (th == 1.0 ? t0 + h : t0 + th * h);
        Vec d = dist(ts, qs, vs);
        if (d.size() != n)
          throw std::invalid_argument("the disturbance returned a vector of wrong size");
        out = tau + d;
        if (wf)
          for (int i = 0; i < n; ++i) out[i] += joint_torque(wa[i], wb[i], vs[i]);
      };
      stick_.step(q, v, h, StageTorque(base));
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
