// hmpc_pin._core.Dynamics: Pinocchio's M(q), C q̇ + G and ABA (dynamics.hpp).
#include "expose.hpp"

#include "hmpc/dynamics.hpp"

namespace hmpc::python {

void expose_dynamics(py::module_& m) {
  py::class_<Dynamics>(m, "Dynamics", py::module_local())
      .def(py::init<const std::string&>(), py::arg("model"))
      .def_readonly("nq", &Dynamics::n)
      .def(
          "mass_matrix", [](Dynamics& d, const CRefVec& q) { return Mat(d.mass_matrix(q)); },
          py::arg("q"))
      .def(
          "nle",
          [](Dynamics& d, const CRefVec& q, const CRefVec& v) { return Vec(d.nle(q, v)); },
          py::arg("q"), py::arg("v"))
      .def(
          "aba",
          [](Dynamics& d, const CRefVec& q, const CRefVec& v, const CRefVec& tau) {
            return Vec(d.aba(q, v, tau));
          },
          py::arg("q"), py::arg("v"), py::arg("tau"));
}

}  // namespace hmpc::python
