// hmpc_pin._core.HierarchicalStep: the hierarchical MPC's step (step.hpp), and
// hmpc_pin._core.StepData: its memory (step_data.hpp), which Python reads through named views.
#include "trampolines.hpp"

#include "hmpc/joint_qps.hpp"
#include "hmpc/observer.hpp"
#include "hmpc/step.hpp"

#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace hmpc::python {

namespace {

// The step's compensation, decoded once: none (d̂ = 0), the compiled NDO (hmpc_pin._core.NDO,
// advanced without Python), a Python subclass of hmpc_pin._core.Compensation, or any other
// Python object of the Compensation protocol (adapted). The step holds it (a Python object:
// its reference, released with the GIL).
std::shared_ptr<Compensation> compensation_port(const py::object& c, int n) {
  if (c.is_none()) return nullptr;
  if (py::isinstance<NDO>(c)) return c.cast<std::shared_ptr<NDO>>();
  if (py::isinstance<Compensation>(c)) {
    return std::shared_ptr<Compensation>(c.cast<Compensation*>(),
                                         [held = py::object(c)](Compensation*) mutable {
                                           py::gil_scoped_acquire gil;
                                           held = py::object();
                                         });
  }
  return std::make_shared<PyCallableCompensation>(c, n);
}

// q or dq of the step: a float64 vector array read in place, anything else through
// pybind11's Eigen conversion (the cost of the conversion only where one is needed);
// TypeError ("incompatible function arguments", as pybind11's) when not a float vector.
class VectorArg {
 public:
  explicit VectorArg(py::handle o) {
    if (py::isinstance<py::array_t<double, py::array::c_style>>(o)) {
      const auto a = py::reinterpret_borrow<py::array>(o);
      if (a.ndim() == 1) {
        data_ = static_cast<const double*>(a.data());
        size_ = a.shape(0);
        return;
      }
    }
    if (!caster_.load(o, true))
      throw py::type_error("step_t(): incompatible function arguments: q and dq float vectors");
    const CRefVec& r = py::detail::cast_op<const CRefVec&>(caster_);
    data_ = r.data();
    size_ = r.size();
  }
  Eigen::Map<const Vec> map() const { return {data_, size_}; }

 private:
  py::detail::make_caster<CRefVec> caster_;
  const double* data_ = nullptr;
  Eigen::Index size_ = 0;
};

void set_reference(PyStep& h, py::object reference) {
  std::unique_ptr<Reference> adapter;
  Reference* port = nullptr;
  if (py::isinstance<Reference>(reference)) {
    port = reference.cast<Reference*>();
  } else if (!reference.is_none()) {
    adapter = std::make_unique<PyCallableReference>(reference);
    port = adapter.get();
  }
  h.set_reference(port);
  h.reference_adapter = std::move(adapter);
  h.reference = std::move(reference);
}

// The step for the controller's model (a serialized Pinocchio model, or None), map F, horizon
// N, QPs, compensation and data.
std::unique_ptr<PyStep> make_step(const py::object& model, const CRefRow& F, int N,
                                    std::shared_ptr<JointQPs> qps, const py::object& comp,
                                    std::shared_ptr<StepData> data) {
  if (!qps || !data) throw std::invalid_argument("HierarchicalStep: qps and data are needed");
  std::optional<std::string> serialized;
  if (!model.is_none()) serialized = model.cast<std::string>();
  auto port = compensation_port(comp, qps->n);
  return std::make_unique<PyStep>(serialized, F, N, std::move(qps), std::move(port),
                                    std::move(data));
}

// Without compiled dynamics: f(q, dq) returns (M, C q̇ + G), copied into the step's data
// (read in place, whatever the arrays' strides).
void set_model(PyStep& h, py::function f) {
  h.model = [f, &h](const Vec& q, const Vec& dq) {
    using Float = py::array_t<double, py::array::forcecast>;
    py::gil_scoped_acquire gil;
    const py::tuple r = f(q, dq);
    const Float M = Float::ensure(r[0]), nle = Float::ensure(r[1]);
    if (!M || !nle || M.ndim() != 2 || M.shape(0) != h.n || M.shape(1) != h.n ||
        nle.ndim() != 1 || nle.shape(0) != h.n)
      throw std::invalid_argument("HierarchicalStep: the model returned M, nle of wrong shape");
    const auto at = [](const Float& a, int d) {
      return static_cast<Eigen::Index>(a.strides(d) / py::ssize_t(sizeof(double)));
    };
    using Strided = Eigen::Stride<Eigen::Dynamic, Eigen::Dynamic>;
    h.M_out = Eigen::Map<const RowMat, 0, Strided>(M.data(), h.n, h.n,
                                                   Strided(at(M, 0), at(M, 1)));
    h.nle_out = Eigen::Map<const RowMat, 0, Strided>(nle.data(), 1, h.n,
                                                     Strided(h.n * at(nle, 0), at(nle, 0)));
  };
}

// StepData's named views: the stack and its rows (written by Python's reference sampling:
// writable), the step's outputs and the model's M, C q̇ + G (read-only).
void expose_step_data(py::module_& m) {
  using D = StepData;
  auto row = [](int i) {  // q (0) or q̇ (1), n
    return [i](py::object self) {
      D& d = self.cast<D&>();
      return view(d.stack.row(i).data(), d.n, self, true);
    };
  };
  auto horizon = [](bool velocity) {  // r_1..r_N or ṙ_1..ṙ_N, N×n
    return [velocity](py::object self) {
      D& d = self.cast<D&>();
      return view(d.stack.row(velocity ? 2 + d.N : 2).data(), d.N, d.n, self, true);
    };
  };
  auto out = [](RowMat D::*field) {
    return [field](py::object self) {
      D& d = self.cast<D&>();
      RowMat& x = d.*field;
      if (x.rows() == 1) return view(x.data(), d.n, self);
      return view(x.data(), x.rows(), x.cols(), self);
    };
  };
  py::class_<D, std::shared_ptr<D>>(m, "StepData", py::module_local())
      .def(py::init<int, int>(), py::arg("n"), py::arg("N"))
      .def_readonly("n", &D::n)
      .def_readonly("N", &D::N)
      .def_property_readonly("stack",  // [q; q̇; r_1..r_N; ṙ_1..ṙ_N], (2 + 2N)×n
                             [](py::object self) {
                               D& d = self.cast<D&>();
                               return view(d.stack.data(), 2 + 2 * d.N, d.n, self, true);
                             })
      .def_property_readonly("q", row(0))
      .def_property_readonly("dq", row(1))
      .def_property_readonly("q_ref", horizon(false))
      .def_property_readonly("dq_ref", horizon(true))
      .def_property_readonly("v", out(&D::v))
      .def_property_readonly("tau", out(&D::tau))
      .def_property_readonly("d_hat", out(&D::dhat))
      .def_property_readonly("M", out(&D::M))
      .def_property_readonly("nle", out(&D::nle))
      .def("__copy__", [](const D& d) { return D(d); })
      .def(
          "assign",  // every array from `other` (restored after a dry step, warm_up)
          [](D& d, const D& other) {
            if (other.n != d.n || other.N != d.N)
              throw std::invalid_argument("StepData.assign: data of another shape");
            d.stack = other.stack;
            d.v = other.v;
            d.tau = other.tau;
            d.dhat = other.dhat;
            d.M = other.M;
            d.nle = other.nle;
          },
          py::arg("other"));
}

}  // namespace

void expose_step(py::module_& m) {
  expose_step_data(m);
  using H = PyStep;
  py::class_<H>(m, "HierarchicalStep", py::module_local())
      .def(py::init(&make_step), py::arg("model"), py::arg("F"), py::arg("N"), py::arg("qps"),
           py::arg("compensation"), py::arg("data"))
      .def("set_model", &set_model, py::arg("model"))
      .def("set_effort", [](H& h, const CRefVec& limit) { h.set_effort(limit); })
      .def(
          "set_observer_model", [](H& h, bool at_start) { h.set_observer_model(at_start); },
          py::arg("at_start"))
      .def(
          "set_latency", [](H& h, double L, double Ts) { h.set_latency(L, Ts); },
          py::arg("L"), py::arg("Ts"))
      .def_property_readonly("latency_periods", [](const H& h) { return h.latency.m; })
      .def_property_readonly("latency_fraction", [](const H& h) { return h.latency.alpha; })
      .def(
          "set_joint_dynamics",
          [](H& h, const CRefVec& damping, const CRefVec& friction, double Ts) {
            h.set_joint_dynamics(damping, friction, Ts);
          },
          py::arg("damping"), py::arg("friction"), py::arg("Ts"))
      .def(
          "reset",  // the compensation restarted at (q0, dq0) through its port, d̂ its estimate
          [](H& h, const CRefVec& q0, const CRefVec& dq0) {
            const int n = h.n;
            if (q0.size() != n || dq0.size() != n)
              throw std::invalid_argument("HierarchicalStep.reset: q0 and dq0 of n values each");
            if (h.comp) {
              h.comp->reset(q0, dq0);
              h.reset(h.comp->estimate());
            } else {
              h.reset(Vec::Zero(n));
            }
          },
          py::arg("q0"), py::arg("dq0"))
      .def(
          "step", [](H& h, const CRefRow& S, double t) { h.step(S, t); }, py::arg("S"),
          py::arg("t"))
      .def("step_t",
           [](H& h, double t, py::handle q, py::handle dq) {
             const VectorArg qa(q), dqa(dq);
             h.step_t(t, qa.map(), dqa.map());
           })
      .def("compiled_step", &compiled_step, py::arg("reference"), py::arg("func"),
           py::arg("owner"))
      .def("fill",
           [](H& h, double t, const CRefVec& q, const CRefVec& dq) { h.fill(t, q, dq); })
      .def_property(  // how faults name the robot: "the robot 'x' has n joints (...)"
          "robot", [](const H& h) { return h.robot; },
          [](H& h, const std::string& robot) { h.robot = robot; })
      .def("set_offsets", [](H& h, const CRefVec& offsets) { h.set_offsets(offsets); })
      .def_property_readonly(  // the step's memory (StepData)
          "data", [](const H& h) { return h.data; })
      .def_property_readonly(  // the last step's gradients G (n×Nc, one row per joint), a view
          "gradients",
          [](py::object self) {
            H& h = self.cast<H&>();
            return view(h.Gt.data(), h.n, h.Nc, self);
          })
      .def("set_reference", &set_reference, py::arg("reference"))
      .def_property(  // what a step carries to the next (restored after a dry step, warm_up)
          "state",
          [](const H& h) {  // copies
            const HierarchicalStep& c = h;
            std::vector<Vec> th = c.latency.tau_hist, vh = c.latency.v_hist;
            return py::make_tuple(c.started, Vec(c.jtau), std::move(th), std::move(vh),
                                  Vec(c.latency.tau_obs), Vec(c.latency.v_obs), c.steps,
                                  Mat(c.prev_M), Vec(c.prev_nle), c.has_prev);
          },
          [](H& h, const py::tuple& s) {
            HierarchicalStep& c = h;
            c.steps = s[6].cast<decltype(c.steps)>();
            c.started = s[0].cast<bool>();
            c.jtau = s[1].cast<Vec>();
            c.latency.tau_hist = s[2].cast<std::vector<Vec>>();
            c.latency.v_hist = s[3].cast<std::vector<Vec>>();
            c.latency.tau_obs = s[4].cast<Vec>();
            c.latency.v_obs = s[5].cast<Vec>();
            c.prev_M = s[7].cast<Mat>();
            c.prev_nle = s[8].cast<Vec>();
            c.has_prev = s[9].cast<bool>();
          })
      .def_property_readonly("has_dynamics", [](const H& h) { return bool(h.dyn); })
      .def_property_readonly(  // a step succeeded since the last reset
          "started", [](const H& h) { return h.started; });
  m.attr("HMPCCore") = m.attr("HierarchicalStep");  // its name before 0.3 (same class)
}

}  // namespace hmpc::python
