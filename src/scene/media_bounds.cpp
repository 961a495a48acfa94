// media_bounds.cpp: see media_bounds.h. The medium transform is composed as in scene_pack.cpp
// (T * Rz * Ry * Rx * S applied to the grid's world point).
#include "scene/media_bounds.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace spectrack {

Vec3 medium_index_to_world(const MediumDesc& md, const GridData& g, const Vec3& p) {
  Vec3 w;
  for (int r = 0; r < 3; ++r)
    w[r] = g.index_to_world[r][0] * p[0] + g.index_to_world[r][1] * p[1] + g.index_to_world[r][2] * p[2] + g.index_to_world[r][3];
  const TransformDesc& t = md.transform;
  for (int a = 0; a < 3; ++a) w[a] *= t.scale[a];
  const double k = M_PI / 180.0;
  auto rot = [&](int i, int j, double deg) {  // rotation in the (i, j) plane
    const double c = std::cos(deg * k), s = std::sin(deg * k);
    const double a = w[i], b = w[j];
    w[i] = c * a - s * b;
    w[j] = s * a + c * b;
  };
  rot(1, 2, t.rotate_deg[0]);  // about x
  rot(2, 0, t.rotate_deg[1]);  // about y
  rot(0, 1, t.rotate_deg[2]);  // about z
  for (int a = 0; a < 3; ++a) w[a] += t.translate[a];
  return w;
}

Box3 medium_world_box(const MediumDesc& md, const GridData& g) {
  Box3 b;
  if (g.empty) {
    b.lo = b.hi = medium_index_to_world(md, g, {0, 0, 0});
    return b;
  }
  for (int a = 0; a < 3; ++a) b.lo[a] = std::numeric_limits<double>::infinity(), b.hi[a] = -b.lo[a];
  for (int c = 0; c < 8; ++c) {
    const Vec3 p{double((c & 1) ? g.index_max[0] + 1 : g.index_min[0] - 1), double((c & 2) ? g.index_max[1] + 1 : g.index_min[1] - 1),
                 double((c & 4) ? g.index_max[2] + 1 : g.index_min[2] - 1)};
    const Vec3 w = medium_index_to_world(md, g, p);
    for (int a = 0; a < 3; ++a) b.lo[a] = std::min(b.lo[a], w[a]), b.hi[a] = std::max(b.hi[a], w[a]);
  }
  return b;
}

std::vector<Box3> media_world_boxes(const SceneDesc& scene) {
  std::vector<Box3> out;
  for (const MediumDesc& md : scene.media) {
    if (md.type == ST_MEDIUM_HOMOGENEOUS) {
      out.push_back(Box3{md.bounds[0], md.bounds[1]});
    } else {
      out.push_back(medium_world_box(md, load_float_grid(md.file, md.grid, md.grid_index, scene.path + ": " + md.json_path)));
    }
  }
  return out;
}

}  // namespace spectrack
