// radiance.h: refusing at load the light magnitudes the single-precision kernels cannot carry.
//
// Design: the kernels hold radiance, pdfs and path weights in float (FLT_MAX = 3.4e38) and a
// pixel's film entry is a float sum of up to 2^24 samples (x 3 channels), so a sample must stay
// below FLT_MAX / 2^26 ~ 5e30. A sample is a sum over path vertices and lights of
// throughput x (radiance / pdf) x (phase x MIS weight) x transmittance. For each light the
// largest factor it can put into one such term per unit throughput, its peak P, is
//   uniform environment:  4 pi x radiance              (next-event estimation: Le / pdf)
//   environment map:      scale x max(texel), 2 pi^2 x scale x the map's integral (Le / pdf, times
//                         sin(theta) / sin(theta_c) within a texel's row, at most 2: in the margin)
//   delta directional:    irradiance x the scene's largest phase value (no pdf, no MIS)
//   directional disc:     its radiance irradiance / (pi sin^2(angle / 2))
//   emission:             radiance x scale (x the emission grid's largest value)
// and P <= kMaxRadiance = 1e20 leaves a factor ~5e10 for throughput weights (spectral tracking
// weights above 1, non-bounding majorants), the sum over vertices and lights, and rounding.
// Pdfs enter the power heuristic squared: a disc's pdf 1 / (2 pi (1 - cos(angle / 2))) must stay
// below kMaxLightPdf = 1e18. The HG peak (1 + |g|) / (4 pi (1 - |g|)^2) is taken at g rounded to
// float, and a g that rounds to +-1 is refused (the phase function is then 0 / 0). Emission is
// scored as (density x sigma_a x Le) x (C / (mubar P_a)): the first product is bounded by
// kMaxEmissionProduct = 1e30. The bounds are generous for any physical scene (the sun's radiance
// is ~2e7 W sr^-1 m^-2) and each refusal names the file, the JSON path, the value and the bound.
#pragma once
#include <string>
#include <vector>

#include "scene/scene.h"

namespace spectrack {

constexpr double kMaxRadiance = 1e20;
constexpr double kMaxLightPdf = 1e18;
constexpr double kMaxEmissionProduct = 1e30;

// The largest value of any medium's phase function (1 / (4 pi) without HG media); throws Error
// for a g that rounds to +-1 in float.
double scene_phase_peak(const SceneDesc& scene);
// Everything that can be checked from the scene file alone (parse_scene calls it).
void check_radiance_bounds(const SceneDesc& scene);
// An environment map's texels (rgb, width x height, linear) times `scale`: finite, >= 0, and
// within the bounds above. `context` is "<scene>: /lights/<i>/map".
void check_env_map_bounds(const std::string& context, const std::string& file, const std::vector<float>& rgb,
                          int width, int height, double scale);
// A VDB medium's emission once its grids are loaded: density_max is the density grid's largest
// value, emission_max the emission grid's (1 without one). `context` is "<scene>: /media/<i>".
void check_emission_bounds(const std::string& context, const MediumDesc& m, double density_max, double emission_max);

}  // namespace spectrack
