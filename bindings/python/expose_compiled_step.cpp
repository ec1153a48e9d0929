// hmpc_pin._core.CompiledStep: HierarchicalMPC.step bound to one controller, called by Python
// without a Python frame and without pybind11's dispatch (a vectorcall type of the C API).
//
// ctrl.step(t, q, dq, reference) with a float t, q and dq float64 C-contiguous vectors of n
// values and the reference the step is set for (the same object) runs the compiled step
// (HierarchicalStep::step_t) and returns a new array of τ (a copy, as HierarchicalMPC.step).
// Any other call (keywords, another reference, other argument types or sizes) is handed to
// the Python method (__func__, HierarchicalMPC.step) with the controller: the same answers
// and the same errors, one Python frame more. The controller is held by a weak reference
// (it holds this object in its __dict__).
#include "trampolines.hpp"

#include <structmember.h>

#include <cstring>
#include <vector>

namespace hmpc::python {

namespace {

struct CompiledStep {
  PyObject_HEAD
  vectorcallfunc vectorcall;
  PyObject* core;       // the HierarchicalStep (a Python object: kept alive)
  PyStep* step;         // its C++ object
  PyObject* reference;  // the reference the step is set for
  PyObject* func;       // the Python method's function (HierarchicalMPC.step)
  PyObject* owner;      // a weak reference to the controller
  PyObject* f64;        // numpy's float64 descriptor
  Py_ssize_t handed_over;  // calls handed to the Python method
};

PyTypeObject* compiled_step_type = nullptr;

// The data of a float64, aligned, C-contiguous vector of n values, or nullptr.
const double* vector_data(PyObject* o, Eigen::Index n, PyObject* f64) {
  const auto& api = py::detail::npy_api::get();
  if (!api.PyArray_Check_(o)) return nullptr;
  const auto* a = py::detail::array_proxy(o);
  constexpr int flags = py::detail::npy_api::NPY_ARRAY_C_CONTIGUOUS_ |
                        py::detail::npy_api::NPY_ARRAY_ALIGNED_;
  if (a->nd != 1 || a->dimensions[0] != n || a->descr != f64 || (a->flags & flags) != flags)
    return nullptr;
  return reinterpret_cast<const double*>(a->data);
}

// The call the compiled path does not take: the Python method with the controller first.
PyObject* hand_over(CompiledStep* self, PyObject* const* args, size_t nargsf, PyObject* kwnames) {
  ++self->handed_over;
  PyObject* owner = PyWeakref_GetObject(self->owner);  // borrowed
  if (owner == nullptr) return nullptr;
  if (owner == Py_None) {
    PyErr_SetString(PyExc_ReferenceError, "the controller of this step no longer exists");
    return nullptr;
  }
  const Py_ssize_t nargs = PyVectorcall_NARGS(nargsf);
  const Py_ssize_t nkw = kwnames ? PyTuple_GET_SIZE(kwnames) : 0;
  std::vector<PyObject*> all(static_cast<size_t>(1 + nargs + nkw));
  all[0] = owner;
  for (Py_ssize_t i = 0; i < nargs + nkw; ++i) all[static_cast<size_t>(1 + i)] = args[i];
  Py_INCREF(owner);
  PyObject* r = PyObject_Vectorcall(self->func, all.data(), static_cast<size_t>(1 + nargs), kwnames);
  Py_DECREF(owner);
  return r;
}

PyObject* call(PyObject* o, PyObject* const* args, size_t nargsf, PyObject* kwnames) {
  auto* self = reinterpret_cast<CompiledStep*>(o);
  if (kwnames != nullptr || PyVectorcall_NARGS(nargsf) != 4 || args[3] != self->reference ||
      !PyFloat_Check(args[0]))
    return hand_over(self, args, nargsf, kwnames);
  PyStep& h = *self->step;
  const double* q = vector_data(args[1], h.n, self->f64);
  const double* dq = q ? vector_data(args[2], h.n, self->f64) : nullptr;
  if (dq == nullptr) return hand_over(self, args, nargsf, kwnames);
  try {
    h.step_t(PyFloat_AS_DOUBLE(args[0]), Eigen::Map<const Vec>(q, h.n),
             Eigen::Map<const Vec>(dq, h.n));
  } catch (...) {
    py::detail::try_translate_exceptions();
    return nullptr;
  }
  const auto& api = py::detail::npy_api::get();
  const Py_intptr_t dims[1] = {h.n};
  Py_INCREF(self->f64);  // stolen
  PyObject* tau = api.PyArray_NewFromDescr_(api.PyArray_Type_, self->f64, 1, dims, nullptr,
                                            nullptr, 0, nullptr);
  if (tau == nullptr) return nullptr;
  std::memcpy(py::detail::array_proxy(tau)->data, h.tau.data(), sizeof(double) * h.n);
  return tau;
}

int traverse(PyObject* o, visitproc visit, void* arg) {
  auto* self = reinterpret_cast<CompiledStep*>(o);
  Py_VISIT(Py_TYPE(o));
  Py_VISIT(self->core);
  Py_VISIT(self->reference);
  Py_VISIT(self->func);
  Py_VISIT(self->owner);
  return 0;
}

int clear(PyObject* o) {
  auto* self = reinterpret_cast<CompiledStep*>(o);
  self->step = nullptr;
  Py_CLEAR(self->core);
  Py_CLEAR(self->reference);
  Py_CLEAR(self->func);
  Py_CLEAR(self->owner);
  Py_CLEAR(self->f64);
  return 0;
}

void dealloc(PyObject* o) {
  PyTypeObject* type = Py_TYPE(o);
  PyObject_GC_UnTrack(o);
  clear(o);
  type->tp_free(o);
  Py_DECREF(type);
}

PyObject* get_func(PyObject* o, void*) {
  PyObject* f = reinterpret_cast<CompiledStep*>(o)->func;
  Py_INCREF(f);
  return f;
}

PyObject* get_self(PyObject* o, void*) {
  PyObject* owner = PyWeakref_GetObject(reinterpret_cast<CompiledStep*>(o)->owner);
  if (owner != nullptr) Py_INCREF(owner);
  return owner;
}

PyObject* get_attr_of_func(PyObject* o, void* name) {
  return PyObject_GetAttrString(reinterpret_cast<CompiledStep*>(o)->func,
                                static_cast<const char*>(name));
}

PyObject* get_reference(PyObject* o, void*) {
  PyObject* r = reinterpret_cast<CompiledStep*>(o)->reference;
  Py_INCREF(r);
  return r;
}

PyObject* repr(PyObject* o) {
  PyObject* owner = get_self(o, nullptr);
  if (owner == nullptr) return nullptr;
  PyObject* r = PyUnicode_FromFormat("<compiled step of %R>", owner);
  Py_DECREF(owner);
  return r;
}

PyMemberDef members[] = {
    {"__vectorcalloffset__", T_PYSSIZET, offsetof(CompiledStep, vectorcall), READONLY, nullptr},
    {"handed_over", T_PYSSIZET, offsetof(CompiledStep, handed_over), READONLY,
     "how many calls were handed to the Python method"},
    {nullptr, 0, 0, 0, nullptr}};

char doc_name[] = "__doc__", name_name[] = "__name__", qualname_name[] = "__qualname__";
PyGetSetDef getset[] = {
    {"__func__", get_func, nullptr, "the Python method's function", nullptr},
    {"__self__", get_self, nullptr, "the controller", nullptr},
    {"__doc__", get_attr_of_func, nullptr, nullptr, doc_name},
    {"__name__", get_attr_of_func, nullptr, nullptr, name_name},
    {"__qualname__", get_attr_of_func, nullptr, nullptr, qualname_name},
    {"reference", get_reference, nullptr, "the reference the compiled path is set for", nullptr},
    {nullptr, nullptr, nullptr, nullptr, nullptr}};

PyType_Slot slots[] = {{Py_tp_call, reinterpret_cast<void*>(PyVectorcall_Call)},
                       {Py_tp_traverse, reinterpret_cast<void*>(traverse)},
                       {Py_tp_clear, reinterpret_cast<void*>(clear)},
                       {Py_tp_dealloc, reinterpret_cast<void*>(dealloc)},
                       {Py_tp_repr, reinterpret_cast<void*>(repr)},
                       {Py_tp_members, members},
                       {Py_tp_getset, getset},
                       {0, nullptr}};

PyType_Spec spec = {"hmpc_pin._core.CompiledStep", sizeof(CompiledStep), 0,
                    Py_TPFLAGS_DEFAULT | Py_TPFLAGS_HAVE_GC | Py_TPFLAGS_HAVE_VECTORCALL, slots};

}  // namespace

// core.compiled_step(reference, func, owner): the CompiledStep of `core` for `reference`.
py::object compiled_step(py::object core, py::object reference, py::object func,
                              py::object owner) {
  if (compiled_step_type == nullptr) throw std::logic_error("CompiledStep: type not made");
  if (!PyCallable_Check(func.ptr())) throw py::type_error("compiled_step: func must be callable");
  py::object weak = py::reinterpret_steal<py::object>(PyWeakref_NewRef(owner.ptr(), nullptr));
  if (!weak) throw py::error_already_set();
  auto* self = PyObject_GC_New(CompiledStep, compiled_step_type);
  if (self == nullptr) throw py::error_already_set();
  self->vectorcall = call;
  self->handed_over = 0;
  self->step = &core.cast<PyStep&>();
  self->core = core.release().ptr();
  self->reference = reference.release().ptr();
  self->func = func.release().ptr();
  self->owner = weak.release().ptr();
  self->f64 = py::detail::npy_api::get().PyArray_DescrFromType_(py::detail::npy_api::NPY_DOUBLE_);
  PyObject_GC_Track(reinterpret_cast<PyObject*>(self));
  return py::reinterpret_steal<py::object>(reinterpret_cast<PyObject*>(self));
}

void expose_compiled_step(py::module_& m) {
  PyObject* type = PyType_FromSpec(&spec);
  if (type == nullptr) throw py::error_already_set();
  compiled_step_type = reinterpret_cast<PyTypeObject*>(type);
  m.attr("CompiledStep") = py::reinterpret_borrow<py::object>(type);  // the module keeps it
}

}  // namespace hmpc::python
