// light_pack.h: the kernels' entries (st_light) of point, spot and sphere lights and their powers for
// light sampling "power" (kernels/light.h; docs/scene-format.md, `lights`). A sphere holds its
// centre, radius and surface radiance.
//
// Design: a local light is delta in direction, so it needs no sampling tables: its entry holds the
// position, the intensity (W/sr), and for a spot the unit axis and the cosines of the cone angle
// and of the falloff's start. Powers follow pbrt-v4's Light::Phi, divided by the factor pi r^2 that
// pack_lights.cpp leaves out of every light's power (r: the radius of the sphere around the media's
// boxes), so that local lights and lights at infinity share one scale.
#pragma once
#include <vector>

#include "scene/framing.h"
#include "scene/scene.h"

namespace spectrack {

// A local light's radiant intensity (W/sr): a point or spot light's own, a sphere's radiance times
// its projected area pi r^2 (the same in every direction).
Vec3 local_light_intensity(const LightDesc& ld);

// Fills l (zero-filled by the caller) for the point, spot or sphere light ld.
void pack_local_light(st_light& l, const LightDesc& ld);

// Phi / (pi r^2) of the point or spot light ld (the mean over channels), r the radius of the
// bounding sphere of media_boxes (1 without media: nothing scatters then).
double local_light_power(const LightDesc& ld, const std::vector<Box3>& media_boxes);

}  // namespace spectrack
