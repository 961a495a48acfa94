// sky.cpp: see sky.h.
#include "color/sky.h"

#include <cmath>

namespace spectrack {

namespace {

using V3 = std::array<double, 3>;

constexpr double kEarthRadius = 6360e3;       // m
constexpr double kAtmosphereRadius = 6420e3;  // m
constexpr double kRayleighScaleHeight = 8e3;  // m
constexpr double kMieScaleHeight = 1.2e3;     // m
constexpr double kRayleighAt550 = 1.2361437e-5;  // sigma_s of air at sea level and 550 nm (m^-1), ~ lambda^-4
constexpr double kMieScattering = 2e-5;          // sigma_s of dust at sea level (m^-1), grey
constexpr double kMieExtinction = 1.11;          // sigma_t / sigma_s of dust
constexpr double kMieG = 0.76;
constexpr double kSunTemperature = 5778;        // K
constexpr double kSunSolidAngle = 6.79016e-5;   // sr, seen from the Earth
constexpr int kViewSteps = 32;

// Ozone's absorption coefficient at its peak density (m^-1) at the model's 21 wavelengths.
constexpr double kOzone[kSkyWavelengths] = {
    3.25126849861e-9, 5.85395365047e-9, 1.977191155085e-8, 7.309568762914e-8, 2.0084561514287e-7,
    4.0383958096161e-7, 6.3551335912363e-7, 9.670704118097e-7, 1.5479740042441e-6, 2.0903864722333e-6,
    2.4612805616457e-6, 2.7355129946151e-6, 2.1512586312864e-6, 1.5905184079199e-6, 1.1235619797986e-6,
    7.3527551487574e-7, 4.6450130357806e-7, 3.3096079921048e-7, 2.2512612292678e-7, 1.487912926649e-7,
    1.6828623364192e-7};

// 8-point Gauss-Laguerre quadrature (Abramowitz and Stegun, table 25.9): nodes x_i and weights
// w_i exp(x_i), so that sum w_i e^x_i g(x_i) approximates int_0^inf g(x) dx for g ~ e^-x. A ray to
// the top of the atmosphere of length L is mapped to x = 25 s / L, so the last node stays inside.
constexpr double kLaguerreX[8] = {0.170279632305, 0.903701776799, 2.251086629866, 4.266700170288,
                                  7.045905402393, 10.758516010181, 15.740678641278, 22.863131736889};
constexpr double kLaguerreW[8] = {0.437723410493, 1.033869347666, 1.669709765659, 2.376924701759,
                                  3.208540913348, 4.268575510825, 5.818083368672, 8.906226215292};
constexpr double kLaguerreEnd = 25;

double dot(const V3& a, const V3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
V3 along(const V3& p, const V3& d, double t) { return {p[0] + t * d[0], p[1] + t * d[1], p[2] + t * d[2]}; }

double rayleigh_sigma(int i) { return kRayleighAt550 * std::pow(550.0 / sky_wavelength_nm(i), 4); }

// Relative densities of air, dust and ozone at height h above sea level.
V3 densities(double h) {
  double ozone = 0;
  if (h >= 10e3 && h < 25e3) ozone = h / 15e3 - 2.0 / 3.0;
  else if (h >= 25e3 && h < 40e3) ozone = 8.0 / 3.0 - h / 15e3;
  return {std::exp(-h / kRayleighScaleHeight), std::exp(-h / kMieScaleHeight), ozone};
}

double height(const V3& p) { return std::sqrt(dot(p, p)) - kEarthRadius; }

// Distance from p (inside the atmosphere) along unit d to the top of the atmosphere.
double to_top(const V3& p, const V3& d) {
  const double b = dot(p, d), c = dot(p, p) - kAtmosphereRadius * kAtmosphereRadius;
  return -b + std::sqrt(std::max(b * b - c, 0.0));
}

// Whether the ray from p along unit d meets the Earth.
bool hits_earth(const V3& p, const V3& d) {
  const double b = dot(p, d);
  if (b >= 0) return false;  // moving away from the centre
  return dot(p, p) - b * b < kEarthRadius * kEarthRadius;
}

// Optical depth of each constituent at unit density from p along d to the top of the atmosphere
// (in metres of sea-level density).
V3 optical_depth(const V3& p, const V3& d) {
  const double L = to_top(p, d);
  V3 depth{0, 0, 0};
  for (int i = 0; i < 8; ++i) {
    const V3 rho = densities(height(along(p, d, kLaguerreX[i] / kLaguerreEnd * L)));
    for (int k = 0; k < 3; ++k) depth[k] += rho[k] * kLaguerreW[i] / kLaguerreEnd * L;
  }
  return depth;
}

// Transmittance at wavelength i through optical depths `tau` (densities already scaled).
double transmittance(const V3& tau, int i) {
  return std::exp(-(tau[0] * rayleigh_sigma(i) + tau[1] * kMieExtinction * kMieScattering + tau[2] * kOzone[i]));
}

double sun_top_irradiance(int i) { return planck(sky_wavelength_nm(i), kSunTemperature) * kSunSolidAngle; }

double phase_rayleigh(double mu) { return 3.0 / (16.0 * M_PI) * (1.0 + mu * mu); }
double phase_mie(double mu) {  // Cornette and Shanks
  const double g2 = kMieG * kMieG;
  return 3.0 * (1.0 - g2) * (1.0 + mu * mu) /
         (8.0 * M_PI * (2.0 + g2) * std::pow(1.0 + g2 - 2.0 * kMieG * mu, 1.5));
}

V3 scaled(const V3& v, const SkyAtmosphere& a) { return {v[0] * a.air, v[1] * a.dust, v[2] * a.ozone}; }

}  // namespace

double sky_wavelength_nm(int i) { return 380.0 + 20.0 * i; }

SkySpectrum sky_radiance_spectrum(const SkyAtmosphere& a, const V3& view, const V3& sun) {
  SkySpectrum L{};
  const V3 origin{0, 0, kEarthRadius + a.altitude_m};
  const double ds = to_top(origin, view) / kViewSteps;
  const double mu = dot(view, sun);
  const double p_air = phase_rayleigh(mu), p_dust = phase_mie(mu);
  V3 tau_view{0, 0, 0};  // optical depth from the viewer to the far end of the current step
  for (int s = 0; s < kViewSteps; ++s) {
    const V3 p = along(origin, view, (s + 0.5) * ds);
    const V3 rho = scaled(densities(height(p)), a);
    for (int k = 0; k < 3; ++k) tau_view[k] += rho[k] * ds;
    if (hits_earth(p, sun)) continue;
    const V3 tau_sun = scaled(optical_depth(p, sun), a);
    const V3 tau{tau_view[0] + tau_sun[0], tau_view[1] + tau_sun[1], tau_view[2] + tau_sun[2]};
    for (int i = 0; i < kSkyWavelengths; ++i) {
      const double sigma_s_phase = rho[0] * rayleigh_sigma(i) * p_air + rho[1] * kMieScattering * p_dust;
      L[i] += transmittance(tau, i) * sigma_s_phase * sun_top_irradiance(i) * ds;
    }
  }
  return L;
}

SkySpectrum sun_irradiance_spectrum(const SkyAtmosphere& a, double elevation_rad) {
  const double e = std::max(elevation_rad, 0.0);
  const V3 origin{0, 0, kEarthRadius + a.altitude_m};
  const V3 tau = scaled(optical_depth(origin, {std::cos(e), 0, std::sin(e)}), a);
  SkySpectrum E{};
  for (int i = 0; i < kSkyWavelengths; ++i) E[i] = sun_top_irradiance(i) * transmittance(tau, i);
  return E;
}

Rgb sky_spectrum_xyz(const SkySpectrum& s) {
  Rgb xyz{0, 0, 0};
  for (int i = 0; i < kSkyWavelengths; ++i) {
    const CieSample& c = kCie1931[int(sky_wavelength_nm(i)) - kCie1931[0].lambda_nm];
    xyz[0] += c.x * s[i] * 20.0;
    xyz[1] += c.y * s[i] * 20.0;
    xyz[2] += c.z * s[i] * 20.0;
  }
  return xyz;
}

Rgb sky_radiance_xyz(const SkyAtmosphere& a, const V3& view, const V3& sun) {
  return sky_spectrum_xyz(sky_radiance_spectrum(a, view, sun));
}

Rgb sun_irradiance_xyz(const SkyAtmosphere& a, double elevation_rad) {
  return sky_spectrum_xyz(sun_irradiance_spectrum(a, elevation_rad));
}

}  // namespace spectrack
