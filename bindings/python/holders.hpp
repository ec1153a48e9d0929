// The components whose state lives in arrays the Python objects own (the observer's z and
// d̂, the joint QPs' solution and slack, the step's inputs and outputs): each holder keeps
// its arrays, and the components it uses, alive as long as the component.
#pragma once

#include "expose.hpp"
#include "trampolines.hpp"

#include "hmpc/joint_qps.hpp"
#include "hmpc/observer.hpp"
#include "hmpc/rk4_plant.hpp"
#include "hmpc/step.hpp"

#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

namespace hmpc::python {

struct PyNDO {
  Array z_array, estimate_array;
  NDO ndo;
  static Array checked(Array a, Eigen::Index n) {
    if (a.ndim() != 1 || a.size() != n || !a.writeable())
      throw std::invalid_argument("NDO: z and estimate must be writable float64 arrays of n");
    return a;
  }
  PyNDO(const CRefMat& cY, double Ts, bool implicit, Array z, Array estimate)
      : z_array(checked(z, cY.rows())), estimate_array(checked(estimate, cY.rows())),
        ndo(cY, Ts, implicit, z_array.mutable_data(), estimate_array.mutable_data()) {}
};

// The compiled RK4 plant, holding its disturbance (and the adapter of a Python callable).
struct PyRK4Plant : RK4Plant {
  using RK4Plant::RK4Plant;
  py::object disturbance;
  std::unique_ptr<Disturbance> adapter;
};

struct PyJointQPs {
  Array U_array, slack_array;
  JointQPs qps;
  PyJointQPs(int n, int N, int Nc, bool block, const CRefMat& H, const CRefVec& v_min,
             const CRefVec& v_max, const QPSettings& warm, const QPSettings& cold, Array U,
             Array slack)
      : U_array(U), slack_array(slack),
        qps(n, N, Nc, block, H, v_min, v_max, warm, cold,
            writable(U_array, static_cast<Eigen::Index>(Nc) * n), writable(slack_array, n)) {}
};

// The step's compensation, decoded once: none (d̂ = 0), the compiled NDO (hmpc_pin._core.NDO,
// advanced without Python), a Python subclass of hmpc_pin._core.Compensation, or any other
// Python object of the Compensation protocol (adapted, `adapter` keeps it).
inline Compensation* compensation_port(const py::object& c, int n,
                                       std::unique_ptr<Compensation>& adapter) {
  if (c.is_none()) return nullptr;
  if (py::isinstance<PyNDO>(c)) return &c.cast<PyNDO&>().ndo;
  if (py::isinstance<Compensation>(c)) return c.cast<Compensation*>();
  adapter = std::make_unique<PyCallableCompensation>(c, n);
  return adapter.get();
}

struct PyHMPCCore {
  std::shared_ptr<PyJointQPs> qp;
  py::object comp_object;  // the compensation, alive as long as the step
  std::unique_ptr<Compensation> adapter;
  Array v, tau, dhat, M, nle;
  std::optional<Array> stack;
  py::object model_fn;  // the caller's model, without compiled dynamics
  py::object reference;  // the reference's port (or the Python callable adapted)
  std::unique_ptr<Reference> reference_adapter;
  HMPCCore core;
  PyHMPCCore(const py::object& model, const CRefRow& FT, int N, std::shared_ptr<PyJointQPs> qp_,
             py::object comp, Array v_, Array tau_, Array dhat_, Array M_, Array nle_)
      : qp(std::move(qp_)), comp_object(std::move(comp)), v(v_), tau(tau_), dhat(dhat_), M(M_),
        nle(nle_),
        core(model.is_none() ? std::nullopt : std::optional<std::string>(model.cast<std::string>()),
             FT, N, &qp->qps, compensation_port(comp_object, qp->qps.n, adapter),
             writable(v, qp->qps.n), writable(tau, qp->qps.n), writable(dhat, qp->qps.n),
             writable(M, static_cast<Eigen::Index>(qp->qps.n) * qp->qps.n),
             writable(nle, qp->qps.n)) {}
};

}  // namespace hmpc::python
