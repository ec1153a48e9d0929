// hmpc_pin._core.Disturbance (the RK4 plant's Disturbance port) and the compiled disturbances
// (disturbances.hpp): GaussianPulses, CoulombViscousFriction and DisturbanceSum (whose terms
// are compiled ports, or Python callables and time-only terms through trampolines.hpp), and
// TimeOnlyTerm, a Python term of time alone as a port.
#include "trampolines.hpp"

#include "hmpc/disturbances.hpp"

#include <memory>
#include <stdexcept>
#include <utility>
#include <vector>

namespace hmpc::python {

namespace {

// The sum, with its terms kept alive (adapted where they are Python callables).
struct PyDisturbanceSum : DisturbanceSum {
  PyDisturbanceSum(std::vector<Disturbance*> ports, int n, std::vector<py::object> held_,
                   std::vector<std::unique_ptr<Disturbance>> adapters_)
      : DisturbanceSum(std::move(ports), n), held(std::move(held_)),
        adapters(std::move(adapters_)) {}
  std::vector<py::object> held;
  std::vector<std::unique_ptr<Disturbance>> adapters;
};

struct PyTimeOnlyTerm : PyTimeOnlyDisturbance {
  using PyTimeOnlyDisturbance::PyTimeOnlyDisturbance;
};

std::unique_ptr<PyDisturbanceSum> make_sum(const std::vector<py::object>& terms, int n) {
  if (n < 1) throw std::invalid_argument("DisturbanceSum: expected n >= 1 joints");
  std::vector<Disturbance*> ports;
  std::vector<std::unique_ptr<Disturbance>> adapters;
  for (const py::object& term : terms) {
    if (py::isinstance<Disturbance>(term)) {
      ports.push_back(term.cast<Disturbance*>());
      continue;
    }
    adapters.push_back(std::make_unique<PyCallableDisturbance>(term, n));
    ports.push_back(adapters.back().get());
  }
  return std::make_unique<PyDisturbanceSum>(std::move(ports), n, terms, std::move(adapters));
}

}  // namespace

void expose_disturbances(py::module_& m) {
  py::class_<Disturbance>(m, "Disturbance", py::module_local())
      .def(
          "at",
          [](Disturbance& d, double t, const CRefVec& q, const CRefVec& dq) {
            return d.at(t, Vec(q), Vec(dq));
          },
          py::arg("t"), py::arg("q"), py::arg("dq"))
      .def(
          "at_times",
          [](Disturbance& d, const CRefVec& times, int n) {
            RowMat out(times.size(), n);
            d.at_times(times, out);
            return out;
          },
          py::arg("times"), py::arg("n"))
      .def_property_readonly("kind",
                             [](const Disturbance& d) {
                               switch (d.kind()) {
                                 case Disturbance::Kind::time_only: return "time_only";
                                 case Disturbance::Kind::friction: return "friction";
                                 default: return "general";
                               }
                             })
      .def_property_readonly("coefficients", [](const Disturbance& d) {
        Vec a, b;
        d.coefficients(a, b);
        return py::make_tuple(a, b);
      });
  py::class_<GaussianPulses, Disturbance>(m, "GaussianPulses", py::module_local())
      .def(py::init<const CRefVec&, const CRefVec&, const CRefVec&>(), py::arg("amplitude"),
           py::arg("center"), py::arg("sigma"));
  py::class_<CoulombViscousFriction, Disturbance>(m, "CoulombViscousFriction",
                                                  py::module_local())
      .def(py::init<const CRefVec&, const CRefVec&>(), py::arg("viscous"), py::arg("coulomb"));
  py::class_<PyDisturbanceSum, Disturbance>(m, "DisturbanceSum", py::module_local())
      .def(py::init(&make_sum), py::arg("terms"), py::arg("n"))
      .def_property_readonly("terms", [](const PyDisturbanceSum& s) { return s.held; });
  py::class_<PyTimeOnlyTerm, Disturbance>(m, "TimeOnlyTerm", py::module_local())
      .def(py::init<py::object, int>(), py::arg("sample_times"), py::arg("n"));
}

}  // namespace hmpc::python
