// light_pack.cpp: see light_pack.h.
#include "scene/light_pack.h"

#include <algorithm>
#include <cmath>

namespace spectrack {

namespace {

// The cosines of a spot's cone angle (0 beyond) and of its falloff's start (full inside).
void spot_cosines(const LightDesc& ld, double* cos_total, double* cos_start) {
  const double deg = M_PI / 180.0;
  *cos_total = std::cos(ld.cone_angle_deg * deg);
  *cos_start = std::cos((ld.cone_angle_deg - ld.cone_delta_deg) * deg);
}

}  // namespace

Vec3 local_light_intensity(const LightDesc& ld) {
  if (ld.type != ST_LIGHT_SPHERE) return ld.intensity;
  const double area = M_PI * ld.radius * ld.radius;  // the sphere's projected area: its intensity L pi r^2
  return Vec3{ld.radiance[0] * area, ld.radiance[1] * area, ld.radiance[2] * area};
}

void pack_local_light(st_light& l, const LightDesc& ld) {
  l.type = ld.type;
  if (ld.type == ST_LIGHT_SPHERE) {  // not delta: an area seen in a cone (kernels/light.h)
    l.radiance = st_float4{float(ld.radiance[0]), float(ld.radiance[1]), float(ld.radiance[2]), 0.0f};
    l.position = st_float4{float(ld.position[0]), float(ld.position[1]), float(ld.position[2]), float(ld.radius)};
    return;
  }
  l.is_delta = 1;
  l.radiance = st_float4{float(ld.intensity[0]), float(ld.intensity[1]), float(ld.intensity[2]), 0.0f};
  l.position = st_float4{float(ld.position[0]), float(ld.position[1]), float(ld.position[2]), 1.0f};
  l.cos_max = -1.0f;
  if (ld.type != ST_LIGHT_SPOT) return;
  const Vec3 axis = unit_vector({ld.look_at[0] - ld.position[0], ld.look_at[1] - ld.position[1], ld.look_at[2] - ld.position[2]});
  l.direction = st_float4{float(axis[0]), float(axis[1]), float(axis[2]), 0.0f};
  double cos_total, cos_start;
  spot_cosines(ld, &cos_total, &cos_start);
  l.cos_max = float(cos_total);
  l.position.w = float(cos_start);
}

double local_light_power(const LightDesc& ld, const std::vector<Box3>& media_boxes) {
  double r2 = 1.0;
  if (!media_boxes.empty()) {
    Box3 u = media_boxes[0];
    for (const Box3& b : media_boxes)
      for (int k = 0; k < 3; ++k) u.lo[k] = std::min(u.lo[k], b.lo[k]), u.hi[k] = std::max(u.hi[k], b.hi[k]);
    r2 = 0;
    for (int k = 0; k < 3; ++k) r2 += 0.25 * (u.hi[k] - u.lo[k]) * (u.hi[k] - u.lo[k]);
    r2 = std::max(r2, 1e-30);
  }
  const Vec3 intensity = local_light_intensity(ld);
  const double I = (intensity[0] + intensity[1] + intensity[2]) / 3.0;
  double solid_angle = 4.0 * M_PI;  // pbrt-v4: a point light's Phi = 4 pi I (a sphere's: 4 pi L pi r^2)
  if (ld.type == ST_LIGHT_SPOT) {   // the cone's full part, and the falloff's at its mean
    double cos_total, cos_start;
    spot_cosines(ld, &cos_total, &cos_start);
    solid_angle = 2.0 * M_PI * ((1.0 - cos_start) + 0.5 * (cos_start - cos_total));
  }
  return solid_angle * I / (M_PI * r2);
}

}  // namespace spectrack
