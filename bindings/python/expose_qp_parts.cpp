// The joint QPs' parts, each bound minimally so that it can be tested alone against a numpy
// oracle (tests/test_qp_parts.py): hmpc_pin._core.BoxQP, BoxActiveSet, GammaRecursion,
// BandedKKT. JointQPs composes them in C++; nothing in hmpc_pin calls these bindings.
#include "expose.hpp"

#include "hmpc/banded_kkt.hpp"
#include "hmpc/box_active_set.hpp"
#include "hmpc/box_qp.hpp"
#include "hmpc/gamma_recursion.hpp"

#include <stdexcept>
#include <vector>

namespace hmpc::python {

namespace {

// The KKT solver with the Γ products it refers to.
struct PyBandedKKT {
  GammaRecursion gamma;
  BandedKKT kkt;
  PyBandedKKT(const CRefMat& Phi, const CRefMat& Gamma, const Mat& T, const Mat& E,
              const Mat& Hp, const Mat& H, const Vec& row_scale, double k_slack, double hss,
              double eps_abs)
      : kkt(T, E, Hp, H, gamma, row_scale, k_slack, hss, eps_abs) {
    gamma.set(Phi, Gamma);
  }
};

std::vector<signed char> chars(const std::vector<int>& v) { return {v.begin(), v.end()}; }
std::vector<int> ints(const std::vector<signed char>& v) { return {v.begin(), v.end()}; }

}  // namespace

void expose_qp_parts(py::module_& m) {
  py::class_<BoxQP>(m, "BoxQP", py::module_local())
      .def(py::init<const Mat&, const Vec&, const Vec&, const QPSettings&, const QPSettings&>(),
           py::arg("H"), py::arg("lo"), py::arg("hi"), py::arg("warm"), py::arg("cold"))
      .def(  // (x, the cold twin answered) or None when neither reported solved
          "solve",
          [](BoxQP& b, const Vec& g, int shift_block) -> py::object {
            bool cold = false;
            const auto* res = b.solve(g, shift_block, cold);
            if (!res) return py::none();
            return py::make_tuple(Vec(res->x), cold);
          },
          py::arg("g"), py::arg("shift_block") = 0)
      .def("restart", &BoxQP::restart)
      .def_property_readonly("x", [](const BoxQP& b) { return Vec(b.x()); });
  py::class_<BoxActiveSet>(m, "BoxActiveSet", py::module_local())
      .def(py::init<const Mat&>(), py::arg("H"))
      .def("unconstrained", [](BoxActiveSet& a, const Vec& g) { return Vec(a.unconstrained(g)); })
      .def(  // (u, z) or None; unconstrained(g) first, as JointQPs calls it
          "solve",
          [](BoxActiveSet& a, const Vec& g, double lo, double hi, const Vec& last, int iter,
             double eps) -> py::object {
            if (g.size() != a.u().size() || last.size() != a.u().size())
              throw std::invalid_argument("BoxActiveSet.solve: g and last must be (Nc,)");
            a.unconstrained(g);
            if (!a.solve(g, lo, hi, last, iter, eps)) return py::none();
            return py::make_tuple(Vec(a.u()), Vec(a.z()));
          },
          py::arg("g"), py::arg("lo"), py::arg("hi"), py::arg("last"), py::arg("iter"),
          py::arg("eps"));
  py::class_<GammaRecursion>(m, "GammaRecursion", py::module_local())
      .def(py::init([](const CRefMat& Phi, const CRefMat& Gamma) {
             GammaRecursion r;
             r.set(Phi, Gamma);
             return r;
           }),
           py::arg("Phi"), py::arg("Gamma"))
      .def_property_readonly("recursion", &GammaRecursion::recursion)
      .def("apply",
           [](const GammaRecursion& r, const Vec& u) {
             if (u.size() != r.cols()) throw std::invalid_argument("GammaRecursion.apply: u of Nc");
             Vec X(r.rows());
             r.apply(u, X);
             return X;
           })
      .def("apply_transpose", [](const GammaRecursion& r, const Vec& lam) {
        if (lam.size() != r.rows())
          throw std::invalid_argument("GammaRecursion.apply_transpose: lam of 2N");
        Vec out(r.cols());
        r.apply_transpose(lam, out);
        return out;
      });
  py::class_<PyBandedKKT>(m, "BandedKKT", py::module_local())
      .def(py::init<const CRefMat&, const CRefMat&, const Mat&, const Mat&, const Mat&,
                    const Mat&, const Vec&, double, double, double>(),
           py::arg("Phi"), py::arg("Gamma"), py::arg("T"), py::arg("E"), py::arg("Hp"),
           py::arg("H"), py::arg("row_scale"), py::arg("k_slack"), py::arg("hss"),
           py::arg("eps_abs"))
      .def(  // {ok, dropped, y, lam, mu, rows, box}
          "solve",
          [](PyBandedKKT& o, const std::vector<int>& rows, const std::vector<int>& box, int slack,
             const Vec& g, double lo, double hi, const Vec& bnd_lo, const Vec& bnd_hi) {
            const auto Nc = static_cast<Eigen::Index>(box.size()), N2 = bnd_lo.size();
            if (g.size() != Nc + 1 || bnd_hi.size() != N2 ||
                rows.size() != static_cast<size_t>(N2) || o.kkt.y().size() != Nc + 1 ||
                o.kkt.lam().size() != N2)
              throw std::invalid_argument(
                  "BandedKKT.solve: expected rows, bnd_lo, bnd_hi of 2N, box of Nc, g of Nc + 1");
            SoftActiveSet st{chars(rows), chars(box), static_cast<signed char>(slack)};
            SoftProblem p;
            p.g = g;
            p.gp.setZero(static_cast<Eigen::Index>(box.size()));
            o.kkt.project(g, p.gp);
            p.lo = lo;
            p.hi = hi;
            p.bnd_lo = bnd_lo;
            p.bnd_hi = bnd_hi;
            const bool ok = o.kkt.solve(st, p);
            py::dict out;
            out["ok"] = ok;
            out["dropped"] = o.kkt.dropped();
            out["y"] = Vec(o.kkt.y());
            out["lam"] = Vec(o.kkt.lam());
            out["mu"] = Vec(o.kkt.mu());
            out["rows"] = ints(st.rows);
            out["box"] = ints(st.box);
            return out;
          },
          py::arg("rows"), py::arg("box"), py::arg("slack"), py::arg("g"), py::arg("lo"),
          py::arg("hi"), py::arg("bnd_lo"), py::arg("bnd_hi"));
}

}  // namespace hmpc::python
