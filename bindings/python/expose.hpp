// The Python module hmpc_pin._core: one expose_*() per component of the library (module.cpp
// calls them). A component owns its data; Python reads numpy views of it (view()).
#pragma once

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "hmpc/types.hpp"

namespace hmpc::python {

namespace py = pybind11;
using Array = py::array_t<double, py::array::c_style>;

void expose_dynamics(py::module_& m);
void expose_references(py::module_& m);
void expose_disturbances(py::module_& m);
void expose_rk4(py::module_& m);
void expose_observer(py::module_& m);
void expose_joint_qps(py::module_& m);
void expose_qp_parts(py::module_& m);
void expose_step(py::module_& m);
void expose_measurement(py::module_& m);
void expose_loop(py::module_& m);
void expose_errors(py::module_& m);
void expose_joint_dynamics(py::module_& m);
void expose_plan_thread(py::module_& m);
void expose_compiled_step(py::module_& m);
// HierarchicalMPC.step of the controller `owner` for `reference`, compiled (expose_compiled_step.cpp):
// the step `core` (a HierarchicalStep), `func` the Python method's function for other calls.
py::object compiled_step(py::object core, py::object reference, py::object func, py::object owner);

// A numpy view of `rows`×`cols` doubles (row-major) that the C++ object `owner` holds: it
// keeps `owner` alive; read-only unless `writable` (Python only reads what the step writes).
inline Array view(double* data, Eigen::Index rows, Eigen::Index cols, py::handle owner,
                  bool writable = false) {
  Array a({static_cast<py::ssize_t>(rows), static_cast<py::ssize_t>(cols)}, data, owner);
  if (!writable) a.attr("setflags")(py::arg("write") = false);
  return a;
}
inline Array view(double* data, Eigen::Index size, py::handle owner, bool writable = false) {
  Array a({static_cast<py::ssize_t>(size)}, data, owner);
  if (!writable) a.attr("setflags")(py::arg("write") = false);
  return a;
}

// The data of a float64 C-contiguous numpy array of `size` values that may be written.
inline double* writable(Array& a, Eigen::Index size) {
  if (a.size() != size || !a.writeable())
    throw std::invalid_argument("native buffer of wrong size or not writable");
  return a.mutable_data();
}

}  // namespace hmpc::python
