// volume.cpp: VDB and NanoVDB loading (.nvdb parsing is in nvdb_file.cpp, the majorant grids are
// built in majorant_grid.cpp).
//
// Design: every grid ends up as a NanoVDB float grid (OpenVDB grids are converted with
// openToNanoVDB), and all checks that matter for rendering (level set, background, negative or
// non-finite values, active bbox, value range) run once on that NanoVDB tree, so .vdb and .nvdb
// files get the same messages. Files are treated as untrusted: OpenVDB exceptions of any kind
// become spectrack::Error, and .nvdb files are parsed here rather than with nanovdb::io, whose
// reader trusts every size in the file; each size is checked against the file length before
// anything is allocated, compressed chunks (BLOSC, ZIP) are decoded through OpenVDB's own codecs
// after checking their headers, and the decoded grid is validated (checksum, node pointers).
#include "volume/volume.h"
#include "volume/volume_detail.h"
#include "util/warning.h"
#include "util/files.h"
#include "volume/vdb_open.h"
#include "volume/vdb_prescan.h"
#include "util/strings.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <memory>
#include <mutex>
#include <sstream>

#include <openvdb/io/Compression.h>
#include <openvdb/openvdb.h>

#include <nanovdb/NanoVDB.h>
#include <nanovdb/util/GridChecksum.h>
#include <nanovdb/util/GridValidator.h>
#include <nanovdb/util/IO.h>
#include <nanovdb/util/OpenToNanoVDB.h>

namespace spectrack {
namespace {

using namespace volume_detail;

namespace fs = std::filesystem;
void init_openvdb() {
  static std::once_flag once;
  std::call_once(once, [] { openvdb::initialize(); });
}

void check_readable(const std::string& file, const Fail& fail) {
  std::error_code ec;
  const fs::file_status st = fs::status(file, ec);
  if (!fs::exists(st)) fail("no such file");
  if (fs::is_directory(st)) fail("is a directory, not a VDB file");
  try {
    check_input_file(file, "");  // a FIFO would block the reader, a device never end
  } catch (const Error& e) {
    // "<file>: <reason>" -> the reason, under this loader's own prefix
    std::string why = e.what();
    fail(why.compare(0, file.size() + 2, file + ": ") == 0 ? why.substr(file.size() + 2) : why);
  }
  std::ifstream f(file, std::ios::binary);
  if (!f) fail(std::string("cannot open for reading: ") + std::strerror(errno));
}

// ---- OpenVDB ----------------------------------------------------------------------------------

std::vector<Entry> vdb_entries(openvdb::io::File& f) {
  std::vector<Entry> out;
  for (auto it = f.beginName(); it != f.endName(); ++it) out.push_back(Entry{});
  // Both iterate the file's descriptor map, so they pair up one to one.
  openvdb::GridPtrVecPtr metas = f.readAllGridMetadata();
  if (!metas || metas->size() != out.size()) throw std::runtime_error("inconsistent grid descriptors");
  size_t i = 0;
  for (auto it = f.beginName(); it != f.endName(); ++it, ++i) {
    const openvdb::GridBase::Ptr& g = (*metas)[i];
    Entry& e = out[i];
    e.vdb_key = it.gridName();
    e.name = g->getName();
    e.type = g->valueType();
    e.cls = openvdb::GridBase::gridClassToString(g->getGridClass());
    // a double grid is read as float (load_vdb): a density grid like a float one
    e.is_float = g->isType<openvdb::FloatGrid>() || g->isType<openvdb::DoubleGrid>();
    e.level_set = g->getGridClass() == openvdb::GRID_LEVEL_SET;
  }
  return out;
}

std::unique_ptr<openvdb::io::File> vdb_open(const std::string& file, const Fail& fail, VdbLayout* layout = nullptr) {
  VdbLayout scanned = prescan_vdb(file, fail);
  if (layout) *layout = std::move(scanned);
  init_openvdb();
  auto f = std::make_unique<openvdb::io::File>(file);
  f->open(/*delayLoad=*/false);
  return f;
}

// Checks the tree against the file_bbox metadata OpenVDB stores with each grid: an empty tree
// whose metadata claims active voxels means the data was lost.
void check_file_bbox(const openvdb::GridBase& g, const Fail& fail) {
  using openvdb::GridBase;
  auto mn = g.getMetadata<openvdb::Vec3IMetadata>(GridBase::META_FILE_BBOX_MIN);
  auto mx = g.getMetadata<openvdb::Vec3IMetadata>(GridBase::META_FILE_BBOX_MAX);
  if (!mn || !mx) return;
  const openvdb::Vec3i a = mn->value(), b = mx->value();
  const bool meta_empty = a.x() > b.x() || a.y() > b.y() || a.z() > b.z();
  const openvdb::CoordBBox box = g.evalActiveVoxelBoundingBox();
  // OpenVDB marks an empty grid with the inverted box CoordBBox(); any other inverted box is damage.
  const openvdb::CoordBBox marker;
  if (meta_empty && (openvdb::Coord(a) != marker.min() || openvdb::Coord(b) != marker.max())) {
    fail("corrupt grid " + in_quotes(g.getName()) + ": its file_bbox metadata " + coord_str(a.x(), a.y(), a.z()) +
         " .. " + coord_str(b.x(), b.y(), b.z()) + " is inverted");
  }
  if (box.empty() && !meta_empty) {
    fail("corrupt grid " + in_quotes(g.getName()) + ": its file_bbox metadata claims active voxels in " +
         coord_str(a.x(), a.y(), a.z()) + " .. " + coord_str(b.x(), b.y(), b.z()) +
         " but its tree is empty");
  }
  // OpenVDB writes file_bbox from the tree, so active voxels outside it mean a damaged tree
  // (typically a flipped node origin, which would also claim a huge majorant grid).
  if (!box.empty() && (meta_empty || !openvdb::CoordBBox(openvdb::Coord(a), openvdb::Coord(b)).isInside(box))) {
    fail("corrupt grid " + in_quotes(g.getName()) + ": active voxels in " +
         coord_str(box.min().x(), box.min().y(), box.min().z()) + " .. " +
         coord_str(box.max().x(), box.max().y(), box.max().z()) + " lie outside its file_bbox metadata " +
         coord_str(a.x(), a.y(), a.z()) + " .. " + coord_str(b.x(), b.y(), b.z()));
  }
}

// Picks the grid to load: by name and index, or the single unnamed float grid as a fallback.
const Entry& select(const std::vector<Entry>& entries, const std::string& grid_name, int grid_index,
                    const Fail& fail) {
  std::vector<const Entry*> hits;
  for (const Entry& e : entries) if (e.name == grid_name) hits.push_back(&e);
  if (hits.empty()) {
    std::vector<const Entry*> unnamed;
    for (const Entry& e : entries) if (e.name.empty() && e.is_float) unnamed.push_back(&e);
    int floats = 0;
    for (const Entry& e : entries) floats += e.is_float;
    if (!grid_name.empty() && unnamed.size() == 1 && floats == 1 && grid_index <= 0) {
      warn((fail.context.empty() ? "" : fail.context + ": ") + fail.file + ": no grid named " + in_quotes(grid_name) +
           "; using the file's only float grid, which has no name");
      return *unnamed[0];
    }
    std::string list;
    for (const Entry& e : entries) list += (list.empty() ? "" : ", ") + describe(e);
    fail("no grid named " + in_quotes(grid_name) + "; the file has " + (list.empty() ? std::string("no grids") : list));
  }
  if (grid_index >= 0) {
    if (size_t(grid_index) >= hits.size()) {
      fail("grid_index " + std::to_string(grid_index) + " is out of range: the file has " +
           std::to_string(hits.size()) + " grid(s) named " + in_quotes(grid_name));
    }
    return *hits[size_t(grid_index)];
  }
  if (hits.size() > 1) {
    warn((fail.context.empty() ? "" : fail.context + ": ") + fail.file + ": " + std::to_string(hits.size()) +
         " grids are named " + in_quotes(grid_name) + "; using the first (set grid_index to select another, 0-based)");
  }
  return *hits[0];
}

void check_entry(const Entry& e, const Fail& fail) {
  if (!e.is_float) {
    const bool nvdb = lower_extension(fail.file) == ".nvdb";
    fail("grid " + in_quotes(e.name) + " has value type " + e.type + " (class " + e.cls + "); only scalar " +
         (nvdb ? "float, double or quantized (Fp4, Fp8, Fp16, FpN) density grids are supported in NanoVDB files"
               : "float or double density grids are supported"));
  }
  if (e.level_set) {
    fail("grid " + in_quotes(e.name) + " is a level set (signed distance field), not a fog volume; convert it to a "
         "fog volume (density) grid first");
  }
}

// A double grid as the float grid the device reads (its metadata, transform and tree, every value
// rounded to the nearest float). A value a float cannot hold is refused here, naming it, rather than
// as the infinity it would round to.
openvdb::FloatGrid::Ptr to_float_grid(const openvdb::DoubleGrid& d, const Fail& fail) {
  const double limit = std::numeric_limits<float>::max();
  for (auto v = d.tree().cbeginValueOn(); v; ++v)
    if (std::abs(*v) > limit) {
      const openvdb::Coord p = v.getCoord();
      char value[32];
      std::snprintf(value, sizeof value, "%.9g", *v);
      fail("grid " + in_quotes(d.getName()) + ": value " + value + " at " +
           (v.isVoxelValue() ? "active voxel " : "active tile at ") + coord_str(p.x(), p.y(), p.z()) +
           " is beyond a 32-bit float's range (double grids are read as float)");
    }
  auto tree = std::make_shared<openvdb::FloatTree>(d.tree());  // OpenVDB's value-converting copy
  openvdb::FloatGrid::Ptr out = openvdb::FloatGrid::create(tree);
  static_cast<openvdb::MetaMap&>(*out) = static_cast<const openvdb::MetaMap&>(d);  // name, class, file_bbox
  out->setTransform(d.transform().copy());
  return out;
}

GridData load_vdb(const std::string& file, const std::string& grid_name, int grid_index, const Fail& fail) {
  GridData out;
  out.file = file;
  openvdb::FloatGrid::Ptr grid;
  try {
    VdbLayout layout;
    auto f = vdb_open(file, fail, &layout);
    const std::vector<Entry> entries = vdb_entries(*f);
    const Entry& e = select(entries, grid_name, grid_index, fail);
    check_entry(e, fail);
    out.name = e.name;
    check_vdb_tree(file, layout, e.vdb_key, fail);
    const openvdb::GridBase::Ptr base = f->readGrid(e.vdb_key);
    f->close();
    grid = openvdb::gridPtrCast<openvdb::FloatGrid>(base);
    if (const openvdb::DoubleGrid::Ptr d = openvdb::gridPtrCast<openvdb::DoubleGrid>(base)) grid = to_float_grid(*d, fail);
    if (!grid) fail("grid " + in_quotes(e.name) + " could not be read as a float grid");
  } catch (const Error&) {
    throw;
  } catch (const std::exception& ex) {
    fail(std::string("cannot read OpenVDB file (corrupt or truncated?): ") + ex.what());
  }
  const std::string gname = in_quotes(out.name);
  if (!grid->transform().isLinear()) {
    fail("grid " + gname + " has a non-affine (" + grid->transform().mapType() +
         ", e.g. frustum) transform; only affine index-to-world maps are supported");
  }
  if (grid->background() != 0.0f) {
    fail("grid " + gname + " has background value " + value_str(grid->background()) +
         "; inactive voxels must read 0 density (background must be 0)");
  }
  check_file_bbox(*grid, fail);
  try {
    out.handle = nanovdb::openToNanoVDB(*grid);
  } catch (const std::exception& ex) {
    fail("cannot convert grid " + gname + " to NanoVDB: " + ex.what());
  }
  finish_grid(out, fail, false);
  // The OpenVDB map is the source of truth; NanoVDB's copy is the same affine map.
  const openvdb::math::Mat4d mat = grid->transform().baseMap()->getAffineMap()->getMat4();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out.index_to_world[r][c] = mat(c, r);
    out.index_to_world[r][3] = mat(3, r);
  }
  return out;
}

GridData load_nvdb(const std::string& file, const std::string& grid_name, int grid_index, const Fail& fail) {
  GridData out;
  out.file = file;
  try {
    const std::vector<Entry> entries = nvdb_entries(file, fail);
    const Entry& e = select(entries, grid_name, grid_index, fail);
    check_entry(e, fail);
    out.name = e.name;
    out.handle = nvdb_read(file, e, fail);
  } catch (const Error&) {
    throw;
  } catch (const std::bad_alloc&) {
    fail("out of memory reading NanoVDB grid");
  } catch (const std::exception& ex) {
    fail(std::string("cannot read NanoVDB file (corrupt or truncated?): ") + ex.what());
  }
  finish_grid(out, fail, true);
  return out;
}

}  // namespace

// For `spectrack info` (vdb_open.h): the same checks as the loaders, on the whole file.
namespace volume_detail {
std::unique_ptr<openvdb::io::File> open_vdb_checked(const std::string& file, const Fail& fail, VdbLayout* layout) {
  check_readable(file, fail);
  return vdb_open(file, fail, layout);
}
void check_vdb_file_bbox(const openvdb::GridBase& g, const Fail& fail) { check_file_bbox(g, fail); }

openvdb::Vec3SGrid::Ptr as_vec3s_grid(const openvdb::GridBase::Ptr& g) {
  if (openvdb::Vec3SGrid::Ptr s = openvdb::gridPtrCast<openvdb::Vec3SGrid>(g)) return s;
  const openvdb::Vec3DGrid::Ptr d = openvdb::gridPtrCast<openvdb::Vec3DGrid>(g);
  if (!d) return nullptr;
  // OpenVDB converts no vec3d tree to vec3s (a narrowing it refuses): the topology is copied, then
  // every value, active and inactive, tiles and voxels, in the one order both trees iterate
  const openvdb::Vec3s bg(d->background());
  auto tree = std::make_shared<openvdb::Vec3STree>(d->tree(), bg, bg, openvdb::TopologyCopy());
  auto to = tree->beginValueAll();
  for (auto from = d->tree().cbeginValueAll(); from; ++from, ++to) to.setValue(openvdb::Vec3s(*from));
  openvdb::Vec3SGrid::Ptr out = openvdb::Vec3SGrid::create(tree);
  static_cast<openvdb::MetaMap&>(*out) = static_cast<const openvdb::MetaMap&>(*d);  // name, class, file_bbox
  out->setTransform(d->transform().copy());
  return out;
}

void set_box_and_map(GridData& g, const openvdb::GridBase& grid) {
  const openvdb::math::Mat4d mat = grid.transform().baseMap()->getAffineMap()->getMat4();
  const openvdb::CoordBBox box = grid.evalActiveVoxelBoundingBox();
  g.empty = box.empty();
  if (!g.empty) {
    g.index_min = {box.min()[0], box.min()[1], box.min()[2]};
    g.index_max = {box.max()[0], box.max()[1], box.max()[2]};
  }
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 3; ++k) g.index_to_world[r][k] = mat(k, r);
    g.index_to_world[r][3] = mat(3, r);
  }
}

std::array<GridData, 3> vec3_components(const openvdb::Vec3SGrid& grid, const std::array<openvdb::FloatGrid::Ptr, 3>& comp,
                                        const std::string& grid_name, const std::string& what, const Fail& fail) {
  std::array<GridData, 3> out;
  for (int c = 0; c < 3; ++c) {
    GridData& g = out[size_t(c)];
    g.file = fail.file;
    g.name = grid_name + "." + "xyz"[c];
    try {
      g.handle = nanovdb::openToNanoVDB(*comp[size_t(c)]);
    } catch (const std::exception& ex) {
      fail("cannot convert " + what + " to NanoVDB: " + ex.what());
    }
    set_box_and_map(g, grid);
  }
  return out;
}
}  // namespace volume_detail

GridData load_float_grid(const std::string& file, const std::string& grid_name, int grid_index,
                         const std::string& context) {
  if (GridData kept; take_kept_grid(file, grid_name, grid_index, &kept)) return kept;
  const Fail fail{context, file};
  const std::string ext = lower_extension(file);
  if (ext != ".vdb" && ext != ".nvdb") fail("unknown volume file extension " + in_quotes(ext) + " (expected .vdb or .nvdb)");
  check_readable(file, fail);
  return ext == ".vdb" ? load_vdb(file, grid_name, grid_index, fail) : load_nvdb(file, grid_name, grid_index, fail);
}

namespace {

// The vec3s grid named grid_name of a .vdb file, read after the file's and the tree's checks.
openvdb::Vec3SGrid::Ptr read_color_grid(const std::string& file, const std::string& grid_name, const Fail& fail) {
  check_readable(file, fail);
  openvdb::Vec3SGrid::Ptr grid;
  try {
    VdbLayout layout;
    auto f = vdb_open(file, fail, &layout);
    const std::vector<Entry> entries = vdb_entries(*f);
    const Entry* hit = nullptr;
    for (const Entry& e : entries)
      if (e.name == grid_name && !hit) hit = &e;
    if (!hit) {
      std::string list;
      for (const Entry& e : entries) list += (list.empty() ? "" : ", ") + describe(e);
      fail("no colour grid named " + in_quotes(grid_name) + "; the file has " +
           (list.empty() ? std::string("no grids") : list));
    }
    if (!vec3_value_type(hit->type)) {
      fail("colour grid " + in_quotes(grid_name) + " has value type " + hit->type + " (class " + hit->cls +
           "); a colour grid must be a vec3s (or vec3d) grid (e.g. Houdini's Cd)");
    }
    check_vdb_tree(file, layout, hit->vdb_key, fail);
    grid = as_vec3s_grid(f->readGrid(hit->vdb_key));
    f->close();
    if (!grid) fail("colour grid " + in_quotes(grid_name) + " could not be read as a vec3s grid");
  } catch (const Error&) {
    throw;
  } catch (const std::exception& ex) {
    fail(std::string("cannot read OpenVDB file (corrupt or truncated?): ") + ex.what());
  }
  return grid;
}

// The three float grids of a colour grid's components (its transform and background kept), with
// each component's range over active values and background in lo, hi; refuses negative or
// non-finite colours.
std::array<openvdb::FloatGrid::Ptr, 3> split_color_grid(const openvdb::Vec3SGrid& grid_in, const std::string& gname,
                                                        const Fail& fail, std::array<float, 3>& lo,
                                                        std::array<float, 3>& hi) {
  const openvdb::Vec3SGrid* grid = &grid_in;
  auto bad = [&](const openvdb::Vec3s& v) {
    for (int c = 0; c < 3; ++c)
      if (!std::isfinite(v[c]) || v[c] < 0.0f) return true;
    return false;
  };
  auto vec_str = [](const openvdb::Vec3s& v) {
    return "(" + value_str(v[0]) + ", " + value_str(v[1]) + ", " + value_str(v[2]) + ")";
  };
  const openvdb::Vec3s bg = grid->background();
  if (bad(bg)) fail("colour grid " + gname + " has background " + vec_str(bg) + "; colours must be finite and >= 0");
  std::array<openvdb::FloatGrid::Ptr, 3> comp;
  lo = {bg[0], bg[1], bg[2]};
  hi = lo;
  try {
    for (int c = 0; c < 3; ++c) {
      comp[c] = openvdb::FloatGrid::create(bg[c]);
      comp[c]->setTransform(grid->transform().copy());
    }
    // Unregistered accessors: a registered one leaves TBB's accessor registry in a state whose
    // teardown UBSan reports (a sentinel bucket pointer downcast in concurrent_hash_map).
    std::array<openvdb::FloatGrid::UnsafeAccessor, 3> acc{comp[0]->getUnsafeAccessor(), comp[1]->getUnsafeAccessor(),
                                                            comp[2]->getUnsafeAccessor()};
    for (auto it = grid->cbeginValueOn(); it; ++it) {
      const openvdb::Vec3s v = *it;
      if (bad(v)) {
        const openvdb::Coord q = it.getCoord();
        fail("colour grid " + gname + ": value " + vec_str(v) + " at " + coord_str(q[0], q[1], q[2]) +
             " is negative or not finite (colours must be finite and >= 0)");
      }
      for (int c = 0; c < 3; ++c) {
        lo[c] = std::min(lo[c], v[c]);
        hi[c] = std::max(hi[c], v[c]);
        if (it.isVoxelValue()) {
          acc[c].setValue(it.getCoord(), v[c]);
        } else {
          comp[c]->fill(it.getBoundingBox(), v[c], true);
        }
      }
    }
  } catch (const Error&) {
    throw;
  } catch (const std::exception& ex) {
    fail("cannot split colour grid " + gname + " into its components: " + ex.what());
  }
  return comp;
}

}  // namespace

// The colour grid: a vec3s OpenVDB grid split into three float grids that keep its transform and
// its background (inactive voxels read the background, as the renderer's lookups do).
std::array<GridData, 3> load_color_grid(const std::string& file, const std::string& grid_name,
                                        const std::string& context) {
  const Fail fail{context, file};
  const std::string ext = lower_extension(file);
  if (ext == ".nvdb") {
    fail("colour grid " + in_quotes(grid_name) + ": colour grids are read from OpenVDB (.vdb) files only; convert "
         "the file with nanovdb_convert or export a .vdb");
  }
  if (ext != ".vdb") fail("unknown volume file extension " + in_quotes(ext) + " (expected .vdb)");
  openvdb::Vec3SGrid::Ptr grid = read_color_grid(file, grid_name, fail);
  const std::string gname = in_quotes(grid_name);
  if (!grid->transform().isLinear()) {
    fail("colour grid " + gname + " has a non-affine (" + grid->transform().mapType() +
         ") transform; only affine index-to-world maps are supported");
  }
  check_file_bbox(*grid, fail);
  std::array<float, 3> lo{}, hi{};
  const std::array<openvdb::FloatGrid::Ptr, 3> comp = split_color_grid(*grid, gname, fail, lo, hi);
  std::array<GridData, 3> out = vec3_components(*grid, comp, grid_name, "colour grid " + gname, fail);
  for (int c = 0; c < 3; ++c) {
    out[size_t(c)].value_min = lo[size_t(c)];  // over active values and the background
    out[size_t(c)].value_max = hi[size_t(c)];
  }
  return out;
}

bool grid_listed(const std::vector<std::string>& listing, const std::string& name) {
  for (const std::string& entry : listing)
    if (entry.substr(0, entry.find(" (")) == name) return true;
  return false;
}

std::vector<std::string> list_grids(const std::string& file) {
  const Fail fail{"", file};
  const std::string ext = lower_extension(file);
  if (ext != ".vdb" && ext != ".nvdb") fail("unknown volume file extension " + in_quotes(ext) + " (expected .vdb or .nvdb)");
  check_readable(file, fail);
  std::vector<Entry> entries;
  try {
    entries = ext == ".vdb" ? vdb_entries(*vdb_open(file, fail)) : nvdb_entries(file, fail);
  } catch (const Error&) {
    throw;
  } catch (const std::exception& ex) {
    fail(std::string("cannot read file (corrupt or truncated?): ") + ex.what());
  }
  std::vector<std::string> out;
  for (const Entry& e : entries) out.push_back(describe(e));
  return out;
}

}  // namespace spectrack
