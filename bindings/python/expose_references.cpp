// hmpc_pin._core.Reference (the step's Reference port) and the compiled references with a
// closed form (references.hpp): SineReference and PolynomialReference, whose sample() is the
// one implementation of sampling them.
#include "expose.hpp"

#include "hmpc/references.hpp"

#include <stdexcept>

namespace hmpc::python {

void expose_references(py::module_& m) {
  py::class_<Reference>(m, "Reference", py::module_local());
  py::class_<SampledReference, Reference>(m, "SampledReference", py::module_local())
      .def(
          "sample",  // q, dq (m, n) at times (m,), written in place
          [](const SampledReference& r, const CRefVec& times, Array q, Array dq) {
            const Eigen::Index count = times.size();
            if (q.ndim() != 2 || dq.ndim() != 2 || q.shape(0) != count || q.shape(1) != r.n ||
                dq.shape(0) != count || dq.shape(1) != r.n || !q.writeable() ||
                !dq.writeable())
              throw std::invalid_argument("Reference.sample: q and dq must be writable (m, n)");
            double* qp = q.mutable_data();
            double* dqp = dq.mutable_data();
            for (Eigen::Index j = 0; j < count; ++j)
              r.sample(times[j], qp + j * r.n, dqp + j * r.n);
          },
          py::arg("times"), py::arg("q"), py::arg("dq"))
      .def_readonly("n", &SampledReference::n);
  py::class_<SineReference, SampledReference>(m, "SineReference", py::module_local())
      .def(py::init<const CRefVec&, const CRefVec&, const CRefVec&, const CRefVec&,
                    const CRefVec&>(),
           py::arg("omega"), py::arg("phase"), py::arg("amp"), py::arg("offset"),
           py::arg("amp_omega"));
  py::class_<PolynomialReference, SampledReference>(m, "PolynomialReference", py::module_local())
      .def(py::init<const CRefVec&, const CRefVec&, const CRefRow&, int>(), py::arg("times"),
           py::arg("knots"), py::arg("coef"), py::arg("deg"));
}

}  // namespace hmpc::python
