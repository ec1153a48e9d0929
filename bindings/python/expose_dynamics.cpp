// hmpc_pin._core.Dynamics: Pinocchio's M(q), C q̇ + G and ABA (dynamics.hpp).
#include "expose.hpp"

#include "hmpc/dynamics.hpp"

#include <algorithm>
#include <chrono>
#include <stdexcept>

namespace hmpc::python {

// The exact floor of a step with Nc = 1, timed here per state k [ns]: M(q_k), C q̇ + G, the
// box QP min ½ h v² + g v over v_min <= v <= v_max per joint in closed form (clip(−g/h)) and
// Eq (4), τ = M v + C q̇ + G − d̂. q, dq, g: (K, n).
static py::array_t<long long> exact_floor(Dynamics& d, const CRefRow& q, const CRefRow& dq,
                                          const CRefRow& g, double h, const CRefVec& v_min,
                                          const CRefVec& v_max, const CRefVec& d_hat) {
  const Eigen::Index K = q.rows(), n = d.n;
  if (q.cols() != n || dq.rows() != K || dq.cols() != n || g.rows() != K || g.cols() != n ||
      v_min.size() != n || v_max.size() != n || d_hat.size() != n || !(h > 0.0))
    throw std::invalid_argument("Dynamics.exact_floor: q, dq, g (K, n); bounds, d_hat (n); h > 0");
  py::array_t<long long> out(K);
  auto ns = out.mutable_unchecked<1>();
  Vec qk(n), dqk(n), v(n), tau(n);
  double sink = 0.0;
  using clock = std::chrono::steady_clock;
  for (Eigen::Index k = 0; k < K; ++k) {
    qk = q.row(k).transpose();
    dqk = dq.row(k).transpose();
    const auto t0 = clock::now();
    const auto& M = d.mass_matrix(qk);
    const auto& nle = d.nle(qk, dqk);
    for (Eigen::Index i = 0; i < n; ++i)
      v[i] = std::min(std::max(-g(k, i) / h, v_min[i]), v_max[i]);
    tau.noalias() = M * v;
    tau += nle - d_hat;
    sink += tau[0];
    ns(k) = std::chrono::duration_cast<std::chrono::nanoseconds>(clock::now() - t0).count();
  }
  if (sink == 1.2345e300) ns(0) = -1;  // keeps the work
  return out;
}

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
          py::arg("q"), py::arg("v"), py::arg("tau"))
      .def("exact_floor", &exact_floor, py::arg("q"), py::arg("dq"), py::arg("g"), py::arg("h"),
           py::arg("v_min"), py::arg("v_max"), py::arg("d_hat"));
}

}  // namespace hmpc::python
