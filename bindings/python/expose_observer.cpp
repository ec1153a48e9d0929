// hmpc_pin._core.NDO: the disturbance observer of Eq (13) (observer.hpp), its state its own
// (DisturbanceObserver.z, .estimate are read-only views of it); and
// hmpc_pin._core.Compensation, the Compensation port (interfaces.hpp) for Python subclasses
// (trampolines.hpp).
#include "trampolines.hpp"

#include "hmpc/observer.hpp"

#include <memory>
#include <stdexcept>

namespace hmpc::python {

void expose_observer(py::module_& m) {
  py::class_<Compensation, PyCompensationPort>(m, "Compensation", py::module_local())
      .def(py::init_alias<int>(), py::arg("n"))
      .def("reset", &Compensation::reset, py::arg("q0"), py::arg("dq0"))
      .def("update", &Compensation::update, py::arg("M"), py::arg("nle"), py::arg("q"),
           py::arg("dq"), py::arg("tau"), py::arg("v"))
      .def_property_readonly("estimate",
                             [](const Compensation& c) { return Vec(c.estimate()); });
  py::class_<NDO, std::shared_ptr<NDO>>(m, "NDO", py::module_local())
      .def(py::init<const CRefMat&, double, bool>(), py::arg("cY"), py::arg("Ts"),
           py::arg("implicit"))
      .def("reset", [](NDO& o, const CRefVec& dq0) { o.reset(dq0); }, py::arg("dq0"))
      .def(
          "update",
          [](NDO& o, const CRefMat& M, const CRefVec& nle, const CRefVec& dq,
             const CRefVec& tau) {
            const int n = o.n;
            if (M.rows() != n || M.cols() != n || nle.size() != n || dq.size() != n ||
                tau.size() != n)
              throw std::invalid_argument("NDO.update: M must be (n, n) and nle, dq, tau (n,)");
            o.update(M, nle, dq, tau);
          },
          py::arg("M"), py::arg("nle"), py::arg("dq"), py::arg("tau_prev"))
      .def_property_readonly("n", [](const NDO& o) { return o.n; })
      .def_property_readonly("implicit", [](const NDO& o) { return o.implicit; })
      // z and d̂: read-only views of the observer's own vectors, updated in place
      .def_property_readonly("z",
                             [](py::object self) {
                               NDO& o = self.cast<NDO&>();
                               return view(o.z.data(), o.n, self);
                             })
      .def_property_readonly("estimate",
                             [](py::object self) {
                               NDO& o = self.cast<NDO&>();
                               return view(o.d_hat.data(), o.n, self);
                             })
      .def_property(  // (z, d̂), copies; restored after a dry step (warm_up)
          "state", [](const NDO& o) { return py::make_tuple(Vec(o.z), Vec(o.d_hat)); },
          [](NDO& o, const py::tuple& s) {
            const Vec z = s[0].cast<Vec>(), e = s[1].cast<Vec>();
            if (z.size() != o.n || e.size() != o.n)
              throw std::invalid_argument("NDO.state: (z, estimate) of n values each");
            o.z = z;
            o.d_hat = e;
          });
}

}  // namespace hmpc::python
