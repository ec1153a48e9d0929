// hmpc_pin._core.Measurement (the port, subclassable in Python through trampolines.hpp),
// SensingSettings (bound field by field) and SensingMeasurement (measurement.hpp) with its
// noise drawn from the caller's numpy Generator.
#include "trampolines.hpp"

#include "hmpc/measurement.hpp"

#include <algorithm>
#include <memory>
#include <utility>

namespace hmpc::python {

namespace {

// A numpy Generator as the NormalSource: `ahead` rows of draws taken per call of
// rng.standard_normal((ahead, count)) (the same stream as one call per row); give_back()
// rewinds the generator to where the rows used leave it (the compiled loop draws ahead and
// gives back at its end, so that the generator is where a draw per measurement leaves it).
struct Normals {
  py::object rng;
  RowMat block;
  Eigen::Index pos = 0;
  long ahead = 1;
  py::object state;

  void draw(double* out, Eigen::Index count) {
    if (pos == block.rows() || block.cols() != count) {
      if (ahead > 1) state = rng.attr("bit_generator").attr("state");
      block = rng.attr("standard_normal")(py::make_tuple(ahead, count)).cast<RowMat>();
      pos = 0;
    }
    std::copy(block.row(pos).data(), block.row(pos).data() + count, out);
    ++pos;
  }

  void give_back() {
    if (pos == block.rows()) return;
    rng.attr("bit_generator").attr("state") = state;
    if (pos > 0) rng.attr("standard_normal")(py::make_tuple(pos, block.cols()));
    block.conservativeResize(pos, block.cols());
  }
};

struct PySensingMeasurement : SensingMeasurement {
  std::shared_ptr<Normals> normals;
  // The chunk hooks: a chunk's rows of draws taken at once, the unused ones given back.
  void reserve(long steps) override {
    if (normals) normals->ahead = steps > 1 ? steps : 1;
  }
  void give_back() override {
    if (!normals) return;
    normals->give_back();
    normals->ahead = 1;
  }
  PySensingMeasurement(const SensingSettings& s, std::shared_ptr<Normals> source)
      : SensingMeasurement(s, source ? NormalSource([source](double* out, Eigen::Index c) {
                                 source->draw(out, c);
                               })
                                     : NormalSource()),
        normals(std::move(source)) {}
};

py::tuple current(const Measurement& m) { return py::make_tuple(m.qm, m.dqm); }

}  // namespace

void expose_measurement(py::module_& m) {
  py::class_<SensingSettings>(m, "SensingSettings", py::module_local())
      .def(py::init<>())
      .def_readwrite("exact", &SensingSettings::exact)
      .def_readwrite("Ts", &SensingSettings::Ts)
      .def_readwrite("ticks", &SensingSettings::ticks)
      .def_readwrite("Tif", &SensingSettings::Tif)
      .def_readwrite("latency", &SensingSettings::latency)
      .def_readwrite("keep", &SensingSettings::keep)
      .def_readwrite("encoder", &SensingSettings::encoder)
      .def_readwrite("encoder_step", &SensingSettings::encoder_step)
      .def_readwrite("finite_difference", &SensingSettings::finite_difference)
      .def_readwrite("velocity_gain", &SensingSettings::velocity_gain)
      .def_readwrite("q_noise", &SensingSettings::q_noise)
      .def_readwrite("dq_noise", &SensingSettings::dq_noise)
      .def_readwrite("delay", &SensingSettings::delay)
      .def_readwrite("torque_filter", &SensingSettings::torque_filter)
      .def_readwrite("torque_gain", &SensingSettings::torque_gain);

  // The port. reset/measure/command call it as a C++ caller does; a Python subclass
  // overrides them. call_reset/call_measure/call_command dispatch through the port (to a
  // Python override too, through the trampoline) and keep the result as `current`, where
  // the compiled loop reads it.
  py::class_<Measurement, PyMeasurementPort>(m, "Measurement", py::module_local())
      .def(py::init<>())
      .def(
          "reset",
          [](Measurement& s, const CRefVec& q0, const CRefVec& dq0) {
            s.restart(q0, dq0);
            return current(s);
          },
          py::arg("q0"), py::arg("dq0"))
      .def(
          "measure",
          [](Measurement& s, double t, const CRefVec& q, const CRefVec& dq) {
            s.measure(t, q, dq);
            return current(s);
          },
          py::arg("t"), py::arg("q"), py::arg("dq"))
      .def(
          "command",
          [](Measurement& s, Vec tau) {
            s.command(tau);
            return tau;
          },
          py::arg("tau"))
      .def(
          "call_reset",
          [](Measurement& s, const CRefVec& q0, const CRefVec& dq0) {
            s.restart(q0, dq0);
            return current(s);
          },
          py::arg("q0"), py::arg("dq0"))
      .def(
          "call_measure",
          [](Measurement& s, double t, const CRefVec& q, const CRefVec& dq) {
            s.measure(t, q, dq);
            return current(s);
          },
          py::arg("t"), py::arg("q"), py::arg("dq"))
      .def(
          "call_command",
          [](Measurement& s, Vec tau) {
            s.command(tau);
            return tau;
          },
          py::arg("tau"))
      .def(
          "hand_over",  // the measurement of a step: reset's at the first, then measure's
          [](Measurement& s, double t, const CRefVec& q, const CRefVec& dq) {
            s.hand_over(t, q, dq);
            return current(s);
          },
          py::arg("t"), py::arg("q"), py::arg("dq"))
      .def(
          "reserve", [](Measurement& s, long steps) { s.reserve(steps); }, py::arg("steps"))
      .def("give_back", [](Measurement& s) { s.give_back(); })
      .def_readonly("started", &Measurement::started)
      .def_property_readonly("current", &current);

  py::class_<PySensingMeasurement, Measurement>(m, "SensingMeasurement", py::module_local())
      .def(py::init([](const SensingSettings& s, const py::object& rng) {
             auto source = rng.is_none() ? nullptr : std::make_shared<Normals>();
             if (source) source->rng = rng;
             return std::make_unique<PySensingMeasurement>(s, source);
           }),
           py::arg("settings"), py::arg("rng"))
      .def_property_readonly("settings",
                             [](const PySensingMeasurement& s) { return SensingSettings(s.s); });
}

}  // namespace hmpc::python
