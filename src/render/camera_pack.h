// camera_pack.h: the camera as the kernels see it (kernels/types.h st_camera).
//
// Design: the one place that turns a resolved camera (framing done, scene/framing.h) into the
// kernels' frame: forward = normalize(look_at - position), right = normalize(forward x up) and
// up' = right x forward, scaled to the frame's half extents (tan(fov/2), or half the orthographic
// height, across the shorter image side). The thin lens, the shutter and camera motion ride along
// (docs/scene-format.md, "Lens and time"); pack_camera also says which kernel features
// (types.h st_feature) the camera needs, so a pinhole without time compiles neither in.
#pragma once
#include <cstdint>

#include "render/settings.h"
#include "scene/scene.h"

namespace spectrack {

// Fills `cam` from the framed camera `c` and the settings' shutter; returns the st_feature bits the
// camera needs (ST_FEATURE_THIN_LENS, ST_FEATURE_TIME). Throws Error (prefixed with `context`)
// for a focus distance that is not a positive finite number once resolved.
uint32_t pack_camera(const CameraDesc& c, int width, int height, const RenderSettings& s, st_camera& cam,
                     const std::string& context);

}  // namespace spectrack
