// The one translation of the library's faults (errors.hpp) into hmpc_pin.exceptions: each
// C++ exception becomes the Python exception a user of the package catches, with its
// message written here once.
#include "expose.hpp"

#include "hmpc/errors.hpp"

namespace hmpc::python {

namespace {

// Raise `exc` (an instance) as the pending Python error.
void set_error(const py::object& exc) {
  PyErr_SetObject(py::type::handle_of(exc).ptr(), exc.ptr());
}

py::object exceptions() { return py::module_::import("hmpc_pin.exceptions"); }

py::object value_of(const NonFinite& e) {
  if (e.scalar) return py::float_(*e.scalar);
  if (e.values.size() == 1) return py::cast(e.values[0]);
  py::tuple out(e.values.size());
  for (std::size_t i = 0; i < e.values.size(); ++i) out[i] = py::cast(e.values[i]);
  return out;
}

py::str at(double t) { return py::str("at t={:.6g}").format(t); }

void translate(std::exception_ptr p) {
  try {
    if (p) std::rethrow_exception(p);
  } catch (const NonFinite& e) {
    set_error(exceptions().attr("NonFiniteError")(e.name, value_of(e),
                                                   e.at ? at(*e.at) : py::str("")));
  } catch (const DimensionMismatch& e) {
    set_error(exceptions().attr("DimensionError")(
        py::str("{} has shape {} but {}; pass a vector of shape ({},)")
            .format(e.name, py::make_tuple(e.size), e.robot, e.expected)));
  } catch (const QPNotSolved& e) {
    set_error(exceptions().attr("SolverError")(e.joint < 0 ? py::object(py::none())
                                                          : py::object(py::int_(e.joint)),
                                               e.joint_name, e.status, e.iterations));
  } catch (const StateOutOfBound& e) {
    if (!e.finite()) {
      set_error(exceptions().attr("NonFiniteError")(
          "plant state", py::make_tuple(py::cast(e.q), py::cast(e.dq)), at(e.t)));
      return;
    }
    set_error(exceptions().attr("SimulationError")(
        py::str("run diverged at t={:.6g}: max |q|={:.3g}, max |dq|={:.3g} exceed "
                "state_bound={}")
            .format(e.t, e.q.cwiseAbs().maxCoeff(), e.dq.cwiseAbs().maxCoeff(), e.bound)));
  }
}

}  // namespace

void expose_errors(py::module_&) { py::register_local_exception_translator(translate); }

}  // namespace hmpc::python
