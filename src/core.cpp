// hmpc_pin native kernels: the simulation's RK4 period and the hierarchical MPC's step.
//
// Built on first use by hmpc_pin/native/__init__.py (g++, the Pinocchio, ProxSuite and
// Eigen headers of the running environment, pybind11), cached per source and versions;
// the Pinocchio part is _dynamics.cpp, compiled beside this file.
// The Python side builds every matrix (the condensed QP data, the soft-limit rows, the
// solver settings): this file only evaluates them, with the same algorithms as the
// Python path (Pinocchio's CRBA, RNEA and ABA in the LOCAL convention, ProxSuite's dense
// QP, Eigen's partial-pivoting LU for the observer), so that the two paths agree to the
// solver tolerance (tests/native/).
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include "dynamics.hpp"
#include "joint_qps.hpp"
#include "observer.hpp"
#include "sampler.hpp"

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cmath>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace py = pybind11;
namespace pqp = proxsuite::proxqp;  // (joint_qps.hpp brings ProxSuite)

using Vec = Eigen::VectorXd;
using Mat = Eigen::MatrixXd;
using RowMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using CRefVec = Eigen::Ref<const Vec>;
using RefVec = Eigen::Ref<Vec>;
using CRefMat = Eigen::Ref<const Mat>;
using CRefRow = Eigen::Ref<const RowMat>;
using MapVec = Eigen::Map<Vec>;
using MapRow = Eigen::Map<RowMat>;


using hmpc_native::Dynamics;

// -------------------------------------------------------------------------------------
// The disturbance observer (observer.hpp), bound on its own: its state lives in two numpy
// arrays that the Python object owns (DisturbanceObserver.z, .estimate).

struct PyNDO {
  py::array_t<double, py::array::c_style> z_array, estimate_array;
  hmpc_native::NDO ndo;
  static py::array_t<double, py::array::c_style> checked(py::array_t<double, py::array::c_style> a,
                                                          Eigen::Index n) {
    if (a.ndim() != 1 || a.size() != n || !a.writeable())
      throw std::invalid_argument("NDO: z and estimate must be writable float64 arrays of n");
    return a;
  }
  PyNDO(const CRefMat& cY, double Ts, bool implicit, py::array_t<double, py::array::c_style> z,
        py::array_t<double, py::array::c_style> estimate)
      : z_array(checked(z, cY.rows())), estimate_array(checked(estimate, cY.rows())),
        ndo(cY, Ts, implicit, z_array.mutable_data(), estimate_array.mutable_data()) {}
  void update(const CRefMat& M, const CRefVec& nle, const CRefVec& dq, const CRefVec& tau) {
    if (M.rows() != ndo.n || M.cols() != ndo.n || nle.size() != ndo.n || dq.size() != ndo.n ||
        tau.size() != ndo.n)
      throw std::invalid_argument("NDO.update: M must be (n, n) and nle, dq, tau (n,)");
    ndo.update(M, nle, dq, tau);
  }
};

// -------------------------------------------------------------------------------------
// The RK4 plant's period (hmpc_pin.sim.plants.RK4Plant), the one implementation: classical
// Runge-Kutta steps of h with the torque held, the disturbance evaluated at every stage,
//   k1 = f(t_s, x), k2 = f(t_s + h/2, x + h/2 k1), k3 = f(t_s + h/2, x + h/2 k2),
//   k4 = f(t_s + h, x + h k3),  x += h/6 (k1 + 2 k2 + 2 k3 + k4),
//   f(t, [q; q̇]) = [q̇; ABA(q, q̇, τ + d(t, q, q̇) − B q̇ − F sgn q̇)].
// B q̇ + F sgn q̇ (sgn 0 = 0) is the arm's own joint damping and Coulomb friction, the URDF's
// <dynamics damping friction> (set_joint_dynamics; none by default), evaluated per stage.
// The disturbance is either fused (period(): time-only terms tabulated by the caller per
// stage time, one Coulomb-viscous friction −(a q̇ + b sgn q̇) here) or any Python callable
// d(t, q, q̇) (period_with()). ABA is Pinocchio's, compiled, or a Python callable for models
// the compiled dynamics cannot load (mimic joints). Oracle: tests/reference/rk4.py.

struct RK4 {
  std::unique_ptr<Dynamics> dyn;  // null: aba_cb
  py::object aba_cb;              // aba(q, v, tau) -> q̈ (Python), when no dyn
  int n;
  Vec q2, v2, q3, v3, q4, v4, a1, a2, a3, a4, u;
  Vec jb, jf;          // joint damping B [N·m·s/rad] and Coulomb friction F [N·m], diagonal
  bool joint = false;  // whether B, F are applied (any non-zero)

  RK4(py::object model, int n_, py::object aba) : aba_cb(std::move(aba)), n(n_) {
    if (!model.is_none()) {
      dyn = std::make_unique<Dynamics>(model.cast<std::string>());
      n = dyn->n;
    } else if (aba_cb.is_none()) {
      throw std::invalid_argument("RK4: give a serialized model or an aba callable");
    }
    for (Vec* x : {&q2, &v2, &q3, &v3, &q4, &v4, &a1, &a2, &a3, &a4, &u, &jb, &jf}) x->setZero(n);
  }

  // The joint damping B and Coulomb friction F applied at every stage (zeros: none).
  void set_joint_dynamics(const CRefVec& damping, const CRefVec& friction) {
    if (damping.size() != n || friction.size() != n)
      throw std::invalid_argument("RK4.set_joint_dynamics: damping and friction must be (n,)");
    if ((damping.array() < 0.0).any() || (friction.array() < 0.0).any() ||
        !damping.allFinite() || !friction.allFinite())
      throw std::invalid_argument("RK4.set_joint_dynamics: expected finite values >= 0");
    jb = damping;
    jf = friction;
    joint = (jb.array() != 0.0).any() || (jf.array() != 0.0).any();
  }

  // u −= B v + F sgn v (sgn 0 = 0), when there are joint dynamics.
  template <class V>
  void joint_terms(const V& v) {
    if (!joint) return;
    for (int i = 0; i < n; ++i) {
      const double s = (v[i] > 0.0) - (v[i] < 0.0);
      u[i] -= jb[i] * v[i] + jf[i] * s;
    }
  }

  // q̈ = ABA(q, q̇, τ) into `out`.
  template <class Q, class V>
  void aba(const Q& q, const V& v, const Vec& tau, Vec& out) {
    if (dyn) {
      out = dyn->aba(q, v, tau);
      return;
    }
    Vec qc = q, vc = v;
    out = aba_cb(qc, vc, tau).template cast<Vec>();
    if (out.size() != n) throw std::invalid_argument("RK4: aba returned a vector of wrong size");
  }

  // Stage torque: the held torque plus the time-only terms T_row, minus the friction
  // a·q̇ + b·sgn(q̇) (sgn(0) = 0) when `friction`.
  template <class Row>
  void torque(const Row& T_row, const Vec& v, const CRefVec& a, const CRefVec& b, bool friction) {
    u = T_row.transpose();
    if (friction) {
      for (int i = 0; i < n; ++i) {
        const double s = (v[i] > 0.0) - (v[i] < 0.0);
        u[i] += -a[i] * v[i] + -b[i] * s;
      }
    }
    joint_terms(v);
  }

  // Advance (q, v) in place over T.rows() / 3 steps of h. T holds, per stage time, the
  // torque without friction: rows t_s (s = 0..S-1), then t_s + h/2, then t_s + h.
  void period(RefVec q, RefVec v, const CRefRow& T, const CRefVec& a, const CRefVec& b,
              bool friction, double h) {
    const int S = static_cast<int>(T.rows() / 3);
    if (T.rows() != 3 * S || T.cols() != n || q.size() != n || v.size() != n)
      throw std::invalid_argument("RK4.period: shapes do not match the model");
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

  // τ + d(t, q, q̇) into u, d a Python callable (given copies of the stage state).
  template <class Q, class V>
  void torque_with(const py::object& dist, const CRefVec& tau, double t, const Q& q, const V& v) {
    Vec qc = q, vc = v;
    Vec d = dist(t, qc, vc).template cast<Vec>();
    if (d.size() != n)
      throw std::invalid_argument("the disturbance returned a vector of wrong size");
    u = tau + d;
    joint_terms(v);
  }

  // Advance (q, v) in place over S steps of h from time t with τ held, the disturbance a
  // Python callable d(t, q, q̇) evaluated at every stage (stage times t_s = t + s·h,
  // t_s + h/2, t_s + h).
  void period_with(RefVec q, RefVec v, const CRefVec& tau, double t, double h, int S,
                   const py::object& dist) {
    if (q.size() != n || v.size() != n || tau.size() != n)
      throw std::invalid_argument("RK4.period_with: shapes do not match the model");
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
};

// -------------------------------------------------------------------------------------
// ProxSuite settings from a dict (keys: the Settings attributes chosen on the Python side,
// hmpc_pin.mpc.condensed.solver_settings), parsed once.

static hmpc_native::QPOptions qp_options(const py::dict& settings) {
  hmpc_native::QPOptions o;
  for (auto item : settings) {
    const std::string key = py::str(item.first);
    py::handle value = item.second;
    if (key == "initial_guess") {
      const std::string name = py::str(value);
      if (name == "WARM_START_WITH_PREVIOUS_RESULT")
        o.initial_guess = pqp::InitialGuessStatus::WARM_START_WITH_PREVIOUS_RESULT;
      else if (name == "NO_INITIAL_GUESS")
        o.initial_guess = pqp::InitialGuessStatus::NO_INITIAL_GUESS;
      else
        throw std::invalid_argument("unknown initial_guess " + name);
    } else if (key == "eps_abs") o.eps_abs = value.cast<double>();
    else if (key == "eps_rel") o.eps_rel = value.cast<double>();
    else if (key == "max_iter") o.max_iter = value.cast<long>();
    else if (key == "verbose") o.verbose = value.cast<bool>();
    else if (key == "check_duality_gap") o.check_duality_gap = value.cast<bool>();
    else if (key == "eps_duality_gap_abs") o.eps_duality_gap_abs = value.cast<double>();
    else if (key == "eps_duality_gap_rel") o.eps_duality_gap_rel = value.cast<double>();
    else if (key == "eps_primal_inf") o.eps_primal_inf = value.cast<double>();
    else if (key == "eps_dual_inf") o.eps_dual_inf = value.cast<double>();
    else throw std::invalid_argument("the compiled core does not know the ProxSuite setting " + key);
  }
  return o;
}

// A float64 C-contiguous numpy buffer owned by Python, written in place by the kernels.
template <class MapT>
struct Buffer {
  py::array_t<double, py::array::c_style> array;
  MapT map;
  static py::array_t<double, py::array::c_style> checked(py::array_t<double, py::array::c_style> a,
                                                          Eigen::Index size) {
    if (a.size() != size || !a.writeable())
      throw std::invalid_argument("native buffer of wrong size or not writable");
    return a;
  }
  Buffer(py::array_t<double, py::array::c_style> a, Eigen::Index rows, Eigen::Index cols)
      : array(checked(a, rows * cols)), map(array.mutable_data(), rows, cols) {}
};

// -------------------------------------------------------------------------------------
// The joint QPs (joint_qps.hpp), bound on their own: the solution and slack live in numpy
// arrays that the Python object owns (hmpc_pin.mpc.condensed.JointQPs.solution, .slack).

struct PyJointQPs {
  Buffer<MapRow> U_buf, slack_buf;
  hmpc_native::JointQPs qps;
  PyJointQPs(int n, int N, int Nc, bool block, const CRefMat& H, const CRefVec& v_min,
             const CRefVec& v_max, const py::dict& warm, const py::dict& cold,
             py::array_t<double, py::array::c_style> U, py::array_t<double, py::array::c_style> slack)
      : U_buf(U, Nc, n), slack_buf(slack, 1, n),
        qps(n, N, Nc, block, H, v_min, v_max, qp_options(warm), qp_options(cold),
            U_buf.map.data(), slack_buf.map.data()) {}
};

// -------------------------------------------------------------------------------------
// The hierarchical MPC's step (hmpc_pin.controllers.hierarchical.HierarchicalMPC.step),
// composed of the components: the reference sampler (below), the gradient map, the
// dynamics (dynamics.hpp), the observer (observer.hpp) or an estimate from Python, the
// joint QPs (joint_qps.hpp), and the inverse dynamics τ = M v + C q̇ + G − d̂ (Eq 4).
//
// Two ways to run it: step(S) (everything here, for the NDO of Eq 13 or no compensation)
// or prepare(S) → the caller's estimate into dhat → finish() (any compensation written in
// Python; with dynamics = false the caller also wrote M and C q̇ + G, for models the
// compiled dynamics cannot load).

struct HMPCCore {
  std::unique_ptr<Dynamics> dyn;  // null: M and nle come from the caller
  int n, N, Nc;
  // Gradient map, rows in stack order [q; q̇; r_1..r_N; ṙ_1..ṙ_N]; rows used.
  RowMat FT;
  Eigen::Index grad_rows;
  Mat Gt;  // Nc×n: one column per joint (the memory of G, n×Nc row-major)
  std::shared_ptr<PyJointQPs> qp;
  std::shared_ptr<PyNDO> ndo;  // the observer advanced by step(); null: none here
  Vec effort;
  bool started = false;
  // Python-owned outputs and inputs, updated in place.
  Buffer<MapRow> v;       // (1, n) commanded acceleration
  Buffer<MapRow> tau;     // (1, n) commanded torque
  Buffer<MapRow> dhat;    // (1, n) disturbance estimate
  Buffer<MapRow> M_out;   // (n, n) M(q) of the last prepare
  Buffer<MapRow> nle_out; // (1, n) C q̇ + G of the last prepare
  Vec applied, qv, dqv;
  const Mat* M = nullptr;    // M(q) of the last prepare (the dynamics' own, or none)
  const Vec* nle = nullptr;  // C q̇ + G of the last prepare
  bool external = false;     // the last prepare took M, nle from the caller (M_out, nle_out)
  // The stack [q; q̇; r_1..r_N; ṙ_1..ṙ_N] ((2 + 2N)×n), Python-owned (fill() writes it).
  std::optional<Buffer<MapRow>> stack;
  // The reference in native form (sampler.hpp).
  hmpc_native::HorizonSampler sampler;
  Vec offsets;  // horizon offsets j·Ts, j = 1..N [s]
  // Measurement latency L = m Ts + alpha Ts (0 <= alpha < 1), known to the controller
  // (set_latency): the observer is fed the torque applied over the interval its two
  // measurements span, and the MPC and the inverse dynamics start from the state predicted
  // over L. Off (latency_on false): the step is exactly the latency-free one.
  bool latency_on = false;
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
  int lat_m = 0;
  double lat_alpha = 0.0, Ts = 0.0;
  long steps = 0;            // finished steps since reset
  std::vector<Vec> tau_hist; // tau_hist[j]: torque applied over [t_{k-1-j}, t_{k-j}), j = 0..m+1
  std::vector<Vec> v_hist;   // v_hist[j]: acceleration commanded then, j = 0..m+1
  Vec tau_obs, v_obs;        // the torque and acceleration aligned with the measurement
  // The arm's joint damping B and Coulomb friction F (the URDF's <dynamics>), compensated:
  // C q̇ + G becomes C q̇ + G + B q̇ + F sgn q̇ (for the observer and Eq 4), and with
  // zoh_Ts > 0 the commanded acceleration of a damped joint is scaled so that over a period
  // of the torque held the damped joint reaches the velocity the MPC's double integrator
  // predicts (finish()).
  Vec jb, jf, nle_j, jv, extra;
  // J = B q̇_k + F σ + ZOH gain: the joint-dynamics torque of the last finish(). The observer
  // is given the applied torque minus J and C q̇ + G without the joint terms: what the
  // joint dynamics took over the period J was designed to cancel, the model of Eq (13) is
  // the plain rigid body again (its Euler model of a damped joint would be wrong by g_j).
  Vec jtau;
  const Vec* nle0 = nullptr;  // C q̇ + G alone of the last prepare (compiled dynamics)
  bool joint = false;
  double zoh_Ts = 0.0;
  Eigen::LLT<Mat> llt;

  HMPCCore(py::object model, const CRefRow& FT_, int N_, std::shared_ptr<PyJointQPs> qp_,
           std::shared_ptr<PyNDO> ndo_, py::array_t<double, py::array::c_style> v_,
           py::array_t<double, py::array::c_style> tau_,
           py::array_t<double, py::array::c_style> dhat_,
           py::array_t<double, py::array::c_style> M_,
           py::array_t<double, py::array::c_style> nle_)
      : n(qp_->qps.n), N(N_), Nc(qp_->qps.Nc), FT(FT_), qp(std::move(qp_)), ndo(std::move(ndo_)),
        v(v_, 1, n), tau(tau_, 1, n), dhat(dhat_, 1, n), M_out(M_, n, n), nle_out(nle_, 1, n),
        sampler(n) {
    if (!model.is_none()) {
      dyn = std::make_unique<Dynamics>(model.cast<std::string>());
      if (dyn->n != n) throw std::invalid_argument("HMPCCore: the model has another size");
    }
    if (FT.rows() != 2 + 2 * N || FT.cols() != Nc || qp->qps.N != N || (ndo && ndo->ndo.n != n))
      throw std::invalid_argument("HMPCCore: shapes do not match the model and horizon");
    // Without a velocity weight the ṙ rows of the map are zero: skip them.
    grad_rows = FT.bottomRows(N).isZero(0.0) ? N + 2 : 2 + 2 * N;
    applied.setZero(n);
    Gt.setZero(Nc, n);
    effort = Vec::Constant(n, std::numeric_limits<double>::infinity());
  }

  void set_stack(py::array_t<double, py::array::c_style> S, const CRefVec& offsets_) {
    stack.emplace(S, 2 + 2 * N, n);
    if (offsets_.size() != N) throw std::invalid_argument("offsets of wrong size");
    offsets = offsets_;
  }

  void set_sine(const CRefVec& omega, const CRefVec& phase, const CRefVec& amp,
                const CRefVec& offset, const CRefVec& amp_omega) {
    sampler.set_sine(omega, phase, amp, offset, amp_omega);
  }
  void set_ppoly(const CRefVec& times, const CRefVec& knots, const CRefRow& coef, int deg) {
    sampler.set_ppoly(times, knots, coef, deg);
  }
  void clear_reference() { sampler.clear(); }

  // The horizon rows of the stack for time t.
  void sample_horizon(double t) {
    auto& S = stack->map;
    for (int j = 0; j < N; ++j) sampler.sample(t + offsets[j], &S(2 + j, 0), &S(2 + N + j, 0));
  }

  // The stack's state and horizon rows for time t (the native reference). Returns 0, 3 (q or
  // q̇ of wrong size) or 4 (t not finite); nothing changed then.
  int fill(double t, const CRefVec& q, const CRefVec& dq) {
    if (!std::isfinite(t)) return 4;
    if (q.size() != n || dq.size() != n) return 3;
    auto& S = stack->map;
    S.row(0) = q.transpose();
    S.row(1) = dq.transpose();
    sample_horizon(t);
    return 0;
  }

  // A whole step at time t with the native reference: fill(), then step().
  int step_t(double t, const CRefVec& q, const CRefVec& dq) {
    const int code = fill(t, q, dq);
    return code ? code : step(stack->map);
  }

  // The measurement latency L [s] at the control period Ts_ [s] (L = 0: off).
  void set_latency(double L, double Ts_) {
    if (!(std::isfinite(L) && L >= 0.0 && std::isfinite(Ts_) && Ts_ > 0.0))
      throw std::invalid_argument("set_latency: expected L >= 0 and Ts > 0");
    Ts = Ts_;
    latency_on = L > 0.0;
    const double periods = L / Ts;
    lat_m = static_cast<int>(std::floor(periods + 1e-9));
    lat_alpha = periods - lat_m;
    if (lat_alpha < 1e-9) lat_alpha = 0.0;
    tau_hist.assign(lat_m + 2, Vec::Zero(n));
    v_hist.assign(lat_m + 2, Vec::Zero(n));
    tau_obs.setZero(n);
    v_obs.setZero(n);
  }

  // Whether the interval [t_{k-1} - L, t_k - L] between the last two measurements lies
  // after the start (k = steps): the observer can be advanced over it.
  bool observer_ready() const {
    if (!latency_on) return started;
    return steps >= lat_m + 1 + (lat_alpha > 0.0 ? 1 : 0);
  }

  // The torque applied over [t_{k-1} - L, t_k - L], averaged (the observer's input):
  //   alpha τ_{k-2-m} + (1 - alpha) τ_{k-1-m};  likewise the commanded acceleration.
  void align() {
    tau_obs = (1.0 - lat_alpha) * tau_hist[lat_m] + lat_alpha * tau_hist[lat_m + 1];
    v_obs = (1.0 - lat_alpha) * v_hist[lat_m] + lat_alpha * v_hist[lat_m + 1];
  }

  // The state at t_k predicted from the measurement of t_k - L by the decoupled double
  // integrator q̈ = v with the accelerations commanded over [t_k - L, t_k]: v_{k-1-m} over
  // alpha Ts, then v_{k-m}, ..., v_{k-1} over Ts each (exact for piecewise-constant v).
  // Writes rows 0 and 1 of S.
  void predict(RefVec q, RefVec dq) const {
    auto seg = [&](const Vec& a, double h) {
      q += h * dq + (0.5 * h * h) * a;
      dq += h * a;
    };
    if (lat_alpha > 0.0) seg(v_hist[lat_m], lat_alpha * Ts);
    for (int j = lat_m - 1; j >= 0; --j) seg(v_hist[j], Ts);
  }
  int predict_stack(py::array_t<double, py::array::c_style> S) {
    if (S.ndim() != 2 || S.shape(0) != 2 + 2 * N || S.shape(1) != n || !S.writeable())
      throw std::invalid_argument("predict: stack of wrong shape");
    MapRow Sm(S.mutable_data(), 2 + 2 * N, n);
    if (!Sm.topRows(2).allFinite()) return 1;
    Vec q = Sm.row(0).transpose(), dq = Sm.row(1).transpose();
    predict(q, dq);
    Sm.row(0) = q.transpose();
    Sm.row(1) = dq.transpose();
    return 0;
  }

  // After a step with latency: the torque as the plant applies it and v enter the history.
  void record() {
    if (!latency_on) return;
    std::rotate(tau_hist.rbegin(), tau_hist.rbegin() + 1, tau_hist.rend());
    std::rotate(v_hist.rbegin(), v_hist.rbegin() + 1, v_hist.rend());
    // what the observer is fed: the applied torque beyond the joint dynamics' J (jtau)
    tau_hist[0] = tau.map.row(0).transpose().cwiseMax(-effort).cwiseMin(effort);
    if (joint) tau_hist[0] -= jtau;
    v_hist[0] = v.map.row(0).transpose();
  }

  // The joint damping B [N·m·s/rad] and Coulomb friction F [N·m] to compensate (zeros:
  // none); Ts > 0 also applies their zero-order-hold terms (zoh_gain(), in finish()).
  void set_joint_dynamics(const CRefVec& damping, const CRefVec& friction, double Ts) {
    if (damping.size() != n || friction.size() != n)
      throw std::invalid_argument("HMPCCore.set_joint_dynamics: damping, friction must be (n,)");
    if ((damping.array() < 0.0).any() || (friction.array() < 0.0).any() ||
        !damping.allFinite() || !friction.allFinite() || !(Ts >= 0.0))
      throw std::invalid_argument("HMPCCore.set_joint_dynamics: expected finite values >= 0");
    jb = damping;
    jf = friction;
    joint = (jb.array() != 0.0).any() || (jf.array() != 0.0).any();
    zoh_Ts = joint ? Ts : 0.0;
    nle_j.setZero(n);
    jv.setZero(n);
    extra.setZero(n);
    jtau.setZero(n);
  }

  void set_observer_model(bool at_start) {
    obs_start = at_start;
    has_prev = false;
  }

  void set_effort(const CRefVec& limit) {
    if (limit.size() != n) throw std::invalid_argument("effort limit of wrong size");
    effort = limit;
  }

  // Start a run: the estimate (the compensation's, after its own reset).
  void reset(const CRefVec& dhat0) {
    dhat.map.row(0) = dhat0.transpose();
    v.map.setZero();
    tau.map.setZero();
    qp->qps.slack.setZero();
    qp->qps.constrained_last = false;
    qp->qps.constrained = 0;
    started = false;
    has_prev = false;
    steps = 0;
    for (Vec& x : tau_hist) x.setZero();
    for (Vec& x : v_hist) x.setZero();
    if (joint) jtau.setZero();
  }

  // The first half of a step from the stack S: the gradients, and M, C q̇ + G -- computed
  // here when `dynamics` (and written to M_out, nle_out when `export_`, for a compensation
  // in Python), else already written by the caller into M_out, nle_out.
  // Returns 0, or 1 (an input is not finite: nothing changed).
  int prepare(const CRefRow& S, bool dynamics = true, bool export_ = true) {
    if (S.rows() != 2 + 2 * N || S.cols() != n)
      throw std::invalid_argument("HMPCCore: stack of wrong shape");
    if (!S.allFinite()) return 1;
    qv = S.row(0).transpose();
    dqv = S.row(1).transpose();
    // Gradients, one column per joint: G^T = FT^T S (Nc×n).
    Gt.noalias() = FT.topRows(grad_rows).transpose() * S.topRows(grad_rows);
    external = !dynamics;
    if (dynamics) {
      if (!dyn) throw std::invalid_argument("HMPCCore.prepare: no compiled dynamics here");
      M = &dyn->mass_matrix(qv);
      nle = nle0 = &dyn->nle(qv, dqv);
      if (joint) {  // + B q̇ + F sgn q̇ (sgn 0 = 0)
        for (int i = 0; i < n; ++i) {
          const double s = (dqv[i] > 0.0) - (dqv[i] < 0.0);
          nle_j[i] = (*nle)[i] + jb[i] * dqv[i] + jf[i] * s;
        }
        nle = &nle_j;
      }
      if (export_) {  // C q̇ + G alone: the compensation's model (the joint terms: J)
        M_out.map = *M;
        nle_out.map.row(0) = nle0->transpose();
      }
    }
    return 0;
  }

  // The torque held over the period that just ended, as the plant applied it.
  const Vec& applied_torque() {
    applied = tau.map.row(0).transpose().cwiseMax(-effort).cwiseMin(effort);
    return applied;
  }

  // The second half: the joint QPs for the gradients, then τ = M v + C q̇ + G − d̂ (Eq 4)
  // with d̂ in dhat. Returns 0, or 2 (a QP did not report solved: fail_*).
  int finish() {
    const Eigen::Map<const RowMat> G(Gt.data(), n, Nc);
    if (!qp->qps.solve(G, qv, dqv)) return 2;
    v.map = qp->qps.U.row(0);
    auto t = tau.map.row(0).transpose();
    if (external) {
      t.noalias() = M_out.map * v.map.row(0).transpose();
      t += nle_out.map.row(0).transpose();
    } else {
      t.noalias() = *M * v.map.row(0).transpose();
      t += *nle;
    }
    if (zoh_Ts > 0.0) {
      if (external) zoh_gain(Mat(M_out.map));
      else zoh_gain(*M);
      t += extra;
    }
    if (joint) {  // J of this step, for the observer's next update
      for (int i = 0; i < n; ++i) {
        const double sg = (dqv[i] > 0.0) - (dqv[i] < 0.0);
        jtau[i] = jb[i] * dqv[i] + jf[i] * sg + extra[i];
      }
    }
    t -= dhat.map.row(0).transpose();
    started = true;
    ++steps;
    record();
    return 0;
  }

  // The zero-order-hold terms of the joint dynamics, into `extra`. With B q̇_k compensated,
  // joint j's velocity over a period of the torque held follows m_j ẇ = −b_j w + m_j v_j + e_j
  // (w = q̇ − q̇_k, m_j = 1/(M⁻¹)_jj its inertia with the others free, a_j = b_j/m_j), so it
  // gains v_j (1 − e^{−a_j Ts})/a_j instead of the v_j Ts the MPC predicts. The extra
  // torque (g_j − 1) m_j v_j, g_j = a_j Ts / (1 − e^{−a_j Ts}), restores v_j Ts
  // (g_j → 1 + a_j Ts/2 as a_j Ts → 0). The Coulomb term f_j sgn(q̇) changes sign where the
  // velocity path from q̇_k to q̇_k + v_j Ts (exponential with a_j, linear without damping)
  // crosses zero, at the fraction s* of the period: f_j sgn(q̇_k) is replaced by f_j σ_j,
  // σ_j the mean sign weighted by e^{−a_j (Ts − t)}, the weight the velocity at the end of
  // the period gives the force at t (σ_j = sgn(q̇_k + v_j Ts) when q̇_k = 0, so that a joint
  // at rest is not left to stick).
  void zoh_gain(const Mat& Mq) {
    extra.setZero(n);
    llt.compute(Mq);
    if (llt.info() != Eigen::Success) return;
    for (int j = 0; j < n; ++j) {
      if (jb[j] == 0.0 && jf[j] == 0.0) continue;
      jv.setZero();
      jv[j] = 1.0;
      const double minv = llt.solve(jv)[j];
      const double x = jb[j] * minv * zoh_Ts;
      const double vj = v.map(0, j);
      if (jb[j] != 0.0) {
        const double g = x < 1e-8 ? 1.0 + 0.5 * x : x / -std::expm1(-x);
        extra[j] = (g - 1.0) / minv * vj;
      }
      if (jf[j] != 0.0) {
        const double a = dqv[j], c = a + vj * zoh_Ts;
        const double sa = (a > 0.0) - (a < 0.0), sc = (c > 0.0) - (c < 0.0);
        double sigma = sc;
        if (sa != 0.0 && sa != sc) {
          const double p = a / (a - c);  // in (0, 1]: the crossing on a linear path
          double w1 = p;                 // weight of the part before the crossing
          if (x > 1e-8) {
            const double E = std::exp(-x);
            const double s_star = -std::log1p(-p * (1.0 - E)) / x;
            w1 = (std::exp(-x * (1.0 - s_star)) - E) / (1.0 - E);
          }
          sigma = sa * w1 + sc * (1.0 - w1);
        }
        extra[j] += jf[j] * (sigma - sa);
      }
    }
  }

  // One control step from the stack S = [q; q̇; r_1..r_N; ṙ_1..ṙ_N] ((2 + 2N)×n), with the
  // observer (or none) advanced here. Returns prepare()'s or finish()'s code.
  int step(const CRefRow& S) {
    if (latency_on) return step_latency(S);
    if (obs_start && started && ndo) {  // the model the held torque was computed from
      prev_M = *M;
      prev_nle = *nle0;
    }
    int code = prepare(S, true, false);
    if (code) return code;
    if (started && ndo) {
      // Eq (13) over the period that just ended, with the torque applied over it.
      const Mat& Mo = obs_start ? prev_M : *M;
      const Vec& no = obs_start ? prev_nle : (joint ? *nle0 : *nle);
      if (joint) {  // the rigid body's model, the torque beyond J (see jtau)
        applied_torque();
        applied -= jtau;
        ndo->ndo.update(Mo, no, dqv, applied);
      } else {
        ndo->ndo.update(Mo, no, dqv, applied_torque());
      }
      dhat.map.row(0) = ndo->ndo.estimate.transpose();
    }
    return finish();
  }

  // The step with latency: the observer over the measured interval (M, C q̇ + G at the
  // measured state, the aligned torque), then the MPC and Eq (4) at the predicted state.
  // Before the measured interval lies after the start, the observer restarts at each
  // measurement (d̂ = 0). S's state rows are overwritten with the prediction.
  int step_latency(const CRefRow& S_in) {
    if (S_in.rows() != 2 + 2 * N || S_in.cols() != n)
      throw std::invalid_argument("HMPCCore: stack of wrong shape");
    if (!S_in.allFinite()) return 1;
    if (!dyn) throw std::invalid_argument("HMPCCore.step: no compiled dynamics here");
    auto& S = stack->map;
    if (S.data() != S_in.data()) S = S_in;
    Vec q = S.row(0).transpose(), dq = S.row(1).transpose();
    if (ndo) {
      const Mat& Mq = dyn->mass_matrix(q);
      const Vec& nq = dyn->nle(q, dq);
      if (observer_ready() && (!obs_start || has_prev)) {
        align();
        if (obs_start) ndo->ndo.update(prev_M, prev_nle, dq, tau_obs);
        else ndo->ndo.update(Mq, nq, dq, tau_obs);
        dhat.map.row(0) = ndo->ndo.estimate.transpose();
      } else {
        ndo->ndo.reset(dq);
        dhat.map.setZero();
      }
      if (obs_start) {  // the start of the next measured interval
        prev_M = Mq;
        prev_nle = nq;
        has_prev = true;
      }
    }
    predict(q, dq);
    S.row(0) = q.transpose();
    S.row(1) = dq.transpose();
    int code = prepare(S, true, false);
    return code ? code : finish();
  }
};

// -------------------------------------------------------------------------------------
// The closed loop (hmpc_pin.sim.compiled_loop): the per-step loop of
// hmpc_pin.sim.simulate.simulate, many control periods per call, when every part has a
// compiled form: the controller's fused step with its native reference (HMPCCore.step_t),
// optionally behind a measurement model of white noise and a whole-period delay
// (MeasuredController: the noise drawn by the caller, one row of 2n per step), and the RK4
// plant's period with its fused disturbance (time-only terms tabulated by the caller, one
// Coulomb-viscous friction here). Per step k, as the Python loop does:
//   τ = step(t_k, measured state) → record q, q̇, τ, d, d̂ → (k = K: stop) → τ finite →
//   clip to the effort limit (count, largest excess) → record τ applied → RK4 period →
//   state finite and within the bound.
// run() returns (k, code) with k the step where it stopped: code 0 the chunk ran (k = k1),
// or stopped at the last step K (recorded); 1-4 the controller's step failed (its code,
// nothing recorded at k); 5 τ not finite; 6 the state not finite; 7 beyond the bound (at k
// recorded). Signals are checked before every step (Ctrl-C: the Python exception is
// raised with `last` the last recorded step).

struct ClosedLoop {
  HMPCCore* core;
  RK4* plant;
  int n, K;
  py::array_t<double, py::array::c_style> t_arr;
  // (K+1)×n records, Python-owned: q, q̇, τ, d, d̂, τ applied.
  std::vector<py::array_t<double, py::array::c_style>> rec;
  py::array_t<std::int64_t, py::array::c_style> step_ns, sat_steps;
  py::array_t<double, py::array::c_style> sat_excess;
  Vec limit, fa, fb;
  bool has_limit, friction;
  double bound, h;
  int substeps;
  // Measurement (MeasuredController): noise levels, delay D, the last D+1 measurements
  // (ring: step k in row k % (D+1), [q; q̇]), Python-owned.
  bool measured = false;
  double q_noise = 0.0, dq_noise = 0.0;
  int delay = 0;
  std::optional<py::array_t<double, py::array::c_style>> hist;
  long last = -1;     // the last recorded step
  long advances = 0;  // plant periods integrated by run()
  long started = 0;   // steps begun by run() (the measurement drew their noise)
  long stepped = 0;   // controller steps that succeeded
  Vec qm, dqm, tau, d;
  RowMat T;

  static double* row_of(py::array_t<double, py::array::c_style>& a, long r0, int n) {
    return a.mutable_data() + r0 * n;
  }

  ClosedLoop(HMPCCore& c, RK4& p, py::array_t<double, py::array::c_style> t_arr_,
             std::vector<py::array_t<double, py::array::c_style>> rec_,
             py::array_t<std::int64_t, py::array::c_style> step_ns_,
             py::array_t<std::int64_t, py::array::c_style> sat_steps_,
             py::array_t<double, py::array::c_style> sat_excess_, const CRefVec& limit_,
             bool has_limit_, double bound_, const CRefVec& a, const CRefVec& b, bool friction_,
             double h_, int substeps_)
      : core(&c), plant(&p), n(c.n), t_arr(t_arr_), rec(std::move(rec_)), step_ns(step_ns_),
        sat_steps(sat_steps_), sat_excess(sat_excess_), limit(limit_), fa(a), fb(b),
        has_limit(has_limit_), friction(friction_), bound(bound_), h(h_), substeps(substeps_) {
    K = static_cast<int>(t_arr.size()) - 1;
    if (p.n != n || rec.size() != 6 || limit.size() != n || fa.size() != n || fb.size() != n ||
        step_ns.size() != K + 1 || sat_steps.size() != n || sat_excess.size() != n ||
        substeps < 1 || !c.stack)
      throw std::invalid_argument("ClosedLoop: shapes do not match");
    for (auto& r : rec)
      if (r.size() != static_cast<py::ssize_t>(K + 1) * n || !r.writeable())
        throw std::invalid_argument("ClosedLoop: records must be writable (K+1, n)");
    qm.setZero(n);
    dqm.setZero(n);
    tau.setZero(n);
    d.setZero(n);
    T.setZero(3 * substeps, n);
  }

  void set_measurement(double qn, double dqn, int D, py::array_t<double, py::array::c_style> H) {
    if (D < 0 || H.ndim() != 2 || H.shape(0) != D + 1 || H.shape(1) != 2 * n || !H.writeable())
      throw std::invalid_argument("ClosedLoop.set_measurement: history of (delay + 1, 2n)");
    measured = true;
    q_noise = qn;
    dq_noise = dqn;
    delay = D;
    hist.emplace(H);
  }

  // Steps k0 .. k1-1 from the plant state (q, v) (updated in place). P: the time-only
  // terms at the stage times of periods k0.. (rows of 3·substeps each; none: 0 rows);
  // noise: one row of 2n standard normal draws per step k0.. (measured; row of step 0
  // unused: the measurement at reset).
  py::tuple run(RefVec q, RefVec v, long k0, long k1, const CRefRow& P, const CRefRow& noise) {
    if (q.size() != n || v.size() != n || k0 < 0 || k1 > K + 1 || k0 > k1)
      throw std::invalid_argument("ClosedLoop.run: bad state or steps");
    const int rows = 3 * substeps;
    const bool pulses = P.rows() > 0;
    if (pulses && (P.rows() < (k1 - k0) * rows || P.cols() != n))
      throw std::invalid_argument("ClosedLoop.run: the table of time-only terms is too short");
    if (measured && (noise.rows() < k1 - k0 || noise.cols() != 2 * n))
      throw std::invalid_argument("ClosedLoop.run: the noise is too short");
    const double* t = t_arr.data();
    std::int64_t* ns = step_ns.mutable_data();
    std::int64_t* sat_n = sat_steps.mutable_data();
    double* sat_x = sat_excess.mutable_data();
    HMPCCore& c = *core;
    for (long k = k0; k < k1; ++k) {
      if (PyErr_CheckSignals() != 0) throw py::error_already_set();
      const long j = k - k0;
      const Vec* qc = &qm;  // the state the controller is given
      const Vec* dqc = &dqm;
      if (measured) {
        ++started;
        double* H = hist->mutable_data();
        if (k > 0) {  // this step's measurement (step 0's was taken at reset)
          double* row = H + (k % (delay + 1)) * 2 * n;
          for (int i = 0; i < n; ++i) {
            row[i] = q[i] + q_noise * noise(j, i);
            row[n + i] = v[i] + dq_noise * noise(j, n + i);
          }
        }
        const double* row = H + ((k > delay ? k - delay : 0) % (delay + 1)) * 2 * n;
        for (int i = 0; i < n; ++i) {
          qm[i] = row[i];
          dqm[i] = row[n + i];
        }
      } else {
        qm = q;
        dqm = v;
      }
      const auto start = std::chrono::steady_clock::now();
      const int code = c.step_t(t[k], *qc, *dqc);
      ns[k] = std::chrono::duration_cast<std::chrono::nanoseconds>(
                  std::chrono::steady_clock::now() - start).count();
      if (code) return py::make_tuple(k, code);
      ++stepped;
      tau = c.tau.map.row(0).transpose();
      // d(t_k, q, q̇): the time-only terms at the period's first stage, minus the friction
      if (pulses) d = P.row(j * rows).transpose();
      else d.setZero();
      if (friction) {
        for (int i = 0; i < n; ++i) {
          const double s = (v[i] > 0.0) - (v[i] < 0.0);
          d[i] = d[i] - (fa[i] * v[i] + fb[i] * s);
        }
      }
      double* rq = row_of(rec[0], k, n);
      double* rdq = row_of(rec[1], k, n);
      double* rtau = row_of(rec[2], k, n);
      double* rd = row_of(rec[3], k, n);
      double* rdh = row_of(rec[4], k, n);
      for (int i = 0; i < n; ++i) {
        rq[i] = q[i];
        rdq[i] = v[i];
        rtau[i] = tau[i];
        rd[i] = d[i];
        rdh[i] = c.dhat.map(0, i);
      }
      last = k;
      if (k == K) return py::make_tuple(k, 0);
      if (!tau.allFinite()) return py::make_tuple(k, 5);
      if (has_limit) {
        for (int i = 0; i < n; ++i) {
          const double excess = std::abs(tau[i]) - limit[i];
          if (excess > 0.0) {
            ++sat_n[i];
            sat_x[i] = std::max(sat_x[i], excess);
            tau[i] = std::min(std::max(tau[i], -limit[i]), limit[i]);
          }
        }
      }
      double* rap = row_of(rec[5], k, n);
      for (int i = 0; i < n; ++i) rap[i] = tau[i];
      for (int r = 0; r < rows; ++r) {
        if (pulses) T.row(r) = tau.transpose() + P.row(j * rows + r);
        else T.row(r) = tau.transpose();
      }
      plant->period(q, v, T, fa, fb, friction, h);
      ++advances;
      bool inside = true;
      for (int i = 0; i < n && inside; ++i)
        inside = std::abs(q[i]) <= bound && std::abs(v[i]) <= bound;
      if (!inside) return py::make_tuple(k, q.allFinite() && v.allFinite() ? 7 : 6);
    }
    return py::make_tuple(k1, 0);
  }
};

PYBIND11_MODULE(_core, m) {
  m.doc() = "hmpc_pin native kernels (RK4 period, hierarchical MPC step)";
  // Every class is module-local: another build of this module (an older version loaded
  // side by side for an A/B benchmark) or another pybind11 extension with classes of the
  // same names cannot take over these bindings.
  // What this module was built against (CMakeLists.txt); hmpc_pin.native checks it.
  py::dict info;
  info["pinocchio"] = HMPC_PINOCCHIO_VERSION;
  info["proxsuite"] = HMPC_PROXSUITE_VERSION;
  info["compiler"] = HMPC_COMPILER;
  info["build_type"] = HMPC_BUILD_TYPE;
  m.attr("build_info") = info;

  py::class_<Dynamics>(m, "Dynamics", py::module_local())
      .def(py::init<const std::string&>(), py::arg("model"))
      .def_readonly("nq", &Dynamics::n)
      .def("mass_matrix", [](Dynamics& d, const CRefVec& q) { return Mat(d.mass_matrix(q)); },
           py::arg("q"))
      .def("nle", [](Dynamics& d, const CRefVec& q, const CRefVec& v) { return Vec(d.nle(q, v)); },
           py::arg("q"), py::arg("v"))
      .def("aba", [](Dynamics& d, const CRefVec& q, const CRefVec& v, const CRefVec& tau) {
             return Vec(d.aba(q, v, tau)); }, py::arg("q"), py::arg("v"), py::arg("tau"));

  using HS = hmpc_native::HorizonSampler;
  py::class_<HS>(m, "Sampler", py::module_local())
      .def(py::init<int>(), py::arg("n"))
      .def("set_sine", &HS::set_sine, py::arg("omega"), py::arg("phase"), py::arg("amp"),
           py::arg("offset"), py::arg("amp_omega"))
      .def("set_ppoly", &HS::set_ppoly, py::arg("times"), py::arg("knots"), py::arg("coef"),
           py::arg("deg"))
      .def("sample",
           [](const HS& h, const CRefVec& times, py::array_t<double, py::array::c_style> q,
              py::array_t<double, py::array::c_style> dq) {
             const Eigen::Index m = times.size();
             if (q.ndim() != 2 || dq.ndim() != 2 || q.shape(0) != m || q.shape(1) != h.n ||
                 dq.shape(0) != m || dq.shape(1) != h.n || !q.writeable() || !dq.writeable())
               throw std::invalid_argument("Sampler.sample: q and dq must be writable (m, n)");
             double* qp = q.mutable_data();
             double* dqp = dq.mutable_data();
             for (Eigen::Index j = 0; j < m; ++j) h.sample(times[j], qp + j * h.n, dqp + j * h.n);
           }, py::arg("times"), py::arg("q"), py::arg("dq"))
      .def_readonly("n", &HS::n)
      .def_readonly("kind", &HS::kind);

  py::class_<RK4>(m, "RK4", py::module_local())
      .def(py::init<py::object, int, py::object>(), py::arg("model"), py::arg("n") = 0,
           py::arg("aba") = py::none())
      .def_property_readonly("nq", [](const RK4& r) { return r.n; })
      .def("period", &RK4::period, py::arg("q"), py::arg("v"), py::arg("T"), py::arg("a"),
           py::arg("b"), py::arg("friction"), py::arg("h"))
      .def("set_joint_dynamics", &RK4::set_joint_dynamics, py::arg("damping"),
           py::arg("friction"))
      .def_property_readonly("joint_damping", [](const RK4& r) { return Vec(r.jb); })
      .def_property_readonly("joint_friction", [](const RK4& r) { return Vec(r.jf); })
      .def("period_with", &RK4::period_with, py::arg("q"), py::arg("v"), py::arg("tau"),
           py::arg("t"), py::arg("h"), py::arg("S"), py::arg("disturbance"))
      .def("aba", [](RK4& r, const CRefVec& q, const CRefVec& v, const CRefVec& tau) {
             Vec out(r.n);
             r.aba(q, v, Vec(tau), out);
             return out; })
      .def("mass_matrix", [](RK4& r, const CRefVec& q) {
             if (!r.dyn) throw std::invalid_argument("RK4: no compiled dynamics");
             return Mat(r.dyn->mass_matrix(q)); })
      .def("nle", [](RK4& r, const CRefVec& q, const CRefVec& v) {
             if (!r.dyn) throw std::invalid_argument("RK4: no compiled dynamics");
             return Vec(r.dyn->nle(q, v)); });

  py::class_<PyNDO, std::shared_ptr<PyNDO>>(m, "NDO", py::module_local())
      .def(py::init<const CRefMat&, double, bool, py::array_t<double, py::array::c_style>,
                    py::array_t<double, py::array::c_style>>(),
           py::arg("cY"), py::arg("Ts"), py::arg("implicit"), py::arg("z"), py::arg("estimate"))
      .def("reset", [](PyNDO& o, const CRefVec& dq0) { o.ndo.reset(dq0); }, py::arg("dq0"))
      .def("update", &PyNDO::update, py::arg("M"), py::arg("nle"), py::arg("dq"),
           py::arg("tau_prev"))
      .def_property_readonly("n", [](const PyNDO& o) { return o.ndo.n; })
      .def_property_readonly("implicit", [](const PyNDO& o) { return o.ndo.implicit; })
      .def_property(  // (z, d̂), copies; restored after a dry step (warm_up)
          "state", [](const PyNDO& o) { return py::make_tuple(Vec(o.ndo.z), Vec(o.ndo.estimate)); },
          [](PyNDO& o, const py::tuple& s) {
            const Vec z = s[0].cast<Vec>(), e = s[1].cast<Vec>();
            if (z.size() != o.ndo.n || e.size() != o.ndo.n)
              throw std::invalid_argument("NDO.state: (z, estimate) of n values each");
            o.ndo.z = z;
            o.ndo.estimate = e;
          });

  using JQ = hmpc_native::JointQPs;
  py::class_<PyJointQPs, std::shared_ptr<PyJointQPs>>(m, "JointQPs", py::module_local())
      .def(py::init<int, int, int, bool, const CRefMat&, const CRefVec&, const CRefVec&,
                    const py::dict&, const py::dict&, py::array_t<double, py::array::c_style>,
                    py::array_t<double, py::array::c_style>>(),
           py::arg("n"), py::arg("N"), py::arg("Nc"), py::arg("block"), py::arg("H"),
           py::arg("v_min"), py::arg("v_max"), py::arg("warm"), py::arg("cold"),
           py::arg("U"), py::arg("slack"))
      .def("set_limits",
           [](PyJointQPs& o, const CRefMat& Phi, const CRefMat& Gamma, const CRefVec& lower,
              const CRefVec& upper, const CRefVec& vel, const CRefMat& Hs, const CRefMat& C,
              const CRefVec& row_scale, double g_slack, double k_slack, const py::dict& soft,
              bool always) {
             o.qps.set_limits(Phi, Gamma, lower, upper, vel, Hs, C, row_scale, g_slack, k_slack,
                              qp_options(soft), always);
           })
      .def("solve", [](PyJointQPs& o, const CRefRow& G, const CRefVec& q, const CRefVec& dq) {
             return o.qps.solve(G, q, dq); }, py::arg("G"), py::arg("q"), py::arg("dq"))
      .def("set_max_iter", [](PyJointQPs& o, long k) { o.qps.set_max_iter(k); })
      .def_property("shortcut", [](const PyJointQPs& o) { return o.qps.shortcut; },
                    [](PyJointQPs& o, bool on) { o.qps.shortcut = on; })
      .def_property("shift", [](const PyJointQPs& o) { return o.qps.shift; },
                    [](PyJointQPs& o, bool on) { o.qps.shift = on; })
      .def_property("active_set_iter", [](const PyJointQPs& o) { return o.qps.active_set_iter; },
                    [](PyJointQPs& o, int k) { o.qps.active_set_iter = k; })
      .def_property_readonly("active_set_solves",
                             [](const PyJointQPs& o) { return o.qps.active_set_solves; })
      .def_property(
          "counters",
          [](const PyJointQPs& o) {
            const auto& q = o.qps;
            return py::make_tuple(q.cold_solves, q.unconstrained_solves, q.active_set_solves,
                                  q.constrained, q.constrained_last);
          },
          [](PyJointQPs& o, const py::tuple& c) {  // restored after a dry step (warm_up)
            auto& q = o.qps;
            q.cold_solves = c[0].cast<long>();
            q.unconstrained_solves = c[1].cast<long>();
            q.active_set_solves = c[2].cast<long>();
            q.constrained = c[3].cast<long>();
            q.constrained_last = c[4].cast<bool>();
          })
      .def_property_readonly("cold_solves", [](const PyJointQPs& o) { return o.qps.cold_solves; })
      .def_property_readonly("unconstrained_solves",
                             [](const PyJointQPs& o) { return o.qps.unconstrained_solves; })
      .def_property_readonly("constrained", [](const PyJointQPs& o) { return o.qps.constrained; })
      .def_property_readonly("constrained_last",
                             [](const PyJointQPs& o) { return o.qps.constrained_last; })
      .def_property_readonly("fail_joint", [](const PyJointQPs& o) { return o.qps.fail_joint; })
      .def_property_readonly("fail_status", [](const PyJointQPs& o) { return o.qps.fail_status; })
      .def_property_readonly("fail_iter", [](const PyJointQPs& o) { return o.qps.fail_iter; });

  py::class_<HMPCCore>(m, "HMPCCore", py::module_local())
      .def(py::init<py::object, const CRefRow&, int, std::shared_ptr<PyJointQPs>,
                    std::shared_ptr<PyNDO>, py::array_t<double, py::array::c_style>,
                    py::array_t<double, py::array::c_style>,
                    py::array_t<double, py::array::c_style>,
                    py::array_t<double, py::array::c_style>,
                    py::array_t<double, py::array::c_style>>(),
           py::arg("model"), py::arg("FT"), py::arg("N"), py::arg("qps"), py::arg("ndo"),
           py::arg("v"), py::arg("tau"), py::arg("d_hat"), py::arg("M"), py::arg("nle"))
      .def("set_effort", &HMPCCore::set_effort)
      .def("set_observer_model", &HMPCCore::set_observer_model, py::arg("at_start"))
      .def("set_latency", &HMPCCore::set_latency, py::arg("L"), py::arg("Ts"))
      .def("observer_ready", &HMPCCore::observer_ready)
      .def("aligned", [](HMPCCore& c) {
             c.align();
             return py::make_tuple(Vec(c.tau_obs), Vec(c.v_obs)); })
      .def("predict", &HMPCCore::predict_stack, py::arg("S"))
      .def_readonly("latency_periods", &HMPCCore::lat_m)
      .def_readonly("latency_fraction", &HMPCCore::lat_alpha)
      .def("set_joint_dynamics", &HMPCCore::set_joint_dynamics, py::arg("damping"),
           py::arg("friction"), py::arg("Ts"))
      .def("reset", &HMPCCore::reset)
      .def("step", &HMPCCore::step)
      .def("step_t", &HMPCCore::step_t)
      .def("fill", &HMPCCore::fill)
      .def("prepare", &HMPCCore::prepare, py::arg("S"), py::arg("dynamics") = true,
           py::arg("export") = true)
      .def("finish", &HMPCCore::finish)
      .def("set_stack", &HMPCCore::set_stack)
      .def("set_sine", &HMPCCore::set_sine)
      .def("set_ppoly", &HMPCCore::set_ppoly)
      .def("clear_reference", &HMPCCore::clear_reference)
      .def_property(  // what a step carries to the next (restored after a dry step, warm_up)
          "state",
          [](const HMPCCore& c) {  // copies
            std::vector<Vec> th = c.tau_hist, vh = c.v_hist;
            return py::make_tuple(c.started, Vec(c.jtau), std::move(th), std::move(vh),
                                  Vec(c.tau_obs), Vec(c.v_obs), c.steps, Mat(c.prev_M),
                                  Vec(c.prev_nle), c.has_prev);
          },
          [](HMPCCore& c, const py::tuple& s) {
            c.steps = s[6].cast<decltype(c.steps)>();
            c.started = s[0].cast<bool>();
            c.jtau = s[1].cast<Vec>();
            c.tau_hist = s[2].cast<std::vector<Vec>>();
            c.v_hist = s[3].cast<std::vector<Vec>>();
            c.tau_obs = s[4].cast<Vec>();
            c.v_obs = s[5].cast<Vec>();
            c.prev_M = s[7].cast<Mat>();
            c.prev_nle = s[8].cast<Vec>();
            c.has_prev = s[9].cast<bool>();
          })
      .def_property_readonly("has_dynamics", [](const HMPCCore& c) { return bool(c.dyn); })
      .def_property_readonly("joint_torque", [](const HMPCCore& c) {
             return c.joint ? Vec(c.jtau) : Vec(Vec::Zero(c.n)); });

  py::class_<ClosedLoop>(m, "ClosedLoop", py::module_local())
      .def(py::init<HMPCCore&, RK4&, py::array_t<double, py::array::c_style>,
                    std::vector<py::array_t<double, py::array::c_style>>,
                    py::array_t<std::int64_t, py::array::c_style>,
                    py::array_t<std::int64_t, py::array::c_style>,
                    py::array_t<double, py::array::c_style>, const CRefVec&, bool, double,
                    const CRefVec&, const CRefVec&, bool, double, int>(),
           py::arg("core"), py::arg("plant"), py::arg("t"), py::arg("records"),
           py::arg("step_ns"), py::arg("sat_steps"), py::arg("sat_excess"), py::arg("limit"),
           py::arg("has_limit"), py::arg("bound"), py::arg("a"), py::arg("b"),
           py::arg("friction"), py::arg("h"), py::arg("substeps"),
           py::keep_alive<1, 2>(), py::keep_alive<1, 3>())
      .def("set_measurement", &ClosedLoop::set_measurement, py::arg("q_noise"),
           py::arg("dq_noise"), py::arg("delay"), py::arg("history"))
      .def("run", &ClosedLoop::run, py::arg("q"), py::arg("v"), py::arg("k0"), py::arg("k1"),
           py::arg("P"), py::arg("noise"))
      .def_readonly("last", &ClosedLoop::last)
      .def_readonly("advances", &ClosedLoop::advances)
      .def_readonly("started", &ClosedLoop::started)
      .def_readonly("stepped", &ClosedLoop::stepped);
}
