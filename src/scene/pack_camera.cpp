// pack_camera.cpp: the camera of a packed scene, framed (scene/framing.h) and turned into the
// kernels' st_camera (position, forward, and right and up scaled to the film's half extent), with
// its thin lens, shutter and motion (docs/scene-format.md, "Lens and time"): the st_feature bits
// ST_FEATURE_THIN_LENS and ST_FEATURE_TIME only where the camera uses them, so a pinhole without
// a moving camera compiles neither in.
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


Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

void Packer::set_camera(const RenderSettings& s) {
  const CameraDesc c = frame_camera(scene.camera, scene.film.width, scene.film.height, media_boxes, scene.path + ": /camera");
  camera_position = c.position;
  st_camera& cam = st.camera;
  cam.type = c.type;
  cam.width = scene.film.width;
  cam.height = scene.film.height;
  Vec3 fwd = unit_vector({c.look_at[0] - c.position[0], c.look_at[1] - c.position[1], c.look_at[2] - c.position[2]});
  Vec3 right = unit_vector(cross(fwd, c.up));
  Vec3 up = cross(right, fwd);
  double shorter = std::min(cam.width, cam.height);
  double half = c.type == ST_CAMERA_ORTHOGRAPHIC ? 0.5 * c.height : std::tan(0.5 * c.fov_deg * M_PI / 180.0);
  double sx = half * cam.width / shorter, sy = half * cam.height / shorter;
  // thin lens: the focus distance defaults to the distance to look_at (after framing)
  const Vec3 to_look_at{c.look_at[0] - c.position[0], c.look_at[1] - c.position[1], c.look_at[2] - c.position[2]};
  const double focus = c.focus_distance > 0 ? c.focus_distance
                                            : std::sqrt(to_look_at[0] * to_look_at[0] + to_look_at[1] * to_look_at[1] +
                                                        to_look_at[2] * to_look_at[2]);
  if (c.aperture_radius > 0 && !(std::isfinite(focus) && float(focus) > 0))
    throw Error(fmt::format("{}: /camera/focus_distance: {} is not a positive finite distance", scene.path, focus));
  cam.position = f4(c.position, c.aperture_radius);
  cam.forward = f4(fwd, c.aperture_radius > 0 ? focus : 0.0);
  cam.right = f4(right[0] * sx, right[1] * sx, right[2] * sx);
  cam.up = f4(up[0] * sy, up[1] * sy, up[2] * sy);
  camera_features = c.aperture_radius > 0 ? uint32_t(ST_FEATURE_THIN_LENS) : 0u;
  // the shutter: the paths' times, stratified over the film's samples (kernels/queues.h path_shutter_u)
  if (!s.shutter) return;
  cam.shutter = f4((*s.shutter)[0], (*s.shutter)[1], std::max(1, s.time_strata));
  const Vec3 position1 = c.position_close.value_or(c.position), look_at1 = c.look_at_close.value_or(c.look_at);
  if ((position1 == c.position && look_at1 == c.look_at) || !((*s.shutter)[1] > (*s.shutter)[0])) return;
  cam.moving = 1;  // raygen.cl camera_frame: position and look_at lerped, the frame rebuilt around up
  cam.position1 = f4(position1);
  cam.look_at0 = f4(c.look_at, sx);
  cam.look_at1 = f4(look_at1, sy);
  cam.up_world = f4(c.up);
  camera_features |= ST_FEATURE_TIME;
}

}  // namespace packing
}  // namespace spectrack
