// majorant_grid.cpp: the sparse majorant/minorant grids of a density grid (volume.h).
//
// Design: the grid follows docs/estimators.md, 'The trilinear-support rule': cell boundaries sit on voxel centres, so a cell of
// B voxels reads the (B+1)^3 voxels of its trilinear support and bounds the interpolated density
// anywhere inside it. The adaptive hierarchy (build_majorant_hierarchy, docs/majorant-hierarchy.md)
// walks each block of fine cells at the level its cost model picks: groups of r^3 cells bounded
// by the max (min) over them.
// sample_index_trilinear is the host reference of the device lookup (kernels/medium.h).
#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <type_traits>
#include <unordered_map>

#include <nanovdb/NanoVDB.h>

#include "volume/volume.h"
#include "volume/volume_detail.h"

namespace spectrack {

using FloatGrid = nanovdb::NanoGrid<float>;
using Leaf = nanovdb::NanoLeaf<float>;

namespace {

// Cells of edge `cell` voxels over the grid's active box plus a voxel of margin on each side.
// The cells of edge `cell` over the active box widened by one voxel and by `margin` (motion blur's
// reach) on each side, as a double (no overflow).
double majorant_cells(const GridData& grid, int cell, const std::array<int, 3>& margin) {
  double n = 1;
  for (int a = 0; a < 3; ++a) {
    const int64_t span = int64_t(grid.index_max[a]) - grid.index_min[a] + 2 + 2 * int64_t(margin[size_t(a)]);
    n *= double(std::max<int64_t>(1, (span + cell - 1) / cell));
  }
  return n;
}

int64_t floor_div(int64_t a, int64_t b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

// Marks the cells whose trilinear support meets the voxel box lo .. hi (inclusive). Cell c's
// support on an axis is origin + c*cell .. origin + (c+1)*cell, so it meets lo .. hi when
// c >= ceil((lo - origin) / cell) - 1 and c <= floor((hi - origin) / cell).
// With a margin of m voxels (build_majorant_grid) the support grows by m on both sides, and so
// does the voxel box it must meet.
void mark_box(const MajorantGrid& mg, const nanovdb::Coord& lo, int width, const std::array<int, 3>& margin,
              std::vector<uint8_t>& marked) {
  int64_t c0[3], c1[3];
  for (int a = 0; a < 3; ++a) {
    const int64_t l = int64_t(lo[a]) - mg.origin[a] - margin[size_t(a)], h = int64_t(lo[a]) - mg.origin[a] + width - 1 + margin[size_t(a)];
    c0[a] = std::max<int64_t>(0, -floor_div(-l, mg.cell) - 1);
    c1[a] = std::min<int64_t>(mg.dims[a] - 1, floor_div(h, mg.cell));
    if (c0[a] > c1[a]) return;
  }
  for (int64_t z = c0[2]; z <= c1[2]; ++z)
    for (int64_t y = c0[1]; y <= c1[1]; ++y)
      for (int64_t x = c0[0]; x <= c1[0]; ++x)
        marked[size_t(x) + size_t(mg.dims[0]) * (size_t(y) + size_t(mg.dims[1]) * size_t(z))] = 1;
}

// The cells whose support holds a leaf or an active tile of the tree. Every other cell reads
// only inactive tiles and the background, which are 0 (the loader zeroes inactive values), so
// its bounds are (0, 0) without a lookup: the build costs what the tree holds, not its bbox.
std::vector<uint8_t> occupied_cells(const FloatGrid& g, const MajorantGrid& mg, const std::array<int, 3>& margin) {
  std::vector<uint8_t> marked(mg.dmax.size(), 0);
  const auto& root = g.tree().root();
  for (uint32_t i = 0; i < root.tileCount(); ++i) {
    const auto* t = root.data()->tile(i);
    if (!t->isChild()) {
      if (t->isActive()) mark_box(mg, t->origin(), nanovdb::NanoUpper<float>::DIM, margin, marked);
      continue;
    }
    const auto* u = root.data()->getChild(t);
    for (uint32_t n = 0; n < nanovdb::NanoUpper<float>::SIZE; ++n) {
      if (!u->data()->isChild(n)) {
        if (u->data()->isActive(n)) mark_box(mg, u->offsetToGlobalCoord(n), nanovdb::NanoLower<float>::DIM, margin, marked);
        continue;
      }
      const auto* l = u->data()->getChild(n);
      for (uint32_t m = 0; m < nanovdb::NanoLower<float>::SIZE; ++m) {
        if (l->data()->isChild(m) || l->data()->isActive(m)) mark_box(mg, l->offsetToGlobalCoord(m), Leaf::DIM, margin, marked);
      }
    }
  }
  return marked;
}

// The largest and smallest value of the voxels lo .. hi (inclusive).
template <typename Accessor>
std::array<float, 2> voxel_bounds(Accessor& acc, const std::array<int, 3>& lo, const std::array<int, 3>& hi) {
  float top = -std::numeric_limits<float>::infinity(), bottom = std::numeric_limits<float>::infinity();
  volume_detail::for_each_box_value(acc, lo, hi, [&](float v) {
    top = std::max(top, v);
    bottom = std::min(bottom, v);
  });
  return {top, bottom};
}

// The largest and smallest trilinear value over the box lo - r .. hi + r (index coordinates; lo, hi
// voxel centres, r >= 0 per axis). The trilinear function is multilinear inside each voxel cube, so
// its extremes over the box lie at the vertices of the box's cuts by the voxel planes: coordinates
// lo - r, the voxels lo - k + 1 .. hi + k - 1 (k = ceil r) and hi + r along each axis. Their values
// are the voxels lo - k .. hi + k with the outermost layer on each side blended towards its
// neighbour, at lo - r = (lo - k) + w with w = k - r: (1 - w) v(lo - k) + w v(lo - k + 1), one axis
// after the other (the blend is linear along each axis, so the order does not matter).
template <typename Accessor>
std::array<float, 2> reach_bounds(Accessor& acc, const std::array<int, 3>& lo, const std::array<int, 3>& hi,
                                  const std::array<double, 3>& r) {
  std::array<int, 3> k{}, n{};
  for (size_t a = 0; a < 3; ++a) k[a] = int(std::ceil(r[a])), n[a] = hi[a] - lo[a] + 1 + 2 * k[a];
  std::vector<double> v(size_t(n[0]) * size_t(n[1]) * size_t(n[2]));
  size_t i = 0;
  for (int z = 0; z < n[2]; ++z)
    for (int y = 0; y < n[1]; ++y)
      for (int x = 0; x < n[0]; ++x) v[i++] = acc.getValue(nanovdb::Coord(lo[0] - k[0] + x, lo[1] - k[1] + y, lo[2] - k[2] + z));
  const std::array<size_t, 3> stride{1, size_t(n[0]), size_t(n[0]) * size_t(n[1])};
  for (size_t a = 0; a < 3; ++a) {
    const double w = double(k[a]) - r[a];
    if (k[a] == 0 || w == 0) continue;
    const size_t last = size_t(n[a] - 1) * stride[a];
    for (size_t j = 0; j < v.size(); ++j) {
      if ((j / stride[a]) % size_t(n[a]) != 0) continue;  // j: the first voxel of a line along a
      v[j] += w * (v[j + stride[a]] - v[j]);
      v[j + last] += w * (v[j + last - stride[a]] - v[j + last]);
    }
  }
  const auto [bottom, top] = std::minmax_element(v.begin(), v.end());
  return {float(*top), float(*bottom)};
}

// The largest and smallest value of every leaf (its 512 voxels; inactive ones read 0), by its
// place in the tree: the bounds of a motion blur's far reach (leaf_reach_bounds).
struct CoordHash {
  size_t operator()(const nanovdb::Coord& c) const {
    return std::hash<uint64_t>()((uint64_t(uint32_t(c[0])) * 0x9E3779B97F4A7C15ull) ^
                                 (uint64_t(uint32_t(c[1])) * 0xC2B2AE3D27D4EB4Full) ^ uint64_t(uint32_t(c[2])));
  }
};
using LeafBounds = std::unordered_map<nanovdb::Coord, std::array<float, 2>, CoordHash>;

// Keyed by each leaf's place in the tree (the root key, then its parents' slots), as a lookup
// finds it: a stored origin is not checked where a node holds no active value (grid_checks.cpp
// scan_tree), so it is never read here. A place met twice (a damaged file) keeps both extremes.
LeafBounds leaf_bounds(const FloatGrid& g) {
  LeafBounds out;
  auto place_of = [](const nanovdb::Coord& origin, uint32_t n, auto* node) {
    using Node = std::remove_const_t<std::remove_pointer_t<decltype(node)>>;
    nanovdb::Coord ijk = Node::OffsetToLocalCoord(n);
    ijk <<= Node::ChildNodeType::TOTAL;
    return ijk + origin;
  };
  const auto& root = g.tree().root();
  for (uint32_t i = 0; i < root.tileCount(); ++i) {
    const auto* t = root.data()->tile(i);
    if (!t->isChild()) continue;
    const auto* u = root.data()->getChild(t);
    for (uint32_t n = 0; n < nanovdb::NanoUpper<float>::SIZE; ++n) {
      if (!u->data()->isChild(n)) continue;
      const auto* l = u->data()->getChild(n);
      const nanovdb::Coord l_place = place_of(t->origin(), n, u);
      for (uint32_t m = 0; m < nanovdb::NanoLower<float>::SIZE; ++m) {
        if (!l->data()->isChild(m)) continue;
        const Leaf* leaf = l->data()->getChild(m);
        const auto [it, added] = out.try_emplace(place_of(l_place, m, l), std::array<float, 2>{
            -std::numeric_limits<float>::infinity(), std::numeric_limits<float>::infinity()});
        std::array<float, 2>& e = it->second;
        for (uint32_t v = 0; v < Leaf::SIZE; ++v) e = {std::max(e[0], leaf->getValue(v)), std::min(e[1], leaf->getValue(v))};
      }
    }
  }
  return out;
}

// A bound of reach_bounds' box at the leaves' resolution: the largest and smallest value of every
// 8^3 leaf-aligned block that meets the voxels lo - k .. hi + k (k = ceil r), a leaf's from
// leaf_bounds, a tile's or the background's read once. It holds every value reach_bounds reads
// (those voxels, and blends of neighbours among them), so it bounds the trilinear density at least
// as widely, at a read per block instead of per voxel: for a reach of many voxels the exact bounds
// would read about (cell + 2 r)^3 voxels per cell.
template <typename Accessor>
std::array<float, 2> leaf_reach_bounds(Accessor& acc, const LeafBounds& leaves, const std::array<int, 3>& lo,
                                       const std::array<int, 3>& hi, const std::array<double, 3>& r) {
  std::array<int64_t, 3> a{}, b{};  // 64-bit: an extent near the int range's end must not wrap
  for (size_t i = 0; i < 3; ++i) {
    const int64_t k = int64_t(std::ceil(r[i]));
    a[i] = (int64_t(lo[i]) - k) & ~int64_t(7), b[i] = int64_t(hi[i]) + k;
  }
  float top = -std::numeric_limits<float>::infinity(), bottom = std::numeric_limits<float>::infinity();
  for (int64_t z = a[2]; z <= b[2]; z += 8)
    for (int64_t y = a[1]; y <= b[1]; y += 8)
      for (int64_t x = a[0]; x <= b[0]; x += 8) {
        const nanovdb::Coord block{int(x), int(y), int(z)};
        const auto it = leaves.find(block);
        const std::array<float, 2> v = it != leaves.end() ? it->second : std::array<float, 2>{acc.getValue(block), acc.getValue(block)};
        top = std::max(top, v[0]);
        bottom = std::min(bottom, v[1]);
      }
  return {top, bottom};
}

}  // namespace

// Refuses a grid whose box (widened by margin) needs more than 2^27 cells of `cell` voxels,
// naming the smallest cell edge that fits, or why none does.
static void check_cell_count(const GridData& grid, int cell, const std::array<int, 3>& margin) {
  const double cells = majorant_cells(grid, cell, margin);
  if (cells <= double(1 << 27)) return;
  // the smallest cell edge, doubling up to the largest, whose grid fits
  int fits = cell;
  while (fits < kMaxMajorantCellEdge && majorant_cells(grid, fits, margin) > double(1 << 27))
    fits = std::min(2 * fits, kMaxMajorantCellEdge);
  const bool moving = margin[0] > 0 || margin[1] > 0 || margin[2] > 0;
  const std::string what = fmt::format(
      "{}: grid \"{}\": its active bounding box ({}, {}, {}) .. ({}, {}, {}){} needs {:.4g} majorant cells of {} "
      "voxels, more than 2^27",
      grid.file, grid.name, grid.index_min[0], grid.index_min[1], grid.index_min[2], grid.index_max[0],
      grid.index_max[1], grid.index_max[2],
      moving ? fmt::format(", widened by the motion blur's reach of ({}, {}, {}) voxels,", margin[0], margin[1], margin[2])
             : std::string(),
      cells, cell);
  if (majorant_cells(grid, fits, margin) <= double(1 << 27))
    throw Error(fmt::format("{}; use --majorant-cell {} or larger", what, fits));
  throw Error(fmt::format("{}, and even the largest cell edge, {} voxels, needs {:.4g}; {}", what, kMaxMajorantCellEdge,
                          majorant_cells(grid, kMaxMajorantCellEdge, margin),
                          moving ? "the velocity moves the medium too far over the shutter (lower the velocity's "
                                   "scale or shorten the shutter)"
                                 : "the active voxels span too wide a box (a stray voxel far from the rest?): prune "
                                   "or crop the grid"));
}

// Each occupied cell (occupied_cells) walks the 8^3 leaf-aligned blocks that meet its support: a
// leaf contributes the voxels inside the support, a block without a leaf (a tile or background)
// its one constant value. The cost is thus about (1 + 1/cell)^3 reads per voxel of allocated
// leaves plus a probe per 8^3 block of active tiles and one byte per cell of the box; the Disney
// cloud (16x11x20 cells) takes a few ms, and a few stray voxels far apart cost a few cells each.
MajorantGrid build_majorant_grid(const GridData& grid, int cell, const std::array<int, 3>& margin,
                                 const CellReach& cell_reach, double exact_read_limit) {
  if (cell < 1) throw Error("build_majorant_grid: cell size must be >= 1, got " + std::to_string(cell));
  for (int m : margin)
    if (m < 0 || m > (1 << 24)) throw Error("build_majorant_grid: margin out of range: " + std::to_string(m));
  MajorantGrid mg;
  mg.cell = cell;
  const FloatGrid* g = grid.handle.grid<float>();
  if (grid.empty || !g) {
    mg.origin = {grid.index_min[0] - 1, grid.index_min[1] - 1, grid.index_min[2] - 1};
    mg.dims = {1, 1, 1};
    mg.dmax.assign(1, 0.0f);
    mg.dmin.assign(1, 0.0f);
    return mg;
  }
  check_cell_count(grid, cell, margin);
  const double cells = majorant_cells(grid, cell, margin);
  for (int a = 0; a < 3; ++a) {
    mg.origin[a] = grid.index_min[a] - 1 - margin[size_t(a)];
    const int64_t span = int64_t(grid.index_max[a]) - grid.index_min[a] + 2 + 2 * int64_t(margin[size_t(a)]);
    mg.dims[a] = int(std::max<int64_t>(1, (span + cell - 1) / cell));
  }
  const size_t n = size_t(cells);
  mg.dmax.assign(n, 0.0f);
  mg.dmin.assign(n, 0.0f);
  const std::vector<uint8_t> occupied = occupied_cells(*g, mg, margin);
  // A far reach (motion blur) bounds each cell by the leaves it meets (leaf_reach_bounds) where
  // its voxels would be more than exact_read_limit reads; a still medium reads its voxels
  double exact_reads = double(std::count(occupied.begin(), occupied.end(), uint8_t(1)));
  for (size_t a = 0; a < 3; ++a) exact_reads *= cell + 2.0 * margin[a] + 1;
  const bool by_leaf = (margin[0] > 0 || margin[1] > 0 || margin[2] > 0) && exact_reads > exact_read_limit;
  const LeafBounds leaves = by_leaf ? leaf_bounds(*g) : LeafBounds();
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 1024), [&](const tbb::blocked_range<size_t>& r) {
    auto acc = g->getAccessor();
    for (size_t idx = r.begin(); idx != r.end(); ++idx) {
      if (!occupied[idx]) continue;  // (0, 0), as assigned
      const std::array<int, 3> c{int(idx % size_t(mg.dims[0])), int((idx / size_t(mg.dims[0])) % size_t(mg.dims[1])),
                                 int(idx / (size_t(mg.dims[0]) * size_t(mg.dims[1])))};
      std::array<int, 3> lo{}, hi{};
      for (size_t a = 0; a < 3; ++a) lo[a] = mg.origin[a] + c[a] * cell, hi[a] = lo[a] + cell;
      std::array<float, 2> b;
      if (cell_reach || by_leaf) {
        std::array<double, 3> r{double(margin[0]), double(margin[1]), double(margin[2])};
        if (cell_reach) r = cell_reach(lo, hi);
        for (size_t a = 0; a < 3; ++a) r[a] = std::clamp(r[a], 0.0, double(margin[a]));
        b = by_leaf ? leaf_reach_bounds(acc, leaves, lo, hi, r) : reach_bounds(acc, lo, hi, r);
      } else {
        for (size_t a = 0; a < 3; ++a) lo[a] -= margin[a], hi[a] += margin[a];
        b = voxel_bounds(acc, lo, hi);
      }
      // Float rounding of the interpolation can exceed the corner values by a few ulps.
      float top = b[0] * (1.0f + 1e-5f);
      if (top > 0.0f) top += 1e-30f;
      mg.dmax[idx] = top;
      mg.dmin[idx] = b[1] * (1.0f - 1e-5f);
    }
  });
  return mg;
}

float sample_index_trilinear(const GridData& grid, double x, double y, double z) {
  const FloatGrid* g = grid.handle.grid<float>();
  if (!g) return 0.0f;
  auto acc = g->getAccessor();
  const double fx = std::floor(x), fy = std::floor(y), fz = std::floor(z);
  const double tx = x - fx, ty = y - fy, tz = z - fz;
  const int ix = int(fx), iy = int(fy), iz = int(fz);
  double c[2][2][2];
  for (int k = 0; k < 2; ++k)
    for (int j = 0; j < 2; ++j)
      for (int i = 0; i < 2; ++i) c[k][j][i] = acc.getValue(nanovdb::Coord(ix + i, iy + j, iz + k));
  double e[2][2];
  for (int k = 0; k < 2; ++k)
    for (int j = 0; j < 2; ++j) e[k][j] = c[k][j][0] + tx * (c[k][j][1] - c[k][j][0]);
  const double f0 = e[0][0] + ty * (e[0][1] - e[0][0]);
  const double f1 = e[1][0] + ty * (e[1][1] - e[1][0]);
  return float(f0 + tz * (f1 - f0));
}

MajorantGrid coarsen_majorant_grid(const MajorantGrid& fine, int block) {
  if (block < 1) throw Error("majorant block must be at least 1 cell");
  MajorantGrid c;
  c.origin = fine.origin;
  c.cell = fine.cell * block;
  for (int a = 0; a < 3; ++a) c.dims[a] = (fine.dims[a] + block - 1) / block;
  size_t n = size_t(c.dims[0]) * c.dims[1] * c.dims[2];
  c.dmax.assign(n, 0.0f);
  c.dmin.assign(n, std::numeric_limits<float>::infinity());
  for (int k = 0; k < fine.dims[2]; ++k)
    for (int j = 0; j < fine.dims[1]; ++j)
      for (int i = 0; i < fine.dims[0]; ++i) {
        size_t f = size_t(i) + size_t(fine.dims[0]) * (size_t(j) + size_t(fine.dims[1]) * k);
        size_t b = size_t(i / block) + size_t(c.dims[0]) * (size_t(j / block) + size_t(c.dims[1]) * (k / block));
        c.dmax[b] = std::max(c.dmax[b], fine.dmax[f]);
        c.dmin[b] = std::min(c.dmin[b], fine.dmin[f]);
      }
  return c;
}

namespace {

// The entry of a block walked in groups of edge r with bounds `groups` (x fastest; one group:
// the block whole), whose groups a refined block appends to the pool.
st_maj_block block_entry(MajorantHierarchy& h, int r, const std::vector<std::array<float, 2>>& groups) {
  st_maj_block e{0.0f, std::numeric_limits<float>::infinity(), r, 0u};
  for (const auto& v : groups) {
    e.dmax = std::max(e.dmax, v[0]);
    e.dmin = std::min(e.dmin, v[1]);
  }
  if (r == h.block) {
    ++(e.dmax > 0.0f ? h.blocks_whole : h.blocks_empty);
    return e;
  }
  ++h.blocks_refined;
  const size_t offset = h.pool.size() / 2;
  if (offset > 0xffffffffu) throw Error("majorant hierarchy: more than 2^32 groups");
  e.pool = uint32_t(offset);
  for (const auto& v : groups) {
    h.pool.push_back(v[0]);
    h.pool.push_back(v[1]);
  }
  return e;
}

}  // namespace

MajorantHierarchy build_majorant_hierarchy(const MajorantGrid& fine, int block, const MajorantCostModel& cost) {
  if (block < 2) throw Error("majorant hierarchy: blocks must be at least 2 cells per edge, got " + std::to_string(block));
  MajorantHierarchy h;
  h.block = block;
  for (int a = 0; a < 3; ++a) h.block_dims[a] = (fine.dims[a] + block - 1) / block;
  // the levels: group edges r = 1, 2, 4, .. dividing the block edge, and the block itself
  std::vector<int> levels;
  for (int r = 1; r < block; r *= 2)
    if (block % r == 0) levels.push_back(r);
  levels.push_back(block);
  h.blocks_per_level.assign(levels.size(), 0);
  const size_t nb = size_t(h.block_dims[0]) * h.block_dims[1] * h.block_dims[2];
  h.blocks.resize(nb);
  auto residual = [&](float dmax, float dmin) { return std::max(0.0, double(dmax) - (cost.decompose ? dmin : 0.0f)); };
  auto at = [&](int i, int j, int k) { return size_t(i) + size_t(fine.dims[0]) * (size_t(j) + size_t(fine.dims[1]) * k); };
  std::vector<std::vector<std::array<float, 2>>> groups(levels.size());
  for (size_t b = 0; b < nb; ++b) {
    const int bx = int(b % size_t(h.block_dims[0])), by = int((b / size_t(h.block_dims[0])) % size_t(h.block_dims[1]));
    const int bz = int(b / (size_t(h.block_dims[0]) * size_t(h.block_dims[1])));
    const int x0 = bx * block, y0 = by * block, z0 = bz * block;
    // each level's group bounds (groups past the grid's far faces: (0, 0), never walked) and cost
    size_t best = levels.size() - 1;
    double best_cost = std::numeric_limits<double>::infinity();
    for (size_t L = levels.size(); L-- > 0;) {
      const int r = levels[L], n = block / r;
      auto& g = groups[L];
      g.assign(size_t(n) * n * n, {0.0f, 0.0f});
      double sum = 0.0;
      int walked = 0, nonempty = 0;
      for (int gz = 0; gz < n; ++gz)
        for (int gy = 0; gy < n; ++gy)
          for (int gx = 0; gx < n; ++gx) {
            const int i0 = x0 + gx * r, j0 = y0 + gy * r, k0 = z0 + gz * r;
            if (i0 >= fine.dims[0] || j0 >= fine.dims[1] || k0 >= fine.dims[2]) continue;
            float hi = 0.0f, lo = std::numeric_limits<float>::infinity();
            for (int k = k0; k < std::min(k0 + r, fine.dims[2]); ++k)
              for (int j = j0; j < std::min(j0 + r, fine.dims[1]); ++j)
                for (int i = i0; i < std::min(i0 + r, fine.dims[0]); ++i) {
                  hi = std::max(hi, fine.dmax[at(i, j, k)]);
                  lo = std::min(lo, fine.dmin[at(i, j, k)]);
                }
            g[size_t(gx) + size_t(n) * (size_t(gy) + size_t(n) * gz)] = {hi, lo};
            sum += residual(hi, lo);
            ++walked;
            nonempty += hi > 0.0f;
          }
      // per unit length of ray: DDA steps (into empty groups: a quarter of the cost, no flight)
      // plus density lookups
      const double f = walked ? double(nonempty) / walked : 0.0;
      const double c = cost.step_cost * 1.5 / (double(r) * fine.cell) * (f + 0.25 * (1.0 - f)) +
                       cost.lookups_per_density * sum / std::max(walked, 1);
      if (c < best_cost * (1.0 - 1e-9)) {  // ties: the coarser level
        best_cost = c;
        best = L;
      }
    }
    ++h.blocks_per_level[best];
    h.blocks[b] = block_entry(h, levels[best], groups[best]);
  }
  for (size_t L = 0; L < levels.size(); ++L) h.levels.push_back(levels[L]);
  return h;
}

std::array<float, 2> majorant_hierarchy_bounds(const MajorantHierarchy& h, int i, int j, int k) {
  const int B = h.block;
  const size_t b = size_t(i / B) + size_t(h.block_dims[0]) * (size_t(j / B) + size_t(h.block_dims[1]) * (k / B));
  const st_maj_block& e = h.blocks.at(b);
  if (e.group == B) return {e.dmax, e.dmin};
  if (e.group < 1 || e.group > B || B % e.group != 0)
    throw Error(fmt::format("majorant hierarchy: block {} has group edge {}, which does not divide {}", b, e.group, B));
  const int r = e.group, n = B / r;
  const size_t g = size_t(e.pool) + size_t((i % B) / r) + size_t(n) * (size_t((j % B) / r) + size_t(n) * ((k % B) / r));
  if (2 * (size_t(e.pool) + size_t(n) * n * n) > h.pool.size())
    throw Error(fmt::format("majorant hierarchy: block {}'s groups at {} lie past the pool's {} groups", b, e.pool,
                            h.pool.size() / 2));
  return {h.pool[2 * g], h.pool[2 * g + 1]};
}

void append_majorant_blocks(std::vector<float>& words, const std::vector<st_maj_block>& blocks) {
  static_assert(sizeof(st_maj_block) == 4 * sizeof(float), "an entry is four words of the majorant buffer");
  const size_t at = words.size();
  words.resize(at + 4 * blocks.size());
  if (!blocks.empty()) std::memcpy(words.data() + at, blocks.data(), blocks.size() * sizeof(st_maj_block));
}

st_maj_block packed_majorant_block(const std::vector<float>& words, size_t offset, size_t b) {
  const size_t at = 2 * offset + 4 * b;
  if (at + 4 > words.size())
    throw Error(fmt::format("majorant buffer: block entry {} at pair {} lies past its {} words", b, offset, words.size()));
  st_maj_block e;
  std::memcpy(&e, words.data() + at, sizeof e);
  return e;
}

}  // namespace spectrack
