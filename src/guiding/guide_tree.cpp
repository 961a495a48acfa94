// guide_tree.cpp: the guide cache's regions refined by record counts (guide_cache.h).
//
// Design: every cell of the cache's grid is the root of a kd-tree; its leaves are the regions.
// After a training pass, the radiance records (one per scatter vertex of every depth: where the
// paths are) are binned into the leaves; a leaf with more than the threshold splits at the median
// of its records' positions along the axis where they spread most, so each half holds at least
// half of them and the regions follow the density of scatter vertices, and the halves split again
// while they hold more. The most crowded leaf splits first (ties: the lower node index), so when
// the memory bound stops refinement the regions it left whole are the least crowded. Record counts
// and medians are functions of the set of records, not of the order the device appended them in,
// so the tree, like the fit, depends only on the scene, the settings and the seed. The tree is
// kept from pass to pass: later passes (more samples) refine it further. The left half keeps its
// parent's region index, the right half takes a new one.
#include <algorithm>
#include <array>
#include <vector>

#include "guiding/guide_cache.h"

namespace spectrack {
namespace {

using Point = std::array<float, 3>;

uint32_t leaf_of(const GuideCache& c, const Point& p) {
  const int cell = guide_cell_index(&c.header, p[0], p[1], p[2]);
  return guide_tree_leaf(c.nodes.data(), uint32_t(cell), p[0], p[1], p[2]);
}

// Whether p lies outside the grid's box by more than a thousandth of a cell (the vertices' rounding).
bool outside_grid(const GuideCache& c, const Point& p) {
  const st_guide_header& h = c.header;
  const float o[3] = {h.origin.x, h.origin.y, h.origin.z}, inv[3] = {h.inv_cell.x, h.inv_cell.y, h.inv_cell.z};
  for (int a = 0; a < 3; ++a) {
    const float u = (p[a] - o[a]) * inv[a];
    if (!(u >= -1e-3f && u <= float(h.dims[a]) + 1e-3f)) return true;
  }
  return false;
}

struct Leaf {
  uint32_t node;
  std::vector<uint32_t> points;  // indices of the records' positions it holds
};

// The heap's order: the most points on top, ties the lower node index.
bool less_crowded(const Leaf& a, const Leaf& b) {
  return a.points.size() != b.points.size() ? a.points.size() < b.points.size() : a.node > b.node;
}

// Splits `leaf` (above) into two new leaves; false where it cannot (the depth bound, or its points
// do not spread, or all but one share the lowest coordinate).
bool split_leaf(GuideCache& c, const std::vector<Point>& pts, const Leaf& leaf, Leaf& lo, Leaf& hi) {
  const int depth = c.node_depth[leaf.node];
  if (depth + 1 > ST_GUIDE_MAX_DEPTH) return false;
  Point a = pts[leaf.points[0]], b = a;
  for (uint32_t i : leaf.points)
    for (int k = 0; k < 3; ++k) a[k] = std::min(a[k], pts[i][k]), b[k] = std::max(b[k], pts[i][k]);
  int axis = 0;
  for (int k = 1; k < 3; ++k)
    if (b[k] - a[k] > b[axis] - a[axis]) axis = k;
  if (!(b[axis] > a[axis])) return false;
  std::vector<float> v;
  for (uint32_t i : leaf.points) v.push_back(pts[i][axis]);
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  const float split = v[v.size() / 2];
  lo.points.clear(), hi.points.clear();
  for (uint32_t i : leaf.points) (pts[i][axis] < split ? lo : hi).points.push_back(i);
  if (lo.points.empty()) return false;
  const uint32_t first = uint32_t(c.nodes.size());
  const uint32_t region = c.nodes[leaf.node].next & ~ST_GUIDE_LEAF;
  c.nodes.push_back(st_guide_node{0.0f, ST_GUIDE_LEAF | region});
  c.nodes.push_back(st_guide_node{0.0f, ST_GUIDE_LEAF | uint32_t(c.regions.size())});
  c.regions.push_back(st_guide_region{});
  c.node_depth.push_back(depth + 1);
  c.node_depth.push_back(depth + 1);
  c.nodes[leaf.node] = st_guide_node{split, (first << 2) | uint32_t(axis)};
  c.header.depth = std::max(c.header.depth, depth + 1);
  lo.node = first, hi.node = first + 1;
  return true;
}

}  // namespace

int guide_region_of(const GuideCache& c, float x, float y, float z) {
  return int(c.nodes[leaf_of(c, Point{x, y, z})].next & ~ST_GUIDE_LEAF);
}

size_t refine_guide_regions(GuideCache& c, const std::vector<st_guide_record>& records, size_t split_above,
                            size_t max_regions) {
  std::vector<Point> pts;
  for (const st_guide_record& r : records)
    if (r.key[3] != ST_GUIDE_RECORD_END && (r.key[3] & ST_GUIDE_RECORD_RADIANCE)) pts.push_back(Point{r.pos.x, r.pos.y, r.pos.z});
  c.records_outside = size_t(std::count_if(pts.begin(), pts.end(), [&](const Point& p) { return outside_grid(c, p); }));
  std::vector<std::vector<uint32_t>> by_leaf(c.nodes.size());  // per node (leaves only), in node order
  for (uint32_t i = 0; i < pts.size(); ++i) by_leaf[leaf_of(c, pts[i])].push_back(i);
  std::vector<Leaf> heap;
  for (uint32_t node = 0; node < by_leaf.size(); ++node)
    if (by_leaf[node].size() > split_above) heap.push_back(Leaf{node, std::move(by_leaf[node])});
  std::make_heap(heap.begin(), heap.end(), less_crowded);
  const size_t before = c.regions.size();
  while (!heap.empty() && c.regions.size() < max_regions) {
    std::pop_heap(heap.begin(), heap.end(), less_crowded);
    const Leaf leaf = std::move(heap.back());
    heap.pop_back();
    Leaf lo, hi;
    if (!split_leaf(c, pts, leaf, lo, hi)) continue;
    for (Leaf* half : {&lo, &hi}) {
      if (half->points.size() <= split_above) continue;
      heap.push_back(std::move(*half));
      std::push_heap(heap.begin(), heap.end(), less_crowded);
    }
  }
  return c.regions.size() - before;
}

}  // namespace spectrack
