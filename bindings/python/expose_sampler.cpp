// hmpc_pin._core.Sampler: the references' horizon sampler (sampler.hpp).
#include "expose.hpp"

#include "hmpc/sampler.hpp"

#include <stdexcept>

namespace hmpc::python {

void expose_sampler(py::module_& m) {
  using HS = HorizonSampler;
  py::class_<HS>(m, "Sampler", py::module_local())
      .def(py::init<int>(), py::arg("n"))
      .def("set_sine", &HS::set_sine, py::arg("omega"), py::arg("phase"), py::arg("amp"),
           py::arg("offset"), py::arg("amp_omega"))
      .def("set_ppoly", &HS::set_ppoly, py::arg("times"), py::arg("knots"), py::arg("coef"),
           py::arg("deg"))
      .def(
          "sample",
          [](const HS& h, const CRefVec& times, Array q, Array dq) {
            const Eigen::Index m = times.size();
            if (q.ndim() != 2 || dq.ndim() != 2 || q.shape(0) != m || q.shape(1) != h.n ||
                dq.shape(0) != m || dq.shape(1) != h.n || !q.writeable() || !dq.writeable())
              throw std::invalid_argument("Sampler.sample: q and dq must be writable (m, n)");
            double* qp = q.mutable_data();
            double* dqp = dq.mutable_data();
            for (Eigen::Index j = 0; j < m; ++j) h.sample(times[j], qp + j * h.n, dqp + j * h.n);
          },
          py::arg("times"), py::arg("q"), py::arg("dq"))
      .def_readonly("n", &HS::n)
      .def_readonly("kind", &HS::kind);
}

}  // namespace hmpc::python
