// args_py.cpp: see args_py.h.
#include "args_py.h"

#include <fmt/format.h>

namespace py = pybind11;

namespace spectrack {
namespace python {
namespace {

std::string type_name(const py::handle& value) { return py::str(py::type::of(value).attr("__name__")); }

// The value's repr, at most 80 characters (a long list stays readable in the message).
std::string short_repr(const py::handle& value) {
  std::string r = py::repr(value).cast<std::string>();
  return r.size() > 80 ? r.substr(0, 77) + "..." : r;
}

[[noreturn]] void wrong_type(const py::handle& value, const char* what, const char* name, const std::string& kind) {
  throw py::type_error(fmt::format("{}: {} must be {}, not {} ({})", what, name, kind, type_name(value),
                                   short_repr(value)));
}

bool is_bool(const py::handle& value) {
  if (py::isinstance<py::bool_>(value)) return true;
  // numpy's bool: numpy.bool_ (numpy.bool since numpy 2)
  const py::handle type = py::type::of(value);
  const std::string name = type_name(value);
  return (name == "bool" || name == "bool_") && py::str(type.attr("__module__")).cast<std::string>() == "numpy";
}

// A number float() takes: int, float, numpy's scalars and 0-d arrays, Decimal; not a bool (True is
// no voxel size), a str or a complex.
bool is_real(const py::handle& value) {
  if (is_bool(value) || py::isinstance<py::str>(value) || py::isinstance<py::bytes>(value)) return false;
  if (PyComplex_Check(value.ptr())) return false;
  return py::hasattr(value, "__float__") || py::hasattr(value, "__index__");
}

double to_double(const py::handle& value, const char* what, const char* name) {
  const double d = PyFloat_AsDouble(value.ptr());
  if (d == -1.0 && PyErr_Occurred()) {  // an int beyond a double's range (OverflowError), a failing __float__
    PyErr_Clear();
    throw py::value_error(fmt::format("{}: {} = {} is not a number a double holds", what, name, short_repr(value)));
  }
  return d;
}

}  // namespace

std::string path_arg(const py::handle& path, const char* what) {
  if (!py::isinstance<py::str>(path) && !py::hasattr(path, "__fspath__"))
    throw py::type_error(fmt::format("{}: a path (str or os.PathLike) is needed, not {}", what,
                                     py::repr(path).cast<std::string>()));
  const py::module_ os = py::module_::import("os");
  const py::object s = os.attr("fspath")(path);
  if (!py::isinstance<py::str>(s)) throw py::type_error(fmt::format("{}: a str path is needed (bytes given)", what));
  // the file system's bytes: a name that is not UTF-8 arrives as os.fsdecode gives it (surrogates)
  return os.attr("fsencode")(s).cast<std::string>();
}

double real_arg(const py::handle& value, const char* what, const char* name) {
  if (!is_real(value)) wrong_type(value, what, name, "a number");
  return to_double(value, what, name);
}

std::vector<double> reals_arg(const py::handle& value, const char* what, const char* name, size_t count) {
  const std::string kind = fmt::format("{} numbers", count);
  // a sequence (a tuple, a list, a 1-D array): a set has no order, a dict would give its keys
  if (py::isinstance<py::str>(value) || py::isinstance<py::bytes>(value) || !PySequence_Check(value.ptr()) ||
      py::isinstance<py::dict>(value))
    wrong_type(value, what, name, kind);
  std::vector<double> out;
  for (const py::handle item : value) {
    if (out.size() == count || !is_real(item)) wrong_type(value, what, name, kind);
    out.push_back(to_double(item, what, name));
  }
  if (out.size() != count) wrong_type(value, what, name, kind);
  return out;
}

bool bool_arg(const py::handle& value, const char* what, const char* name) {
  if (!is_bool(value)) wrong_type(value, what, name, "True or False");
  return py::bool_(py::reinterpret_borrow<py::object>(value)).cast<bool>();
}

std::string str_arg(const py::handle& value, const char* what, const char* name) {
  if (!py::isinstance<py::str>(value)) wrong_type(value, what, name, "a str");
  return value.cast<std::string>();
}

}  // namespace python
}  // namespace spectrack
