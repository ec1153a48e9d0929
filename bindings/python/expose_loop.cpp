// hmpc_pin._core.ClosedLoop: the compiled closed loop (loop.hpp) over its ports: the
// controller (hmpc_pin._core.StepController, the hierarchical MPC's compiled step with its
// Measurement port and its core's Reference port, or a Python controller as a whole), the plant (the compiled
// RK4Plant, or a Python plant through the Plant port); its records in numpy arrays that hmpc_pin.sim.compiled_loop owns; Ctrl-C is checked
// before every step.
#include "trampolines.hpp"

#include "hmpc/loop.hpp"
#include "hmpc/rk4_plant.hpp"
#include "hmpc/step.hpp"

#include <cstdint>
#include <memory>
#include <stdexcept>
#include <vector>

namespace hmpc::python {

namespace {

using IntArray = py::array_t<std::int64_t, py::array::c_style>;

// The step as the Controller port, with the Python objects it uses kept alive.
struct PyStepController {
  py::object core_object, measurement_object;
  StepController controller;
  explicit PyStepController(py::object core)
      : core_object(std::move(core)), controller(&core_object.cast<PyStep&>()) {}
};

struct PyClosedLoop {
  Array t;
  std::vector<Array> records;
  IntArray step_ns, sat_steps;
  Array sat_excess;
  std::unique_ptr<PyCallableController> controller;
  py::object step_controller;  // a StepController, kept alive
  std::unique_ptr<PyCallablePlant> python_plant;
  py::object plant;  // the plant object, kept alive
  std::unique_ptr<ClosedLoop> loop;
};

std::array<double*, 6> record_data(std::vector<Array>& rec, Eigen::Index rows, int n) {
  if (rec.size() != 6) throw std::invalid_argument("ClosedLoop: shapes do not match");
  std::array<double*, 6> out{};
  for (std::size_t i = 0; i < 6; ++i) {
    if (rec[i].size() != rows * n || !rec[i].writeable())
      throw std::invalid_argument("ClosedLoop: records must be writable (K+1, n)");
    out[i] = rec[i].mutable_data();
  }
  return out;
}

}  // namespace

void expose_loop(py::module_& m) {
  py::class_<PyStepController>(m, "StepController", py::module_local())
      .def(py::init<py::object>(), py::arg("core"))
      .def(
          "set_measurement",
          [](PyStepController& o, py::object m) {
            o.controller.measurement = m.is_none() ? nullptr : m.cast<Measurement*>();
            o.measurement_object = std::move(m);
          },
          py::arg("measurement"));
  py::class_<PyClosedLoop>(m, "ClosedLoop", py::module_local())
      .def(py::init([](py::object plant, int n, Array t, std::vector<Array> records,
                       IntArray step_ns, IntArray sat_steps, Array sat_excess,
                       const CRefVec& limit, bool has_limit, double bound, double Ts) {
             auto o = std::make_unique<PyClosedLoop>();
             const auto K = static_cast<Eigen::Index>(t.size()) - 1;
             if (step_ns.size() != K + 1 || sat_steps.size() != n || sat_excess.size() != n)
               throw std::invalid_argument("ClosedLoop: shapes do not match");
             o->t = t;
             o->records = std::move(records);
             o->step_ns = step_ns;
             o->sat_steps = sat_steps;
             o->sat_excess = sat_excess;
             Plant* port = nullptr;  // the compiled plant as it is, any other through Python
             if (py::isinstance<PyRK4Plant>(plant)) {
               port = plant.cast<PyRK4Plant*>();
               if (plant.cast<PyRK4Plant*>()->n != n)
                 throw std::invalid_argument("ClosedLoop: shapes do not match");
             } else {
               o->python_plant = std::make_unique<PyCallablePlant>(plant, n);
               port = o->python_plant.get();
             }
             o->plant = std::move(plant);
             o->loop = std::make_unique<ClosedLoop>(
                 port, n, o->t.data(), static_cast<int>(K),
                 record_data(o->records, K + 1, n), o->step_ns.mutable_data(),
                 o->sat_steps.mutable_data(), o->sat_excess.mutable_data(), limit, has_limit,
                 bound, Ts);
             o->loop->interrupted = [] {
               if (PyErr_CheckSignals() != 0) throw py::error_already_set();
             };
             return o;
           }),
           py::arg("plant"), py::arg("n"), py::arg("t"), py::arg("records"),
           py::arg("step_ns"), py::arg("sat_steps"), py::arg("sat_excess"), py::arg("limit"),
           py::arg("has_limit"), py::arg("bound"), py::arg("Ts"))
      .def(
          "set_controller",  // a StepController, or a Python controller stepped as a whole
          [](PyClosedLoop& o, py::object controller, py::object reference) {
            if (py::isinstance<PyStepController>(controller)) {
              if (controller.cast<PyStepController&>().controller.core->n != o.loop->n)
                throw std::invalid_argument("ClosedLoop: the step has another size");
              o.loop->set_controller(&controller.cast<PyStepController&>().controller);
              o.step_controller = std::move(controller);
              o.controller.reset();
              return;
            }
            auto port = std::make_unique<PyCallableController>(std::move(controller),
                                                               std::move(reference), o.loop->n);
            o.loop->set_controller(port.get());
            o.controller = std::move(port);
          },
          py::arg("controller"), py::arg("reference") = py::none())
      .def(
          "set_recorded",
          [](PyClosedLoop& o, py::function f) {
            o.loop->recorded = [f = std::move(f)](long k) { f(k); };
          },
          py::arg("callback"))
      .def(
          "run",
          [](PyClosedLoop& o, RefVec q, RefVec v, long k0, long k1) {
            return o.loop->run(q, v, k0, k1);
          },
          py::arg("q"), py::arg("v"), py::arg("k0"), py::arg("k1"))
      .def_property_readonly("k", [](const PyClosedLoop& o) { return o.loop->k; })
      .def_property_readonly("last", [](const PyClosedLoop& o) { return o.loop->last; })
      .def_property_readonly("advances", [](const PyClosedLoop& o) { return o.loop->advances; })
      .def_property_readonly("started", [](const PyClosedLoop& o) { return o.loop->started; })
      .def_property_readonly("stepped", [](const PyClosedLoop& o) { return o.loop->stepped; });
}

}  // namespace hmpc::python
