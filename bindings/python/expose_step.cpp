// hmpc_pin._core.HMPCCore: the hierarchical MPC's step (step.hpp), its inputs and outputs in
// numpy arrays that the Python controller owns.
#include "holders.hpp"

#include <memory>
#include <stdexcept>
#include <utility>
#include <vector>

namespace hmpc::python {

namespace {

// The step's reference: a compiled Reference as it is, a Python callable horizon(t) adapted
// (none: no reference).
void set_reference(PyHMPCCore& h, py::object reference) {
  std::unique_ptr<Reference> adapter;
  Reference* port = nullptr;
  if (py::isinstance<Reference>(reference)) {
    port = reference.cast<Reference*>();
  } else if (!reference.is_none()) {
    adapter = std::make_unique<PyCallableReference>(reference);
    port = adapter.get();
  }
  h.core.set_reference(port);
  h.reference_adapter = std::move(adapter);
  h.reference = std::move(reference);
}

}  // namespace

void expose_step(py::module_& m) {
  using H = PyHMPCCore;
  py::class_<H>(m, "HMPCCore", py::module_local())
      .def(py::init<const py::object&, const CRefRow&, int, std::shared_ptr<PyJointQPs>,
                    py::object, Array, Array, Array, Array, Array>(),
           py::arg("model"), py::arg("FT"), py::arg("N"), py::arg("qps"),
           py::arg("compensation"), py::arg("v"), py::arg("tau"), py::arg("d_hat"),
           py::arg("M"), py::arg("nle"))
      .def(
          "set_model",  // without compiled dynamics: model(q, dq) writes M and nle
          [](H& h, py::function f) {
            h.model_fn = f;
            h.core.model = [f](const Vec& q, const Vec& dq) {
              py::gil_scoped_acquire gil;
              f(q, dq);
            };
          },
          py::arg("model"))
      .def("set_effort", [](H& h, const CRefVec& limit) { h.core.set_effort(limit); })
      .def(
          "set_observer_model", [](H& h, bool at_start) { h.core.set_observer_model(at_start); },
          py::arg("at_start"))
      .def(
          "set_latency", [](H& h, double L, double Ts) { h.core.set_latency(L, Ts); },
          py::arg("L"), py::arg("Ts"))
      .def_property_readonly("latency_periods", [](const H& h) { return h.core.latency.m; })
      .def_property_readonly("latency_fraction", [](const H& h) { return h.core.latency.alpha; })
      .def(
          "set_joint_dynamics",
          [](H& h, const CRefVec& damping, const CRefVec& friction, double Ts) {
            h.core.set_joint_dynamics(damping, friction, Ts);
          },
          py::arg("damping"), py::arg("friction"), py::arg("Ts"))
      .def(
          "reset",  // the compensation restarted at (q0, dq0) through its port, d̂ its estimate
          [](H& h, const CRefVec& q0, const CRefVec& dq0) {
            const int n = h.core.n;
            if (q0.size() != n || dq0.size() != n)
              throw std::invalid_argument("HMPCCore.reset: q0 and dq0 of n values each");
            if (h.core.comp) {
              h.core.comp->reset(q0, dq0);
              h.core.reset(h.core.comp->estimate());
            } else {
              h.core.reset(Vec::Zero(n));
            }
          },
          py::arg("q0"), py::arg("dq0"))
      .def(
          "step", [](H& h, const CRefRow& S, double t) { h.core.step(S, t); }, py::arg("S"),
          py::arg("t"))
      .def("step_t",
           [](H& h, double t, const CRefVec& q, const CRefVec& dq) { h.core.step_t(t, q, dq); })
      .def("fill",
           [](H& h, double t, const CRefVec& q, const CRefVec& dq) { h.core.fill(t, q, dq); })
      .def_property(  // how faults name the robot: "the robot 'x' has n joints (...)"
          "robot", [](const H& h) { return h.core.robot; },
          [](H& h, const std::string& robot) { h.core.robot = robot; })
      .def("set_stack",
           [](H& h, Array S, const CRefVec& offsets) {
             double* data = writable(S, static_cast<Eigen::Index>(2 + 2 * h.core.N) * h.core.n);
             h.stack = S;
             h.core.set_stack(data, offsets);
           })
      .def("set_reference", &set_reference, py::arg("reference"))
      .def_property(  // what a step carries to the next (restored after a dry step, warm_up)
          "state",
          [](const H& h) {  // copies
            const HMPCCore& c = h.core;
            std::vector<Vec> th = c.latency.tau_hist, vh = c.latency.v_hist;
            return py::make_tuple(c.started, Vec(c.jtau), std::move(th), std::move(vh),
                                  Vec(c.latency.tau_obs), Vec(c.latency.v_obs), c.steps,
                                  Mat(c.prev_M), Vec(c.prev_nle), c.has_prev);
          },
          [](H& h, const py::tuple& s) {
            HMPCCore& c = h.core;
            c.steps = s[6].cast<decltype(c.steps)>();
            c.started = s[0].cast<bool>();
            c.jtau = s[1].cast<Vec>();
            c.latency.tau_hist = s[2].cast<std::vector<Vec>>();
            c.latency.v_hist = s[3].cast<std::vector<Vec>>();
            c.latency.tau_obs = s[4].cast<Vec>();
            c.latency.v_obs = s[5].cast<Vec>();
            c.prev_M = s[7].cast<Mat>();
            c.prev_nle = s[8].cast<Vec>();
            c.has_prev = s[9].cast<bool>();
          })
      .def_property_readonly("has_dynamics", [](const H& h) { return bool(h.core.dyn); })
      .def_property_readonly(  // a step succeeded since the last reset
          "started", [](const H& h) { return h.core.started; });
}

}  // namespace hmpc::python
