// args_py.h: the Python module's argument conversions. pybind11's own conversion answers a value
// of the wrong type with "incompatible function arguments" and the whole signature; these take the
// argument as a Python object and raise a TypeError that names the function and the argument (as
// spectrack.Scene.render's checks in python/spectrack/__init__.py do), so a user sees which value
// is wrong.
#pragma once
#include <pybind11/pybind11.h>

#include <string>
#include <vector>

namespace spectrack {
namespace python {

// A file path argument: a str or any os.PathLike (pathlib.Path); TypeError naming `what` otherwise.
std::string path_arg(const pybind11::handle& path, const char* what);

// A real number (int or float, numpy's scalars too; not a bool): TypeError "what: name must be a
// number, not TYPE (VALUE)" otherwise.
double real_arg(const pybind11::handle& value, const char* what, const char* name);

// `count` real numbers (a tuple, a list or a 1-D array): TypeError naming the argument otherwise.
std::vector<double> reals_arg(const pybind11::handle& value, const char* what, const char* name, size_t count);

// True or False (numpy's bool_ too): an int or a string is refused, as render's checks refuse it.
bool bool_arg(const pybind11::handle& value, const char* what, const char* name);

// A str.
std::string str_arg(const pybind11::handle& value, const char* what, const char* name);

}  // namespace python
}  // namespace spectrack
