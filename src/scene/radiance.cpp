// radiance.cpp: see radiance.h for the bounds and their derivation.
#include "scene/radiance.h"
#include "scene/phase_models.h"
#include "util/warning.h"

#include <fmt/format.h>

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <sstream>

namespace spectrack {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kMaxFloat = FLT_MAX;

// 7 digits: values that come from floats (texels) print as written (1e+38, not 9.99999968e+37)
std::string num(double v, int digits = 9) {
  std::ostringstream s;
  s << std::setprecision(digits) << v;
  return s.str();
}

double max3(const Vec3& v) { return std::max({v[0], v[1], v[2]}); }

[[noreturn]] void fail(const SceneDesc& s, const std::string& path, const std::string& reason,
                       const std::string& medium = "") {
  throw Error(s.path + ": " + path + ": " + reason + (medium.empty() ? "" : ", in medium \"" + medium + "\""));
}

const char* kWhy = " (the kernels carry light in single-precision float: see docs/limits.md)";

}  // namespace

double scene_phase_peak(const SceneDesc& s) {
  double peak = 1.0 / (4.0 * kPi);
  for (const MediumDesc& m : s.media) {
    if (m.phase.type == ST_PHASE_ISOTROPIC) continue;
    // the asymmetries as the kernels hold them: HG's g, the blend's two lobes' g
    const bool hg = m.phase.type == ST_PHASE_HG;
    const std::pair<const char*, double> gs[2] = {{hg ? "/g" : "/g1", m.phase.g}, {"/g2", m.phase.blend[1]}};
    for (int i = 0; i < (hg ? 1 : 2); ++i) {
      const float g = float(gs[i].second);
      if (!(std::abs(g) < 1.0f))
        fail(s, m.json_path + "/phase" + (m.phase.name == "hg" || m.phase.name == "hg2" ? gs[i].first : ""),
             "value " + num(gs[i].second) + " rounds to " + num(g) +
                 " in single precision, where the HG phase function is 0/0; |g| must be at most 0.99999994",
             m.name);
    }
    peak = std::max(peak, phase_peak(m.phase));
  }
  return peak;
}

void check_radiance_bounds(const SceneDesc& s) {
  const double peak = scene_phase_peak(s);
  for (const LightDesc& l : s.lights) {
    if (l.type == ST_LIGHT_ENV_UNIFORM) {
      const double r = max3(l.radiance);
      if (4.0 * kPi * r > kMaxRadiance)
        fail(s, l.json_path + "/radiance",
             "value " + num(r) + " is too large: 4 pi x radiance must be at most " + num(kMaxRadiance) +
                 " (radiance at most " + num(kMaxRadiance / (4.0 * kPi)) + ")" + kWhy);
    } else if (l.type == ST_LIGHT_ENV_MAP) {
      // scale x the largest texel is bounded once the map is read (check_env_map_bounds); the kernels
      // hold the scale itself in float
      if (l.scale > kMaxFloat)
        fail(s, l.json_path + "/scale", "value " + num(l.scale) + " is beyond the largest float (" + num(kMaxFloat) +
                                            ")" + kWhy);
    } else if (l.type == ST_LIGHT_SPHERE) {  // the kernels hold the radiance in float, and Le / pdf
      const double r = max3(l.radiance);
      if (4.0 * kPi * r > kMaxRadiance)
        fail(s, l.json_path + "/radiance", "value " + num(r) + " is too large: 4 pi x radiance must be at most " +
                                               num(kMaxRadiance) + kWhy);
    } else if (l.type == ST_LIGHT_POINT || l.type == ST_LIGHT_SPOT) {
      // I / r^2 grows without bound near the light; the kernels hold I itself in float
      const double i = max3(l.intensity);
      if (i > kMaxRadiance)
        fail(s, l.json_path + "/intensity",
             "value " + num(i) + " is more than " + num(kMaxRadiance) + kWhy);
    } else if (l.type == ST_LIGHT_DIRECTIONAL) {
      const double e = max3(l.irradiance);
      const double half = l.angle_deg * 0.5 * kPi / 180.0;
      if (half <= 0) {
        if (e * peak > kMaxRadiance)
          fail(s, l.json_path + "/irradiance",
               "value " + num(e) + " is too large: irradiance x the largest phase-function value (" + num(peak) +
                   ") must be at most " + num(kMaxRadiance) + " (irradiance at most " + num(kMaxRadiance / peak) + ")" +
                   kWhy);
      } else {
        const double s2 = std::sin(half) * std::sin(half);
        const double one_minus_cos = 2.0 * std::sin(0.5 * half) * std::sin(0.5 * half);
        const double pdf = 1.0 / (2.0 * kPi * one_minus_cos);
        if (pdf > kMaxLightPdf)
          fail(s, l.json_path + "/angle_deg",
               "value " + num(l.angle_deg) + " is too small: the disc's sampling pdf " + num(pdf) + " is more than " +
                   num(kMaxLightPdf) + kWhy + "; use angle_deg 0 for a delta light");
        const double radiance = e / (kPi * s2);
        if (radiance > kMaxRadiance)
          fail(s, l.json_path + "/irradiance",
               "value " + num(e) + " over a disc of " + num(l.angle_deg) + " degrees is a radiance of " +
                   num(radiance) + ", more than " + num(kMaxRadiance) + kWhy);
      }
    }
  }
  for (const MediumDesc& m : s.media) {
    if (!m.emission.present) continue;
    const EmissionDesc& e = m.emission;
    if (e.blackbody && e.temperature > 0 && !(e.temperature > e.temperature_cutoff))
      warn(fmt::format("{}: {}/emission/temperature: {:g} K is at or below the cutoff {:g} K: the medium does not emit",
                       s.path, m.json_path, e.temperature, e.temperature_cutoff));
    const double le = max3(m.emission.radiance) * m.emission.scale;
    if (le > kMaxRadiance)
      fail(s, m.json_path + "/emission",
           "radiance x scale = " + num(le) + " is more than " + num(kMaxRadiance) + kWhy, m.name);
    if (m.type == ST_MEDIUM_HOMOGENEOUS) {
      const double mua = max3(m.sigma_a) * m.density_scale;
      if (mua * le > kMaxEmissionProduct)
        fail(s, m.json_path + "/emission",
             "sigma_a x density_scale x radiance x scale = " + num(mua * le) + " is more than " +
                 num(kMaxEmissionProduct) + kWhy,
             m.name);
    }
  }
}

void check_env_map_bounds(const std::string& context, const std::string& file, const std::vector<float>& rgb,
                          int width, int height, double scale) {
  const std::string where = context + ": " + file + ": ";
  double vmax = 0, total = 0;
  size_t at = 0;
  for (int y = 0; y < height; ++y) {
    const double sin_theta = std::sin(kPi * (y + 0.5) / height);
    for (int x = 0; x < width; ++x) {
      const float* px = &rgb[(size_t(y) * size_t(width) + size_t(x)) * 3];
      for (int c = 0; c < 3; ++c)
        if (!std::isfinite(px[c]) || px[c] < 0)
          throw Error(where + "texel (" + std::to_string(x) + ", " + std::to_string(y) + ") channel " +
                      std::to_string(c) + " is " + num(px[c], 7) + ": texels must be finite and >= 0");
      const double m = std::max({px[0], px[1], px[2]});
      if (m > vmax) vmax = m, at = size_t(y) * size_t(width) + size_t(x);
      total += m * sin_theta;
    }
  }
  if (vmax * scale > kMaxRadiance)
    throw Error(where + "texel (" + std::to_string(at % size_t(width)) + ", " + std::to_string(at / size_t(width)) +
                ") = " + num(vmax, 7) + " times scale " + num(scale) + " is " + num(vmax * scale, 7) + ", more than " +
                num(kMaxRadiance) + kWhy);
  const double ratio = 2.0 * kPi * kPi * scale * total / (double(width) * height);
  if (ratio > kMaxRadiance)
    throw Error(where + "2 pi^2 x scale x the map's mean (its radiance / pdf) is " + num(ratio) + ", more than " +
                num(kMaxRadiance) + kWhy);
}

void check_emission_bounds(const std::string& context, const MediumDesc& m, double density_max, double emission_max) {
  if (!m.emission.present) return;
  const double le = max3(m.emission.radiance) * emission_gain(m) * emission_max;
  const std::string in_medium = ", in medium \"" + m.name + "\"";
  if (le > kMaxRadiance)
    throw Error(context + "/emission: radiance x scale (/ sigma_a, model density) x the emission grid's largest value (" + num(emission_max) +
                ") = " + num(le) + " is more than " + num(kMaxRadiance) + kWhy + in_medium);
  const double mua = max3(m.sigma_a) * m.density_scale * density_max;
  if (mua * le > kMaxEmissionProduct)
    throw Error(context + "/emission: sigma_a x density_scale x the density grid's largest value (" +
                num(density_max) + ") x the emitted radiance = " + num(mua * le) + " is more than " +
                num(kMaxEmissionProduct) + kWhy + in_medium);
}

}  // namespace spectrack
