// hmpc_pin._core.JointQPs: the per-joint MPC's box QPs (joint_qps.hpp), the solution and
// slack in numpy arrays that the Python object owns (hmpc_pin.mpc.condensed.JointQPs); their
// ProxSuite settings, QPSettings, bound field by field.
#include "holders.hpp"

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

void expose_joint_qps(py::module_& m) {
  expose_qp_settings(m);
  py::class_<PyJointQPs, std::shared_ptr<PyJointQPs>>(m, "JointQPs", py::module_local())
      .def(py::init<int, int, int, bool, const CRefMat&, const CRefVec&, const CRefVec&,
                    const QPSettings&, const QPSettings&, Array, Array>(),
           py::arg("n"), py::arg("N"), py::arg("Nc"), py::arg("block"), py::arg("H"),
           py::arg("v_min"), py::arg("v_max"), py::arg("warm"), py::arg("cold"), py::arg("U"),
           py::arg("slack"))
      .def("set_limits",
           [](PyJointQPs& o, const CRefMat& Phi, const CRefMat& Gamma, const CRefVec& lower,
              const CRefVec& upper, const CRefVec& vel, const CRefMat& Hs, const CRefMat& C,
              const CRefVec& row_scale, double g_slack, double k_slack, const QPSettings& soft,
              bool always, const CRefMat& T, const CRefMat& E, const CRefMat& Hp) {
             o.qps.set_limits(Phi, Gamma, lower, upper, vel, Hs, C, row_scale, g_slack, k_slack,
                              soft, always, T, E, Hp);
           })
      .def(
          "solve",
          [](PyJointQPs& o, const CRefRow& G, const CRefVec& q, const CRefVec& dq) {
            if (!o.qps.solve(G, q, dq)) throw o.qps.failure();
          },
          py::arg("G"), py::arg("q"), py::arg("dq"))
      .def_property(  // for the faults' messages
          "joint_names", [](const PyJointQPs& o) { return o.qps.joint_names; },
          [](PyJointQPs& o, std::vector<std::string> names) { o.qps.joint_names = names; })
      .def("set_max_iter", [](PyJointQPs& o, long k) { o.qps.set_max_iter(k); })
      .def("restart", [](PyJointQPs& o) { o.qps.restart(); })
      .def_property(
          "shortcut", [](const PyJointQPs& o) { return o.qps.shortcut; },
          [](PyJointQPs& o, bool on) { o.qps.shortcut = on; })
      .def_property(
          "shift", [](const PyJointQPs& o) { return o.qps.shift; },
          [](PyJointQPs& o, bool on) { o.qps.shift = on; })
      .def_property(
          "active_set_iter", [](const PyJointQPs& o) { return o.qps.active_set_iter; },
          [](PyJointQPs& o, int k) { o.qps.active_set_iter = k; })
      .def_property_readonly("active_set_solves",
                             [](const PyJointQPs& o) { return o.qps.active_set_solves; })
      .def_property(
          "soft_active_set_iter", [](const PyJointQPs& o) { return o.qps.soft_active_set_iter; },
          [](PyJointQPs& o, int k) { o.qps.soft_active_set_iter = k; })
      .def_property_readonly("soft_active_set_solves",
                             [](const PyJointQPs& o) { return o.qps.soft_active_set_solves; })
      .def_property_readonly("soft_failures",
                             [](const PyJointQPs& o) {
                               const auto& q = o.qps;
                               return py::make_tuple(q.soft_fail_pivot, q.soft_fail_exchanges,
                                                     q.soft_fail_kkt);
                             })
      .def_property(
          "counters",
          [](const PyJointQPs& o) {
            const auto& q = o.qps;
            return py::make_tuple(q.cold_solves, q.unconstrained_solves, q.active_set_solves,
                                  q.constrained, q.constrained_last, q.soft_active_set_solves);
          },
          [](PyJointQPs& o, const py::tuple& c) {  // restored after a dry step (warm_up)
            auto& q = o.qps;
            q.cold_solves = c[0].cast<long>();
            q.unconstrained_solves = c[1].cast<long>();
            q.active_set_solves = c[2].cast<long>();
            q.constrained = c[3].cast<long>();
            q.constrained_last = c[4].cast<bool>();
            if (c.size() > 5) q.soft_active_set_solves = c[5].cast<long>();
          })
      .def_property_readonly("cold_solves", [](const PyJointQPs& o) { return o.qps.cold_solves; })
      .def_property_readonly("unconstrained_solves",
                             [](const PyJointQPs& o) { return o.qps.unconstrained_solves; })
      .def_property_readonly("constrained", [](const PyJointQPs& o) { return o.qps.constrained; })
      .def_property_readonly("constrained_last",
                             [](const PyJointQPs& o) { return o.qps.constrained_last; })
      .def_property_readonly("fail_joint", [](const PyJointQPs& o) { return o.qps.fail_joint; })
      .def_property_readonly("fail_status", [](const PyJointQPs& o) { return o.qps.fail_status; })
      .def_property_readonly("fail_iter", [](const PyJointQPs& o) { return o.qps.fail_iter; });
}

}  // namespace hmpc::python
