// hmpc_pin._core.JointQPs: the per-joint MPC's box QPs (joint_qps.hpp), their solution and
// slack read by Python as read-only views (hmpc_pin.mpc.condensed.JointQPs); their ProxSuite
// settings, QPSettings, bound field by field.
#include "expose.hpp"

#include "hmpc/joint_qps.hpp"

#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace hmpc::python {

namespace pqp = proxsuite::proxqp;

static void expose_qp_settings(py::module_& m) {
  py::enum_<pqp::InitialGuessStatus>(m, "InitialGuess", py::module_local())
      .value("NO_INITIAL_GUESS", pqp::InitialGuessStatus::NO_INITIAL_GUESS)
      .value("EQUALITY_CONSTRAINED_INITIAL_GUESS",
             pqp::InitialGuessStatus::EQUALITY_CONSTRAINED_INITIAL_GUESS)
      .value("WARM_START_WITH_PREVIOUS_RESULT",
             pqp::InitialGuessStatus::WARM_START_WITH_PREVIOUS_RESULT)
      .value("WARM_START", pqp::InitialGuessStatus::WARM_START)
      .value("COLD_START_WITH_PREVIOUS_RESULT",
             pqp::InitialGuessStatus::COLD_START_WITH_PREVIOUS_RESULT);
  py::class_<QPSettings>(m, "QPSettings", py::module_local())
      .def(py::init<>())  // ProxSuite's defaults
      .def_readwrite("initial_guess", &QPSettings::initial_guess)
      .def_readwrite("eps_abs", &QPSettings::eps_abs)
      .def_readwrite("eps_rel", &QPSettings::eps_rel)
      .def_readwrite("eps_duality_gap_abs", &QPSettings::eps_duality_gap_abs)
      .def_readwrite("eps_duality_gap_rel", &QPSettings::eps_duality_gap_rel)
      .def_readwrite("eps_primal_inf", &QPSettings::eps_primal_inf)
      .def_readwrite("eps_dual_inf", &QPSettings::eps_dual_inf)
      .def_readwrite("max_iter", &QPSettings::max_iter)
      .def_readwrite("verbose", &QPSettings::verbose)
      .def_readwrite("check_duality_gap", &QPSettings::check_duality_gap);
}

// JointQPs' knobs and counters, field by field (ProxSuite's Settings and Info).
static void expose_options_stats(py::module_& m) {
  using O = JointQPsOptions;
  py::class_<O>(m, "JointQPsOptions", py::module_local())
      .def(py::init<>())
      .def_readwrite("shortcut", &O::shortcut)
      .def_readwrite("shift", &O::shift)
      .def_readwrite("active_set_iter", &O::active_set_iter)
      .def_readwrite("soft_active_set_iter", &O::soft_active_set_iter)
      .def_readwrite("soft_step_exchanges", &O::soft_step_exchanges)
      .def_readwrite("soft_step_work", &O::soft_step_work)
      .def_readwrite("soft_reach_test", &O::soft_reach_test)
      .def_readonly("always_constrained", &O::always_constrained);
  using S = JointQPsStats;
  auto fields = [](const S& s) {
    return py::make_tuple(s.cold_solves, s.unconstrained_solves, s.active_set_solves,
                          s.soft_active_set_solves, s.soft_fail_pivot, s.soft_fail_exchanges,
                          s.soft_fail_kkt, s.soft_exchanges, s.soft_fallbacks, s.constrained,
                          s.constrained_last, s.soft_reach_inside);
  };
  py::class_<S>(m, "JointQPsStats", py::module_local())
      .def(py::init<>())
      .def(py::init<const S&>())
      .def("__copy__", [](const S& s) { return S(s); })
      .def("__eq__", [fields](const S& a, const S& b) { return fields(a).equal(fields(b)); })
      .def("__repr__",
           [](const S& s) {
             return "JointQPsStats(cold_solves=" + std::to_string(s.cold_solves) +
                    ", unconstrained_solves=" + std::to_string(s.unconstrained_solves) +
                    ", active_set_solves=" + std::to_string(s.active_set_solves) +
                    ", soft_active_set_solves=" + std::to_string(s.soft_active_set_solves) +
                    ", soft_fail_pivot=" + std::to_string(s.soft_fail_pivot) +
                    ", soft_fail_exchanges=" + std::to_string(s.soft_fail_exchanges) +
                    ", soft_fail_kkt=" + std::to_string(s.soft_fail_kkt) +
                    ", soft_exchanges=" + std::to_string(s.soft_exchanges) +
                    ", soft_fallbacks=" + std::to_string(s.soft_fallbacks) +
                    ", soft_reach_inside=" + std::to_string(s.soft_reach_inside) +
                    ", constrained=" + std::to_string(s.constrained) +
                    ", constrained_last=" + (s.constrained_last ? "True" : "False") + ")";
           })
      .def_readwrite("cold_solves", &S::cold_solves)
      .def_readwrite("unconstrained_solves", &S::unconstrained_solves)
      .def_readwrite("active_set_solves", &S::active_set_solves)
      .def_readwrite("soft_active_set_solves", &S::soft_active_set_solves)
      .def_readwrite("soft_fail_pivot", &S::soft_fail_pivot)
      .def_readwrite("soft_fail_exchanges", &S::soft_fail_exchanges)
      .def_readwrite("soft_fail_kkt", &S::soft_fail_kkt)
      .def_readwrite("soft_exchanges", &S::soft_exchanges)
      .def_readwrite("soft_fallbacks", &S::soft_fallbacks)
      .def_readwrite("soft_reach_inside", &S::soft_reach_inside)
      .def_readwrite("constrained", &S::constrained)
      .def_readwrite("constrained_last", &S::constrained_last);
}

void expose_joint_qps(py::module_& m) {
  expose_qp_settings(m);
  expose_options_stats(m);
  py::class_<JointQPs::Memory, std::shared_ptr<JointQPs::Memory>>(m, "JointQPsMemory",
                                                                   py::module_local());
  using Q = JointQPs;
  py::class_<Q, std::shared_ptr<Q>>(m, "JointQPs", py::module_local())
      .def(py::init<int, int, int, bool, const CRefMat&, const CRefVec&, const CRefVec&,
                    const QPSettings&, const QPSettings&>(),
           py::arg("n"), py::arg("N"), py::arg("Nc"), py::arg("block"), py::arg("H"),
           py::arg("v_min"), py::arg("v_max"), py::arg("warm"), py::arg("cold"))
      .def("set_limits",
           [](Q& o, const CRefMat& Phi, const CRefMat& Gamma, const CRefVec& lower,
              const CRefVec& upper, const CRefVec& vel, const CRefMat& Hs, const CRefMat& C,
              const CRefVec& row_scale, double g_slack, double k_slack, const QPSettings& soft,
              bool always, const CRefMat& T, const CRefMat& E, const CRefMat& Hp) {
             o.set_limits(Phi, Gamma, lower, upper, vel, Hs, C, row_scale, g_slack, k_slack,
                          soft, always, T, E, Hp);
           })
      .def(
          "solve",
          [](Q& o, const CRefRow& G, const CRefVec& q, const CRefVec& dq) {
            if (!o.solve(G, q, dq)) throw o.failure();
          },
          py::arg("G"), py::arg("q"), py::arg("dq"))
      .def_property(  // for the faults' messages
          "joint_names", [](const Q& o) { return o.joint_names; },
          [](Q& o, std::vector<std::string> names) { o.joint_names = names; })
      .def("set_max_iter", [](Q& o, long k) { o.set_max_iter(k); })
      .def("restart", [](Q& o) { o.restart(); })
      // The QPs' memory between steps (warm starts, remembered active sets): an opaque
      // copy, put back by restore_memory (a dry step: HierarchicalMPC.warm_up).
      .def("save_memory",
           [](const Q& o) {
             auto m = std::make_shared<JointQPs::Memory>();
             o.save(*m);
             return m;
           })
      .def("restore_memory", [](Q& o, const JointQPs::Memory& m) { o.restore(m); })
      // The knobs and the counters, live (qps.options.shift = True; a copy: copy.copy).
      .def_property(
          "options",
          py::cpp_function([](Q& o) -> JointQPsOptions& { return o.options; },
                           py::return_value_policy::reference_internal),
          [](Q& o, const JointQPsOptions& v) {
            const bool always = o.options.always_constrained;  // set_limits' own
            o.options = v;
            o.options.always_constrained = always;
          })
      .def_property(  // set: restored after a dry step (warm_up)
          "stats",
          py::cpp_function([](Q& o) -> JointQPsStats& { return o.stats; },
                           py::return_value_policy::reference_internal),
          [](Q& o, const JointQPsStats& s) { o.stats = s; })
      .def_property_readonly("fail_joint", [](const Q& o) { return o.fail_joint; })
      .def_property_readonly("fail_status", [](const Q& o) { return o.fail_status; })
      .def_property_readonly("fail_iter", [](const Q& o) { return o.fail_iter; })
      // The solution U (Nc×n) and the slack (n): read-only views, written by solve()
      .def_property_readonly("solution",
                             [](py::object self) {
                               Q& o = self.cast<Q&>();
                               return view(o.U.data(), o.Nc, o.n, self);
                             })
      .def_property_readonly("slack",
                             [](py::object self) {
                               Q& o = self.cast<Q&>();
                               return view(o.slack.data(), o.n, self);
                             })
      .def_property(  // (U, slack), copies; restored after a dry step (warm_up)
          "state", [](const Q& o) { return py::make_tuple(RowMat(o.U), Vec(o.slack)); },
          [](Q& o, const py::tuple& s) {
            const RowMat U = s[0].cast<RowMat>();
            const Vec slack = s[1].cast<Vec>();
            if (U.rows() != o.Nc || U.cols() != o.n || slack.size() != o.n)
              throw std::invalid_argument("JointQPs.state: (U of (Nc, n), slack of n)");
            o.U = U;
            o.slack = slack;
          });
}

}  // namespace hmpc::python
