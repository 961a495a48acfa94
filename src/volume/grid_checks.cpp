// grid_checks.cpp: the checks every loaded grid passes, on its NanoVDB tree (volume_detail.h
// finish_grid): node pointers and statistics, the active bbox, the value range and the first
// negative or non-finite active value (one parallel scan, reported independently of the
// threads), inactive values set to 0, and the refusals of level sets, non-zero backgrounds and
// degenerate maps. .vdb and .nvdb files go through the same checks and messages.
#include "volume/volume.h"
#include "volume/volume_detail.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstring>
#include <iostream>
#include <limits>
#include <sstream>

#include <nanovdb/NanoVDB.h>
#include <nanovdb/util/GridChecksum.h>
#include <nanovdb/util/GridValidator.h>

namespace spectrack {
namespace volume_detail {
namespace {

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

// The origin of child n of an internal node at `origin` (NanoVDB's offsetToGlobalCoord, from the
// place in the tree instead of the stored origin).
template <typename Node>
nanovdb::Coord child_origin(const nanovdb::Coord& origin, uint32_t n) {
  nanovdb::Coord ijk = Node::OffsetToLocalCoord(n);
  ijk <<= Node::ChildNodeType::TOTAL;
  return ijk + origin;
}

[[noreturn]] void misplaced_node(const nanovdb::Coord& stored, const nanovdb::Coord& place, const Fail& fail) {
  fail("corrupt NanoVDB grid (a node stores the origin " + coord_str(stored[0], stored[1], stored[2]) + " but sits at " +
       coord_str(place[0], place[1], place[2]) + " in the tree)");
}

// Walks the tree through child pointers, checking that each lies inside the grid buffer and that
// each node holding active values stores as its origin its place in the tree (the root's key,
// then the slots of its parents). A lookup finds a voxel through those slots, while this scan,
// the majorant grid's occupancy and the renderer's bounds read positions from the stored origins
// (NanoVDB 32.4 keeps an internal node's origin in its active box, which a node without active
// values leaves empty: those are not checked and never read). A file whose origins disagree with
// the slots (a flipped byte that a partial or absent checksum does not cover) would render voxels
// where every bound reads 0 (fuzz_nvdb found one: a majorant of 0 under a density of 1.05).
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
  auto check_origin = [&](const nanovdb::Coord& stored, const nanovdb::Coord& place) {
    if (stored != place) misplaced_node(stored, place, fail);
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
    const nanovdb::Coord u_place = t->origin();
    bool u_active = false;
    for (uint32_t n = 0; n < Upper::SIZE; ++n) {
      if (!u->data()->isChild(n)) {
        if (u->data()->isActive(n)) {
          check_origin(u->origin(), u_place);
          u_active = true;
          tiles.add(u->offsetToGlobalCoord(n), Lower::DIM, u->data()->getValue(n), order++);
        }
        continue;
      }
      const Lower* l = reinterpret_cast<const Lower*>(child_at(u->data(), u->data()->mTable[n].child, sizeof(Lower)));
      if (!inside(l, sizeof(Lower))) fail("corrupt NanoVDB grid (node pointer outside the grid)");
      const nanovdb::Coord l_place = child_origin<Upper>(u_place, n);
      bool l_active = false;
      for (uint32_t m = 0; m < Lower::SIZE; ++m) {
        if (!l->data()->isChild(m)) {
          if (l->data()->isActive(m)) {
            check_origin(l->origin(), l_place);
            l_active = true;
            tiles.add(l->offsetToGlobalCoord(m), Leaf::DIM, l->data()->getValue(m), order++);
          }
          continue;
        }
        const Leaf* leaf = reinterpret_cast<const Leaf*>(child_at(l->data(), l->data()->mTable[m].child, sizeof(Leaf)));
        if (!inside(leaf, sizeof(Leaf))) fail("corrupt NanoVDB grid (node pointer outside the grid)");
        if (leaf->valueMask().isOff()) continue;  // no active voxel: nothing of it is read
        check_origin(leaf->origin(), child_origin<Lower>(l_place, m));
        l_active = true;
        leaves.push_back(leaf);
      }
      if (l_active) check_origin(l->origin(), l_place), u_active = true;
    }
    if (u_active) check_origin(u->origin(), u_place);
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

}  // namespace

std::string value_str(float v) {
  std::ostringstream s;
  s.precision(9);
  s << v;
  return s.str();
}

// Fills GridData from a validated NanoVDB float grid: refuses level sets, non-zero
// backgrounds, degenerate maps and negative or non-finite active values.
void finish_grid(GridData& out, const Fail& fail, bool untrusted) {
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

}  // namespace volume_detail
}  // namespace spectrack
