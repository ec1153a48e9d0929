// The MPC off the torque loop: a planner thread that owns its own copy of the MPC part of
// the step (the outer loop: the gradients G = Fᵀ S of the stack S = [q; q̇; r_1..r_N;
// ṙ_1..ṙ_N] and the joint QPs, Eq 25–26, over the horizon), runs it whenever the torque
// loop hands it a new state (a request: t_k, q_k, q̇_k), and publishes the plan -- its time
// stamp t_plan and the accelerations U (Nc×n) over the control horizon -- through a
// mutex-protected double buffer: the planner writes the back buffer without a lock and
// swaps it in under the lock; the reader copies one row under the same lock (n doubles).
//
// The torque loop (at its own period, e.g. the arm's 1 ms) reads the input of the latest
// plan for its time t: row j = min(⌊(t − t_plan)/Ts⌋, Nc − 1) of U (past the control
// horizon the last input is held), and refuses it -- input() returns false, counted in
// `stale` -- when there is no plan or the plan is older than the staleness bound
// (t − t_plan > max_age) or from the future (t < t_plan). The caller then applies its
// fallback (the Python law brakes: see hmpc_pin.realtime.franka.rates).
//
// Deterministic mode: request() then wait() hands the plan over synchronously; the plan is
// then, bit for bit, the one the synchronous step (HMPCCore) computes from the same state
// (the same expression for G, the same JointQPs history).
//
// The thread never calls Python: the reference is a compiled one (set_reference), or the
// caller samples the horizon itself (request_stack). It is started by the constructor and
// stopped and joined by stop() and by the destructor. An exception of the planner is kept
// and rethrown by the next wait() or input() on the caller's thread.
#pragma once

#include "hmpc/interfaces.hpp"
#include "hmpc/types.hpp"

#include <atomic>
#include <condition_variable>
#include <exception>
#include <memory>
#include <mutex>
#include <thread>

namespace hmpc {

class JointQPs;

class PlanThread {
 public:
  // F: the condensed MPC's gradient map ((2 + 2N)×Nc, CondensedMPC.FT, as HMPCCore's);
  // qps: the planner's own joint QPs (not shared with a step that runs); offsets: the
  // horizon offsets j·Ts, j = 1..N [s]; Ts: the MPC's period [s]; max_age: the staleness
  // bound [s] (> 0). Starts the thread.
  PlanThread(const CRefRow& F, int N, std::shared_ptr<JointQPs> qps, const CRefVec& offsets,
             double Ts, double max_age);
  ~PlanThread();  // stop()
  PlanThread(const PlanThread&) = delete;
  PlanThread& operator=(const PlanThread&) = delete;

  // The compiled reference request() samples (the caller keeps it alive; none: only
  // request_stack()).
  void set_reference(Reference* r);
  // A new state for the planner: (t [s], q [rad], q̇ [rad/s]), the horizon sampled by the
  // planner through the reference. Replaces a request not yet taken (counted in
  // `dropped`); does not wait.
  void request(double t, const CRefVec& q, const CRefVec& dq);
  // The same with the whole stack S ((2 + 2N)×n) given by the caller.
  void request_stack(double t, const CRefRow& S);
  // Wait until the plan of the last request is published, at most `timeout` seconds
  // (< 0: no limit). Returns whether it is. Rethrows the planner's exception.
  bool wait(double timeout = -1.0);
  // The torque loop's input at time t [s] into v (n): false (v untouched) when there is no
  // plan, or it is stale (module doc). Rethrows the planner's exception.
  bool input(double t, RefVec v);
  // Start a run: wait for the planner to be idle, drop the plan and any request, restart
  // the joint QPs (as HMPCCore::reset).
  void reset();
  // Stop the thread and join it (idempotent).
  void stop();

  bool running() const { return thread_.joinable(); }
  // The number of planner threads alive in the process (started and not yet joined).
  static long live() { return live_.load(); }

  int n, N, Nc;
  double Ts, max_age;
  // Counters since construction: requests made, requests replaced before the planner took
  // them, plans published, inputs refused (no plan or stale).
  long requests = 0, dropped = 0, published = 0, stale = 0;
  double plan_time() const;  // t_plan of the plan the reader sees [s] (NaN: none)
  RowMat plan() const;       // a copy of its U (Nc×n)

 private:
  void run();
  void plan_once(double t);
  std::exception_ptr take_error();

  std::shared_ptr<JointQPs> qps_;
  RowMat FT_;  // the map in the stack's order (as HMPCCore::FT)
  Eigen::Index grad_rows_;
  Mat Gt_;
  Vec offsets_;
  Reference* reference_ = nullptr;
  // The request: guarded by m_. `pending_` is set by request*() and taken by the planner.
  mutable std::mutex m_;
  std::condition_variable cv_;       // a request, or stop
  std::condition_variable done_cv_;  // a plan published (or an error)
  RowMat req_stack_, work_stack_;
  double req_t_ = 0.0;
  bool req_sampled_ = false;  // req_stack_ holds the horizon too
  bool pending_ = false, busy_ = false, stop_ = false;
  long asked_ = 0, answered_ = 0;  // request serials
  std::exception_ptr error_;
  // The double buffer: buf_[front_] is the published plan (guarded by m_); the planner
  // writes buf_[1 - front_] without the lock (only it writes there).
  RowMat buf_[2];
  double t_buf_[2];
  int front_ = 0;
  bool has_plan_ = false;
  std::thread thread_;
  static std::atomic<long> live_;
};

}  // namespace hmpc
