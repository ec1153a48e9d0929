// The hierarchical MPC's step: see step.hpp.
#include "hmpc/step.hpp"

#include "hmpc/joint_qps.hpp"
#include "hmpc/stack_map.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

namespace hmpc {

HierarchicalStep::HierarchicalStep(const std::optional<std::string>& model, const CRefRow& F, int N_,
                   std::shared_ptr<JointQPs> qps_, std::shared_ptr<Compensation> comp_,
                   std::shared_ptr<StepData> data_)
    : n(qps_->n), N(N_), Nc(qps_->Nc), qps(std::move(qps_)), comp_held(std::move(comp_)),
      data(std::move(data_)), qp(qps.get()), comp(comp_held.get()), stack(data->stack),
      v(data->v), tau(data->tau), dhat(data->dhat), M_out(data->M), nle_out(data->nle) {
  if (model) {
    dyn = std::make_unique<Dynamics>(*model);
    if (dyn->n != n) throw std::invalid_argument("HierarchicalStep: the model has another size");
  }
  if (F.rows() != 2 + 2 * N || F.cols() != Nc || qp->N != N || data->n != n || data->N != N ||
      (comp && comp->estimate().size() != n))
    throw std::invalid_argument("HierarchicalStep: shapes do not match the model and horizon");
  // The map's rows in the stack's order; without a velocity weight its ṙ rows are skipped.
  FT = map_in_stack_order(F, N);
  grad_rows = gradient_rows(FT, N);
  applied.setZero(n);
  Gt.setZero(Nc, n);
  effort = Vec::Constant(n, std::numeric_limits<double>::infinity());
}

void HierarchicalStep::set_offsets(const CRefVec& offsets_) {
  if (offsets_.size() != N) throw std::invalid_argument("offsets of wrong size");
  offsets = offsets_;
}

void HierarchicalStep::sample_horizon(double t) {
  if (!reference) throw std::logic_error("HierarchicalStep: no reference set");
  reference->horizon(t, offsets, stack);
}

void HierarchicalStep::fill(double t, const CRefVec& q, const CRefVec& dq) {
  if (!std::isfinite(t)) throw NonFinite("t", t);
  if (q.size() != n) throw DimensionMismatch("q", q.size(), n, robot);
  if (dq.size() != n) {
    if (!q.allFinite()) throw NonFinite("q", {Vec(q)});
    throw DimensionMismatch("dq", dq.size(), n, robot);
  }
  if (offsets.size() != N)
    throw std::invalid_argument("HierarchicalStep: no horizon offsets (set_offsets)");
  t_now = t;
  auto& S = stack;
  S.row(0) = q.transpose();
  S.row(1) = dq.transpose();
  sample_horizon(t);
}

void HierarchicalStep::step_t(double t, const CRefVec& q, const CRefVec& dq) {
  fill(t, q, dq);
  step(stack, t);
}

// Whether every entry of S is finite: x·0 is ±0 for a finite x and NaN otherwise, summed in
// four independent sums (no early exit: the step's stacks are finite), rows as they lie.
static bool all_finite(const CRefRow& S) {
  double a0 = 0.0, a1 = 0.0, a2 = 0.0, a3 = 0.0;
  const Eigen::Index cols = S.cols();
  const bool flat = S.outerStride() == cols;
  const Eigen::Index rows = flat ? 1 : S.rows(), len = flat ? S.size() : cols;
  for (Eigen::Index r = 0; r < rows; ++r) {
    const double* p = S.data() + r * S.outerStride();
    Eigen::Index k = 0;
    for (; k + 4 <= len; k += 4) {
      a0 += p[k] * 0.0;
      a1 += p[k + 1] * 0.0;
      a2 += p[k + 2] * 0.0;
      a3 += p[k + 3] * 0.0;
    }
    for (; k < len; ++k) a0 += p[k] * 0.0;
  }
  return (a0 + a1) + (a2 + a3) == 0.0;
}

void HierarchicalStep::non_finite(const CRefRow& S) const {
  const Vec q = S.row(0).transpose(), dq = S.row(1).transpose();
  if (!q.allFinite()) throw NonFinite("q", {q});
  if (!dq.allFinite()) throw NonFinite("dq", {dq});
  for (int j = 0; j < N; ++j) {
    if (S.row(2 + j).allFinite() && S.row(2 + N + j).allFinite()) continue;
    const double at = j < offsets.size() ? t_now + offsets[j] : t_now;
    throw NonFinite(
        "reference", {Vec(S.row(2 + j).transpose()), Vec(S.row(2 + N + j).transpose())}, at);
  }
  throw NonFinite("q, dq or the reference horizon", {q, dq}, t_now);
}

// After a step with latency: the torque as the plant applies it and v enter the history.
void HierarchicalStep::record() {
  if (!latency.on) return;
  // what the observer is fed: the applied torque beyond the joint dynamics' J (jtau)
  Vec fed = tau.row(0).transpose().cwiseMax(-effort).cwiseMin(effort);
  if (joint.any) fed -= jtau;
  latency.record(fed, v.row(0).transpose());
}

void HierarchicalStep::set_joint_dynamics(const CRefVec& damping, const CRefVec& friction, double Ts) {
  if (!(Ts >= 0.0)) throw std::invalid_argument("HierarchicalStep.set_joint_dynamics: expected Ts >= 0");
  joint.set(damping, friction, n, "HierarchicalStep.set_joint_dynamics");
  zoh_Ts = joint.any ? Ts : 0.0;
  nle_j.setZero(n);
  extra.setZero(n);
  jtau.setZero(n);
}

void HierarchicalStep::set_effort(const CRefVec& limit) {
  if (limit.size() != n) throw std::invalid_argument("effort limit of wrong size");
  effort = limit;
}

void HierarchicalStep::reset(const CRefVec& dhat0) {
  dhat.row(0) = dhat0.transpose();
  v.setZero();
  tau.setZero();
  qp->restart();  // no warm start or active set of the last run
  started = false;
  has_prev = false;
  steps = 0;
  latency.clear();
  if (joint.any) jtau.setZero();
}

void HierarchicalStep::prepare(const CRefRow& S, double t) {
  if (S.rows() != 2 + 2 * N || S.cols() != n)
    throw std::invalid_argument("HierarchicalStep: stack of wrong shape");
  t_now = t;
  if (!all_finite(S)) non_finite(S);
  qv = S.row(0).transpose();
  dqv = S.row(1).transpose();
  // Gradients, one column per joint: G^T = FT^T S (Nc×n).
  if (Nc == 1) {
    // A row times the stack, summed over its rows in order, row by row of the stack
    // (contiguous over the joints): the sums Eigen's product forms, without its dispatch.
    double* gt = Gt.data();
    for (int i = 0; i < n; ++i) gt[i] = 0.0;
    for (Eigen::Index r = 0; r < grad_rows; ++r) {
      const double f = FT(r, 0);
      const double* s = S.data() + r * S.outerStride();
      for (int i = 0; i < n; ++i) gt[i] += s[i] * f;
    }
  } else {
    Gt.noalias() = FT.topRows(grad_rows).transpose() * S.topRows(grad_rows);
  }
  evaluate(qv, dqv);
}

void HierarchicalStep::evaluate(const Vec& q, const Vec& dq) {
  if (dyn) {
    M = &dyn->mass_matrix(q);
    nle = nle0 = &dyn->nle(q, dq);
    external = false;
  } else {
    if (!model) throw std::invalid_argument("HierarchicalStep: no compiled dynamics and no model here");
    model(q, dq);  // M_out, nle_out
    Mx = M_out;
    nx = nle_out.row(0).transpose();
    M = &Mx;
    nle = nle0 = &nx;
    external = true;
  }
  if (joint.any) {  // + B q̇ + F sgn q̇
    for (int i = 0; i < n; ++i) nle_j[i] = (*nle0)[i] + joint.torque(i, dq[i]);
    nle = &nle_j;
    if (external) nle_out.row(0) = nle_j.transpose();
  }
}

const Vec& HierarchicalStep::applied_torque() {
  applied = tau.row(0).transpose().cwiseMax(-effort).cwiseMin(effort);
  return applied;
}

void HierarchicalStep::finish() {
  const Eigen::Map<const RowMat> G(Gt.data(), n, Nc);
  if (!qp->solve(G, qv, dqv)) throw qp->failure();
  v = qp->U.row(0);
  auto t = tau.row(0).transpose();
  if (external) {
    t.noalias() = M_out * v.row(0).transpose();
    t += nle_out.row(0).transpose();
  } else {
    t.noalias() = *M * v.row(0).transpose();
    t += *nle;
  }
  if (zoh_Ts > 0.0) {
    if (external) joint.zoh(Mat(M_out), dqv, v.data(), zoh_Ts, extra);
    else joint.zoh(*M, dqv, v.data(), zoh_Ts, extra);
    t += extra;
  }
  if (joint.any)  // J of this step, for the observer's next update
    for (int i = 0; i < n; ++i) jtau[i] = joint.torque(i, dqv[i]) + extra[i];
  t -= dhat.row(0).transpose();
  started = true;
  ++steps;
  record();
}

void HierarchicalStep::step(const CRefRow& S, double t) {
  t_now = t;
  if (latency.on) return step_latency(S);
  if (obs_start && started && comp) {  // the model the held torque was computed from
    prev_M = *M;
    prev_nle = *nle0;
  }
  prepare(S, t);
  if (started && comp) {
    // Eq (13) (or any compensation) over the period that just ended: the rigid body's
    // model, the torque applied over it beyond the joint dynamics' J (see jtau).
    const Mat& Mo = obs_start ? prev_M : *M;
    const Vec& no = obs_start ? prev_nle : *nle0;
    applied_torque();
    if (joint.any) applied -= jtau;
    vprev = v.row(0).transpose();
    comp->update(Mo, no, qv, dqv, applied, vprev);
    dhat.row(0) = comp->estimate().transpose();
  }
  finish();
}

// The step with latency: the compensation over the measured interval (M, C q̇ + G at the
// measured state, the aligned torque and acceleration), then the MPC and Eq (4) at the
// predicted state. Before the measured interval lies after the start, the compensation
// restarts at each measurement. S's state rows are overwritten with the prediction.
void HierarchicalStep::step_latency(const CRefRow& S_in) {
  if (S_in.rows() != 2 + 2 * N || S_in.cols() != n)
    throw std::invalid_argument("HierarchicalStep: stack of wrong shape");
  if (!all_finite(S_in)) non_finite(S_in);
  auto& S = stack;
  if (S.data() != S_in.data()) S = S_in;
  Vec q = S.row(0).transpose(), dq = S.row(1).transpose();
  if (comp) {
    evaluate(q, dq);
    const Mat& Mq = *M;
    const Vec& nq = *nle0;
    if (observer_ready() && (!obs_start || has_prev)) {
      latency.align();
      if (obs_start) comp->update(prev_M, prev_nle, q, dq, latency.tau_obs, latency.v_obs);
      else comp->update(Mq, nq, q, dq, latency.tau_obs, latency.v_obs);
    } else {
      comp->reset(q, dq);
    }
    dhat.row(0) = comp->estimate().transpose();
    if (obs_start) {  // the start of the next measured interval
      prev_M = Mq;
      prev_nle = nq;
      has_prev = true;
    }
  }
  latency.predict(q, dq);
  S.row(0) = q.transpose();
  S.row(1) = dq.transpose();
  prepare(S, t_now);
  finish();
}

StepController::StepController(HierarchicalStep* c) : core(c) {
  if (!core || core->offsets.size() != core->N)
    throw std::invalid_argument("StepController: a step with its offsets (set_offsets) is needed");
}

void StepController::step(double t, const Vec& q, const Vec& dq, Vec& tau, Vec& dhat) {
  HierarchicalStep& c = *core;
  const Vec* qc = &q;  // the state the controller is given
  const Vec* dqc = &dq;
  if (measurement) {
    measurement->hand_over(t, q, dq);  // the first step's was taken at reset
    qc = &measurement->qm;
    dqc = &measurement->dqm;
  }
  c.step_t(t, *qc, *dqc);
  tau = c.tau.row(0).transpose();
  dhat = c.dhat.row(0).transpose();
  if (measurement) measurement->command(tau);
}

}  // namespace hmpc
