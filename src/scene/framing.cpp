// framing.cpp: see framing.h. The camera basis is the one of scene/scene_pack.cpp set_camera:
// forward = normalize(look_at - position), right = normalize(forward x up), up' = right x forward;
// the half extent of the frame at unit depth is tan(fov/2) across the shorter image side.
#include "scene/framing.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace spectrack {
namespace {

Vec3 sub(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
double len(const Vec3& v) { return vec3_length(v); }  // scene.h: any length, the plain bits otherwise
Vec3 scaled(const Vec3& v, double s) { return {v[0] * s, v[1] * s, v[2] * s}; }

Vec3 corner(const Box3& b, int c) { return {(c & 1) ? b.hi[0] : b.lo[0], (c & 2) ? b.hi[1] : b.lo[1], (c & 4) ? b.hi[2] : b.lo[2]}; }

struct Basis {
  Vec3 f, r, u;
  double tx, ty;  // half extents of the frame: at unit depth (perspective) or in world units (orthographic)
};

Basis basis(const CameraDesc& c, int width, int height) {
  Basis b;
  b.f = scaled(sub(c.look_at, c.position), 1.0 / len(sub(c.look_at, c.position)));
  b.r = cross(b.f, c.up);
  b.r = scaled(b.r, 1.0 / len(b.r));
  b.u = cross(b.r, b.f);
  const double shorter = std::min(width, height);
  const double half = c.type == ST_CAMERA_ORTHOGRAPHIC ? 0.5 * c.height : std::tan(0.5 * c.fov_deg * M_PI / 180.0);
  b.tx = half * width / shorter;
  b.ty = half * height / shorter;
  return b;
}

}  // namespace

bool camera_needs_framing(const CameraDesc& c) { return c.look_at_media || c.position_auto || c.fit > 0; }

std::string camera_identity(const CameraDesc& c) {
  auto v = [](const Vec3& p) { return fmt::format("({:.9g}, {:.9g}, {:.9g})", p[0], p[1], p[2]); };
  return fmt::format("position {} look_at {} up {} {}", v(c.position), v(c.look_at), v(c.up),
                     c.type == ST_CAMERA_ORTHOGRAPHIC ? fmt::format("height {:.9g}", c.height)
                                                      : fmt::format("fov {:.9g}", c.fov_deg));
}

CameraDesc frame_camera(const CameraDesc& in, int width, int height, const std::vector<Box3>& boxes,
                        const std::string& context) {
  if (!camera_needs_framing(in)) return in;
  CameraDesc c = in;
  c.look_at_media = c.position_auto = false;
  c.fit = 0;
  if (boxes.empty()) throw Error(context + ": the camera frames the media (look_at \"media\", position \"auto\" or fit), but the scene has none");
  Box3 all = boxes[0];
  for (const Box3& b : boxes)
    for (int a = 0; a < 3; ++a) all.lo[a] = std::min(all.lo[a], b.lo[a]), all.hi[a] = std::max(all.hi[a], b.hi[a]);
  // empty grids give degenerate boxes (scene/media_bounds.h): nothing to fit a view to
  const bool all_empty = std::none_of(boxes.begin(), boxes.end(), [](const Box3& b) { return len(sub(b.hi, b.lo)) > 0; });
  if (all_empty && (in.position_auto || in.fit > 0))
    throw Error(context + ": the camera frames the media (position \"auto\" or fit), but every medium is empty (an "
                          "empty grid): there is nothing to frame; give the camera a position and a look_at");
  const double diag = std::max(len(sub(all.hi, all.lo)), 1e-12);
  if (in.look_at_media) c.look_at = scaled(Vec3{all.lo[0] + all.hi[0], all.lo[1] + all.hi[1], all.lo[2] + all.hi[2]}, 0.5);
  if (in.position_auto) {  // the default direction (0, 0, 1); (0, 1, 0) for a z-up camera
    Vec3 dir{0, 0, 1};
    if (len(cross(dir, unit_vector(c.up))) < 1e-3) dir = {0, 1, 0};
    c.position = sub(c.look_at, scaled(dir, diag));
  }
  Vec3 d = sub(c.look_at, c.position);
  if (!(len(d) > 1e-12 * diag)) throw Error(context + "/position: equals the point the camera looks at (no view direction)");
  if (!(len(cross(unit_vector(d), unit_vector(c.up))) > 1e-6))  // unit vectors: any lengths
    throw Error(context + "/up: is parallel to the view direction (from the position to the media)");
  if (!(in.fit > 0)) return c;
  // Move along the view direction: position = look_at - t * f, with t the least distance at which
  // every corner q (relative to look_at) has fit * |q.r| <= tx * depth and fit * |q.u| <= ty * depth.
  const double fit = in.fit;
  Basis b = basis(c, width, height);
  double t = 0, front = -std::numeric_limits<double>::infinity(), hx = 0, hy = 0;
  for (const Box3& box : boxes)
    for (int k = 0; k < 8; ++k) {
      const Vec3 q = sub(corner(box, k), c.look_at);
      const double qx = std::abs(dot(q, b.r)), qy = std::abs(dot(q, b.u)), qz = dot(q, b.f);
      front = std::max(front, -qz);  // the corner farthest behind look_at
      hx = std::max(hx, qx), hy = std::max(hy, qy);
      if (c.type == ST_CAMERA_PERSPECTIVE) t = std::max({t, fit * qx / b.tx - qz, fit * qy / b.ty - qz});
    }
  if (c.type == ST_CAMERA_ORTHOGRAPHIC) {
    // height spans the shorter side: the frame's half extents are 0.5 * height * (w, h) / shorter
    const double shorter = std::min(width, height);
    c.height = std::max({2.0 * fit * hx * shorter / width, 2.0 * fit * hy * shorter / height, 1e-9 * diag});
    t = front + 0.05 * diag;  // the image plane in front of every box
  } else {
    t = std::max(t, front + 1e-3 * diag);
  }
  c.position = sub(c.look_at, scaled(b.f, t));
  return c;
}

bool box_in_view(const CameraDesc& c, int width, int height, const Box3& box, double slack) {
  const Basis b = basis(c, width, height);
  for (int k = 0; k < 8; ++k) {
    const Vec3 q = sub(corner(box, k), c.position);
    const double qx = std::abs(dot(q, b.r)), qy = std::abs(dot(q, b.u)), qz = dot(q, b.f);
    if (c.type == ST_CAMERA_ORTHOGRAPHIC) {
      if (qz < 0 || qx > b.tx * (1 + slack) || qy > b.ty * (1 + slack)) return false;
    } else {
      if (qz <= 0 || qx > b.tx * qz * (1 + slack) || qy > b.ty * qz * (1 + slack)) return false;
    }
  }
  return true;
}

}  // namespace spectrack
