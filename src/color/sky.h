// sky.h: a physical sky: the single-scattering atmosphere of Nishita et al., "Display of the Earth
// Taking into Account Atmospheric Scattering" (SIGGRAPH 1993), with the constants and quadratures
// of the "Nishita (improved)" sky of Blender's Cycles renderer (Blender 2.90, 2020).
//
// Design: the Earth is a sphere of radius 6360 km under an atmosphere 60 km thick, holding air
// (Rayleigh scattering, scale height 8 km, phase 3/(16 pi) (1 + mu^2)), dust (Mie scattering
// 2e-5 /m at sea level, extinction 1.11 x scattering, scale height 1.2 km, Cornette-Shanks phase
// with g = 0.76) and ozone (absorption only, a tent from 10 to 40 km peaking at 25 km). The sun
// is a blackbody of 5778 K filling 6.7902e-5 sr (its irradiance at the top of the atmosphere). The
// radiance seen from `altitude` along a view direction is the sunlight scattered once towards the
// viewer: 32 midpoint steps along the view ray to the top of the atmosphere, each lit by the sun
// through the optical depth towards it (8-point Gauss-Laguerre quadrature, exact for densities
// falling exponentially), unless the Earth hides the sun from that step. Spectra are evaluated at
// 21 wavelengths, 380-780 nm in 20 nm steps, and reduced to CIE 1931 XYZ by the observer at those
// wavelengths times 20 nm: Y is luminance / 683 lm/W (W m^-2 sr^-1 for the sky, W m^-2 for the
// sun's irradiance). Cycles leaves ozone out of the sun's own transmittance; here the sun crosses
// the same ozone as the skylight does. Directions are in the model's frame: z up (the zenith),
// the sun in the x-z plane.
#pragma once
#include <array>

#include "color/blackbody.h"

namespace spectrack {

// The atmosphere's densities as multiples of the model's (1: Earth's clear-day atmosphere; 0
// removes that constituent), and where the viewer stands.
struct SkyAtmosphere {
  double altitude_m = 0;  // above sea level, in [0, 60000)
  double air = 1;         // Rayleigh scatterers
  double dust = 1;        // Mie scatterers (aerosols, haze)
  double ozone = 1;       // ozone (absorbs orange and red light: blue twilight)
};

constexpr int kSkyWavelengths = 21;  // 380..780 nm, 20 nm apart
using SkySpectrum = std::array<double, kSkyWavelengths>;
double sky_wavelength_nm(int i);

// Spectral radiance (W m^-2 sr^-1 nm^-1) scattered once towards the viewer from the unit view
// direction `view` with the sun along the unit direction `sun` (model frame, z up).
SkySpectrum sky_radiance_spectrum(const SkyAtmosphere& a, const std::array<double, 3>& view,
                                  const std::array<double, 3>& sun);

// Spectral irradiance (W m^-2 nm^-1) of the sun's disc seen through the atmosphere at elevation
// `elevation_rad` (clamped to >= 0: the disc's visible edge lies on the horizon).
SkySpectrum sun_irradiance_spectrum(const SkyAtmosphere& a, double elevation_rad);

// CIE 1931 XYZ of a spectrum at the model's wavelengths (sum of S x-bar 20 nm).
Rgb sky_spectrum_xyz(const SkySpectrum& s);

// The sky's XYZ radiance along `view` and the sun's XYZ irradiance: the above reduced to XYZ.
Rgb sky_radiance_xyz(const SkyAtmosphere& a, const std::array<double, 3>& view, const std::array<double, 3>& sun);
Rgb sun_irradiance_xyz(const SkyAtmosphere& a, double elevation_rad);

}  // namespace spectrack
