// The MPC off the torque loop: a planner thread that owns its own copy of the MPC part of
// the step (the outer loop: the gradients G = Fᵀ S of the stack S = [q; q̇; r_1..r_N;
// ṙ_1..ṙ_N] and the joint QPs, Eq 25–26, over the horizon), runs it whenever the torque
// loop hands it a new state (a request: t_k, q_k, q̇_k), and publishes the plan -- its time
// stamp t_plan and the accelerations U (Nc×n) over the control horizon. Both hand-overs are
// lock-free triple buffers (one writer, one reader, an atomic exchange of the middle
// buffer's index with a "fresh" bit): the torque loop never waits for the planner (a mutex
// held by a planner preempted on a loaded machine blocked a cycle for milliseconds). The
// planner sleeps on a condition variable, notified after each request (if the notice is
// lost in the instant the planner goes to sleep, it looks again within 2 ms).
//
// The torque loop (at its own period, e.g. the arm's 1 ms) reads the input of the latest
// plan for its time t: row j = min(⌊(t − t_plan)/Ts⌋, Nc − 1) of U (past the control
// horizon the last input is held), and refuses it -- input() returns false, counted in
// `stale` -- when there is no plan or the plan is older than the staleness bound
// (t − t_plan > max_age) or from the future (t < t_plan). The caller then applies its
// fallback (the Python law brakes: see hmpc_pin.realtime.franka.rates).
//
// Deterministic mode: request() then wait() hands the plan over synchronously; the plan is
// then, bit for bit, the one the synchronous step (HierarchicalStep) computes from the same state
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
#include <limits>
#include <memory>
#include <mutex>
#include <thread>

namespace hmpc {

class JointQPs;

class PlanThread {
 public:
  // F: the condensed MPC's gradient map ((2 + 2N)×Nc, CondensedMPC.FT, as HierarchicalStep's);
  // qps: the planner's own joint QPs (not shared with a step that runs); offsets: the
  // horizon offsets j·Ts, j = 1..N [s]; Ts: the MPC's period [s]; max_age: the staleness
  // bound [s] (> 0); nice: the planner thread's niceness (Linux; 0: the caller's), above
  // the torque loop's so that a woken planner does not take the core from the cycle that
  // woke it (a loop under a normal policy); set_nice() changes it. Starts the thread (its
  // tid is known when the constructor returns; `nice` then holds the niceness it runs at).
  PlanThread(const CRefRow& F, int N, std::shared_ptr<JointQPs> qps, const CRefVec& offsets,
             double Ts, double max_age, int nice = 10);
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
  // (< 0: no limit). Returns whether it is. Rethrows the planner's exception. (The only
  // call of the torque loop that blocks: the deterministic mode's.)
  bool wait(double timeout = -1.0);
  // The torque loop's input at time t [s] into v (n): false (v untouched) when there is no
  // plan, or it is stale (module doc). Rethrows the planner's exception.
  bool input(double t, RefVec v);
  // Start a run: drop any request not taken, wait for the planner to be idle, drop the
  // plan, restart the joint QPs (as HierarchicalStep::reset), zero the counters. Not during
  // a run's cycles.
  void reset();
  // Stop the thread and join it (idempotent).
  void stop();
  // The planner thread's niceness, now (Linux: setpriority on its tid; elsewhere stored
  // only): −20..19, else std::invalid_argument; refused by the system (e.g. lowered
  // without the right): std::runtime_error naming the reason, `nice` unchanged.
  void set_nice(int value);
  // The planner thread's kernel thread id (Linux; 0 elsewhere, or once stopped).
  long tid() const { return tid_.load(); }

  bool running() const { return thread_.joinable(); }
  // The number of planner threads alive in the process (started and not yet joined).
  static long live() { return live_.load(); }

  int n, N, Nc, nice;
  double Ts, max_age;
  // Counters since construction or the last reset() (a run's): requests made, requests
  // replaced before the planner took them, inputs refused (no plan or stale) -- the torque
  // loop's -- and plans published.
  long requests = 0, dropped = 0, stale = 0;
  long published() const { return published_.load(); }
  // The torque loop's last input(): the age t − t_plan [s] of the newest plan it saw (NaN:
  // none; used when input() answered true), and that plan's solve time [s] (the planner's
  // clock around its MPC: the gradients and the joint QPs).
  double last_age = std::numeric_limits<double>::quiet_NaN();
  double last_solve = std::numeric_limits<double>::quiet_NaN();
  // The longest solve of a published plan [s] since construction or reset(), by the
  // planner's clock and by its thread's CPU time (Linux; elsewhere NaN).
  double max_solve() const { return max_solve_.load(); }
  double max_solve_cpu() const { return max_solve_cpu_.load(); }
  // The torque loop's view: t_plan of the plan it reads [s] (NaN: none) and its U (Nc×n)
  // (the freshest plan taken first).
  double plan_time();
  RowMat plan();

 private:
  static constexpr int FRESH = 4;  // the middle buffer holds what its reader has not taken
  struct Request {
    RowMat stack;  // (2 + 2N)×n
    double t = 0.0;
    bool sampled = false;  // the stack holds the horizon too
    Reference* reference = nullptr;
    long serial = 0;
  };
  void run();
  void plan_once(const Request& r);
  void publish(Request& r, double t, Reference* reference);
  void notify();

  std::shared_ptr<JointQPs> qps_;
  RowMat FT_;  // the map in the stack's order (as HierarchicalStep::FT)
  Eigen::Index grad_rows_;
  Mat Gt_;
  Vec offsets_;
  Reference* reference_ = nullptr;  // the torque loop's (copied into each request)
  // Requests: the torque loop writes req_[req_back_], the planner reads req_[req_front_].
  Request req_[3];
  int req_back_ = 0, req_front_ = 2;
  std::atomic<int> req_mid_{1};
  // Plans: the planner writes buf_[back_], the torque loop reads buf_[front_].
  RowMat buf_[3];
  double t_buf_[3];
  double s_buf_[3];  // the plans' solve times [s]
  int back_ = 0, front_ = 2;
  std::atomic<int> mid_{1};
  bool has_front_ = false;  // buf_[front_] holds a plan (the torque loop's)
  // The planner's sleep and the caller's wait: guarded by m_.
  mutable std::mutex m_;
  std::condition_variable cv_;       // a request, or stop
  std::condition_variable done_cv_;  // a plan published (or an error)
  bool busy_ = false, stop_ = false;
  long answered_ = 0;  // the serial of the last request answered
  std::atomic<long> asked_{0}, published_{0};
  std::atomic<double> max_solve_{0.0}, max_solve_cpu_{0.0};
  std::atomic<bool> failed_{false};
  std::atomic<long> tid_{0};
  bool started_ = false;  // the thread has read its tid (guarded by m_)
  std::exception_ptr error_;
  std::thread thread_;
  static std::atomic<long> live_;
};

}  // namespace hmpc
