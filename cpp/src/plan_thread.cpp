// The MPC off the torque loop: see plan_thread.hpp.
#include "hmpc/plan_thread.hpp"

#include "hmpc/errors.hpp"
#include "hmpc/joint_qps.hpp"

#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <utility>
#include <vector>
#include <algorithm>

namespace hmpc {

std::atomic<long> PlanThread::live_{0};

PlanThread::PlanThread(const CRefRow& F, int N_, std::shared_ptr<JointQPs> qps,
                       const CRefVec& offsets, double Ts_, double max_age_)
    : n(qps ? qps->n : 0), N(N_), Nc(qps ? qps->Nc : 0), Ts(Ts_), max_age(max_age_),
      qps_(std::move(qps)) {
  if (!qps_) throw std::invalid_argument("PlanThread: the planner's joint QPs are needed");
  if (F.rows() != 2 + 2 * N || F.cols() != Nc || qps_->N != N || offsets.size() != N)
    throw std::invalid_argument("PlanThread: F, N, offsets do not match the joint QPs");
  if (!(Ts > 0.0) || !std::isfinite(Ts))
    throw std::invalid_argument("PlanThread: expected a period Ts > 0");
  if (!(max_age > 0.0)) throw std::invalid_argument("PlanThread: expected max_age > 0");
  // The map's rows in the stack's order, as HMPCCore's (the same G, bit for bit).
  FT_.resize(2 + 2 * N, Nc);
  FT_.topRows(2) = F.topRows(2);
  for (int j = 0; j < N; ++j) {
    FT_.row(2 + j) = F.row(2 + 2 * j);
    FT_.row(2 + N + j) = F.row(3 + 2 * j);
  }
  grad_rows_ = FT_.bottomRows(N).isZero(0.0) ? N + 2 : 2 + 2 * N;
  Gt_.setZero(Nc, n);
  offsets_ = offsets;
  req_stack_.setZero(2 + 2 * N, n);
  work_stack_.setZero(2 + 2 * N, n);
  for (auto& b : buf_) b.setZero(Nc, n);
  t_buf_[0] = t_buf_[1] = std::numeric_limits<double>::quiet_NaN();
  thread_ = std::thread(&PlanThread::run, this);
  ++live_;
}

PlanThread::~PlanThread() { stop(); }

void PlanThread::stop() {
  {
    std::lock_guard<std::mutex> lock(m_);
    stop_ = true;
  }
  cv_.notify_all();
  done_cv_.notify_all();
  if (thread_.joinable()) {
    thread_.join();
    --live_;
  }
}

void PlanThread::set_reference(Reference* r) {
  std::lock_guard<std::mutex> lock(m_);
  reference_ = r;
}

void PlanThread::request(double t, const CRefVec& q, const CRefVec& dq) {
  if (!std::isfinite(t)) throw NonFinite("t", t);
  if (q.size() != n || dq.size() != n)
    throw std::invalid_argument("PlanThread.request: q and dq of n values each");
  {
    std::lock_guard<std::mutex> lock(m_);
    if (stop_) throw std::logic_error("PlanThread: stopped");
    if (!reference_)
      throw std::logic_error("PlanThread.request: no compiled reference (request_stack)");
    req_stack_.row(0) = q.transpose();
    req_stack_.row(1) = dq.transpose();
    req_t_ = t;
    req_sampled_ = false;
    if (pending_) ++dropped;
    pending_ = true;
    ++requests;
    ++asked_;
  }
  cv_.notify_one();
}

void PlanThread::request_stack(double t, const CRefRow& S) {
  if (!std::isfinite(t)) throw NonFinite("t", t);
  if (S.rows() != 2 + 2 * N || S.cols() != n)
    throw std::invalid_argument("PlanThread.request_stack: a stack of (2 + 2N)×n");
  {
    std::lock_guard<std::mutex> lock(m_);
    if (stop_) throw std::logic_error("PlanThread: stopped");
    req_stack_ = S;
    req_t_ = t;
    req_sampled_ = true;
    if (pending_) ++dropped;
    pending_ = true;
    ++requests;
    ++asked_;
  }
  cv_.notify_one();
}

std::exception_ptr PlanThread::take_error() {
  std::exception_ptr e;
  std::swap(e, error_);
  return e;
}

bool PlanThread::wait(double timeout) {
  std::unique_lock<std::mutex> lock(m_);
  const auto ready = [this] { return answered_ >= asked_ || error_ || stop_; };
  bool ok;
  if (timeout < 0.0) {
    done_cv_.wait(lock, ready);
    ok = true;
  } else {
    ok = done_cv_.wait_for(lock, std::chrono::duration<double>(timeout), ready);
  }
  if (error_) std::rethrow_exception(take_error());
  return ok && answered_ >= asked_;
}

bool PlanThread::input(double t, RefVec v) {
  if (v.size() != n) throw std::invalid_argument("PlanThread.input: v of n values");
  std::lock_guard<std::mutex> lock(m_);
  if (error_) std::rethrow_exception(take_error());
  const double age = t - t_buf_[front_];
  // a plan from the future, or older than the bound (NaN: none) is refused
  if (!has_plan_ || !(age >= 0.0) || !(age <= max_age)) {
    ++stale;
    return false;
  }
  // row ⌊age/Ts⌋, the time of the cycle taken within a relative 1e-9 of a period
  const double k = std::floor(age / Ts + 1e-9);
  const Eigen::Index j = k < Nc - 1 ? static_cast<Eigen::Index>(k) : Nc - 1;
  v = buf_[front_].row(j).transpose();
  return true;
}

void PlanThread::reset() {
  std::unique_lock<std::mutex> lock(m_);
  pending_ = false;
  answered_ = asked_;
  done_cv_.wait(lock, [this] { return !busy_ || stop_; });
  has_plan_ = false;
  t_buf_[0] = t_buf_[1] = std::numeric_limits<double>::quiet_NaN();
  error_ = nullptr;
  qps_->restart();  // the planner is idle: its QPs are this thread's to touch
}

double PlanThread::plan_time() const {
  std::lock_guard<std::mutex> lock(m_);
  return has_plan_ ? t_buf_[front_] : std::numeric_limits<double>::quiet_NaN();
}

RowMat PlanThread::plan() const {
  std::lock_guard<std::mutex> lock(m_);
  return buf_[front_];
}

void PlanThread::run() {
  std::unique_lock<std::mutex> lock(m_);
  while (true) {
    cv_.wait(lock, [this] { return pending_ || stop_; });
    if (stop_) return;
    pending_ = false;
    busy_ = true;
    const long serial = asked_;
    const double t = req_t_;
    const bool sampled = req_sampled_;
    work_stack_ = req_stack_;
    Reference* ref = reference_;
    lock.unlock();
    std::exception_ptr err;
    try {
      if (!sampled) ref->horizon(t, offsets_, work_stack_);
      plan_once(t);
    } catch (...) {
      err = std::current_exception();
    }
    lock.lock();
    busy_ = false;
    if (err) {
      error_ = err;
    } else {
      front_ = 1 - front_;  // the back buffer, written by plan_once, becomes the plan
      has_plan_ = true;
      ++published;
    }
    answered_ = std::max(answered_, serial);
    done_cv_.notify_all();
  }
}

// The MPC part of HMPCCore::prepare() and finish(): G = Fᵀ S, the joint QPs; U into the
// back buffer.
void PlanThread::plan_once(double t) {
  const auto& S = work_stack_;
  const Vec q = S.row(0).transpose(), dq = S.row(1).transpose();
  if (!S.allFinite()) throw NonFinite("q, dq or the reference horizon", std::vector<Vec>{q, dq}, t);
  Gt_.noalias() = FT_.topRows(grad_rows_).transpose() * S.topRows(grad_rows_);
  const Eigen::Map<const RowMat> G(Gt_.data(), n, Nc);
  if (!qps_->solve(G, q, dq)) throw qps_->failure();
  const int back = 1 - front_;  // front_ changes only on this thread
  buf_[back] = qps_->U;
  t_buf_[back] = t;
}

}  // namespace hmpc
