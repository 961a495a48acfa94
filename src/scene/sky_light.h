// sky_light.h: a "sky" light (docs/scene-format.md) as the lights the kernels already have: a
// lat-long environment map of the sky's radiance and a directional light for its sun.
//
// Design: the sky model (color/sky.h) is evaluated on the host when the scene is loaded (the sun)
// and packed (the map), so the kernels need nothing new: the map goes through the environment
// map's path (its importance sampling by max(rgb) sin(theta), MIS against phase sampling, and in
// spectral mode its texels upsampled as illuminants), the sun through the directional light's
// (a uniform disc of the sun's angular diameter). The model's frame (z up, the sun at azimuth 0)
// is turned into the world's (y up; azimuth measured from -z towards +x, the map's centre and the
// environment map's convention of kernels/light.h). The radiance varies slowly except near the
// horizon and towards the sun (Mie scattering), so the model is evaluated on a grid of elevations,
// denser towards the horizon (elevation = pi/2 t^2 for t evenly spaced, as Cycles' own table), by
// azimuths from the sun (1 degree apart; the sky is symmetric about the sun's vertical plane),
// and each texel is interpolated bilinearly there. Below the horizon the sky is the horizon's
// radiance fading as (1 + 2.5 y)^3 to black at y = -0.4 (Cycles' ground), the sun's colour is the
// transmitted sunlight at its elevation, and linear sRGB comes from XYZ (components < 0 set to 0).
#pragma once
#include <optional>

#include "image/image.h"
#include "scene/scene.h"

namespace spectrack {

// The unit direction towards the sky's sun (y up).
Vec3 sky_sun_direction(const SkyDesc& s);

// The sky's radiance along the unit world direction d (linear sRGB, before the intensity), from
// the model directly (no grid).
Rgb sky_radiance_rgb(const SkyDesc& s, const Vec3& d);

// The sun's irradiance on a surface facing it (linear sRGB, before the intensity).
Rgb sky_sun_irradiance_rgb(const SkyDesc& s);

// The sky light's sun as a directional light (to_light, irradiance x intensity, the disc's
// angle), or none when sun_disc is false or the disc lies wholly below the horizon.
std::optional<LightDesc> sky_sun_light(const LightDesc& sky);

// The sky's lat-long map, resolution x resolution / 2 texels (linear sRGB before the intensity,
// row 0 at the top), each texel the model at its centre direction interpolated from the grid.
RgbImage sky_map(const SkyDesc& s);

}  // namespace spectrack
