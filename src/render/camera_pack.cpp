// camera_pack.cpp: see camera_pack.h. Vectors are composed in double and rounded to float once.
#include "render/camera_pack.h"

#include <algorithm>
#include <cmath>

namespace spectrack {
namespace {

Vec3 sub(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
double length(const Vec3& v) { return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }
Vec3 unit(const Vec3& v) {
  const double l = length(v);
  return {v[0] / l, v[1] / l, v[2] / l};
}
Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
st_float4 f4(const Vec3& v, double w = 0) { return {float(v[0]), float(v[1]), float(v[2]), float(w)}; }

}  // namespace

uint32_t pack_camera(const CameraDesc& c, int width, int height, const RenderSettings& s, st_camera& cam,
                     const std::string& context) {
  cam.type = c.type;
  cam.width = width;
  cam.height = height;
  const Vec3 fwd = unit(sub(c.look_at, c.position));
  const Vec3 right = unit(cross(fwd, c.up));
  const Vec3 up = cross(right, fwd);
  const double shorter = std::min(width, height);
  const double half = c.type == ST_CAMERA_ORTHOGRAPHIC ? 0.5 * c.height : std::tan(0.5 * c.fov_deg * M_PI / 180.0);
  const double sx = half * width / shorter, sy = half * height / shorter;
  // thin lens: the focus distance defaults to the distance to look_at (after framing)
  const double focus = c.focus_distance > 0 ? c.focus_distance : length(sub(c.look_at, c.position));
  if (c.aperture_radius > 0 && !(std::isfinite(focus) && focus > 0 && float(focus) > 0))
    throw Error(context + "/focus_distance: " + std::to_string(focus) + " is not a positive finite distance");
  cam.position = f4(c.position, c.aperture_radius);
  cam.forward = f4(fwd, c.aperture_radius > 0 ? focus : 0.0);
  cam.right = f4({right[0] * sx, right[1] * sx, right[2] * sx});
  cam.up = f4({up[0] * sy, up[1] * sy, up[2] * sy});
  uint32_t features = c.aperture_radius > 0 ? uint32_t(ST_FEATURE_THIN_LENS) : 0u;
  // the shutter: the paths' times, stratified over the film's samples (queues.h path_shutter_u)
  if (!s.shutter) return features;
  cam.shutter = {float((*s.shutter)[0]), float((*s.shutter)[1]), float(std::max(1, s.time_strata)), 0.0f};
  const Vec3 position1 = c.position_close.value_or(c.position), look_at1 = c.look_at_close.value_or(c.look_at);
  const bool moving = (position1 != c.position || look_at1 != c.look_at) && (*s.shutter)[1] > (*s.shutter)[0];
  if (!moving) return features;
  cam.moving = 1;
  cam.position1 = f4(position1);
  cam.look_at0 = f4(c.look_at, sx);
  cam.look_at1 = f4(look_at1, sy);
  cam.up_world = f4(c.up);
  return features | ST_FEATURE_TIME;
}

}  // namespace spectrack
