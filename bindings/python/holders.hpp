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

// The compiled RK4 plant, holding the Python disturbance it calls (if any).
struct PyRK4Plant : RK4Plant {
  using RK4Plant::RK4Plant;
  std::unique_ptr<PyCallableDisturbance> held;
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

struct PyHMPCCore {
  std::shared_ptr<PyJointQPs> qp;
  std::shared_ptr<PyNDO> ndo;
  Array v, tau, dhat, M, nle;
  std::optional<Array> stack;
  HMPCCore core;
  PyHMPCCore(const py::object& model, const CRefRow& FT, int N, std::shared_ptr<PyJointQPs> qp_,
             std::shared_ptr<PyNDO> ndo_, Array v_, Array tau_, Array dhat_, Array M_,
             Array nle_)
      : qp(std::move(qp_)), ndo(std::move(ndo_)), v(v_), tau(tau_), dhat(dhat_), M(M_),
        nle(nle_),
        core(model.is_none() ? std::nullopt : std::optional<std::string>(model.cast<std::string>()),
             FT, N, &qp->qps, ndo ? &ndo->ndo : nullptr, writable(v, qp->qps.n),
             writable(tau, qp->qps.n), writable(dhat, qp->qps.n),
             writable(M, static_cast<Eigen::Index>(qp->qps.n) * qp->qps.n),
             writable(nle, qp->qps.n)) {}
};

}  // namespace hmpc::python
