// The MPC off the torque loop: see plan_thread.hpp.
#include "hmpc/plan_thread.hpp"

#include "hmpc/errors.hpp"
#include "hmpc/joint_qps.hpp"
#include "hmpc/stack_map.hpp"

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#ifdef __linux__
#include <sys/resource.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>
#endif

namespace hmpc {

namespace {
// The calling thread's CPU time [s] (NaN where it cannot be read).
double thread_cpu() {
#ifdef __linux__
  timespec ts;
  if (clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts) == 0) return ts.tv_sec + 1e-9 * ts.tv_nsec;
#endif
  return std::numeric_limits<double>::quiet_NaN();
}
}  // namespace

std::atomic<long> PlanThread::live_{0};

PlanThread::PlanThread(const CRefRow& F, int N_, std::shared_ptr<JointQPs> qps,
                       const CRefVec& offsets, double Ts_, double max_age_, int nice_)
    : n(qps ? qps->n : 0), N(N_), Nc(qps ? qps->Nc : 0), nice(nice_), Ts(Ts_), max_age(max_age_),
      qps_(std::move(qps)) {
  if (!qps_) throw std::invalid_argument("PlanThread: the planner's joint QPs are needed");
  if (F.rows() != 2 + 2 * N || F.cols() != Nc || qps_->N != N || offsets.size() != N)
    throw std::invalid_argument("PlanThread: F, N, offsets do not match the joint QPs");
  if (!(Ts > 0.0) || !std::isfinite(Ts))
    throw std::invalid_argument("PlanThread: expected a period Ts > 0");
  if (!(max_age > 0.0)) throw std::invalid_argument("PlanThread: expected max_age > 0");
  // The map's rows in the stack's order, as HierarchicalStep's (the same G, bit for bit).
  FT_ = map_in_stack_order(F, N);
  grad_rows_ = gradient_rows(FT_, N);
  Gt_.setZero(Nc, n);
  offsets_ = offsets;
  for (auto& r : req_) r.stack.setZero(2 + 2 * N, n);
  for (auto& b : buf_) b.setZero(Nc, n);
  std::fill(t_buf_, t_buf_ + 3, std::numeric_limits<double>::quiet_NaN());
  std::fill(s_buf_, s_buf_ + 3, std::numeric_limits<double>::quiet_NaN());
  thread_ = std::thread(&PlanThread::run, this);
  ++live_;
  std::unique_lock<std::mutex> lock(m_);
  done_cv_.wait(lock, [this] { return started_; });  // its tid and niceness set
}

void PlanThread::set_nice(int value) {
  if (value < -20 || value > 19)
    throw std::invalid_argument("PlanThread.set_nice: expected a niceness in -20..19, got " +
                                std::to_string(value));
#ifdef __linux__
  const long t = tid_.load();
  if (t != 0 && setpriority(PRIO_PROCESS, static_cast<id_t>(t), value) != 0) {
    const int e = errno;
    throw std::runtime_error("PlanThread.set_nice(" + std::to_string(value) +
                             "): the system refused it (" + std::strerror(e) +
                             (e == EACCES || e == EPERM
                                  ? "; lowering a niceness needs CAP_SYS_NICE or RLIMIT_NICE)"
                                  : ")"));
  }
#endif
  nice = value;
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
  tid_ = 0;
}

void PlanThread::set_reference(Reference* r) { reference_ = r; }

// After a request: wake the planner. Under the lock when it is free (no notice lost); else
// the planner holds it, awake, and sees the request before it sleeps, or within 2 ms.
void PlanThread::notify() {
  std::unique_lock<std::mutex> lock(m_, std::try_to_lock);
  cv_.notify_one();
}

void PlanThread::request(double t, const CRefVec& q, const CRefVec& dq) {
  if (!std::isfinite(t)) throw NonFinite("t", t);
  if (q.size() != n || dq.size() != n)
    throw std::invalid_argument("PlanThread.request: q and dq of n values each");
  if (!running()) throw std::logic_error("PlanThread: stopped");
  if (!reference_)
    throw std::logic_error("PlanThread.request: no compiled reference (request_stack)");
  Request& r = req_[req_back_];
  r.stack.row(0) = q.transpose();
  r.stack.row(1) = dq.transpose();
  publish(r, t, reference_);
}

void PlanThread::request_stack(double t, const CRefRow& S) {
  if (!std::isfinite(t)) throw NonFinite("t", t);
  if (S.rows() != 2 + 2 * N || S.cols() != n)
    throw std::invalid_argument("PlanThread.request_stack: a stack of (2 + 2N)×n");
  if (!running()) throw std::logic_error("PlanThread: stopped");
  Request& r = req_[req_back_];
  r.stack = S;
  publish(r, t, nullptr);
}

// The request in the back buffer handed over: it becomes the middle one (fresh), a fresh
// one not taken is dropped (counted), and the planner is woken. `reference`: the compiled
// reference the planner samples the horizon from (none: the stack holds it).
void PlanThread::publish(Request& r, double t, Reference* reference) {
  r.t = t;
  r.sampled = reference == nullptr;
  r.reference = reference;
  r.serial = ++asked_;
  const int old = req_mid_.exchange(req_back_ | FRESH);
  if (old & FRESH) ++dropped;
  req_back_ = old & 3;
  ++requests;
  notify();
}

bool PlanThread::wait(double timeout) {
  std::unique_lock<std::mutex> lock(m_);
  const long target = asked_.load();
  const auto ready = [&] { return answered_ >= target || error_ || stop_; };
  bool ok = true;
  if (timeout < 0.0) done_cv_.wait(lock, ready);
  else ok = done_cv_.wait_for(lock, std::chrono::duration<double>(timeout), ready);
  if (error_) {
    std::exception_ptr e;
    std::swap(e, error_);
    failed_ = false;
    std::rethrow_exception(e);
  }
  return ok && answered_ >= target;
}

bool PlanThread::input(double t, RefVec v) {
  if (v.size() != n) throw std::invalid_argument("PlanThread.input: v of n values");
  if (failed_.load()) wait(0.0);  // rethrows the planner's failure
  if (mid_.load() & FRESH) {  // the newest plan
    front_ = mid_.exchange(front_) & 3;
    has_front_ = true;
  }
  const double age = t - t_buf_[front_];
  last_age = has_front_ ? age : std::numeric_limits<double>::quiet_NaN();
  last_solve = has_front_ ? s_buf_[front_] : std::numeric_limits<double>::quiet_NaN();
  // a plan from the future, or older than the bound (NaN: none) is refused
  if (!has_front_ || !(age >= 0.0) || !(age <= max_age)) {
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
  req_mid_.fetch_and(3);  // a request not taken is dropped
  done_cv_.wait(lock, [this] { return !busy_ || stop_; });
  answered_ = asked_.load();
  mid_.fetch_and(3);  // and a plan not taken
  has_front_ = false;
  std::fill(t_buf_, t_buf_ + 3, std::numeric_limits<double>::quiet_NaN());
  std::fill(s_buf_, s_buf_ + 3, std::numeric_limits<double>::quiet_NaN());
  last_age = last_solve = std::numeric_limits<double>::quiet_NaN();
  max_solve_ = 0.0;
  max_solve_cpu_ = 0.0;
  requests = dropped = stale = 0;  // the planner is idle: it has counted what it published
  published_ = 0;
  error_ = nullptr;
  failed_ = false;
  qps_->restart();  // the planner is idle: its QPs are this thread's to touch
}

double PlanThread::plan_time() {
  Vec v(n);
  const double age = last_age, solve = last_solve;  // the torque loop's, kept
  input(std::numeric_limits<double>::quiet_NaN(), v);  // the newest plan taken (refused)
  --stale;
  last_age = age;
  last_solve = solve;
  return has_front_ ? t_buf_[front_] : std::numeric_limits<double>::quiet_NaN();
}

RowMat PlanThread::plan() {
  plan_time();
  return buf_[front_];
}

void PlanThread::run() {
#ifdef __linux__
  // below the torque loop: on a loaded machine a woken planner does not take the core
  // from the cycle that woke it (the niceness of this thread only; refused: as is)
  const long self = static_cast<long>(syscall(SYS_gettid));
  if (nice > 0) setpriority(PRIO_PROCESS, static_cast<id_t>(self), nice);
  errno = 0;
  const int actual = getpriority(PRIO_PROCESS, static_cast<id_t>(self));
  tid_ = self;
#endif
  {
    std::lock_guard<std::mutex> lock(m_);
#ifdef __linux__
    if (errno == 0) nice = actual;  // what the thread runs at (0 asked: the caller's)
#endif
    started_ = true;
  }
  done_cv_.notify_all();
  while (true) {
    {
      std::unique_lock<std::mutex> lock(m_);
      cv_.wait_for(lock, std::chrono::milliseconds(2),
                   [this] { return stop_ || (req_mid_.load() & FRESH); });
      if (stop_) return;
      if (!(req_mid_.load() & FRESH)) continue;
      req_front_ = req_mid_.exchange(req_front_) & 3;  // the newest request
      busy_ = true;
    }
    const Request& r = req_[req_front_];
    std::exception_ptr err;
    const auto start = std::chrono::steady_clock::now();
    const double cpu0 = thread_cpu();
    try {
      plan_once(r);
    } catch (...) {
      err = std::current_exception();
    }
    if (!err) {
      const double took =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      s_buf_[back_] = took;
      const double cpu = thread_cpu() - cpu0;
      if (took > max_solve_.load()) max_solve_ = took;  // the planner alone writes them
      if (cpu > max_solve_cpu_.load()) max_solve_cpu_ = cpu;
      back_ = mid_.exchange(back_ | FRESH) & 3;  // publish
      ++published_;
    }
    std::lock_guard<std::mutex> lock(m_);
    busy_ = false;
    if (err) {
      error_ = err;
      failed_ = true;
    }
    answered_ = std::max(answered_, r.serial);
    done_cv_.notify_all();
  }
}

// The MPC part of HierarchicalStep::prepare() and finish(): G = Fᵀ S, the joint QPs; U into the
// back buffer.
void PlanThread::plan_once(const Request& r) {
  // the request's buffer is the planner's until it takes the next one
  RowMat& S = const_cast<RowMat&>(r.stack);
  if (!r.sampled) r.reference->horizon(r.t, offsets_, S);
  const Vec q = S.row(0).transpose(), dq = S.row(1).transpose();
  if (!S.allFinite())
    throw NonFinite("q, dq or the reference horizon", std::vector<Vec>{q, dq}, r.t);
  Gt_.noalias() = FT_.topRows(grad_rows_).transpose() * S.topRows(grad_rows_);
  const Eigen::Map<const RowMat> G(Gt_.data(), n, Nc);
  if (!qps_->solve(G, q, dq)) throw qps_->failure();
  buf_[back_] = qps_->U;
  t_buf_[back_] = r.t;
}

}  // namespace hmpc
