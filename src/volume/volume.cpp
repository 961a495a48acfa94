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
#include "util/files.h"
#include "volume/vdb_open.h"
#include "volume/vdb_prescan.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cmath>
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

std::string lower_extension(const std::string& file) {
  std::string ext = fs::path(file).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext;
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
    e.is_float = g->isType<openvdb::FloatGrid>();
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

// ---- checks on the NanoVDB tree ---------------------------------------------------------------

// Active bbox, value range and the first bad (negative or non-finite) active value.
struct Scan {
  int lo[3] = {INT_MAX, INT_MAX, INT_MAX}, hi[3] = {INT_MIN, INT_MIN, INT_MIN};
  float vmin = std::numeric_limits<float>::infinity(), vmax = -std::numeric_limits<float>::infinity();
  uint64_t bad_order = UINT64_MAX;  // smallest wins, so the report does not depend on threads
  float bad_value = 0;
  nanovdb::Coord bad_ijk;
  int bad_width = 0;
  uint64_t voxels = 0;  // active voxels, tiles counted by volume

  void add(const nanovdb::Coord& ijk, int width, float v, uint64_t order) {
    voxels += uint64_t(width) * uint64_t(width) * uint64_t(width);
    if (!(v >= 0.0f) || !std::isfinite(v)) {
      if (order < bad_order) { bad_order = order; bad_value = v; bad_ijk = ijk; bad_width = width; }
      return;
    }
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], ijk[a]);
      hi[a] = std::max(hi[a], ijk[a] + (width - 1));
    }
    vmin = std::min(vmin, v);
    vmax = std::max(vmax, v);
  }
  void merge(const Scan& o) {
    voxels += o.voxels;
    for (int a = 0; a < 3; ++a) { lo[a] = std::min(lo[a], o.lo[a]); hi[a] = std::max(hi[a], o.hi[a]); }
    vmin = std::min(vmin, o.vmin);
    vmax = std::max(vmax, o.vmax);
    if (o.bad_order < bad_order) { bad_order = o.bad_order; bad_value = o.bad_value; bad_ijk = o.bad_ijk; bad_width = o.bad_width; }
  }
};

// Walks the tree through child pointers, checking that each lies inside the grid buffer.
Scan scan_tree(const FloatGrid& g, const Fail& fail) {
  const char* begin = reinterpret_cast<const char*>(&g);
  const char* end = begin + g.gridSize();
  auto inside = [&](const void* p, size_t n) {
    const char* c = reinterpret_cast<const char*>(p);
    return c >= begin && c + n <= end;
  };
  // A child is `off` bytes from its parent's data: checked as integers before a pointer is
  // formed (base + a wild offset is undefined behaviour even if never dereferenced; fuzz_nvdb).
  auto child_at = [&](const void* base, int64_t off, size_t n) {
    const int64_t at = int64_t(reinterpret_cast<const char*>(base) - begin), size = int64_t(end - begin);
    if (off < -at || off > size - at - int64_t(n) || (at + off) % NANOVDB_DATA_ALIGNMENT != 0)
      fail("corrupt NanoVDB grid (node pointer outside the grid or misaligned)");
    return begin + (at + off);
  };
  Scan tiles;
  std::vector<const Leaf*> leaves;
  const Root& root = g.tree().root();
  uint64_t order = uint64_t(1) << 62;
  for (uint32_t i = 0; i < root.tileCount(); ++i) {
    const auto* t = root.data()->tile(i);
    if (!t->isChild()) {
      if (t->isActive()) tiles.add(t->origin(), Upper::DIM, t->value, order++);
      continue;
    }
    const Upper* u = reinterpret_cast<const Upper*>(child_at(root.data(), t->child, sizeof(Upper)));
    if (!inside(u, sizeof(Upper))) fail("corrupt NanoVDB grid (node pointer outside the grid)");
    for (uint32_t n = 0; n < Upper::SIZE; ++n) {
      if (!u->data()->isChild(n)) {
        if (u->data()->isActive(n)) tiles.add(u->offsetToGlobalCoord(n), Lower::DIM, u->data()->getValue(n), order++);
        continue;
      }
      const Lower* l = reinterpret_cast<const Lower*>(child_at(u->data(), u->data()->mTable[n].child, sizeof(Lower)));
      if (!inside(l, sizeof(Lower))) fail("corrupt NanoVDB grid (node pointer outside the grid)");
      for (uint32_t m = 0; m < Lower::SIZE; ++m) {
        if (!l->data()->isChild(m)) {
          if (l->data()->isActive(m)) tiles.add(l->offsetToGlobalCoord(m), Leaf::DIM, l->data()->getValue(m), order++);
          continue;
        }
        const Leaf* leaf = reinterpret_cast<const Leaf*>(child_at(l->data(), l->data()->mTable[m].child, sizeof(Leaf)));
        if (!inside(leaf, sizeof(Leaf))) fail("corrupt NanoVDB grid (node pointer outside the grid)");
        leaves.push_back(leaf);
      }
    }
  }
  Scan s = tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, leaves.size(), 64), Scan{},
      [&](const tbb::blocked_range<size_t>& r, Scan acc) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
          const Leaf& leaf = *leaves[i];
          for (auto it = leaf.valueMask().beginOn(); it; ++it) {
            acc.add(leaf.offsetToGlobalCoord(*it), 1, leaf.getValue(*it), uint64_t(i) * Leaf::SIZE + *it);
          }
        }
        return acc;
      },
      [](Scan a, const Scan& b) { a.merge(b); return a; });
  s.merge(tiles);
  return s;
}

// Inactive voxels read 0 on the device and in every bound (volume.h), whatever the file stores
// there: writers leave old values in voxels they deactivate (Houdini's VDB Activate), and a
// stored +inf or 1e30 would otherwise blacken the image or stall every flight. Sets each inactive
// leaf voxel and inactive tile that is not 0 to 0 (-0 stays, so grids without inactive values
// stay bit-identical); node statistics cover active values only and so stay valid; the
// checksum, where the grid has one, is recomputed. Runs after scan_tree checked the pointers.
uint64_t zero_inactive_values(FloatGrid& g) {
  uint64_t changed = 0;
  auto zero = [&](float& v) {
    if (v != 0.0f) { v = 0.0f; ++changed; }  // NaN too
  };
  auto* root = g.tree().root().data();
  for (uint32_t i = 0; i < root->mTableSize; ++i) {
    auto* t = root->tile(i);
    if (!t->isChild()) {
      if (!t->state) zero(t->value);
      continue;
    }
    auto* u = root->getChild(t)->data();
    for (uint32_t n = 0; n < Upper::SIZE; ++n) {
      if (!u->isChild(n)) {
        if (!u->mValueMask.isOn(n)) zero(u->mTable[n].value);
        continue;
      }
      auto* l = u->getChild(n)->data();
      for (uint32_t m = 0; m < Lower::SIZE; ++m) {
        if (!l->isChild(m)) {
          if (!l->mValueMask.isOn(m)) zero(l->mTable[m].value);
          continue;
        }
        auto* leaf = l->getChild(m)->data();
        for (auto it = leaf->mValueMask.beginOff(); it; ++it) zero(leaf->mValues[*it]);
      }
    }
  }
  if (changed > 0 && g.checksum() != nanovdb::GridChecksum::EMPTY)
    nanovdb::updateChecksum(g, nanovdb::GridChecksum(g.checksum()).mode());
  return changed;
}

std::string value_str(float v) {
  std::ostringstream s;
  s.precision(9);
  s << v;
  return s.str();
}

// Fills GridData from a validated NanoVDB float grid: refuses level sets, non-zero
// backgrounds, degenerate maps and negative or non-finite active values.
void finish(GridData& out, const Fail& fail, bool untrusted) {
  const FloatGrid* g = out.handle.grid<float>();
  if (!g) fail("grid " + in_quotes(out.name) + " is not a float grid");
  const std::string gname = in_quotes(out.name);
  if (g->gridClass() == nanovdb::GridClass::LevelSet) {
    fail("grid " + gname + " is a level set (signed distance field), not a fog volume; convert it to a fog "
         "volume (density) grid first");
  }
  const float bg = g->tree().background();
  if (bg != 0.0f) {
    fail("grid " + gname + " has background value " + value_str(bg) +
         "; inactive voxels must read 0 density (background must be 0)");
  }
  const nanovdb::Map& map = g->map();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out.index_to_world[r][c] = map.mMatD[3 * r + c];
    out.index_to_world[r][3] = map.mVecD[r];
  }
  const double(*m)[4] = out.index_to_world;
  const double det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
                     m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                     m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
  bool finite = std::isfinite(det);
  for (int r = 0; r < 3; ++r) for (int c = 0; c < 4; ++c) finite = finite && std::isfinite(m[r][c]);
  if (!finite || std::abs(det) < 1e-300) fail("grid " + gname + " has a singular or non-finite index-to-world transform");

  const Scan s = scan_tree(*g, fail);
  if (untrusted) {
    // Checksum (a full one where the writer stored it) and node pointers.
    const std::string why = nanovdb::GridValidator<float>::check(*g, /*detailed=*/true);
    if (!why.empty()) fail("corrupt NanoVDB grid " + gname + ": " + why);
    // Nodes below the root are outside a partial checksum; the writer's voxel count and bbox
    // catch a flipped mask bit or a moved node, which could otherwise claim a huge bbox.
    const auto& stored = g->tree().root().bbox();
    const bool stored_empty = stored[0][0] > stored[1][0];
    bool same_box = true;
    for (int a = 0; a < 3 && !stored_empty && s.lo[0] <= s.hi[0]; ++a) {
      same_box = same_box && stored[0][a] == s.lo[a] && stored[1][a] == s.hi[a];
    }
    if (s.bad_order == UINT64_MAX && (g->activeVoxelCount() != s.voxels || !same_box)) {
      fail("corrupt NanoVDB grid " + gname + ": its active voxels (" + std::to_string(s.voxels) +
           ") disagree with the count or bounding box stored in the grid (" +
           std::to_string(g->activeVoxelCount()) + ")");
    }
  }
  if (s.bad_order != UINT64_MAX) {
    const nanovdb::Coord& p = s.bad_ijk;
    std::string where = s.bad_width == 1
                            ? "active voxel " + coord_str(p[0], p[1], p[2])
                            : "active tile " + coord_str(p[0], p[1], p[2]) + " .. " +
                                  coord_str(p[0] + s.bad_width - 1, p[1] + s.bad_width - 1, p[2] + s.bad_width - 1);
    const char* what = std::isfinite(s.bad_value) ? "is negative (densities must be >= 0)" : "is not finite";
    fail("grid " + gname + ": value " + value_str(s.bad_value) + " at " + where + " " + what);
  }
  zero_inactive_values(*out.handle.grid<float>());
  out.empty = s.lo[0] > s.hi[0];
  if (out.empty) {
    out.index_min = {0, 0, 0};
    out.index_max = {-1, -1, -1};
    out.value_min = out.value_max = 0;
  } else {
    out.index_min = {s.lo[0], s.lo[1], s.lo[2]};
    out.index_max = {s.hi[0], s.hi[1], s.hi[2]};
    out.value_min = s.vmin;
    out.value_max = s.vmax;
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
      std::cerr << "warning: " << (fail.context.empty() ? "" : fail.context + ": ") << fail.file << ": no grid named "
                << in_quotes(grid_name) << "; using the file's only float grid, which has no name\n";
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
    std::cerr << "warning: " << (fail.context.empty() ? "" : fail.context + ": ") << fail.file << ": "
              << hits.size() << " grids are named " << in_quotes(grid_name)
              << "; using the first (set grid_index to select another, 0-based)\n";
  }
  return *hits[0];
}

void check_entry(const Entry& e, const Fail& fail) {
  if (!e.is_float) {
    fail("grid " + in_quotes(e.name) + " has value type " + e.type + " (class " + e.cls +
         "); only scalar float density grids are supported");
  }
  if (e.level_set) {
    fail("grid " + in_quotes(e.name) + " is a level set (signed distance field), not a fog volume; convert it to a "
         "fog volume (density) grid first");
  }
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
    grid = openvdb::gridPtrCast<openvdb::FloatGrid>(f->readGrid(e.vdb_key));
    f->close();
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
  finish(out, fail, false);
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
  finish(out, fail, true);
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
}  // namespace volume_detail

GridData load_float_grid(const std::string& file, const std::string& grid_name, int grid_index,
                         const std::string& context) {
  const Fail fail{context, file};
  const std::string ext = lower_extension(file);
  if (ext != ".vdb" && ext != ".nvdb") fail("unknown volume file extension " + in_quotes(ext) + " (expected .vdb or .nvdb)");
  check_readable(file, fail);
  return ext == ".vdb" ? load_vdb(file, grid_name, grid_index, fail) : load_nvdb(file, grid_name, grid_index, fail);
}

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
    if (hit->type != "vec3s") {
      fail("colour grid " + in_quotes(grid_name) + " has value type " + hit->type + " (class " + hit->cls +
           "); a colour grid must be a vec3s grid (e.g. Houdini's Cd)");
    }
    check_vdb_tree(file, layout, hit->vdb_key, fail);
    grid = openvdb::gridPtrCast<openvdb::Vec3SGrid>(f->readGrid(hit->vdb_key));
    f->close();
    if (!grid) fail("colour grid " + in_quotes(grid_name) + " could not be read as a vec3s grid");
  } catch (const Error&) {
    throw;
  } catch (const std::exception& ex) {
    fail(std::string("cannot read OpenVDB file (corrupt or truncated?): ") + ex.what());
  }
  const std::string gname = in_quotes(grid_name);
  if (!grid->transform().isLinear()) {
    fail("colour grid " + gname + " has a non-affine (" + grid->transform().mapType() +
         ") transform; only affine index-to-world maps are supported");
  }
  check_file_bbox(*grid, fail);
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
  std::array<float, 3> lo{bg[0], bg[1], bg[2]}, hi = lo;
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
  std::array<GridData, 3> out;
  const openvdb::math::Mat4d mat = grid->transform().baseMap()->getAffineMap()->getMat4();
  const openvdb::CoordBBox box = grid->evalActiveVoxelBoundingBox();
  for (int c = 0; c < 3; ++c) {
    GridData& g = out[size_t(c)];
    g.file = file;
    g.name = grid_name + "." + "xyz"[c];
    try {
      g.handle = nanovdb::openToNanoVDB(*comp[c]);
    } catch (const std::exception& ex) {
      fail("cannot convert colour grid " + gname + " to NanoVDB: " + ex.what());
    }
    g.empty = box.empty();
    if (!g.empty) {
      g.index_min = {box.min()[0], box.min()[1], box.min()[2]};
      g.index_max = {box.max()[0], box.max()[1], box.max()[2]};
    }
    g.value_min = lo[size_t(c)];  // over active values and the background
    g.value_max = hi[size_t(c)];
    for (int r = 0; r < 3; ++r) {
      for (int k = 0; k < 3; ++k) g.index_to_world[r][k] = mat(k, r);
      g.index_to_world[r][3] = mat(3, r);
    }
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
