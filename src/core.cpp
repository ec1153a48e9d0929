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

#include <Eigen/LU>
#include <proxsuite/proxqp/dense/dense.hpp>

#include "dynamics.hpp"
#include "observer.hpp"

#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace py = pybind11;
namespace pqp = proxsuite::proxqp;

using Vec = Eigen::VectorXd;
using Mat = Eigen::MatrixXd;
using RowMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using CRefVec = Eigen::Ref<const Vec>;
using RefVec = Eigen::Ref<Vec>;
using CRefMat = Eigen::Ref<const Mat>;
using CRefRow = Eigen::Ref<const RowMat>;
using MapVec = Eigen::Map<Vec>;
using MapRow = Eigen::Map<RowMat>;
using DenseQP = pqp::dense::QP<double>;

static constexpr double BIG = 1e10;  // as hmpc_pin.mpc.condensed.BIG

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
// The RK4 plant's period: see hmpc_pin.sim.plants.RK4Plant (same stages, same torques).

struct RK4 {
  Dynamics dyn;
  Vec q2, v2, q3, v3, q4, v4, a1, a2, a3, a4, u;

  explicit RK4(const std::string& serialized) : dyn(serialized) {
    const int n = dyn.n;
    for (Vec* x : {&q2, &v2, &q3, &v3, &q4, &v4, &a1, &a2, &a3, &a4, &u}) x->setZero(n);
  }

  // Stage torque: the held torque plus the time-only terms T_row, minus the friction
  // a·q̇ + b·sgn(q̇) (sgn(0) = 0) when `friction`.
  template <class Row>
  void torque(const Row& T_row, const Vec& v, const CRefVec& a, const CRefVec& b, bool friction) {
    u = T_row.transpose();
    if (friction) {
      for (int i = 0; i < dyn.n; ++i) {
        const double s = (v[i] > 0.0) - (v[i] < 0.0);
        u[i] += -a[i] * v[i] + -b[i] * s;
      }
    }
  }

  // Advance (q, v) in place over T.rows() / 3 steps of h. T holds, per stage time, the
  // torque without friction: rows t_s (s = 0..S-1), then t_s + h/2, then t_s + h.
  void period(RefVec q, RefVec v, const CRefRow& T, const CRefVec& a, const CRefVec& b,
              bool friction, double h) {
    const int S = static_cast<int>(T.rows() / 3);
    if (T.rows() != 3 * S || T.cols() != dyn.n || q.size() != dyn.n || v.size() != dyn.n)
      throw std::invalid_argument("RK4.period: shapes do not match the model");
    const double hh = 0.5 * h, h6 = h / 6.0;
    Vec vq = v;  // v as a Vec for the stage torque
    for (int s = 0; s < S; ++s) {
      vq = v;
      torque(T.row(s), vq, a, b, friction);
      a1 = dyn.aba(q, v, u);
      q2 = q + hh * v;
      v2 = v + hh * a1;
      torque(T.row(S + s), v2, a, b, friction);
      a2 = dyn.aba(q2, v2, u);
      q3 = q + hh * v2;
      v3 = v + hh * a2;
      torque(T.row(S + s), v3, a, b, friction);
      a3 = dyn.aba(q3, v3, u);
      q4 = q + h * v3;
      v4 = v + h * a3;
      torque(T.row(2 * S + s), v4, a, b, friction);
      a4 = dyn.aba(q4, v4, u);
      q += h6 * v + (2.0 * h6) * v2 + (2.0 * h6) * v3 + h6 * v4;
      v += h6 * a1 + (2.0 * h6) * a2 + (2.0 * h6) * a3 + h6 * a4;
    }
  }
};

// -------------------------------------------------------------------------------------
// ProxSuite settings from a dict (keys: the Settings attributes set by the Python side).

static void apply_settings(DenseQP& qp, const py::dict& settings) {
  for (auto item : settings) {
    const std::string key = py::str(item.first);
    py::handle value = item.second;
    auto& s = qp.settings;
    if (key == "initial_guess") {
      const std::string name = py::str(value);
      if (name == "WARM_START_WITH_PREVIOUS_RESULT")
        s.initial_guess = pqp::InitialGuessStatus::WARM_START_WITH_PREVIOUS_RESULT;
      else if (name == "NO_INITIAL_GUESS")
        s.initial_guess = pqp::InitialGuessStatus::NO_INITIAL_GUESS;
      else
        throw std::invalid_argument("unknown initial_guess " + name);
    } else if (key == "eps_abs") s.eps_abs = value.cast<double>();
    else if (key == "eps_rel") s.eps_rel = value.cast<double>();
    else if (key == "max_iter") s.max_iter = value.cast<long>();
    else if (key == "verbose") s.verbose = value.cast<bool>();
    else if (key == "check_duality_gap") s.check_duality_gap = value.cast<bool>();
    else if (key == "eps_duality_gap_abs") s.eps_duality_gap_abs = value.cast<double>();
    else if (key == "eps_duality_gap_rel") s.eps_duality_gap_rel = value.cast<double>();
    else if (key == "eps_primal_inf") s.eps_primal_inf = value.cast<double>();
    else if (key == "eps_dual_inf") s.eps_dual_inf = value.cast<double>();
    else throw std::invalid_argument("native kernels do not know the ProxSuite setting " + key);
  }
}

static std::string status_name(pqp::QPSolverOutput status) {
  switch (status) {
    case pqp::QPSolverOutput::PROXQP_SOLVED: return "QPSolverOutput.PROXQP_SOLVED";
    case pqp::QPSolverOutput::PROXQP_MAX_ITER_REACHED: return "QPSolverOutput.PROXQP_MAX_ITER_REACHED";
    case pqp::QPSolverOutput::PROXQP_PRIMAL_INFEASIBLE: return "QPSolverOutput.PROXQP_PRIMAL_INFEASIBLE";
    case pqp::QPSolverOutput::PROXQP_DUAL_INFEASIBLE: return "QPSolverOutput.PROXQP_DUAL_INFEASIBLE";
    case pqp::QPSolverOutput::PROXQP_SOLVED_CLOSEST_PRIMAL_FEASIBLE:
      return "QPSolverOutput.PROXQP_SOLVED_CLOSEST_PRIMAL_FEASIBLE";
    case pqp::QPSolverOutput::PROXQP_NOT_RUN: return "QPSolverOutput.PROXQP_NOT_RUN";
  }
  return "QPSolverOutput.UNKNOWN";
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
// The hierarchical MPC's step: hmpc_pin.controllers.hierarchical.HierarchicalMPC.step with
// the NDO of hmpc_pin.compensation.observers.DisturbanceObserver (or none) and the QPs
// of hmpc_pin.mpc.condensed.JointQPs (block or per joint, soft limits).

struct HMPCCore {
  Dynamics dyn;
  int n, N, Nc;
  // Gradient map, rows in stack order [q; q̇; r_1..r_N; ṙ_1..ṙ_N]; rows used.
  RowMat FT;
  Eigen::Index grad_rows;
  // Box QPs.
  bool block;
  Mat H;           // one joint's scaled Hessian (Nc×Nc)
  Mat H_block;     // kron(I_n, H) for the block layout
  Vec v_min, v_max;
  py::dict warm_settings, cold_settings, soft_settings;
  std::vector<std::unique_ptr<DenseQP>> qps, cold;
  long cold_solves = 0;
  long unconstrained_solves = 0;
  Mat neg_Hinv;    // −H⁻¹ (per-joint layout's shortcut)
  Vec g_block;
  // Soft state limits.
  bool limits = false;
  Mat Phi, Gamma;  // 2N×2, 2N×Nc
  Vec lower, upper, vel, row_scale;
  Vec mid, half;
  double g_slack = 0.0, k_slack = 0.0;
  Mat Hs, C;
  std::vector<std::unique_ptr<DenseQP>> soft;
  Vec g_soft, l_soft, u_soft, X;
  bool constrained_last = false;
  long constrained = 0;
  // The observer (observer.hpp), shared with the Python DisturbanceObserver; none: null.
  std::shared_ptr<PyNDO> ndo;
  // Effort limit (inf: none).
  Vec effort;
  bool started = false;
  // Python-owned outputs, updated in place.
  Buffer<MapRow> U;       // (Nc, n) solution
  Buffer<MapRow> slack;   // (1, n)
  Buffer<MapRow> v;       // (1, n) commanded acceleration
  Buffer<MapRow> tau;     // (1, n) commanded torque
  Buffer<MapRow> dhat;    // (1, n) disturbance estimate
  Vec applied;
  // The stack [q; q̇; r_1..r_N; ṙ_1..ṙ_N] ((2 + 2N)×n), Python-owned (step_t fills it).
  std::optional<Buffer<MapRow>> stack;
  // The reference in native form (step_t): 0 none, 1 sine, 2 piecewise polynomial.
  int ref_kind = 0;
  Vec offsets;                           // horizon offsets j·Ts, j = 1..N [s]
  Vec s_omega, s_phase, s_amp, s_offset, s_amp_omega;
  Vec p_times, p_knots;                  // breakpoints t_0..t_{K-1}; segment origins
  RowMat p_coef;                         // (segments·(deg + 1))×2n: [q | q̇] per power
  int p_deg = 0;
  Eigen::RowVectorXd acc;                // one segment's [q | q̇] at s
  // Failure report.
  int fail_joint = -2;
  std::string fail_status;
  long fail_iter = 0;

  HMPCCore(const std::string& serialized, const CRefRow& FT_, int N_, int Nc_, bool block_,
           const CRefMat& H_, const CRefVec& v_min_, const CRefVec& v_max_,
           py::dict warm_settings_, py::dict cold_settings_, std::shared_ptr<PyNDO> ndo_,
           py::array_t<double, py::array::c_style> U_,
           py::array_t<double, py::array::c_style> slack_,
           py::array_t<double, py::array::c_style> v_,
           py::array_t<double, py::array::c_style> tau_,
           py::array_t<double, py::array::c_style> dhat_)
      : dyn(serialized), n(dyn.n), N(N_), Nc(Nc_), FT(FT_), block(block_), H(H_),
        v_min(v_min_), v_max(v_max_), warm_settings(warm_settings_),
        cold_settings(cold_settings_), ndo(std::move(ndo_)),
        U(U_, Nc_, dyn.n), slack(slack_, 1, dyn.n), v(v_, 1, dyn.n), tau(tau_, 1, dyn.n),
        dhat(dhat_, 1, dyn.n) {
    if (FT.rows() != 2 + 2 * N || FT.cols() != Nc || H.rows() != Nc || H.cols() != Nc ||
        v_min.size() != n || v_max.size() != n || (ndo && ndo->ndo.n != n))
      throw std::invalid_argument("HMPCCore: shapes do not match the model and horizon");
    // Without a velocity weight the ṙ rows of the map are zero: skip them.
    grad_rows = FT.bottomRows(N).isZero(0.0) ? N + 2 : 2 + 2 * N;
    applied.setZero(n);
    effort = Vec::Constant(n, std::numeric_limits<double>::infinity());
    if (block) {
      H_block = Mat::Zero(n * Nc, n * Nc);
      Vec lo(n * Nc), hi(n * Nc);
      for (int i = 0; i < n; ++i) {
        H_block.block(i * Nc, i * Nc, Nc, Nc) = H;
        lo.segment(i * Nc, Nc).setConstant(v_min[i]);
        hi.segment(i * Nc, Nc).setConstant(v_max[i]);
      }
      g_block.setZero(n * Nc);
      qps.emplace_back(new_box_qp(H_block, g_block, lo, hi, warm_settings));
    } else {
      const Mat Hinv = H.inverse();
      neg_Hinv = -0.5 * (Hinv + Hinv.transpose());
      for (int i = 0; i < n; ++i) {
        Vec g = Vec::Zero(Nc);
        qps.emplace_back(new_box_qp(H, g, Vec::Constant(Nc, v_min[i]),
                                    Vec::Constant(Nc, v_max[i]), warm_settings));
      }
    }
    cold.resize(qps.size());
  }

  std::unique_ptr<DenseQP> new_box_qp(const Mat& Hq, const Vec& g, const Vec& lo, const Vec& hi,
                                      const py::dict& settings) {
    auto qp = std::make_unique<DenseQP>(Hq.rows(), 0, 0, true);
    apply_settings(*qp, settings);
    qp->init(Hq, g, std::nullopt, std::nullopt, std::nullopt, std::nullopt, std::nullopt, lo, hi);
    qp->solve();
    return qp;
  }

  void set_limits(const CRefMat& Phi_, const CRefMat& Gamma_, const CRefVec& lower_,
                  const CRefVec& upper_, const CRefVec& vel_, const CRefMat& Hs_,
                  const CRefMat& C_, const CRefVec& row_scale_, double g_slack_, double k_slack_,
                  py::dict soft_settings_) {
    Phi = Phi_;
    Gamma = Gamma_;
    lower = lower_;
    upper = upper_;
    vel = vel_;
    Hs = Hs_;
    C = C_;
    row_scale = row_scale_;
    g_slack = g_slack_;
    k_slack = k_slack_;
    soft_settings = soft_settings_;
    if (Phi.rows() != 2 * N || Phi.cols() != 2 || Gamma.rows() != 2 * N || Gamma.cols() != Nc ||
        lower.size() != n || upper.size() != n || vel.size() != n || Hs.rows() != Nc + 1 ||
        C.rows() != 4 * N || C.cols() != Nc + 1 || row_scale.size() != 4 * N)
      throw std::invalid_argument("HMPCCore.set_limits: shapes do not match");
    mid = 0.5 * (lower + upper);
    half = 0.5 * (upper - lower);
    g_soft.setZero(Nc + 1);
    l_soft.setZero(4 * N);
    u_soft.setZero(4 * N);
    X.setZero(2 * N);
    soft.clear();
    for (int i = 0; i < n; ++i) {
      auto qp = std::make_unique<DenseQP>(Nc + 1, 0, 4 * N, true);
      apply_settings(*qp, soft_settings);
      g_soft.head(Nc).setZero();
      g_soft[Nc] = g_slack;
      soft_bounds(i, Vec::Zero(N), Vec::Zero(N));
      Vec lo(Nc + 1), hi(Nc + 1);
      lo.head(Nc).setConstant(v_min[i]);
      hi.head(Nc).setConstant(v_max[i]);
      lo[Nc] = 0.0;
      hi[Nc] = BIG;
      qp->init(Hs, g_soft, std::nullopt, std::nullopt, C, l_soft, u_soft, lo, hi);
      qp->solve();
      soft.push_back(std::move(qp));
    }
    limits = true;
  }

  // Row bounds of joint i's soft QP for the free responses of q and q̇ (JointQPs._soft_bounds).
  void soft_bounds(int i, const Vec& q_free, const Vec& v_free) {
    for (int j = 0; j < N; ++j) {
      l_soft[j] = -BIG;
      u_soft[j] = (upper[i] - q_free[j]) * row_scale[j];
      l_soft[N + j] = (lower[i] - q_free[j]) * row_scale[N + j];
      u_soft[N + j] = BIG;
      l_soft[2 * N + j] = -BIG;
      u_soft[2 * N + j] = (vel[i] - v_free[j]) * row_scale[2 * N + j];
      l_soft[3 * N + j] = (-vel[i] - v_free[j]) * row_scale[3 * N + j];
      u_soft[3 * N + j] = BIG;
    }
  }

  void set_stack(py::array_t<double, py::array::c_style> S, const CRefVec& offsets_) {
    stack.emplace(S, 2 + 2 * N, n);
    if (offsets_.size() != N) throw std::invalid_argument("offsets of wrong size");
    offsets = offsets_;
  }

  // q_ref = offset + amplitude·sin(ω t + φ), q̇_ref = (amplitude·ω)·cos(ω t + φ)
  // (hmpc_pin.tasks.sine.SineReference).
  void set_sine(const CRefVec& omega, const CRefVec& phase, const CRefVec& amp,
                const CRefVec& offset, const CRefVec& amp_omega) {
    for (const CRefVec* x : {&omega, &phase, &amp, &offset, &amp_omega})
      if (x->size() != n) throw std::invalid_argument("sine coefficients of wrong size");
    s_omega = omega; s_phase = phase; s_amp = amp; s_offset = offset; s_amp_omega = amp_omega;
    ref_kind = 1;
  }

  // Piecewise polynomial in s = t − knot of its segment (hmpc_pin.tasks.trajectory):
  // segment index = the number of breakpoints <= t (0: before the first, K: after the last).
  void set_ppoly(const CRefVec& times, const CRefVec& knots, const CRefRow& coef, int deg) {
    const Eigen::Index K = times.size();
    if (knots.size() != K + 1 || coef.rows() != (K + 1) * (deg + 1) || coef.cols() != 2 * n)
      throw std::invalid_argument("piecewise polynomial of wrong shape");
    p_times = times; p_knots = knots; p_coef = coef; p_deg = deg;
    acc.setZero(2 * n);
    ref_kind = 2;
  }

  void clear_reference() { ref_kind = 0; }

  // The horizon rows of the stack for time t.
  void sample_horizon(double t) {
    auto& S = stack->map;
    if (ref_kind == 1) {
      for (int j = 0; j < N; ++j) {
        const double tj = t + offsets[j];
        for (int i = 0; i < n; ++i) {
          const double arg = tj * s_omega[i] + s_phase[i];
          S(2 + j, i) = std::sin(arg) * s_amp[i] + s_offset[i];
          S(2 + N + j, i) = std::cos(arg) * s_amp_omega[i];
        }
      }
      return;
    }
    const double* begin = p_times.data();
    const double* end = begin + p_times.size();
    for (int j = 0; j < N; ++j) {
      const double tj = t + offsets[j];
      const Eigen::Index seg = std::upper_bound(begin, end, tj) - begin;
      const double s = tj - p_knots[seg];
      const auto block = p_coef.middleRows(seg * (p_deg + 1), p_deg + 1);
      double power = 1.0;
      acc = block.row(0);
      for (int k = 1; k <= p_deg; ++k) {
        power *= s;
        acc += power * block.row(k);
      }
      S.row(2 + j) = acc.head(n);
      S.row(2 + N + j) = acc.tail(n);
    }
  }

  // A step at time t with the native reference: fills the stack, then step(). Returns
  // step()'s codes, 3 (q or q̇ of wrong size) or 4 (t not finite), nothing changed then.
  int step_t(double t, const CRefVec& q, const CRefVec& dq) {
    if (!std::isfinite(t)) return 4;
    if (q.size() != n || dq.size() != n) return 3;
    auto& S = stack->map;
    S.row(0) = q.transpose();
    S.row(1) = dq.transpose();
    sample_horizon(t);
    return step(S);
  }

  void set_effort(const CRefVec& limit) {
    if (limit.size() != n) throw std::invalid_argument("effort limit of wrong size");
    effort = limit;
  }

  // Start a run: the estimate (the observer's, after its own reset).
  void reset(const CRefVec& dhat0) {
    dhat.map.row(0) = dhat0.transpose();
    v.map.setZero();
    tau.map.setZero();
    slack.map.setZero();
    constrained_last = false;
    constrained = 0;
    started = false;
  }

  bool fail(int joint, const pqp::Results<double>& res) {
    fail_joint = joint;
    fail_status = status_name(res.info.status);
    fail_iter = res.info.iter;
    return false;
  }

  // Box QP k with gradient g; on a failed warm solve, its cold twin (JointQPs._solve_cold).
  const pqp::Results<double>* solve_box(int k, const Vec& g, int joint) {
    DenseQP& qp = *qps[k];
    qp.update(std::nullopt, g, std::nullopt, std::nullopt, std::nullopt, std::nullopt,
              std::nullopt, std::nullopt, std::nullopt);
    qp.solve();
    if (qp.results.info.status == pqp::QPSolverOutput::PROXQP_SOLVED) return &qp.results;
    if (!cold[k]) {
      const Mat& Hq = block ? H_block : H;
      Vec lo(Hq.rows()), hi(Hq.rows());
      if (block) {
        for (int i = 0; i < n; ++i) {
          lo.segment(i * Nc, Nc).setConstant(v_min[i]);
          hi.segment(i * Nc, Nc).setConstant(v_max[i]);
        }
      } else {
        lo.setConstant(v_min[k]);
        hi.setConstant(v_max[k]);
      }
      auto twin = std::make_unique<DenseQP>(Hq.rows(), 0, 0, true);
      apply_settings(*twin, cold_settings);
      twin->init(Hq, g, std::nullopt, std::nullopt, std::nullopt, std::nullopt, std::nullopt, lo, hi);
      twin->solve();
      cold[k] = std::move(twin);
    } else {
      cold[k]->update(std::nullopt, g, std::nullopt, std::nullopt, std::nullopt, std::nullopt,
                      std::nullopt, std::nullopt, std::nullopt);
      cold[k]->solve();
    }
    const auto& res = cold[k]->results;
    if (res.info.status != pqp::QPSolverOutput::PROXQP_SOLVED) {
      fail(joint, res);
      return nullptr;
    }
    ++cold_solves;
    Vec x = res.x, y = res.y;
    qp.solve(x, y, std::nullopt);
    if (qp.results.info.status == pqp::QPSolverOutput::PROXQP_SOLVED) return &qp.results;
    return &res;
  }

  // One control step from the stack S = [q; q̇; r_1..r_N; ṙ_1..ṙ_N] ((2 + 2N)×n).
  // Returns 0 (done: tau, v, dhat, U written), 1 (an input is not finite: nothing changed)
  // or 2 (a QP did not report solved: fail_joint, fail_status, fail_iter).
  int step(const CRefRow& S) {
    if (S.rows() != 2 + 2 * N || S.cols() != n)
      throw std::invalid_argument("HMPCCore.step: stack of wrong shape");
    if (!S.allFinite()) return 1;
    const auto q = S.row(0).transpose();
    const auto dq = S.row(1).transpose();
    // Gradients, one column per joint: G^T = FT^T S (Nc×n).
    Mat Gt = FT.topRows(grad_rows).transpose() * S.topRows(grad_rows);
    const Mat& M = dyn.mass_matrix(q);
    const Vec& nle = dyn.nle(q, dq);
    auto d = dhat.map.row(0).transpose();
    if (started && ndo) {
      // Eq (13) over the period that just ended, with the torque applied over it.
      applied = tau.map.row(0).transpose().cwiseMax(-effort).cwiseMin(effort);
      ndo->ndo.update(M, nle, dq, applied);
      d = ndo->ndo.estimate;
    }
    // Box QPs.
    if (block) {
      for (int i = 0; i < n; ++i) g_block.segment(i * Nc, Nc) = Gt.col(i);
      const auto* res = solve_box(0, g_block, -1);
      if (!res) return 2;
      for (int i = 0; i < n; ++i) U.map.col(i) = res->x.segment(i * Nc, Nc);
    } else {
      Vec g(Nc), u(Nc);
      for (int i = 0; i < n; ++i) {
        g = Gt.col(i);
        // Exact shortcut (as JointQPs.solve): the unconstrained minimiser inside the box
        // is the box QP's solution.
        u.noalias() = neg_Hinv * g;
        if ((u.array() >= v_min[i]).all() && (u.array() <= v_max[i]).all()) {
          U.map.col(i) = u;
          ++unconstrained_solves;
          continue;
        }
        const auto* res = solve_box(i, g, i);
        if (!res) return 2;
        U.map.col(i) = res->x;
      }
    }
    constrained = 0;
    if (limits && !enforce_limits(Gt, q, dq)) return 2;
    v.map = U.map.row(0);
    auto t = tau.map.row(0).transpose();
    t.noalias() = M * v.map.row(0).transpose();
    t += nle;
    t -= d;
    started = true;
    return 0;
  }

  // JointQPs._enforce_limits: re-solve with the soft state constraints the joints whose
  // box-only prediction leaves the limits.
  bool enforce_limits(const Mat& Gt, const Eigen::Ref<const Vec>& q, const Eigen::Ref<const Vec>& dq) {
    if (constrained_last) {
      slack.map.setZero();
      constrained_last = false;
    }
    Vec q_free(N), v_free(N);
    for (int i = 0; i < n; ++i) {
      X.noalias() = Phi.col(0) * q[i] + Phi.col(1) * dq[i];
      X.noalias() += Gamma * U.map.col(i);
      bool outside = false;
      const double m = mid[i];
      for (int j = 0; j < N && !outside; ++j)
        outside = std::abs(X[2 * j] - m) > half[i] || std::abs(X[2 * j + 1]) > vel[i];
      if (!outside) continue;
      constrained_last = true;
      for (int j = 0; j < N; ++j) {
        q_free[j] = Phi(2 * j, 0) * q[i] + Phi(2 * j, 1) * dq[i];
        v_free[j] = Phi(2 * j + 1, 0) * q[i] + Phi(2 * j + 1, 1) * dq[i];
      }
      g_soft.head(Nc) = Gt.col(i);
      g_soft[Nc] = g_slack;
      soft_bounds(i, q_free, v_free);
      DenseQP& qp = *soft[i];
      qp.update(std::nullopt, g_soft, std::nullopt, std::nullopt, std::nullopt, l_soft, u_soft,
                std::nullopt, std::nullopt);
      qp.solve();
      if (qp.results.info.status != pqp::QPSolverOutput::PROXQP_SOLVED) return fail(i, qp.results);
      U.map.col(i) = qp.results.x.head(Nc);
      slack.map(0, i) = std::max(qp.results.x[Nc], 0.0) * k_slack;
      ++constrained;
    }
    return true;
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

  py::class_<RK4>(m, "RK4", py::module_local())
      .def(py::init<const std::string&>(), py::arg("model"))
      .def_property_readonly("nq", [](const RK4& r) { return r.dyn.n; })
      .def("period", &RK4::period, py::arg("q"), py::arg("v"), py::arg("T"), py::arg("a"),
           py::arg("b"), py::arg("friction"), py::arg("h"))
      .def("aba", [](RK4& r, const CRefVec& q, const CRefVec& v, const CRefVec& tau) {
             return Vec(r.dyn.aba(q, v, tau)); })
      .def("mass_matrix", [](RK4& r, const CRefVec& q) { return Mat(r.dyn.mass_matrix(q)); })
      .def("nle", [](RK4& r, const CRefVec& q, const CRefVec& v) { return Vec(r.dyn.nle(q, v)); });

  py::class_<PyNDO, std::shared_ptr<PyNDO>>(m, "NDO", py::module_local())
      .def(py::init<const CRefMat&, double, bool, py::array_t<double, py::array::c_style>,
                    py::array_t<double, py::array::c_style>>(),
           py::arg("cY"), py::arg("Ts"), py::arg("implicit"), py::arg("z"), py::arg("estimate"))
      .def("reset", [](PyNDO& o, const CRefVec& dq0) { o.ndo.reset(dq0); }, py::arg("dq0"))
      .def("update", &PyNDO::update, py::arg("M"), py::arg("nle"), py::arg("dq"),
           py::arg("tau_prev"))
      .def_property_readonly("n", [](const PyNDO& o) { return o.ndo.n; })
      .def_property_readonly("implicit", [](const PyNDO& o) { return o.ndo.implicit; });

  py::class_<HMPCCore>(m, "HMPCCore", py::module_local())
      .def(py::init<const std::string&, const CRefRow&, int, int, bool, const CRefMat&,
                    const CRefVec&, const CRefVec&, py::dict, py::dict, std::shared_ptr<PyNDO>,
                    py::array_t<double, py::array::c_style>,
                    py::array_t<double, py::array::c_style>,
                    py::array_t<double, py::array::c_style>,
                    py::array_t<double, py::array::c_style>,
                    py::array_t<double, py::array::c_style>>())
      .def("set_limits", &HMPCCore::set_limits)
      .def("set_effort", &HMPCCore::set_effort)
      .def("reset", &HMPCCore::reset)
      .def("step", &HMPCCore::step)
      .def("step_t", &HMPCCore::step_t)
      .def("set_stack", &HMPCCore::set_stack)
      .def("set_sine", &HMPCCore::set_sine)
      .def("set_ppoly", &HMPCCore::set_ppoly)
      .def("clear_reference", &HMPCCore::clear_reference)
      .def_readonly("constrained", &HMPCCore::constrained)
      .def_readonly("constrained_last", &HMPCCore::constrained_last)
      .def_readonly("cold_solves", &HMPCCore::cold_solves)
      .def_readonly("unconstrained_solves", &HMPCCore::unconstrained_solves)
      .def_readonly("fail_joint", &HMPCCore::fail_joint)
      .def_readonly("fail_status", &HMPCCore::fail_status)
      .def_readonly("fail_iter", &HMPCCore::fail_iter);
}
