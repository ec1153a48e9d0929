// hmpc_pin._core: the library's components bound one by one (expose_*.cpp).
#include "expose.hpp"

PYBIND11_MODULE(_core, m) {
  namespace hp = hmpc::python;
  m.doc() = "hmpc_pin native kernels (RK4 period, hierarchical MPC step)";
  // Every class is module-local: another build of this module (an older version loaded
  // side by side for an A/B benchmark) or another pybind11 extension with classes of the
  // same names cannot take over these bindings.
  // What this module was built against (CMakeLists.txt); hmpc_pin.native checks it.
  pybind11::dict info;
  info["pinocchio"] = HMPC_PINOCCHIO_VERSION;
  info["proxsuite"] = HMPC_PROXSUITE_VERSION;
  info["compiler"] = HMPC_COMPILER;
  info["build_type"] = HMPC_BUILD_TYPE;
  m.attr("build_info") = info;
  hp::expose_dynamics(m);
  hp::expose_references(m);
  hp::expose_disturbances(m);
  hp::expose_rk4(m);
  hp::expose_observer(m);
  hp::expose_joint_qps(m);
  hp::expose_qp_parts(m);
  hp::expose_step(m);
  hp::expose_compiled_step(m);
  hp::expose_measurement(m);
  hp::expose_loop(m);
  hp::expose_errors(m);
  hp::expose_joint_dynamics(m);
  hp::expose_plan_thread(m);
}
