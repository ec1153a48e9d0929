// hmpc_pin._core.RK4: the RK4 plant's period (rk4.hpp), ABA or the disturbance from Python
// where given.
#include "expose.hpp"

#include "hmpc/rk4.hpp"

#include <memory>
#include <stdexcept>

namespace hmpc::python {

void expose_rk4(py::module_& m) {
  py::class_<RK4>(m, "RK4", py::module_local())
      .def(py::init([](const py::object& model, int n, const py::object& aba) {
             if (!model.is_none()) return std::make_unique<RK4>(model.cast<std::string>());
             if (aba.is_none())
               throw std::invalid_argument("RK4: give a serialized model or an aba callable");
             return std::make_unique<RK4>(n, [aba](const Vec& q, const Vec& v, const Vec& tau) {
               return aba(q, v, tau).cast<Vec>();
             });
           }),
           py::arg("model"), py::arg("n") = 0, py::arg("aba") = py::none())
      .def_property_readonly("nq", [](const RK4& r) { return r.n; })
      .def("period", &RK4::period, py::arg("q"), py::arg("v"), py::arg("T"), py::arg("a"),
           py::arg("b"), py::arg("friction"), py::arg("h"))
      .def("set_joint_dynamics", &RK4::set_joint_dynamics, py::arg("damping"),
           py::arg("friction"))
      .def("set_friction_in_disturbance", &RK4::set_friction_in_disturbance, py::arg("a"),
           py::arg("b"))
      .def_readwrite("stick_slip", &RK4::stick_slip)
      .def_readonly("events", &RK4::events)
      .def_property_readonly("joint_damping", [](const RK4& r) { return Vec(r.joint.b); })
      .def_property_readonly("joint_friction", [](const RK4& r) { return Vec(r.joint.f); })
      .def(
          "period_with",
          [](RK4& r, RefVec q, RefVec v, const CRefVec& tau, double t, double h, int S,
             const py::object& dist) {
            r.period_with(q, v, tau, t, h, S, [&dist](double ts, const Vec& qs, const Vec& vs) {
              return dist(ts, qs, vs).cast<Vec>();
            });
          },
          py::arg("q"), py::arg("v"), py::arg("tau"), py::arg("t"), py::arg("h"), py::arg("S"),
          py::arg("disturbance"))
      .def("aba",
           [](RK4& r, const CRefVec& q, const CRefVec& v, const CRefVec& tau) {
             Vec out(r.n);
             r.aba_into(q, v, Vec(tau), out);
             return out;
           })
      .def("mass_matrix",
           [](RK4& r, const CRefVec& q) {
             if (!r.dyn) throw std::invalid_argument("RK4: no compiled dynamics");
             return Mat(r.dyn->mass_matrix(q));
           })
      .def("nle", [](RK4& r, const CRefVec& q, const CRefVec& v) {
        if (!r.dyn) throw std::invalid_argument("RK4: no compiled dynamics");
        return Vec(r.dyn->nle(q, v));
      });
}

}  // namespace hmpc::python
