// inspect.cpp: inspect_volume (inspect.h), for `spectrack info`. .vdb files are opened with the
// loaders' pre-scan (vdb_open.h) and every grid whose tree it checked read by OpenVDB; .nvdb files through the loaders'
// own .nvdb reader (nvdb_file.cpp), float grids through load_float_grid (validated value range).
#include "volume/inspect.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <limits>
#include <memory>
#include <type_traits>

#include <fmt/format.h>
#include <nanovdb/util/OpenToNanoVDB.h>
#include <openvdb/io/GridDescriptor.h>
#include <openvdb/openvdb.h>

#include "volume/vdb_open.h"
#include "volume/volume.h"
#include "volume/volume_detail.h"
#include "util/strings.h"

namespace spectrack {
namespace {

using namespace volume_detail;

template <class GridT>
void scalar_range(const openvdb::GridBase& base, GridInfo& out) {
  const auto& g = static_cast<const GridT&>(base);
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (auto it = g.cbeginValueOn(); it; ++it) {
    lo = std::min(lo, double(*it));
    hi = std::max(hi, double(*it));
  }
  out.has_range = lo <= hi;
  if (out.has_range) out.value_min = lo, out.value_max = hi;
}

template <class GridT>
void vector_range(const openvdb::GridBase& base, GridInfo& out) {
  const auto& g = static_cast<const GridT&>(base);
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (auto it = g.cbeginValueOn(); it; ++it) {
    const double l = double(it->length());
    lo = std::min(lo, l);
    hi = std::max(hi, l);
  }
  out.has_range = lo <= hi;
  if (out.has_range) out.value_min = lo, out.value_max = hi;
}

template <class GridT>
int64_t nano_bytes(const openvdb::GridBase& base) {
  try {
    if constexpr (std::is_same_v<GridT, openvdb::DoubleGrid>) {  // loaded as float (volume.cpp to_float_grid)
      const openvdb::FloatGrid f(std::make_shared<openvdb::FloatTree>(static_cast<const GridT&>(base).tree()));
      return int64_t(nanovdb::openToNanoVDB(f).size());
    }
    return int64_t(nanovdb::openToNanoVDB(static_cast<const GridT&>(base)).size());
  } catch (const std::exception&) {
    return -1;
  }
}

// Value range and NanoVDB size of g when its type is one of GridTs (vector grids: the range of
// the length); false when it is none of them.
template <bool Vector, class... GridTs>
bool describe_values(const openvdb::GridBase& g, GridInfo& out) {
  auto one = [&](auto* tag) {
    using GridT = std::remove_pointer_t<decltype(tag)>;
    if (!g.isType<GridT>()) return false;
    if constexpr (Vector) vector_range<GridT>(g, out);
    else scalar_range<GridT>(g, out);
    out.nanovdb_bytes = nano_bytes<GridT>(g);
    return true;
  };
  return (one(static_cast<GridTs*>(nullptr)) || ...);
}

GridInfo vdb_grid(const openvdb::GridBase& g, const Fail& fail) {
  check_vdb_file_bbox(g, fail);
  GridInfo out;
  out.name = g.getName();
  out.type = g.valueType();
  out.cls = openvdb::GridBase::gridClassToString(g.getGridClass());
  const openvdb::CoordBBox box = g.evalActiveVoxelBoundingBox();
  out.empty = box.empty();
  out.active_voxels = g.activeVoxelCount();
  const openvdb::Vec3d vs = g.voxelSize();
  out.voxel_size = {vs.x(), vs.y(), vs.z()};
  if (!out.empty) {
    out.index_min = {box.min().x(), box.min().y(), box.min().z()};
    out.index_max = {box.max().x(), box.max().y(), box.max().z()};
    const openvdb::BBoxd w = g.transform().indexToWorld(box);
    out.world_min = {w.min().x(), w.min().y(), w.min().z()};
    out.world_max = {w.max().x(), w.max().y(), w.max().z()};
  }
  describe_values<false, openvdb::FloatGrid, openvdb::DoubleGrid, openvdb::Int32Grid, openvdb::Int64Grid>(g, out) ||
      describe_values<true, openvdb::Vec3SGrid, openvdb::Vec3DGrid>(g, out);
  // As a medium's velocity (velocity_grid.cpp): the largest speed over the active values, in the
  // grid's own units (before the medium's scale and fps)
  if (vec3_value_type(out.type)) {  // vec3d as vec3s (vdb_open.h as_vec3s_grid)
    const bool staggered = g.getGridClass() == openvdb::GRID_STAGGERED;
    if (!g.transform().isLinear()) out.velocity_use = "no: non-affine transform";
    else if (out.has_range && !std::isfinite(out.value_max)) out.velocity_use = "no: non-finite values";
    else
      out.velocity_use = fmt::format("yes{}, largest speed {:.6g} (\"velocity\": {{\"grid\": \"{}\"}})",
                                     staggered ? " (staggered)" : "", out.has_range ? out.value_max : 0.0,
                                     printable(out.name));
  }
  // The loader's refusals (volume.cpp), as a note rather than an error.
  const bool is_double = g.isType<openvdb::DoubleGrid>();  // read as float (volume.cpp to_float_grid)
  if (!g.isType<openvdb::FloatGrid>() && !is_double) {
    out.density_use = vec3_value_type(out.type) ? "no: value type " + out.type + "; usable as a medium's colour grid (\"color\": {\"grid\": \"" + out.name + "\"})" : "no: value type " + out.type + " (only float or double density grids)";
  } else if (g.getGridClass() == openvdb::GRID_LEVEL_SET) {
    out.density_use = "no: a level set, not a fog volume";
  } else if (!g.transform().isLinear()) {
    out.density_use = "no: non-affine transform";
  } else if ((is_double ? static_cast<const openvdb::DoubleGrid&>(g).background()
                        : static_cast<const openvdb::FloatGrid&>(g).background()) != 0.0) {
    out.density_use = "no: background is not 0";
  } else if (out.has_range && (!(out.value_min >= 0) || !std::isfinite(out.value_max))) {
    out.density_use = "no: negative or non-finite values";
  } else if (is_double && out.has_range && out.value_max > std::numeric_limits<float>::max()) {
    out.density_use = "no: values beyond a 32-bit float's range";
  } else {
    out.density_use = is_double ? "yes (64-bit values, read as 32-bit floats)" : "yes";
  }
  return out;
}

// Each grid read on its own after check_vdb_tree walked its tree; a grid whose tree type the walk
// cannot check is listed from its metadata, not read.
std::vector<GridInfo> inspect_vdb(const std::string& file, const Fail& fail) {
  std::vector<GridInfo> out;
  try {
    VdbLayout layout;
    auto f = open_vdb_checked(file, fail, &layout);
    // in io::File's order (its descriptor map's), as getGrids lists them
    for (auto it = f->beginName(); it != f->endName(); ++it) {
      const std::string key = it.gridName(), unique = openvdb::io::GridDescriptor::stringAsUniqueName(key);
      const VdbGridSpan* tree = nullptr;
      for (const VdbGridSpan& s : layout.grids)
        if (s.unique_name == unique) tree = &s;
      if (tree && !tree->parent.empty())
        for (const VdbGridSpan& p : layout.grids)
          if (p.unique_name == tree->parent) tree = &p;
      if (!tree || vdb_tree_checkable(*tree)) {
        check_vdb_tree(file, layout, key, fail);  // refuses a grid missing from the walk's list
        out.push_back(vdb_grid(*f->readGrid(key), fail));
        continue;
      }
      openvdb::GridBase::ConstPtr meta = f->readGridMetadata(key);
      GridInfo gi;
      gi.name = meta->getName();
      gi.type = meta->valueType();
      gi.cls = openvdb::GridBase::gridClassToString(meta->getGridClass());
      gi.density_use = "no: tree type " + printable(tree->tree_type) + " is not read (spectrack cannot check its data)";
      out.push_back(gi);
    }
    f->close();
    if (layout.version < openvdb::OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION || !layout.has_offsets)
      check_vdb_tree(file, layout, "", fail);  // refuses the layouts it cannot walk
  } catch (const Error&) {
    throw;
  } catch (const std::exception& ex) {
    fail(std::string("cannot read OpenVDB file (corrupt or truncated?): ") + ex.what());
  }
  return out;
}

// What `info` says of a NanoVDB density grid of this value type that the loader reads.
std::string nvdb_density_use(nanovdb::GridType t) {
  switch (t) {
    case nanovdb::GridType::Double: return "yes (64-bit values, read as 32-bit floats)";
    case nanovdb::GridType::Fp4: return "yes (4-bit quantized values, read as 32-bit floats)";
    case nanovdb::GridType::Fp8: return "yes (8-bit quantized values, read as 32-bit floats)";
    case nanovdb::GridType::Fp16: return "yes (16-bit quantized values, read as 32-bit floats)";
    case nanovdb::GridType::FpN: return "yes (quantized values of 1 to 16 bits, read as 32-bit floats)";
    default: return "yes";
  }
}

std::vector<GridInfo> inspect_nvdb(const std::string& file, const Fail& fail) {
  std::vector<GridInfo> out;
  std::vector<Entry> entries;
  try {
    entries = nvdb_entries(file, fail);
  } catch (const Error&) {
    throw;
  } catch (const std::exception& ex) {
    fail(std::string("cannot read NanoVDB file (corrupt or truncated?): ") + ex.what());
  }
  for (size_t i = 0; i < entries.size(); ++i) {
    const Entry& e = entries[i];
    GridInfo gi;
    gi.name = e.name, gi.type = e.type, gi.cls = e.cls;
    nanovdb::GridHandle<nanovdb::HostBuffer> h;
    try {
      h = nvdb_read_raw(file, e, fail);  // the metadata of any value type; the density is read below
    } catch (const Error&) {
      throw;
    } catch (const std::exception& ex) {
      fail(std::string("cannot read NanoVDB grid (corrupt or truncated?): ") + ex.what());
    }
    const nanovdb::GridMetaData* m = h.gridMetaData();
    if (!m) fail("cannot read NanoVDB grid " + in_quotes(e.name));
    gi.nanovdb_bytes = int64_t(h.size());
    gi.active_voxels = m->activeVoxelCount();
    const nanovdb::Vec3R vs = m->voxelSize();
    gi.voxel_size = {vs[0], vs[1], vs[2]};
    const nanovdb::CoordBBox ib = nvdb_index_bbox(h, fail);  // not m->indexBBox(): the root is unchecked
    gi.empty = ib[0][0] > ib[1][0] || m->activeVoxelCount() == 0;
    if (!gi.empty) {
      gi.index_min = {ib[0][0], ib[0][1], ib[0][2]};
      gi.index_max = {ib[1][0], ib[1][1], ib[1][2]};
    }
    if (e.is_float && !e.level_set) {
      int same = 0;
      for (size_t j = 0; j < i; ++j) same += entries[j].name == e.name;
      try {
        GridData d = load_float_grid(file, e.name, same, "");
        gi.empty = d.empty;
        gi.index_min = d.index_min, gi.index_max = d.index_max;
        gi.has_range = !d.empty;
        gi.value_min = d.value_min, gi.value_max = d.value_max;
        gi.density_use = nvdb_density_use(m->gridType());
        gi.nanovdb_bytes = int64_t(d.handle.size());  // the float grid the device reads
      } catch (const Error& ex) {
        // a grid render refuses as damaged (checksum, node pointers) fails info too
        if (std::string(ex.what()).find("corrupt NanoVDB grid") != std::string::npos) throw;
        gi.density_use = std::string("no: ") + ex.what();
      }
    } else {
      gi.density_use = e.level_set ? "no: a level set, not a fog volume"
                                   : "no: value type " + e.type + " (only float, double or quantized density grids)";
    }
    if (!gi.empty) {
      const nanovdb::Map& map = m->map();
      for (int a = 0; a < 3; ++a) gi.world_min[a] = std::numeric_limits<double>::infinity(), gi.world_max[a] = -gi.world_min[a];
      for (int c = 0; c < 8; ++c) {
        const nanovdb::Vec3d p((c & 1) ? gi.index_max[0] : gi.index_min[0], (c & 2) ? gi.index_max[1] : gi.index_min[1],
                               (c & 4) ? gi.index_max[2] : gi.index_min[2]);
        const nanovdb::Vec3d w = map.applyMap(p);
        for (int a = 0; a < 3; ++a) gi.world_min[a] = std::min(gi.world_min[a], w[a]), gi.world_max[a] = std::max(gi.world_max[a], w[a]);
      }
    }
    out.push_back(gi);
  }
  return out;
}

}  // namespace

std::string printable_name(const std::string& s) { return printable(s); }

std::vector<GridInfo> inspect_volume(const std::string& file) {
  const Fail fail{"", file};
  std::string ext = lower_extension(file);
  if (ext != ".vdb" && ext != ".nvdb") fail("unknown volume file extension " + in_quotes(ext) + " (expected .vdb or .nvdb)");
  std::error_code ec;
  if (!std::filesystem::exists(file, ec)) fail("no such file");
  if (std::filesystem::is_directory(file, ec)) fail("is a directory, not a VDB file");
  return ext == ".vdb" ? inspect_vdb(file, fail) : inspect_nvdb(file, fail);
}

}  // namespace spectrack
