// warnings_py.cpp: see warnings_py.h.
#include "warnings_py.h"

#include <pybind11/pybind11.h>

#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "util/warning.h"

namespace py = pybind11;

namespace spectrack {
namespace python {
namespace {
std::mutex queue_mutex;
std::vector<std::string> queue;
}  // namespace

void install_warning_queue() {
  set_warning_sink([](const std::string& text) {
    std::lock_guard<std::mutex> lock(queue_mutex);
    queue.push_back(text);
  });
}

void flush_warnings() {
  std::vector<std::string> texts;
  {
    std::lock_guard<std::mutex> lock(queue_mutex);
    texts.swap(queue);
  }
  if (texts.empty()) return;
  // an exception already being raised stays the one raised: the write must not replace it
  PyObject *type = nullptr, *value = nullptr, *trace = nullptr;
  PyErr_Fetch(&type, &value, &trace);
  try {
    py::object err = py::module_::import("sys").attr("stderr");
    for (const std::string& t : texts) {
      const py::str line = py::reinterpret_steal<py::str>(
          PyUnicode_DecodeUTF8(("warning: " + t + "\n").data(), Py_ssize_t(t.size() + 10), "backslashreplace"));
      if (!line) throw py::error_already_set();
      err.attr("write")(line);
    }
  } catch (py::error_already_set& e) {
    e.discard_as_unraisable("spectrack: writing a warning to sys.stderr");
  } catch (...) {
  }
  PyErr_Restore(type, value, trace);
}

}  // namespace python
}  // namespace spectrack
