// velocity_grid.cpp: loading a velocity grid (velocity_grid.h) through the loaders' structural
// checks (vdb_open.h), cleaned of outliers and converted to a NanoVDB Vec3f grid.
#include "volume/velocity_grid.h"

#include <openvdb/openvdb.h>

#include <algorithm>
#include <cmath>

#include <nanovdb/util/OpenToNanoVDB.h>

#include "util/strings.h"
#include "volume/vdb_open.h"
#include "volume/vdb_prescan.h"
#include "volume/volume_detail.h"

namespace spectrack {
namespace {

using namespace volume_detail;

std::string vec_str(const openvdb::Vec3s& v) {
  return "(" + value_str(v[0]) + ", " + value_str(v[1]) + ", " + value_str(v[2]) + ")";
}

bool finite(const openvdb::Vec3s& v) { return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]); }

// The grid named `name`, read after check_vdb_tree walked its tree; refuses other value types.
openvdb::Vec3SGrid::Ptr read_vec3s(const std::string& file, const std::string& name, const Fail& fail) {
  const std::string gname = in_quotes(name);
  try {
    VdbLayout layout;
    auto f = open_vdb_checked(file, fail, &layout);
    openvdb::GridPtrVecPtr metas = f->readAllGridMetadata();
    std::string key, list;
    size_t i = 0;
    for (auto it = f->beginName(); it != f->endName() && metas && i < metas->size(); ++it, ++i) {
      const openvdb::GridBase::Ptr& g = (*metas)[i];
      list += (list.empty() ? "" : ", ") + in_quotes(g->getName()) + " (" + printable(g->valueType()) + ")";
      if (g->getName() != name || !key.empty()) continue;
      if (!vec3_value_type(g->valueType()))
        fail("velocity grid " + gname + " has value type " + printable(g->valueType()) +
             "; a velocity grid must be a vec3s (or vec3d) grid (e.g. Houdini's vel, Blender's velocity)");
      key = it.gridName();
    }
    if (key.empty()) fail("no velocity grid named " + gname + "; the file has " + (list.empty() ? "no grids" : list));
    check_vdb_tree(file, layout, key, fail);
    auto grid = as_vec3s_grid(f->readGrid(key));
    f->close();
    if (!grid) fail("velocity grid " + gname + " could not be read as a vec3s grid");
    return grid;
  } catch (const Error&) {
    throw;
  } catch (const std::exception& ex) {
    fail(std::string("cannot read OpenVDB file (corrupt or truncated?): ") + ex.what());
  }
}

// The grid with its outliers (and a background beyond the threshold) zeroed, transform and class
// kept, with the bounds; refuses non-finite values.
openvdb::Vec3SGrid::Ptr clean(const openvdb::Vec3SGrid& grid, const std::string& gname, double outlier_speed,
                              const Fail& fail, VelocityGrid& out) {
  openvdb::Vec3s bg = grid.background();
  if (!finite(bg)) fail("velocity grid " + gname + " has background " + vec_str(bg) + ", which is not finite");
  if (double(bg.length()) > outlier_speed) bg = openvdb::Vec3s(0.0f);  // an outlier as every other value
  auto account = [&](const openvdb::Vec3s& v) {
    for (int c = 0; c < 3; ++c) out.max_abs[size_t(c)] = std::max(out.max_abs[size_t(c)], std::abs(double(v[c])));
    out.max_speed = std::max(out.max_speed, double(v.length()));
  };
  account(bg);
  openvdb::Vec3SGrid::Ptr g = openvdb::Vec3SGrid::create(bg);
  g->setTransform(grid.transform().copy());
  g->setGridClass(grid.getGridClass());
  auto acc = g->getUnsafeAccessor();
  for (auto it = grid.cbeginValueOn(); it; ++it) {
    openvdb::Vec3s v = *it;
    if (!finite(v)) {
      const openvdb::Coord q = it.getCoord();
      fail("velocity grid " + gname + ": value " + vec_str(v) + " at " + coord_str(q[0], q[1], q[2]) + " is not finite");
    }
    if (double(v.length()) > outlier_speed) {
      v = openvdb::Vec3s(0.0f);
      out.outliers += it.isVoxelValue() ? 1 : it.getBoundingBox().volume();
    }
    account(v);
    if (it.isVoxelValue()) acc.setValue(it.getCoord(), v);
    else g->fill(it.getBoundingBox(), v, true);
  }
  return g;
}

}  // namespace

VelocityGrid load_velocity_grid(const std::string& file, const std::string& grid_name, double outlier_speed,
                                const std::string& context) {
  const Fail fail{context, file};
  const std::string gname = in_quotes(grid_name);
  const std::string ext = lower_extension(file);
  if (ext == ".nvdb")
    fail("velocity grid " + gname + ": velocity grids are read from OpenVDB (.vdb) files only; export a .vdb");
  if (ext != ".vdb") fail("unknown volume file extension " + in_quotes(ext) + " (expected .vdb)");
  openvdb::Vec3SGrid::Ptr grid = read_vec3s(file, grid_name, fail);
  if (!grid->transform().isLinear())
    fail("velocity grid " + gname + " has a non-affine (" + grid->transform().mapType() +
         ") transform; only affine index-to-world maps are supported");
  check_vdb_file_bbox(*grid, fail);
  VelocityGrid out;
  out.staggered = grid->getGridClass() == openvdb::GRID_STAGGERED;
  const openvdb::Vec3SGrid::Ptr g = clean(*grid, gname, outlier_speed, fail, out);
  out.grid.file = file;
  out.grid.name = grid_name;
  try {
    out.grid.handle = nanovdb::openToNanoVDB(*g);
  } catch (const std::exception& ex) {
    fail("cannot convert velocity grid " + gname + " to NanoVDB: " + ex.what());
  }
  set_box_and_map(out.grid, *grid);
  out.grid.value_max = float(out.max_speed);
  return out;
}

std::array<double, 3> velocity_max_abs(const VelocityGrid& v, const std::array<int, 3>& lo,
                                       const std::array<int, 3>& hi) {
  std::array<double, 3> m{0, 0, 0};
  const auto* g = v.grid.handle.grid<nanovdb::Vec3f>();
  if (!g) return v.max_abs;
  auto account = [&](const nanovdb::Vec3f& x) {
    for (int c = 0; c < 3; ++c) m[size_t(c)] = std::max(m[size_t(c)], std::abs(double(x[c])));
  };
  auto acc = g->getAccessor();
  volume_detail::for_each_box_value(acc, lo, hi, account);
  return m;
}

}  // namespace spectrack
