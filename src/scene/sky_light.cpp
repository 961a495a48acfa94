// sky_light.cpp: see sky_light.h.
#include "scene/sky_light.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace spectrack {

namespace {

constexpr double kDeg = M_PI / 180.0;
constexpr int kGridElevations = 97;  // t = 0 .. 1, elevation = pi/2 t^2
constexpr int kGridAzimuths = 181;   // 0 .. 180 degrees from the sun's azimuth

// A world direction's elevation above the horizon and its azimuth from the sun's, folded to [0, pi].
struct SkyAngles {
  double elevation, azimuth;
};

SkyAngles angles_of(const SkyDesc& s, const Vec3& d) {
  const double phi = std::atan2(d[0], -d[2]);  // the map's azimuth (kernels/light.h env_dir_to_uv)
  double a = std::remainder(phi - s.sun_azimuth_deg * kDeg, 2.0 * M_PI);
  return {std::asin(std::clamp(d[1], -1.0, 1.0)), std::abs(a)};
}

// The model's sky above (or on) the horizon at the given angles, in XYZ.
Rgb model_xyz(const SkyDesc& s, double elevation, double azimuth) {
  const double e = s.sun_elevation_deg * kDeg;
  const std::array<double, 3> view{std::cos(elevation) * std::cos(azimuth), std::cos(elevation) * std::sin(azimuth),
                                   std::sin(elevation)};
  return sky_radiance_xyz(s.atmosphere, view, {std::cos(e), 0.0, std::sin(e)});
}

// Cycles' ground: the horizon's radiance fading to black at y = -0.4.
double ground_fade(double y) {
  if (y >= 0) return 1.0;
  if (y < -0.4) return 0.0;
  const double f = 1.0 + 2.5 * y;
  return f * f * f;
}

Rgb to_rgb(const Rgb& xyz, double scale) {
  Rgb c = xyz_to_linear_srgb(xyz);
  for (double& v : c) v = std::max(v, 0.0) * scale;
  return c;
}

// The model on the grid of sky_light.h: XYZ at (elevation index j, azimuth index k).
struct SkyGrid {
  std::vector<Rgb> xyz;
  explicit SkyGrid(const SkyDesc& s) : xyz(size_t(kGridElevations) * kGridAzimuths) {
    for (int j = 0; j < kGridElevations; ++j) {
      const double t = double(j) / (kGridElevations - 1);
      for (int k = 0; k < kGridAzimuths; ++k)
        xyz[size_t(j) * kGridAzimuths + k] = model_xyz(s, 0.5 * M_PI * t * t, M_PI * k / (kGridAzimuths - 1));
    }
  }
  Rgb at(const SkyAngles& a) const {
    const double t = std::sqrt(std::max(a.elevation, 0.0) / (0.5 * M_PI)) * (kGridElevations - 1);
    const double u = a.azimuth / M_PI * (kGridAzimuths - 1);
    const int j = std::min(int(t), kGridElevations - 2), k = std::min(int(u), kGridAzimuths - 2);
    const double ft = std::clamp(t - j, 0.0, 1.0), fu = std::clamp(u - k, 0.0, 1.0);
    Rgb out{0, 0, 0};
    for (int c = 0; c < 3; ++c) {
      auto v = [&](int dj, int dk) { return xyz[size_t(j + dj) * kGridAzimuths + k + dk][c]; };
      out[c] = (1 - ft) * ((1 - fu) * v(0, 0) + fu * v(0, 1)) + ft * ((1 - fu) * v(1, 0) + fu * v(1, 1));
    }
    return out;
  }
};

}  // namespace

Vec3 sky_sun_direction(const SkyDesc& s) {
  const double e = s.sun_elevation_deg * kDeg, a = s.sun_azimuth_deg * kDeg;
  return {std::cos(e) * std::sin(a), std::sin(e), -std::cos(e) * std::cos(a)};
}

Rgb sky_radiance_rgb(const SkyDesc& s, const Vec3& d) {
  const SkyAngles a = angles_of(s, d);
  return to_rgb(model_xyz(s, std::max(a.elevation, 0.0), a.azimuth), ground_fade(d[1]));
}

Rgb sky_sun_irradiance_rgb(const SkyDesc& s) {
  return to_rgb(sun_irradiance_xyz(s.atmosphere, s.sun_elevation_deg * kDeg), 1.0);
}

std::optional<LightDesc> sky_sun_light(const LightDesc& sky) {
  const SkyDesc& s = *sky.sky;
  if (!s.sun_disc || s.sun_elevation_deg + 0.5 * s.sun_angle_deg <= 0) return std::nullopt;
  LightDesc sun;
  sun.json_path = sky.json_path;
  sun.type = ST_LIGHT_DIRECTIONAL;
  sun.to_light = sky_sun_direction(s);
  const Rgb e = sky_sun_irradiance_rgb(s);
  for (int c = 0; c < 3; ++c) sun.irradiance[c] = e[c] * s.intensity;
  sun.angle_deg = s.sun_angle_deg;
  return sun;
}

RgbImage sky_map(const SkyDesc& s) {
  const SkyGrid grid(s);
  RgbImage img;
  img.width = s.resolution;
  img.height = s.resolution / 2;
  img.rgb.resize(size_t(img.width) * img.height * 3);
  for (int y = 0; y < img.height; ++y) {
    const double theta = M_PI * (y + 0.5) / img.height;
    for (int x = 0; x < img.width; ++x) {
      const double phi = 2.0 * M_PI * ((x + 0.5) / img.width - 0.5);  // kernels/light.h env_uv_to_dir
      const Vec3 d{std::sin(theta) * std::sin(phi), std::cos(theta), -std::sin(theta) * std::cos(phi)};
      const Rgb c = to_rgb(grid.at(angles_of(s, d)), ground_fade(d[1]));
      for (int k = 0; k < 3; ++k) img.rgb[(size_t(y) * img.width + x) * 3 + k] = float(c[k]);
    }
  }
  return img;
}

}  // namespace spectrack
