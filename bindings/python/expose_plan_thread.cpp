// hmpc_pin._core.PlanThread: the MPC's planner thread (plan_thread.hpp). The thread never
// takes the GIL; the calls that block (wait, reset, stop) release it, and wait() answers
// Ctrl-C (checked every 50 ms) with KeyboardInterrupt.
#include "expose.hpp"

#include "hmpc/joint_qps.hpp"
#include "hmpc/plan_thread.hpp"

#include <algorithm>
#include <memory>
#include <stdexcept>

namespace hmpc::python {

namespace {

// The thread with the Python reference object its compiled port belongs to (kept alive).
struct PyPlanThread : PlanThread {
  using PlanThread::PlanThread;
  py::object reference;
};

void plan_set_reference(PyPlanThread& p, py::object reference) {
  Reference* port = nullptr;
  if (!reference.is_none()) {
    if (!py::isinstance<Reference>(reference))
      throw std::invalid_argument(
          "PlanThread.set_reference: a compiled reference (hmpc_pin._core.Reference) or None; "
          "sample any other in Python and call request_stack");
    port = reference.cast<Reference*>();
  }
  p.set_reference(port);
  p.reference = std::move(reference);
}

// wait() without the GIL, in slices of 50 ms between which Ctrl-C is seen.
bool plan_wait(PyPlanThread& p, double timeout) {
  constexpr double slice = 0.05;
  double left = timeout;
  while (true) {
    const double now = timeout < 0.0 ? slice : std::min(slice, left);
    bool ok;
    {
      py::gil_scoped_release release;
      ok = p.wait(now);
    }
    if (ok) return true;
    if (PyErr_CheckSignals() != 0) throw py::error_already_set();
    if (timeout >= 0.0) {
      left -= now;
      if (left <= 0.0) return false;
    }
  }
}

}  // namespace

void expose_plan_thread(py::module_& m) {
  using P = PyPlanThread;
  using release = py::call_guard<py::gil_scoped_release>;
  py::class_<P>(m, "PlanThread", py::module_local())
      .def(py::init([](const CRefRow& F, int N, std::shared_ptr<JointQPs> qps,
                       const CRefVec& offsets, double Ts, double max_age, int nice) {
             return std::make_unique<P>(F, N, std::move(qps), offsets, Ts, max_age, nice);
           }),
           py::arg("F"), py::arg("N"), py::arg("qps"), py::arg("offsets"), py::arg("Ts"),
           py::arg("max_age"), py::arg("nice") = 10)
      .def("set_reference", &plan_set_reference, py::arg("reference"))
      .def(
          "request",
          [](P& p, double t, const CRefVec& q, const CRefVec& dq) { p.request(t, q, dq); },
          py::arg("t"), py::arg("q"), py::arg("dq"))
      .def(
          "request_stack", [](P& p, double t, const CRefRow& S) { p.request_stack(t, S); },
          py::arg("t"), py::arg("S"))
      .def("wait", &plan_wait, py::arg("timeout") = -1.0)
      .def(
          "input",
          [](P& p, double t, Array v) {
            double* out = writable(v, p.n);
            return p.input(t, Eigen::Map<Vec>(out, p.n));
          },
          py::arg("t"), py::arg("v"))
      .def("reset", &P::reset, release())
      .def("stop", &P::stop, release())
      .def_property_readonly("running", &P::running)
      .def_static("live", &PlanThread::live)
      .def_readonly("n", &P::n)
      .def_readonly("N", &P::N)
      .def_readonly("Nc", &P::Nc)
      .def_readonly("nice", &P::nice)
      .def("set_nice", &P::set_nice, py::arg("nice"))
      .def_property_readonly("tid", &P::tid)
      .def_readonly("Ts", &P::Ts)
      .def_readwrite("max_age", &P::max_age)
      .def_property_readonly("requests", [](const P& p) { return p.requests; })
      .def_property_readonly("dropped", [](const P& p) { return p.dropped; })
      .def_property_readonly("published", &P::published)
      .def_property_readonly("stale", [](const P& p) { return p.stale; })
      .def_readonly("last_age", &P::last_age)
      .def_readonly("last_solve", &P::last_solve)
      .def_property_readonly("max_solve", &P::max_solve)
      .def_property_readonly("max_solve_cpu", &P::max_solve_cpu)
      .def_property_readonly("plan_time", &P::plan_time)
      .def_property_readonly("plan", &P::plan);
}

}  // namespace hmpc::python
