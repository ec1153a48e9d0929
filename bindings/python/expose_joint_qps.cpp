// hmpc_pin._core.JointQPs: the per-joint MPC's box QPs (joint_qps.hpp), the solution and
// slack in numpy arrays that the Python object owns (hmpc_pin.mpc.condensed.JointQPs).
#include "holders.hpp"

namespace hmpc::python {

namespace pqp = proxsuite::proxqp;

QPOptions qp_options(const py::dict& settings) {
  QPOptions o;
  for (auto item : settings) {
    const std::string key = py::str(item.first);
    py::handle value = item.second;
    if (key == "initial_guess") {
      const std::string name = py::str(value);
      if (name == "WARM_START_WITH_PREVIOUS_RESULT")
        o.initial_guess = pqp::InitialGuessStatus::WARM_START_WITH_PREVIOUS_RESULT;
      else if (name == "NO_INITIAL_GUESS")
        o.initial_guess = pqp::InitialGuessStatus::NO_INITIAL_GUESS;
      else
        throw std::invalid_argument("unknown initial_guess " + name);
    } else if (key == "eps_abs") o.eps_abs = value.cast<double>();
    else if (key == "eps_rel") o.eps_rel = value.cast<double>();
    else if (key == "max_iter") o.max_iter = value.cast<long>();
    else if (key == "verbose") o.verbose = value.cast<bool>();
    else if (key == "check_duality_gap") o.check_duality_gap = value.cast<bool>();
    else if (key == "eps_duality_gap_abs") o.eps_duality_gap_abs = value.cast<double>();
    else if (key == "eps_duality_gap_rel") o.eps_duality_gap_rel = value.cast<double>();
    else if (key == "eps_primal_inf") o.eps_primal_inf = value.cast<double>();
    else if (key == "eps_dual_inf") o.eps_dual_inf = value.cast<double>();
    else throw std::invalid_argument("the compiled core does not know the ProxSuite setting " + key);
  }
  return o;
}

void expose_joint_qps(py::module_& m) {
  py::class_<PyJointQPs, std::shared_ptr<PyJointQPs>>(m, "JointQPs", py::module_local())
      .def(py::init<int, int, int, bool, const CRefMat&, const CRefVec&, const CRefVec&,
                    const py::dict&, const py::dict&, Array, Array>(),
           py::arg("n"), py::arg("N"), py::arg("Nc"), py::arg("block"), py::arg("H"),
           py::arg("v_min"), py::arg("v_max"), py::arg("warm"), py::arg("cold"), py::arg("U"),
           py::arg("slack"))
      .def("set_limits",
           [](PyJointQPs& o, const CRefMat& Phi, const CRefMat& Gamma, const CRefVec& lower,
              const CRefVec& upper, const CRefVec& vel, const CRefMat& Hs, const CRefMat& C,
              const CRefVec& row_scale, double g_slack, double k_slack, const py::dict& soft,
              bool always) {
             o.qps.set_limits(Phi, Gamma, lower, upper, vel, Hs, C, row_scale, g_slack, k_slack,
                              qp_options(soft), always);
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
          "counters",
          [](const PyJointQPs& o) {
            const auto& q = o.qps;
            return py::make_tuple(q.cold_solves, q.unconstrained_solves, q.active_set_solves,
                                  q.constrained, q.constrained_last);
          },
          [](PyJointQPs& o, const py::tuple& c) {  // restored after a dry step (warm_up)
            auto& q = o.qps;
            q.cold_solves = c[0].cast<long>();
            q.unconstrained_solves = c[1].cast<long>();
            q.active_set_solves = c[2].cast<long>();
            q.constrained = c[3].cast<long>();
            q.constrained_last = c[4].cast<bool>();
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
