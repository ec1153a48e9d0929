// hmpc_pin._core.joint_torque: the arm's joint damping and Coulomb friction law
// (joint_dynamics.hpp), for the Python parts that evaluate it outside the compiled step and
// period (a Python-evaluated disturbance, the Euler plant, dynamics from Python).
#include "expose.hpp"

#include "hmpc/joint_dynamics.hpp"

#include <stdexcept>

namespace hmpc::python {

void expose_joint_dynamics(py::module_& m) {
  m.def(
      "joint_torque",
      [](const CRefVec& b, const CRefVec& f, const CRefVec& v) {
        if (b.size() != v.size() || f.size() != v.size())
          throw std::invalid_argument("joint_torque: b, f and v must have one value per joint");
        Vec out(v.size());
        for (Eigen::Index i = 0; i < v.size(); ++i) out[i] = joint_torque(b[i], f[i], v[i]);
        return out;
      },
      py::arg("b"), py::arg("f"), py::arg("v"),
      "B q̇ + F sgn q̇ [N·m] (sgn 0 = 0), per joint: b, f and v of n values each.");
}

}  // namespace hmpc::python
