// pack_camera.cpp: the camera of a packed scene, framed (scene/framing.h) and turned into the
// kernels' st_camera (position, forward, and right and up scaled to the film's half extent).
#include "scene/packer.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

#include "color/spectrum.h"
#include "image/image.h"
#include "scene/radiance.h"
#include "volume/float_limits.h"
#include "scene/media_bounds.h"
#include "integrator/memory_budget.h"
#include "scene/framing.h"
#include "volume/volume.h"

namespace spectrack {
namespace packing {

Vec3 normalize(Vec3 v) {
  double l = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  return {v[0] / l, v[1] / l, v[2] / l};
}

Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

void Packer::set_camera() {
  const CameraDesc c = frame_camera(scene.camera, scene.film.width, scene.film.height, media_boxes, scene.path + ": /camera");
  camera_position = c.position;
  st_camera& cam = st.camera;
  cam.type = c.type;
  cam.width = scene.film.width;
  cam.height = scene.film.height;
  Vec3 fwd = normalize({c.look_at[0] - c.position[0], c.look_at[1] - c.position[1], c.look_at[2] - c.position[2]});
  Vec3 right = normalize(cross(fwd, c.up));
  Vec3 up = cross(right, fwd);
  double shorter = std::min(cam.width, cam.height);
  double half = c.type == ST_CAMERA_ORTHOGRAPHIC ? 0.5 * c.height : std::tan(0.5 * c.fov_deg * M_PI / 180.0);
  double sx = half * cam.width / shorter, sy = half * cam.height / shorter;
  cam.position = f4(c.position);
  cam.forward = f4(fwd);
  cam.right = f4(right[0] * sx, right[1] * sx, right[2] * sx);
  cam.up = f4(up[0] * sy, up[1] * sy, up[2] * sy);
}

}  // namespace packing
}  // namespace spectrack
