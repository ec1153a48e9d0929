// hmpc_pin._core.NDO: the disturbance observer of Eq (13) (observer.hpp), its state in two
// numpy arrays that the Python object owns (DisturbanceObserver.z, .estimate); and
// hmpc_pin._core.Compensation, the Compensation port (interfaces.hpp) for Python subclasses
// (trampolines.hpp).
#include "holders.hpp"
#include "trampolines.hpp"

namespace hmpc::python {

void expose_observer(py::module_& m) {
  py::class_<Compensation, PyCompensationPort>(m, "Compensation", py::module_local())
      .def(py::init_alias<int>(), py::arg("n"))
      .def("reset", &Compensation::reset, py::arg("q0"), py::arg("dq0"))
      .def("update", &Compensation::update, py::arg("M"), py::arg("nle"), py::arg("q"),
           py::arg("dq"), py::arg("tau"), py::arg("v"))
      .def_property_readonly("estimate",
                             [](const Compensation& c) { return Vec(c.estimate()); });
  py::class_<PyNDO, std::shared_ptr<PyNDO>>(m, "NDO", py::module_local())
      .def(py::init<const CRefMat&, double, bool, Array, Array>(), py::arg("cY"), py::arg("Ts"),
           py::arg("implicit"), py::arg("z"), py::arg("estimate"))
      .def("reset", [](PyNDO& o, const CRefVec& dq0) { o.ndo.reset(dq0); }, py::arg("dq0"))
      .def(
          "update",
          [](PyNDO& o, const CRefMat& M, const CRefVec& nle, const CRefVec& dq,
             const CRefVec& tau) {
            const int n = o.ndo.n;
            if (M.rows() != n || M.cols() != n || nle.size() != n || dq.size() != n ||
                tau.size() != n)
              throw std::invalid_argument("NDO.update: M must be (n, n) and nle, dq, tau (n,)");
            o.ndo.update(M, nle, dq, tau);
          },
          py::arg("M"), py::arg("nle"), py::arg("dq"), py::arg("tau_prev"))
      .def_property_readonly("n", [](const PyNDO& o) { return o.ndo.n; })
      .def_property_readonly("implicit", [](const PyNDO& o) { return o.ndo.implicit; })
      .def_property(  // (z, d̂), copies; restored after a dry step (warm_up)
          "state",
          [](const PyNDO& o) { return py::make_tuple(Vec(o.ndo.z), Vec(o.ndo.d_hat)); },
          [](PyNDO& o, const py::tuple& s) {
            const Vec z = s[0].cast<Vec>(), e = s[1].cast<Vec>();
            if (z.size() != o.ndo.n || e.size() != o.ndo.n)
              throw std::invalid_argument("NDO.state: (z, estimate) of n values each");
            o.ndo.z = z;
            o.ndo.d_hat = e;
          });
}

}  // namespace hmpc::python
