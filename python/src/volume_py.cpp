// volume_py.cpp: see volume_py.h. Array index (i, j, k) is voxel (x, y, z) = (i, j, k): voxel
// centres sit at origin + (i, j, k) * voxel_size in world units, the renderer's convention
// (src/volume/volume.h: values at integer index coordinates, trilinear between them).
#include "volume_py.h"

#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <openvdb/openvdb.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>

#include "args_py.h"
#include "util/error.h"
#include "volume/inspect.h"
#include "warnings_py.h"

namespace py = pybind11;
namespace fs = std::filesystem;

namespace spectrack {
namespace python {
namespace {

// The array (a numpy array, or what numpy.asarray takes) as float64 C-contiguous values, after the
// checks: a floating dtype, three dimensions, no empty axis; TypeError and ValueError name what is wrong.
py::array_t<double, py::array::c_style | py::array::forcecast> checked_array(const py::object& density) {
  const py::array a = py::array::ensure(density);
  if (!a) {
    PyErr_Clear();
    throw py::type_error(fmt::format("Volume.from_numpy: density must be a 3-D array of floats, not {}",
                                     py::repr(density).cast<std::string>().substr(0, 80)));
  }
  const char kind = a.dtype().kind();
  if (kind != 'f')
    throw py::type_error(fmt::format("Volume.from_numpy: density has dtype {}; a floating dtype (float32, float64, "
                                     "float16, ...) is needed", std::string(py::str(a.dtype()))));
  if (a.ndim() != 3)
    throw py::value_error(fmt::format("Volume.from_numpy: density has {} dimensions; 3 (x, y, z) are needed", a.ndim()));
  for (int d = 0; d < 3; ++d)
    if (a.shape(d) < 1 || a.shape(d) > (1 << 20))
      throw py::value_error(fmt::format("Volume.from_numpy: density axis {} has {} voxels (1 to 2^20)", d, a.shape(d)));
  return py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(a);
}

std::array<double, 3> checked_origin(const py::object& origin_arg) {
  const std::vector<double> origin = reals_arg(origin_arg, "Volume.from_numpy", "origin", 3);
  for (double v : origin)
    if (!std::isfinite(v)) throw py::value_error("Volume.from_numpy: origin must be finite");
  return {origin[0], origin[1], origin[2]};
}

// A temporary folder only this process writes to.
std::string make_temp_dir() {
  std::string pattern = (fs::temp_directory_path() / "spectrack-volume-XXXXXX").string();
  if (!::mkdtemp(pattern.data())) throw Error(fmt::format("{}: cannot create a temporary folder", pattern));
  return pattern;
}

constexpr double kMinVoxelSize = 1.5e-5;  // above OpenVDB's least uniform scale, (3e-15)^(1/3)

std::unique_ptr<Volume> from_numpy(const py::object& density, const py::object& voxel_size_arg,
                                   const py::object& origin_arg, const py::object& grid_arg) {
  auto arr = checked_array(density);
  const double voxel_size = real_arg(voxel_size_arg, "Volume.from_numpy", "voxel_size");
  const std::string grid_name = str_arg(grid_arg, "Volume.from_numpy", "grid");
  if (!(voxel_size > 0) || !std::isfinite(voxel_size))
    throw py::value_error(fmt::format("Volume.from_numpy: voxel_size {} must be a positive finite number", voxel_size));
  const std::array<double, 3> origin = checked_origin(origin_arg);
  if (grid_name.empty()) throw py::value_error("Volume.from_numpy: grid must not be empty (a medium names its grid)");
  // what a VDB transform holds (OpenVDB refuses a uniform scale whose cube is below 3e-15 as
  // singular: voxels under 1.44e-5) and the kernels' float coordinates can place
  // (volume/float_limits.h checks the world box again when packing)
  if (voxel_size < kMinVoxelSize || voxel_size > 1e12)
    throw py::value_error(fmt::format(
        "Volume.from_numpy: voxel_size {:g} is outside [{:g}, 1e12] (OpenVDB's smallest voxel; for a finer grid give "
        "voxel_size 1 and scale the medium with its \"transform\")",
        voxel_size, kMinVoxelSize));
  for (int a = 0; a < 3; ++a)
    if (std::abs(origin[size_t(a)]) > 1e15)
      throw py::value_error(fmt::format("Volume.from_numpy: origin {} = {} is beyond 1e15 (float coordinates cannot "
                                        "place voxels there)", "xyz"[a], origin[size_t(a)]));
  auto v = std::make_unique<Volume>();
  v->grid = grid_name;
  for (int d = 0; d < 3; ++d) v->shape[size_t(d)] = int(arr.shape(d));
  openvdb::FloatGrid::Ptr grid = openvdb::FloatGrid::create(0.0f);
  grid->setName(grid_name);
  grid->setGridClass(openvdb::GRID_FOG_VOLUME);
  openvdb::math::Transform::Ptr xf = openvdb::math::Transform::createLinearTransform(voxel_size);
  xf->postTranslate(openvdb::Vec3d(origin[0], origin[1], origin[2]));
  grid->setTransform(xf);
  const double* src = arr.data();
  {
    py::gil_scoped_release unlocked;
    auto acc = grid->getAccessor();
    const int nx = v->shape[0], ny = v->shape[1], nz = v->shape[2];
    for (int i = 0; i < nx; ++i)
      for (int j = 0; j < ny; ++j)
        for (int k = 0; k < nz; ++k) {
          const double d = src[(size_t(i) * ny + j) * nz + k];
          if (!std::isfinite(d) || d < 0 || !std::isfinite(float(d)))
            throw Error(fmt::format("Volume.from_numpy: density[{}, {}, {}] = {}: values must be finite and >= 0 (and "
                                    "within float32's range, which the grid holds)", i, j, k, d));
          if (d == 0) continue;
          acc.setValue(openvdb::Coord(i, j, k), float(d));
          ++v->active_voxels;
        }
  }
  v->temp_dir = make_temp_dir();
  v->file = (fs::path(v->temp_dir) / "volume.vdb").string();
  openvdb::io::File out(v->file);
  out.write({grid});
  out.close();
  return v;
}

// The grid of a file, checked as `spectrack info` reads it (volume/inspect.h): the file a VDB or
// NanoVDB one, the grid present and usable as a density; its shape is the active voxels' box.
std::unique_ptr<Volume> from_file(const py::object& path_object, const py::object& grid_arg) {
  const std::string path = path_arg(path_object, "Volume.from_file");
  const std::string grid = str_arg(grid_arg, "Volume.from_file", "grid");
  if (!fs::exists(path)) throw Error(fmt::format("{}: no such volume file", path));
  std::vector<std::string> names;
  const std::vector<GridInfo> grids = inspect_volume(path);
  // the loader's fallback (volume.cpp select): no grid of that name, and the file's only float grid
  // has none, so a medium naming `grid` renders that one
  const GridInfo* unnamed = nullptr;
  int floats = 0;
  for (const GridInfo& g : grids) {
    const bool is_float = g.type == "float" || g.type == "double";
    floats += is_float;
    if (g.name.empty() && is_float) unnamed = &g;
  }
  const bool named = std::any_of(grids.begin(), grids.end(), [&](const GridInfo& g) { return g.name == grid; });
  for (const GridInfo& g : grids) {
    if (g.name != grid && !(!named && !grid.empty() && floats == 1 && &g == unnamed)) {
      names.push_back("'" + printable_name(g.name) + "'");
      continue;
    }
    if (g.density_use.rfind("yes", 0) != 0)  // "yes", or "yes (...)"; else "no: why"
      throw py::value_error(fmt::format("Volume.from_file: {}: grid '{}' cannot be a density: {}", path,
                                        printable_name(g.name),
                                        g.density_use.rfind("no: ", 0) == 0 ? g.density_use.substr(4) : g.density_use));
    auto v = std::make_unique<Volume>();
    v->file = fs::absolute(path).string();
    v->grid = grid;
    for (size_t d = 0; d < 3; ++d) v->shape[d] = g.empty ? 0 : g.index_max[d] - g.index_min[d] + 1;
    v->active_voxels = g.active_voxels;
    return v;
  }
  throw py::value_error(fmt::format("Volume.from_file: {}: no grid '{}' (the file has {})", path, printable_name(grid),
                                    names.empty() ? std::string("none") : fmt::format("{}", fmt::join(names, ", "))));
}

}  // namespace

Volume::~Volume() {
  if (temp_dir.empty()) return;
  std::error_code ec;
  fs::remove_all(temp_dir, ec);
}

void bind_volume(py::module_& m) {
  py::class_<Volume>(m, "Volume", "A float grid usable as a medium's density (docs/python.md)")
      .def_static("from_numpy", &from_numpy, py::call_guard<FlushWarnings>(), py::arg("density"), py::arg("voxel_size") = 1.0,
                  py::arg("origin") = py::make_tuple(0.0, 0.0, 0.0), py::arg("grid") = "density",
                  "an OpenVDB grid of a 3-D float array (x, y, z), sparse where it is zero; voxel centres at origin + "
                  "(i, j, k) * voxel_size")
      .def_static("from_file", &from_file, py::call_guard<FlushWarnings>(), py::arg("path"), py::arg("grid") = "density", "a grid of a .vdb or .nvdb file")
      .def_property_readonly("file", [](const Volume& v) { return v.file; })
      .def_property_readonly("grid", [](const Volume& v) { return v.grid; })
      .def_property_readonly("shape", [](const Volume& v) { return v.shape; })
      .def_property_readonly("active_voxels", [](const Volume& v) { return v.active_voxels; })
      .def("__repr__", [](const Volume& v) { return fmt::format("<spectrack.Volume {} of {}>", v.grid, v.file); });
}

}  // namespace python
}  // namespace spectrack
