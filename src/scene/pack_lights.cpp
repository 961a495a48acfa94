// pack_lights.cpp: the lights of a packed scene: directional lights, environment maps and their
// sampling CDFs, each light's power, and the light selection of next-event estimation (the
// chord estimate that resolves light sampling "auto").
#include "scene/packer.h"
#include "scene/light_pack.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

#include "color/spectrum.h"
#include "image/image.h"
#include "scene/radiance.h"
#include "scene/sky_light.h"
#include "volume/float_limits.h"
#include "scene/media_bounds.h"
#include "integrator/memory_budget.h"
#include "scene/framing.h"
#include "util/warning.h"
#include "volume/volume.h"

namespace spectrack {
namespace packing {

void Packer::add_light(int i, const LightDesc& ld) {
  st_light& l = st.lights[i];
  std::memset(&l, 0, sizeof(l));
  l.type = ld.type;
  auto mean = [](const Vec3& v) { return (v[0] + v[1] + v[2]) / 3.0; };
  if (ld.type >= ST_LIGHT_POINT) {
    pack_local_light(l, ld);
    light_power[i] = local_light_power(ld, media_boxes);
    local_strength[i] = mean(local_light_intensity(ld));
    return;
  }
  if (ld.type == ST_LIGHT_DIRECTIONAL) {
    light_power[i] = mean(ld.irradiance);
    Vec3 d = unit_vector(ld.to_light);
    l.direction = f4(d);
    double half = ld.angle_deg * 0.5 * M_PI / 180.0;
    if (half <= 0) {
      l.is_delta = 1;
      l.radiance = f4(ld.irradiance);
      l.cos_max = 1.0f;
    } else {
      // a uniform disc of angular radius `half` gives irradiance E = L * pi * sin^2(half)
      double s2 = std::sin(half) * std::sin(half);
      double L = 1.0 / (M_PI * s2);
      l.radiance = f4(ld.irradiance[0] * L, ld.irradiance[1] * L, ld.irradiance[2] * L);
      l.cos_max = float(std::cos(half));
      l.pdf_cone = float(1.0 / (2.0 * M_PI * (1.0 - std::cos(half))));
    }
    return;
  }
  if (ld.map.empty() && !ld.sky) {
    l.type = ST_LIGHT_ENV_UNIFORM;
    l.radiance = f4(ld.radiance);
    light_power[i] = 4.0 * M_PI * mean(ld.radiance);
    return;
  }
  light_power[i] = 4.0 * M_PI * ld.scale * add_env_map(l, ld);
}

// Light sampling "auto" (types.h): contribution where a shadow ray through the media takes
// kAutoContributionLookups lookups or more and there is a choice to make, else all.
int Packer::resolve_light_sampling(int requested) const {
  if (requested != ST_LIGHT_SAMPLING_AUTO) return requested;
  return st.n_lights > 1 && chord_lookups >= kAutoContributionLookups ? ST_LIGHT_SAMPLING_CONTRIBUTION
                                                                       : ST_LIGHT_SAMPLING_ALL;
}

// Equi-angular sampling (kernels/equiangular.h) towards every point, spot and sphere light, each
// chosen with 1 / n_local; "auto" turns it on while the media are thin (settings.h
// kAutoEquiangularDepth). Its MIS weights take the media's mean gray majorant extinction as the
// free-flight density's rate.
void Packer::set_equiangular(int requested) {
  int n_local = 0;
  for (int i = 0; i < st.n_lights; ++i) n_local += st.lights[i].type >= ST_LIGHT_POINT ? 1 : 0;
  const bool on = requested == kEquiangularOn || (requested == kEquiangularAuto && chord_depth < kAutoEquiangularDepth);
  st.equiangular.n_local = on && st.n_media > 0 ? n_local : 0;
  st.equiangular.sigma_t = float(mean_sigma_maj);
}

// The probabilities with which next-event estimation picks each light (st_light::select_pmf):
// 1 for every light with light sampling "all" (one shadow ray each) or "contribution" (chosen per
// event: its MIS weights are all's, types.h) or a single light; 1 / n with "uniform"; with
// "power" in proportion to power (uniform if no light has any), a light without power never being
// picked. Every light's nee_strength: its mean irradiance (directional) or mean radiance over the
// sphere (environment), i.e. its power without the 4 pi of an environment.
void Packer::set_light_selection(int light_sampling) {
  double total = 0;
  for (int i = 0; i < st.n_lights; ++i) total += light_power[i];
  double acc = 0;
  for (int i = 0; i < st.n_lights; ++i) {
    st_light& l = st.lights[i];
    l.nee_strength = float(l.type >= ST_LIGHT_POINT         ? local_strength[i]
                           : l.type == ST_LIGHT_DIRECTIONAL ? light_power[i]
                                                            : light_power[i] / (4.0 * M_PI));
    if (light_sampling == ST_LIGHT_SAMPLING_ALL || light_sampling == ST_LIGHT_SAMPLING_CONTRIBUTION || st.n_lights == 1) {
      l.select_pmf = 1.0f;
      l.select_cdf = 1.0f;
      continue;
    }
    double pmf = light_sampling == ST_LIGHT_SAMPLING_POWER && total > 0 ? light_power[i] / total : 1.0 / st.n_lights;
    acc += pmf;
    l.select_pmf = float(pmf);
    l.select_cdf = i == st.n_lights - 1 ? 1.0f : float(acc);
  }
}

double Packer::add_env_map(st_light& l, const LightDesc& ld) {
  l.type = ST_LIGHT_ENV_MAP;
  RgbImage img;
  if (ld.sky) {  // a sky: its map is made from the model (scene/sky_light.h)
    check_env_map_memory(scene.path + ": " + ld.json_path + "/resolution", ld.sky->resolution, ld.sky->resolution / 2);
    img = sky_map(*ld.sky);
  } else {
    try {
      img = read_image(ld.map, ImageUse::kEnvironmentMap, [&](int w, int h) { check_env_map_memory(ld.map, w, h); });
    } catch (const Error& e) {
      throw Error(fmt::format("{}: {}/map: {}", scene.path, ld.json_path, e.what()));
    }
  }
  check_env_map_bounds(scene.path + ": " + ld.json_path + (ld.sky ? "/intensity" : "/map"),
                       ld.sky ? std::string("the sky's map") : ld.map, img.rgb, img.width, img.height, ld.scale);
  if (!ld.sky && img.width != 2 * img.height)  // read as lat-long all the same: a map of any size is unbiased
    warn(fmt::format("{}: {}/map: {} is {}x{}; a lat-long map is twice as wide as it is high, so this one's texels "
                     "are not square{} (docs/scene-format.md, environment)",
                     scene.path, ld.json_path, ld.map, img.width, img.height,
                     img.width == img.height ? " (a square map may be pbrt-v4's equal-area layout, which spectrack "
                                               "does not read: convert it to lat-long)"
                                             : ""));
  l.radiance = f4(ld.scale, ld.scale, ld.scale);
  l.map_turn = float(std::remainder(ld.rotate_deg, 360.0) / 360.0);  // 360 is no turn: exactly 0
  const size_t W = size_t(img.width), H = size_t(img.height);
  l.map_width = img.width;
  l.map_height = img.height;
  l.map_offset = uint32_t(env_data.size());
  env_data.reserve(env_data.size() + W * H * 4 + (H + 1) + H * (W + 1));  // texels, then the CDFs
  for (size_t p = 0; p < W * H; ++p) {
    for (int c = 0; c < 3; ++c) env_data.push_back(img.rgb[p * 3 + c]);
    env_data.push_back(0.0f);
  }
  std::vector<float>().swap(img.rgb);  // the CDFs read the packed texels
  return add_env_cdf(l);
}

// sampling distribution: f(u, v) = max(rgb) * sin(theta), piecewise constant per texel; the
// marginal CDF over rows, then one conditional CDF per row, after the texels in env_data (read
// from there; f is evaluated again per texel rather than held)
double Packer::add_env_cdf(st_light& l) {
  const int W = l.map_width, H = l.map_height;
  auto texel = [&](int x, int y) { return &env_data[l.map_offset + (size_t(y) * W + x) * 4]; };
  auto f = [&](int x, int y, double s) {
    const float* px = texel(x, y);
    return std::max({px[0], px[1], px[2]}) * s;
  };
  double mean_radiance = 0;
  std::vector<double> row_sum(H, 0.0);
  for (int y = 0; y < H; ++y) {
    double s = std::sin(M_PI * (y + 0.5) / H);
    for (int x = 0; x < W; ++x) {
      const float* px = texel(x, y);
      // the texel's solid angle over the whole sphere's: (2 pi / W) (cos theta0 - cos theta1) / (4 pi)
      double omega = (std::cos(M_PI * y / H) - std::cos(M_PI * (y + 1.0) / H)) / (2.0 * W);
      mean_radiance += (double(px[0]) + px[1] + px[2]) / 3.0 * omega;
      row_sum[y] += f(x, y, s);
    }
  }
  double total = 0;
  for (double r : row_sum) total += r;
  l.cdf_offset = uint32_t(env_data.size());
  l.map_integral = float(total / (double(W) * H));
  double acc = 0;
  env_data.push_back(0.0f);
  for (int y = 0; y < H; ++y) {
    acc += row_sum[y];
    env_data.push_back(total > 0 ? float(acc / total) : float(y + 1) / H);
  }
  env_data[l.cdf_offset + H] = 1.0f;
  for (int y = 0; y < H; ++y) {
    const double s = std::sin(M_PI * (y + 0.5) / H);
    double a = 0;
    size_t base = env_data.size();
    env_data.push_back(0.0f);
    for (int x = 0; x < W; ++x) {
      a += f(x, y, s);
      env_data.push_back(row_sum[y] > 0 ? float(a / row_sum[y]) : float(x + 1) / W);
    }
    env_data[base + W] = 1.0f;
  }
  return mean_radiance;
}

}  // namespace packing
}  // namespace spectrack
