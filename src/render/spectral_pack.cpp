// spectral_pack.cpp: see spectral_pack.h.
#include "render/spectral_pack.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "color/spectrum.h"
#include "util/error.h"

namespace spectrack {

namespace {

st_float4 coefficients(const Rgb2SpecFit& fit, const Vec3& rgb) {
  const RgbSpectrum s = rgb2spec_unbounded(fit, rgb2spec_srgb(), Rgb{rgb[0], rgb[1], rgb[2]});
  return st_float4{float(s.c[0]), float(s.c[1]), float(s.c[2]), float(s.scale)};
}

Vec3 rgb_of(const st_float4& v) { return Vec3{v.x, v.y, v.z}; }

}  // namespace

double spectrum_max(const st_float4& c) {
  // x(u) = c0 u^2 + c1 u + c2 on [0, 1]: the endpoints, and the vertex when it is a maximum inside
  double x = std::max(double(c.z), double(c.x) + c.y + c.z);
  if (c.x < 0) {
    const double u = -double(c.y) / (2.0 * c.x);
    if (u > 0 && u < 1) x = std::max(x, (double(c.x) * u + c.y) * u + c.z);
  }
  return double(c.w) * sigmoid(x);
}

void make_spectral(const SceneDesc& scene, PackedScene& packed) {
  st_scene& st = packed.st;
  const Rgb2SpecFit fit;
  for (int i = 0; i < st.n_media; ++i) {
    st_medium& m = st.media[i];
    const MediumDesc& md = scene.media[size_t(i)];
    const std::string where = scene.path + ": " + md.json_path;
    if (md.color.present)
      throw Error(fmt::format("{}/color: colour grids are not available in spectral mode yet (render.color \"spectral\", "
                              "--spectral); render medium '{}' in rgb",
                              where, md.name));
    if (md.emission.present && md.emission.blackbody)
      throw Error(fmt::format("{}/emission: blackbody emission is not available in spectral mode yet (render.color "
                              "\"spectral\", --spectral); render medium '{}' in rgb",
                              where, md.name));
    // the packed coefficients (density_scale applied), as the rgb kernels would read them
    m.sigma_a = coefficients(fit, rgb_of(m.sigma_a));
    m.sigma_s = coefficients(fit, rgb_of(m.sigma_s));
    // the majorants take the extinction at each path's wavelengths (kernels/majorant.h); its
    // largest value over every wavelength must stay a float, as the rgb values were checked to
    const double sigma_t_max = spectrum_max(m.sigma_a) + spectrum_max(m.sigma_s);
    if (!(sigma_t_max <= double(std::numeric_limits<float>::max())))
      throw Error(fmt::format("{}: the spectra of sigma_a and sigma_s reach past the float range (largest extinction "
                              "{:g} per unit density)",
                              where, sigma_t_max));
    if (m.emissive) m.Le = coefficients(fit, rgb_of(m.Le));
    m.spectral = 1;
  }
  for (int i = 0; i < st.n_lights; ++i) {
    st_light& l = st.lights[i];
    const LightDesc& ld = scene.lights[size_t(i)];
    if (l.type == ST_LIGHT_ENV_MAP)
      throw Error(fmt::format("{}: {}/map: environment maps are not available in spectral mode yet (render.color "
                              "\"spectral\", --spectral); use a uniform environment or render in rgb",
                              scene.path, ld.json_path));
    l.radiance = coefficients(fit, rgb_of(l.radiance));
    l.spectral = 1;
  }
  st.color = ST_FILM_COLOR_SPECTRAL;
  packed.features |= ST_FEATURE_SPECTRAL;
}

}  // namespace spectrack
