// framing.h: a camera that frames the media (docs/scene-format.md, "Framing"). The scene asks for
// it with "look_at": "media" (aim at the centre of the union of the media's world boxes),
// "position": "auto" (look along the default direction (0, 0, 1), i.e. from -z; along (0, 1, 0)
// when `up` is parallel to z) and "fit" (move
// the camera along its view direction, for an orthographic camera also set its height, so that
// every medium's box spans at most 1/fit of the frame on each side of the centre). pack_scene
// resolves it (scene/scene_pack.cpp set_camera) with the boxes of scene/media_bounds.h.
#pragma once
#include <string>
#include <vector>

#include "scene/scene.h"

namespace spectrack {

struct Box3 {
  Vec3 lo{0, 0, 0}, hi{0, 0, 0};
};

// True when the camera asks for any framing.
bool camera_needs_framing(const CameraDesc& c);

// The camera with its framing resolved: plain position/look_at/up/fov_deg/height, flags cleared.
// A camera that asks for nothing is returned as it is. Throws Error (prefixed with `context`)
// when framing is asked without media, or the resolved view direction is degenerate.
CameraDesc frame_camera(const CameraDesc& c, int width, int height, const std::vector<Box3>& boxes,
                        const std::string& context);

// A resolved camera as one line of text, to 9 significant digits: position, look_at, up and the
// field of view (or an orthographic camera's height). A film records it where the framing of a
// sequence's camera depends on the frame range (film.h RenderIdentity::camera).
std::string camera_identity(const CameraDesc& c);

// Whether the 8 corners of `b` lie inside the camera's view (in front of it, within the frame,
// widened by `slack`, a relative tolerance). For tests and `spectrack info`.
bool box_in_view(const CameraDesc& c, int width, int height, const Box3& b, double slack = 1e-6);

}  // namespace spectrack
