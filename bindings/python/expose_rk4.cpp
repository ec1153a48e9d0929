// hmpc_pin._core.RK4: the RK4 plant's period (rk4.hpp), ABA or the disturbance from Python
// where given; hmpc_pin._core.RK4Plant: the RK4 plant as the loop's Plant port
// (rk4_plant.hpp), its disturbance a Disturbance port (expose_disturbances.cpp) or a Python
// callable.
#include "trampolines.hpp"

#include "hmpc/rk4.hpp"
#include "hmpc/rk4_plant.hpp"

#include <memory>
#include <stdexcept>

namespace hmpc::python {

namespace {

void expose_rk4_plant(py::module_& m) {
  py::class_<PyRK4Plant, std::shared_ptr<PyRK4Plant>>(m, "RK4Plant", py::module_local())
      .def(py::init<std::shared_ptr<RK4>, double, int>(), py::arg("rk4"), py::arg("Ts"),
           py::arg("substeps"))
      .def("reset", py::method_adaptor<PyRK4Plant>(&RK4Plant::reset), py::arg("q0"),
           py::arg("dq0"), py::arg("t0") = 0.0)
      .def(
          "set_disturbance",  // a compiled Disturbance, a Python callable, or None
          [](PyRK4Plant& p, py::object d) {
            std::unique_ptr<Disturbance> adapter;
            Disturbance* port = nullptr;
            if (py::isinstance<Disturbance>(d)) {
              port = d.cast<Disturbance*>();
            } else if (!d.is_none()) {
              adapter = std::make_unique<PyCallableDisturbance>(d, p.n);
              port = adapter.get();
            }
            p.set_disturbance(port);
            p.adapter = std::move(adapter);
            p.disturbance = std::move(d);
          },
          py::arg("disturbance"))
      .def_property_readonly("fused", py::method_adaptor<PyRK4Plant>(&RK4Plant::fused))
      .def(
          "advance",
          [](PyRK4Plant& p, const CRefVec& tau) {
            Vec q, dq;
            p.advance(Vec(tau), q, dq);
            return py::make_tuple(q, dq);
          },
          py::arg("tau"))
      .def("disturbance_now", py::method_adaptor<PyRK4Plant>(&RK4Plant::disturbance_now))
      .def(
          "applied_disturbance",
          [](PyRK4Plant& p, const CRefVec& d) {
            Vec out = d;
            p.applied_disturbance(out);
            return out;
          },
          py::arg("d"))
      .def_property_readonly("q", [](const PyRK4Plant& p) { return Vec(p.q); })
      .def_property_readonly("dq", [](const PyRK4Plant& p) { return Vec(p.v); })
      .def_property(  // (set: a plant restored from a pickle)
          "k", [](const PyRK4Plant& p) { return p.k; }, [](PyRK4Plant& p, long k) { p.k = k; })
      .def_property_readonly("t", py::method_adaptor<PyRK4Plant>(&RK4Plant::t))
      .def_property_readonly("t0", [](const PyRK4Plant& p) { return p.t0; })
      .def_property_readonly("events", [](const PyRK4Plant& p) { return p.rk4->events; })
      .def_property_readonly("rk4", [](const PyRK4Plant& p) { return p.rk4; });
}

}  // namespace

void expose_rk4(py::module_& m) {
  py::class_<RK4, std::shared_ptr<RK4>>(m, "RK4", py::module_local())
      .def(py::init([](const py::object& model, int n, const py::object& aba) {
             if (!model.is_none()) return std::make_shared<RK4>(model.cast<std::string>());
             if (aba.is_none())
               throw std::invalid_argument("RK4: give a serialized model or an aba callable");
             return std::make_shared<RK4>(n, [aba](const Vec& q, const Vec& v, const Vec& tau) {
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
  expose_rk4_plant(m);
}

}  // namespace hmpc::python
