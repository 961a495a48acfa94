// module.cpp: the extension module spectrack._spectrack (the Python package spectrack wraps it,
// python/spectrack/__init__.py). Everything here calls the library the command line uses
// (spectrack_core): the scene loader and its validation, the renderer, the film pieces.
//
// Errors: spectrack::Error (a bad scene field, file or option; its message names the file, the
// JSON field path and the reason) becomes ValueError; anything else keeps pybind11's mapping.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cstring>

#include <fmt/format.h>
#include <openvdb/openvdb.h>

#include "device/opencl.h"
#include "image_py.h"
#include "render_py.h"
#include "scene/scene.h"
#include "volume_py.h"
#include "warnings_py.h"

namespace py = pybind11;
using namespace spectrack;

namespace {

py::list devices() {
  py::list l;
  for (const DeviceInfo& d : enumerate_devices(false)) {
    py::dict e;
    e["spec"] = fmt::format("{}:{}", d.platform_index, d.device_index);
    e["name"] = d.name;
    e["type"] = d.type_name();
    e["compute_units"] = d.compute_units;
    e["memory_bytes"] = d.global_mem;
    e["max_alloc_bytes"] = d.max_alloc;
    e["platform"] = d.platform_name;
    e["driver"] = d.driver_version;
    l.append(e);
  }
  return l;
}

void bind_scene(py::module_& m) {
  py::class_<SceneDesc>(m, "SceneDesc", "a validated scene (spectrack-scene/1)")
      .def_readonly("path", &SceneDesc::path)
      .def_property_readonly("width", [](const SceneDesc& s) { return s.film.width; })
      .def_property_readonly("height", [](const SceneDesc& s) { return s.film.height; })
      .def_property_readonly("spp", [](const SceneDesc& s) { return s.film.spp; })
      .def_property_readonly("seed", [](const SceneDesc& s) { return s.render.seed; })
      .def_property_readonly("media", [](const SceneDesc& s) { return s.media.size(); })
      .def_property_readonly("lights", [](const SceneDesc& s) { return s.lights.size(); });
  m.def("load_scene", &load_scene, py::call_guard<python::FlushWarnings>(), py::arg("path"), "parses and validates a scene file");
  m.def("read_scene_text", [](const std::string& path) { return py::bytes(read_scene_text(path)); }, py::arg("path"),
        "a scene file's bytes, after the loader's checks of the file (not a folder, a USD stage or too large)");
  m.def("parse_scene", &parse_scene, py::call_guard<python::FlushWarnings>(), py::arg("json_text"), py::arg("name"), py::arg("dir"),
        "parses and validates scene JSON text; `name` stands for the file in messages, `dir` resolves relative paths");
  m.def("render", [](const SceneDesc& scene, std::optional<int> spp, std::optional<int64_t> seed, std::string device,
                     std::optional<std::pair<int64_t, int64_t>> spp_range, std::optional<std::array<int, 4>> pixel_bounds,
                     std::optional<std::string> tracker, std::optional<std::string> scheme,
                     std::optional<std::string> guiding, std::string guide_cache, std::optional<bool> alpha,
                     std::vector<std::string> aovs, std::optional<double> time_limit, int chunk_spp, bool verbose,
                     py::object progress, std::string json_text, std::optional<bool> guide_splitting) {
    python::RenderArgs a{spp, seed, std::move(device), spp_range, pixel_bounds, std::move(tracker), std::move(scheme),
                         std::move(guiding), std::move(guide_cache), alpha, std::move(aovs), time_limit, chunk_spp,
                         verbose, std::move(progress), std::move(json_text), guide_splitting};
    return python::render(scene, a);
  }, py::call_guard<python::FlushWarnings>(), py::arg("scene"), py::arg("spp") = py::none(), py::arg("seed") = py::none(), py::arg("device") = "",
     py::arg("spp_range") = py::none(), py::arg("pixel_bounds") = py::none(), py::arg("tracker") = py::none(),
     py::arg("scheme") = py::none(), py::arg("guiding") = py::none(), py::arg("guide_cache") = "",
     py::arg("alpha") = py::none(), py::arg("aovs") = std::vector<std::string>{},
     py::arg("time_limit") = py::none(), py::arg("chunk_spp") = 0, py::arg("verbose") = false,
     py::arg("progress") = py::none(), py::arg("json_text") = "", py::arg("guide_splitting") = py::none());
  m.def("devices", &devices, "the OpenCL devices: spec (P:D, what device= takes), name, type, memory");
}

}  // namespace

PYBIND11_MODULE(_spectrack, m) {
  m.doc() = "spectrack: chromatic heterogeneous volume rendering (the library of the spectrack command)";
  m.attr("__version__") = SPECTRACK_VERSION;
  openvdb::initialize();  // Volume.from_numpy builds grids before any loader runs
  python::install_warning_queue();
  // Messages name files and grids as the files spell them, which need not be UTF-8: decoded with
  // backslash escapes for such bytes (PyErr_SetString would leave the message empty).
  py::register_exception_translator([](std::exception_ptr p) {
    auto set = [](PyObject* type, const char* what) {
      PyObject* msg = PyUnicode_DecodeUTF8(what, Py_ssize_t(std::strlen(what)), "backslashreplace");
      if (!msg) return;  // the decode's own error is set
      PyErr_SetObject(type, msg);
      Py_DECREF(msg);
    };
    try {
      if (p) std::rethrow_exception(p);
    } catch (const Error& e) {
      set(PyExc_ValueError, e.what());
    } catch (const py::value_error& e) {
      set(PyExc_ValueError, e.what());
    } catch (const py::type_error& e) {
      set(PyExc_TypeError, e.what());
    }
  });
  bind_scene(m);
  python::bind_image(m);
  python::bind_volume(m);
}
