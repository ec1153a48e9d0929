// The Python-side ports: a Python subclass of a bound port (interfaces.hpp) runs inside the
// compiled loop through these trampolines, as Crocoddyl's Python action models run inside
// its solvers. Each override is called with the GIL held (the loop runs with it); what it
// returns is checked here and kept where the loop reads it.
#pragma once

#include "expose.hpp"

#include "hmpc/errors.hpp"
#include "hmpc/interfaces.hpp"
#include "hmpc/rk4_plant.hpp"
#include "hmpc/step.hpp"

#include <memory>
#include <stdexcept>
#include <string>
#include <utility>

namespace hmpc::python {

// n floats of a Python value: a float vector of n, or what numpy broadcasts to (n,) (as the
// per-step loop's records do; numpy's error otherwise).
inline Vec broadcast_vector(const py::object& value, int n) {
  auto a = py::array_t<double, py::array::forcecast>::ensure(value);
  if (a && a.ndim() == 1 && a.shape(0) == n) return a.cast<Vec>();
  py::object np = py::module_::import("numpy");
  return np.attr("broadcast_to")(np.attr("asarray")(value, "float"), n).cast<Vec>();
}

// hmpc_pin._core.Measurement subclassed in Python: reset(q0, dq0) and measure(t, q, dq)
// return the measurement handed over, a pair (q, dq) of n floats each; command(tau), when
// defined, returns the torque the plant receives (n floats).
class PyMeasurementPort : public Measurement {
 public:
  using Measurement::Measurement;

  void reset(const CRefVec& q0, const CRefVec& dq0) override {
    py::gil_scoped_acquire gil;
    keep(override_of("reset")(Vec(q0), Vec(dq0)), q0.size(), "reset");
  }

  void measure(double t, const CRefVec& q, const CRefVec& dq) override {
    py::gil_scoped_acquire gil;
    keep(override_of("measure")(t, Vec(q), Vec(dq)), q.size(), "measure");
  }

  void command(RefVec tau) override {
    py::gil_scoped_acquire gil;
    py::function f = py::get_override(static_cast<const Measurement*>(this), "command");
    if (!f) return;  // no filter of the torque
    Vec out = vector(f(Vec(tau)), "command");
    if (out.size() != tau.size())
      throw DimensionMismatch("the torque Measurement.command returned", out.size(), tau.size(),
                              "the controller commands " + std::to_string(tau.size()));
    tau = out;
  }

  void reserve(long steps) override {
    py::gil_scoped_acquire gil;
    py::function f = py::get_override(static_cast<const Measurement*>(this), "reserve");
    if (f) f(steps);
  }

  void give_back() override {
    py::gil_scoped_acquire gil;
    py::function f = py::get_override(static_cast<const Measurement*>(this), "give_back");
    if (f) f();
  }

 private:
  py::function override_of(const char* name) const {
    py::function f = py::get_override(static_cast<const Measurement*>(this), name);
    if (!f)
      throw py::type_error(std::string("a subclass of Measurement must define ") + name +
                           " (returning the measurement (q, dq) handed over)");
    return f;
  }

  static Vec vector(const py::handle& value, const char* name) {
    try {
      return value.cast<Vec>();
    } catch (const py::cast_error&) {
      throw py::type_error(std::string("Measurement.") + name +
                           " must return float vectors, got " +
                           std::string(py::str(py::repr(value))));
    }
  }

  void keep(const py::object& result, Eigen::Index n, const char* name) {
    if (!py::isinstance<py::sequence>(result) || py::len(result) != 2)
      throw py::type_error(std::string("Measurement.") + name +
                           " must return the pair (q, dq), got " +
                           std::string(py::str(py::repr(result))));
    const auto pair = result.cast<py::sequence>();
    Vec q = vector(pair[0], name);
    Vec dq = vector(pair[1], name);
    for (const Vec* v : {&q, &dq})
      if (v->size() != n)
        throw DimensionMismatch(std::string("the measurement Measurement.") + name +
                                    " returned",
                                v->size(), n, "the plant has " + std::to_string(n) + " joints");
    qm = std::move(q);
    dqm = std::move(dq);
  }
};

// A Python callable d(t, q, dq) -> (n,) [N·m] as the loop's Disturbance port (the
// disturbance protocol of hmpc_pin.sim.disturbances is any such callable), called at every
// stage.
class PyCallableDisturbance : public Disturbance {
 public:
  PyCallableDisturbance(py::object f, int n_) : fn(std::move(f)), n(n_) {}
  Vec at(double t, const Vec& q, const Vec& dq) override {
    py::gil_scoped_acquire gil;
    return broadcast_vector(fn(t, q, dq), n);
  }
  py::object fn;
  int n;
};

// A Python term of time alone (hmpc_pin.sim.disturbances.TimeOnly: sample_times(times) ->
// (m, n) [N·m]) as a time-only Disturbance port: the plant calls it once per period with the
// period's stage times.
class PyTimeOnlyDisturbance : public Disturbance {
 public:
  PyTimeOnlyDisturbance(py::object f, int n_) : fn(std::move(f)), n(n_) {}
  Vec at(double t, const Vec&, const Vec&) override {
    RowMat one(1, n);
    at_times(Vec::Constant(1, t), one);
    return one.row(0).transpose();
  }
  Kind kind() const override { return Kind::time_only; }
  void at_times(const CRefVec& ts, Eigen::Ref<RowMat> out) override {
    py::gil_scoped_acquire gil;
    auto values = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(
        fn(Vec(ts)));
    if (!values || values.ndim() != 2 || values.shape(0) != ts.size() || values.shape(1) != n)
      throw DimensionMismatch("the values sample_times returned", values ? values.size() : 0,
                              ts.size() * n, "(len(times), n) for n = " + std::to_string(n));
    out = Eigen::Map<const RowMat>(values.data(), ts.size(), n);
  }
  py::object fn;
  int n;
};

// A Python callable horizon(t) as the step's Reference port: it writes the horizon into the
// step's stack through the numpy array the stack maps (HierarchicalMPC._sample_horizon).
class PyCallableReference : public Reference {
 public:
  explicit PyCallableReference(py::object f) : fn(std::move(f)) {}
  void horizon(double t, const CRefVec&, Eigen::Ref<RowMat>) override {
    py::gil_scoped_acquire gil;
    fn(t);
  }
  py::object fn;
};

// A Python compensation (the Compensation protocol of hmpc_pin.compensation.base: reset(q0,
// dq0), update(M, nle, q, dq, tau, v) -> d̂, estimate; the momentum observer, ISM, a gate, a
// user class) as the step's Compensation port. M goes over as a C-contiguous (n, n) array,
// as the controller's own buffer did; the estimate is what update returned (after reset: the
// object's estimate), broadcast to n floats as the controller's record of it.
class PyCallableCompensation : public Compensation {
 public:
  PyCallableCompensation(py::object c, int n_) : comp(std::move(c)), n(n_), est(Vec::Zero(n_)) {}
  void reset(const CRefVec& q, const CRefVec& dq) override {
    py::gil_scoped_acquire gil;
    comp.attr("reset")(Vec(q), Vec(dq));
    est = broadcast_vector(comp.attr("estimate"), n);
  }
  void update(const CRefMat& M, const CRefVec& nle, const CRefVec& q, const CRefVec& dq,
              const CRefVec& tau, const CRefVec& v) override {
    py::gil_scoped_acquire gil;
    est = broadcast_vector(
        comp.attr("update")(RowMat(M), Vec(nle), Vec(q), Vec(dq), Vec(tau), Vec(v)), n);
  }
  CRefVec estimate() const override { return est; }
  py::object comp;
  int n;
  Vec est;
};

// hmpc_pin._core.Compensation subclassed in Python: update(M, nle, q, dq, tau, v) returns
// the estimate d̂ (n floats); reset(q0, dq0), when defined, restarts it (d̂ = 0 then, as the
// protocol says). The subclass calls Compensation.__init__(self, n).
class PyCompensationPort : public Compensation {
 public:
  explicit PyCompensationPort(int n_) : n(n_), est(Vec::Zero(n_)) {
    if (n_ < 1) throw std::invalid_argument("Compensation: expected n >= 1 joints");
  }
  void reset(const CRefVec& q, const CRefVec& dq) override {
    py::gil_scoped_acquire gil;
    py::function f = py::get_override(static_cast<const Compensation*>(this), "reset");
    if (f) f(Vec(q), Vec(dq));
    est.setZero();
  }
  void update(const CRefMat& M, const CRefVec& nle, const CRefVec& q, const CRefVec& dq,
              const CRefVec& tau, const CRefVec& v) override {
    py::gil_scoped_acquire gil;
    py::function f = py::get_override(static_cast<const Compensation*>(this), "update");
    if (!f)
      throw py::type_error(
          "a subclass of Compensation must define update(M, nle, q, dq, tau, v) returning "
          "the estimate d̂ (n floats)");
    py::object out = f(RowMat(M), Vec(nle), Vec(q), Vec(dq), Vec(tau), Vec(v));
    Vec d;
    try {
      d = out.cast<Vec>();
    } catch (const py::cast_error&) {
      throw py::type_error("Compensation.update must return a float vector, got " +
                           std::string(py::str(py::repr(out))));
    }
    if (d.size() != n)
      throw DimensionMismatch("the estimate Compensation.update returned", d.size(), n,
                              "the controller has " + std::to_string(n) + " joints");
    est = std::move(d);
  }
  CRefVec estimate() const override { return est; }
  int n;
  Vec est;
};

// A Python plant (the Plant protocol of hmpc_pin.sim.base: advance(tau) -> (q, dq),
// disturbance_now(); applied_disturbance(d) -> d where it has one) as the loop's Plant port.
class PyCallablePlant : public Plant {
 public:
  PyCallablePlant(py::object p, int n_)
      : plant(std::move(p)), n(n_), applied(py::hasattr(plant, "applied_disturbance")) {}
  void applied_disturbance(RefVec d) override {
    if (!applied) return;
    py::gil_scoped_acquire gil;
    d = broadcast_vector(plant.attr("applied_disturbance")(Vec(d)), n);
  }
  void advance(const Vec& tau, Vec& q, Vec& dq) override {
    py::gil_scoped_acquire gil;
    py::object state = plant.attr("advance")(tau);
    const auto pair = state.cast<py::sequence>();
    if (py::len(pair) != 2)
      throw py::type_error("Plant.advance must return the pair (q, dq)");
    q = pair[0].cast<Vec>();
    dq = pair[1].cast<Vec>();
  }
  Vec disturbance_now() override {
    py::gil_scoped_acquire gil;
    return broadcast_vector(plant.attr("disturbance_now")(), n);
  }
  py::object plant;
  int n;
  bool applied;  // the plant has applied_disturbance
};

// A Python controller (the Controller protocol of hmpc_pin.controllers.base) as the loop's
// Controller port: step(t, q, dq, reference) and disturbance_estimate, each n floats (a
// shape numpy broadcasts to (n,) is broadcast, as the per-step loop's records do).
class PyCallableController : public Controller {
 public:
  PyCallableController(py::object c, py::object r, int n_)
      : ctrl(std::move(c)), ref(std::move(r)), n(n_) {}
  void step(double t, const Vec& q, const Vec& dq, Vec& tau, Vec& dhat) override {
    py::gil_scoped_acquire gil;
    tau = broadcast_vector(ctrl.attr("step")(t, q, dq, ref), n);
    dhat = broadcast_vector(ctrl.attr("disturbance_estimate"), n);
  }
  py::object ctrl, ref;
  int n;
};

// The compiled RK4 plant, holding its disturbance (and the adapter of a Python callable).
struct PyRK4Plant : RK4Plant {
  using RK4Plant::RK4Plant;
  py::object disturbance;
  std::unique_ptr<Disturbance> adapter;
};

// The step, holding its reference's port: a compiled Reference as it is, or the adapter of a
// Python callable horizon(t) (none: no reference).
struct PyStep : HierarchicalStep {
  using HierarchicalStep::HierarchicalStep;
  py::object reference;
  std::unique_ptr<Reference> reference_adapter;
};

}  // namespace hmpc::python
