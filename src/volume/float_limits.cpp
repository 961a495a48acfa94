// float_limits.cpp: see float_limits.h.
#include "volume/float_limits.h"

#include <algorithm>
#include <array>
#include <cfloat>
#include <cmath>

#include <fmt/format.h>
#include <nanovdb/NanoVDB.h>

namespace spectrack {
namespace {


// " at voxel (i, j, k)" of an active voxel holding the grid's largest value ("" when that value
// sits in a tile). Walks the leaves; only called to word a refusal.
std::string where_max(const GridData& g) {
  const nanovdb::NanoGrid<float>* grid = g.handle.grid<float>();
  if (!grid) return "";
  const auto& tree = grid->tree();
  const auto* leaves = tree.getFirstLeaf();
  for (uint32_t n = 0; n < tree.nodeCount(0); ++n) {
    const auto& leaf = leaves[n];
    for (auto it = leaf.valueMask().beginOn(); it; ++it) {
      if (leaf.getValue(*it) == g.value_max) {
        const nanovdb::Coord p = leaf.offsetToGlobalCoord(*it);
        return fmt::format(" at voxel ({}, {}, {})", p[0], p[1], p[2]);
      }
    }
  }
  return " in an active tile";
}

void check_coefficient(const std::string& context, const char* field, const Vec3& v, double density_scale,
                       const st_float4& packed) {
  const float p[3] = {packed.x, packed.y, packed.z};
  for (int c = 0; c < 3; ++c) {
    if (std::isfinite(p[c])) continue;
    if (!(std::abs(v[c]) <= FLT_MAX))
      throw Error(fmt::format("{}/{}: {:g} is beyond the largest float ({:g}); the kernels compute in float", context,
                              field, v[c], FLT_MAX));
    throw Error(fmt::format("{}/{}: {:g} times density_scale {:g} is {:g}, beyond the largest float ({:g}); the "
                            "kernels compute in float",
                            context, field, v[c], density_scale, v[c] * density_scale, FLT_MAX));
  }
}

// A homogeneous box has a tight majorant (no null collisions to pay for), so its size is no
// limit: the walker advances t exactly whatever the flight length (kernels/walker.h). What a
// float cannot do is move a scattering point by less than the spacing of its coordinates: a mean
// free path below the float spacing of world coordinates everywhere in the box (at its point
// nearest the origin, where they are finest) leaves paths scattering in place.
void check_homogeneous(const MediumDesc& md, double mu, const std::string& context) {
  if (mu > kMaxExtinction)
    throw Error(fmt::format("{}: extinction up to {:g} per unit length (sigma_a + sigma_s times density_scale) is "
                            "beyond 2^60 (about 1.2e18), where the products of two coefficients in the float kernels "
                            "overflow; lower density_scale, sigma_a or sigma_s",
                            context, mu));
  double nearest = 0;  // max-norm of the box's point nearest the origin
  for (int a = 0; a < 3; ++a) {
    const double lo = md.bounds[0][a], hi = md.bounds[1][a];
    nearest = std::max(nearest, (lo <= 0 && hi >= 0) ? 0.0 : std::min(std::abs(lo), std::abs(hi)));
  }
  const double spacing = std::ldexp(nearest, -23);  // float spacing of coordinates of that size (upper bound)
  if (mu * spacing <= 1.0) return;
  throw Error(fmt::format("{}: extinction up to {:g} per unit length gives a mean free path of {:g}, shorter than "
                          "the float spacing {:g} of world coordinates anywhere in the box (its nearest point to the "
                          "origin is {:g} away): scattering points could not move; lower density_scale, sigma_a or "
                          "sigma_s, or place the medium nearer the origin",
                          context, mu, 1.0 / mu, spacing, nearest));
}

}  // namespace

// World-space edges of one index-space unit: the column norms of index -> world, the inverse of
// the packed world -> index rows.
static std::array<double, 3> voxel_edges(const st_medium& m) {
  double a[3][3];
  for (int r = 0; r < 3; ++r) {
    a[r][0] = m.world_to_index[r].x;
    a[r][1] = m.world_to_index[r].y;
    a[r][2] = m.world_to_index[r].z;
  }
  const double det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) -
                     a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
                     a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
  double inv[3][3];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      // cofactor of a[c][r] over det (adjugate: transposed cofactors)
      const int r1 = (c + 1) % 3, r2 = (c + 2) % 3, c1 = (r + 1) % 3, c2 = (r + 2) % 3;
      inv[r][c] = (a[r1][c1] * a[r2][c2] - a[r1][c2] * a[r2][c1]) / det;
    }
  std::array<double, 3> edge{};
  for (int c = 0; c < 3; ++c)
    edge[size_t(c)] = std::sqrt(inv[0][c] * inv[0][c] + inv[1][c] * inv[1][c] + inv[2][c] * inv[2][c]);
  return edge;
}

double longest_voxel_edge(const st_medium& m) {
  const std::array<double, 3> e = voxel_edges(m);
  return std::max({e[0], e[1], e[2]});
}

double shortest_voxel_edge(const st_medium& m) {
  const std::array<double, 3> e = voxel_edges(m);
  return std::min({e[0], e[1], e[2]});
}

void check_float_limits(const MediumDesc& md, const st_medium& packed, const GridData* grid,
                        const std::string& context) {
  check_coefficient(context, "sigma_a", md.sigma_a, md.density_scale, packed.sigma_a);
  check_coefficient(context, "sigma_s", md.sigma_s, md.density_scale, packed.sigma_s);
  if (!(md.majorant_scale >= kMinMajorantScale))
    throw Error(fmt::format("{}/majorant_scale: {:g} is below 2^-24 (about 6e-8): the majorant s x mu is then less "
                            "than half the float spacing of mu, so mu - s x mu rounds to mu and tentative collisions "
                            "become too rare for any practical sample count to see the medium",
                            context, md.majorant_scale));
  const double sigma_t = std::max({double(packed.sigma_a.x) + packed.sigma_s.x, double(packed.sigma_a.y) + packed.sigma_s.y,
                                   double(packed.sigma_a.z) + packed.sigma_s.z});
  const double density = grid ? (grid->empty ? 0.0 : double(grid->value_max)) : 1.0;
  const double mu = sigma_t * density * std::max({1.0, md.majorant_scale, md.minorant_scale});
  if (!grid) {
    check_homogeneous(md, mu, context);
    return;
  }
  const double edge = longest_voxel_edge(packed);
  const double depth = mu * edge;
  if (mu <= kMaxExtinction && depth <= kMaxOpticalDepthPerVoxel) return;
  const std::string at = grid ? where_max(*grid) : "";
  const std::string what =
      fmt::format("{}: extinction up to {:g} per unit length (sigma_a + sigma_s up to {:g} per unit density, "
                  "times density_scale {:g}, times the largest density {:g}{})",
                  context, mu, sigma_t / md.density_scale, md.density_scale, density, at);
  if (mu > kMaxExtinction)
    throw Error(fmt::format("{} is beyond 2^60 (about 1.2e18), where the products of two coefficients in the float "
                            "kernels overflow; lower density_scale, sigma_a or sigma_s{}",
                            what, grid ? ", or fix the voxel" : ""));
  throw Error(fmt::format("{} gives an optical depth of {:g} across one {} ({:g} world units), beyond 2^24 "
                          "(16777216): float tracking cannot resolve free flights that short in a segment that long, "
                          "and each walk across it would take more than 2^24 tentative collisions; lower "
                          "density_scale, sigma_a or sigma_s{}",
                          what, depth, grid ? "voxel" : "box of the medium", edge, grid ? ", or fix the voxel" : ""));
}

int majorant_cell_for(const st_medium& packed, const GridData& grid, double majorant_scale, int requested) {
  if (grid.empty || requested <= 1) return requested;
  const double sigma_t = std::max({double(packed.sigma_a.x) + packed.sigma_s.x, double(packed.sigma_a.y) + packed.sigma_s.y,
                                   double(packed.sigma_a.z) + packed.sigma_s.z});
  const double depth_per_voxel = sigma_t * grid.value_max * std::max(1.0, majorant_scale) * longest_voxel_edge(packed);
  auto cells = [&](int c) {
    double n = 1;
    for (int a = 0; a < 3; ++a) n *= double((grid.index_max[a] - grid.index_min[a] + 2) / c + 2);
    return n;
  };
  int cell = requested;
  while (cell > 1 && depth_per_voxel * cell > kMaxOpticalDepthPerCell && cells(cell / 2) <= kMaxMajorantCells) cell /= 2;
  return cell;
}

int auto_majorant_cell(const GridData& grid) {
  auto cells = [&](int c) {
    double n = 1;
    for (int a = 0; a < 3; ++a) n *= double((int64_t(grid.index_max[a]) - grid.index_min[a] + 2) / c + 1);
    return n;
  };
  int cell = 2;
  while (cell < kMaxMajorantCellEdge && cells(cell) > kAutoMajorantCells) cell *= 2;
  return cell;
}


namespace {

double max_norm(const Vec3& v) { return std::max({std::abs(v[0]), std::abs(v[1]), std::abs(v[2])}); }
double box_max_norm(const Box3& b) { return std::max(max_norm(b.lo), max_norm(b.hi)); }

// The field of a medium that places and sizes its box: the bounds of a homogeneous box; for a VDB
// medium the translate when it alone is beyond `limit`, else the transform's one given part (scale
// or translate), the whole transform when several are given, the grid's file when none is.
std::string placing_field(const MediumDesc& md, double limit) {
  if (md.type == ST_MEDIUM_HOMOGENEOUS) return md.json_path + "/bounds";
  const TransformDesc& t = md.transform;
  if (max_norm(t.translate) > limit) return md.json_path + "/transform/translate";
  const bool scaled = t.scale != Vec3{1, 1, 1}, rotated = t.rotate_deg != Vec3{0, 0, 0};
  const bool moved = t.translate != Vec3{0, 0, 0};
  if (!scaled && !rotated && !moved) return md.json_path + "/file";
  if (int(scaled) + int(rotated) + int(moved) > 1) return md.json_path + "/transform";
  return md.json_path + (scaled ? "/transform/scale" : moved ? "/transform/translate" : "/transform");
}

// The float spacing of coordinates of magnitude up to x: 2^-23 of x rounded down to a power of two.
double float_spacing(double x) { return x > 0 ? std::ldexp(1.0, std::ilogb(x) - 23) : 0.0; }

}  // namespace

void check_coordinates(const SceneDesc& scene, const st_scene& st, const std::vector<Box3>& boxes,
                       const Vec3& camera_position) {
  const std::string why = " (about 1.2e18): the kernels square differences of float coordinates (distances, "
                          "ray-box tests), which would overflow";
  // the media first: a camera framed on them (position auto, fit) lies where they are, and the field
  // to name is the one that placed them, not the position the framing derived
  for (size_t i = 0; i < scene.media.size() && i < boxes.size(); ++i) {
    const MediumDesc& md = scene.media[i];
    const double far = box_max_norm(boxes[i]);
    if (!(far <= kMaxCoordinate))
      throw Error(fmt::format("{}: {}: the medium's world box reaches {:g}, beyond 2^60{}, in medium \"{}\"",
                              scene.path, placing_field(md, kMaxCoordinate), far, why, md.name));
  }
  const double cam = max_norm(camera_position);
  if (!(cam <= kMaxCoordinate))
    throw Error(fmt::format("{}: /camera/position: ({:g}, {:g}, {:g}) is beyond 2^60{}", scene.path,
                            camera_position[0], camera_position[1], camera_position[2], why));
  // the lens's points and the camera's place at shutter close are ray origins too
  const CameraDesc& c = scene.camera;
  if (!(cam + c.aperture_radius <= kMaxCoordinate))
    throw Error(fmt::format("{}: /camera/aperture_radius: {:g} puts the lens beyond 2^60{}", scene.path,
                            c.aperture_radius, why));
  if (c.position_close && !(max_norm(*c.position_close) <= kMaxCoordinate))
    throw Error(fmt::format("{}: /camera/position_close: ({:g}, {:g}, {:g}) is beyond 2^60{}", scene.path,
                            (*c.position_close)[0], (*c.position_close)[1], (*c.position_close)[2], why));
  if (c.focus_distance > kMaxCoordinate)
    throw Error(fmt::format("{}: /camera/focus_distance: {:g} is beyond 2^60{}", scene.path, c.focus_distance, why));
  for (const LightDesc& l : scene.lights)  // a local light's distance to every point it lights
    if (l.type >= ST_LIGHT_POINT && !(max_norm(l.position) <= kMaxCoordinate))
      throw Error(fmt::format("{}: {}/position: ({:g}, {:g}, {:g}) is beyond 2^60{}", scene.path, l.json_path,
                              l.position[0], l.position[1], l.position[2], why));
  for (size_t i = 0; i < scene.media.size() && i < boxes.size(); ++i) {
    const MediumDesc& md = scene.media[i];
    const double far = box_max_norm(boxes[i]);
    const double spacing = float_spacing(std::max(far, cam));
    const double edge = shortest_voxel_edge(st.media[i]);
    if (spacing * kMinVoxelsPerSpacing <= edge) continue;
    // the camera is to blame where the medium alone would be resolved
    const bool camera_far = cam > far && float_spacing(far) * kMinVoxelsPerSpacing <= edge;
    const std::string field = camera_far ? "/camera/position" : placing_field(md, kMaxCoordinate);
    throw Error(fmt::format(
        "{}: {}: {} {:g} from the origin, where float coordinates are {:g} apart, more than 1/16 of the medium's "
        "shortest {} ({:g}): rays would reach it at positions rounded across {}; {}, in medium \"{}\"",
        scene.path, field, camera_far ? "the camera is" : "the medium's world box reaches", std::max(far, cam),
        spacing, md.type == ST_MEDIUM_HOMOGENEOUS ? "side" : "voxel edge", edge,
        md.type == ST_MEDIUM_HOMOGENEOUS ? "the box" : "voxels",
        camera_far ? "move the camera nearer the origin" : "move the medium nearer the origin or make it larger",
        md.name));
  }
}

}  // namespace spectrack
