// spectral_pack.cpp: see spectral_pack.h.
#include "scene/spectral_pack.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstring>
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
  uint32_t table_offset = ST_NO_GRID;  // the RGB-to-spectrum table in the grid buffer, once
  for (int i = 0; i < st.n_media; ++i) {
    st_medium& m = st.media[i];
    const MediumDesc& md = scene.media[size_t(i)];
    const std::string where = scene.path + ": " + md.json_path;
    if (md.color.present) {
      // the kernels turn each collision's colour into a spectrum through the table (kernels/medium.h),
      // one copy in the grid buffer for every colour medium: a word holding res, then the z levels
      // and the coefficients (kernels/spectrum.h rgb2spec_lookup)
      if (table_offset == ST_NO_GRID) {
        const Rgb2SpecTable& t = rgb2spec_srgb();
        std::vector<uint32_t>& words = packed.grid_words;
        table_offset = uint32_t(words.size());
        words.push_back(uint32_t(t.res));
        const size_t first = words.size();
        words.resize(first + t.z.size() + t.coeffs.size());
        std::memcpy(words.data() + first, t.z.data(), t.z.size() * sizeof(float));
        std::memcpy(words.data() + first + t.z.size(), t.coeffs.data(), t.coeffs.size() * sizeof(float));
        if (words.size() > (size_t(1) << 30))
          throw Error(where + "/color: volumes and the colour table exceed 4 GiB, which 32-bit addressing cannot reach");
      }
      m.color_grid[3] = table_offset;
    }
    // the packed coefficients (density_scale applied), as the rgb kernels would read them
    m.sigma_a = coefficients(fit, rgb_of(m.sigma_a));
    m.sigma_s = coefficients(fit, rgb_of(m.sigma_s));
    // the majorants take the extinction at each path's wavelengths (kernels/majorant.h); its
    // largest value over every wavelength must stay a float, as the rgb values were checked to
    // (a colour medium's scattering part at its bound over the colour, scene_pack.cpp)
    const double color_bound = md.color.present ? double(m.sigma_t_maj.x) : 1.0;
    const double sigma_t_max = spectrum_max(m.sigma_a) + spectrum_max(m.sigma_s) * color_bound;
    if (!(sigma_t_max <= double(std::numeric_limits<float>::max())))
      throw Error(fmt::format("{}: the spectra of sigma_a and sigma_s reach past the float range (largest extinction "
                              "{:g} per unit density)",
                              where, sigma_t_max));
    const EmissionDesc& e = md.emission;
    if (m.emissive && e.blackbody) {
      // Planck's law per wavelength (kernels/medium.h blackbody_spectral_Le), in the film's unit;
      // the bounds were checked by the packer, which knew the mode
      const double le = film_emission_scale() * emission_gain(md);
      m.Le = st_float4{float(le), float(le), float(le), 0.0f};
      m.blackbody = 1;
      if (m.emission_grid == ST_NO_GRID) {  // a constant temperature (above the cutoff: emissive)
        double log_norm = 0;
        blackbody_xyz(std::max(e.temperature, kBlackbodyTableFloor), e.normalization, &log_norm);
        m.temperature = st_float4{0.0f, float(e.temperature), float(e.temperature_cutoff), float(kBlackbodyWarpA)};
        m.blackbody_log_norm = float(log_norm);
      }
    } else if (m.emissive) {
      m.Le = coefficients(fit, rgb_of(m.Le));
    }
    m.spectral = 1;
  }
  for (int i = 0; i < st.n_lights; ++i) {
    st_light& l = st.lights[i];
    if (l.type == ST_LIGHT_ENV_MAP) {
      // each texel's colour becomes its spectrum's coefficients in place, from the table (a map
      // has too many texels to fit one by one); the map's scale stays a number, and the sampling
      // distribution (built on max(rgb)) reads max(rgb) back as half the coefficients' scale
      const Rgb2SpecTable& table = rgb2spec_srgb();
      float* px = packed.env_data.data() + l.map_offset;
      for (size_t p = 0; p < size_t(l.map_width) * size_t(l.map_height); ++p, px += 4) {
        const RgbSpectrum c = rgb2spec_unbounded_lookup(table, Rgb{px[0], px[1], px[2]});
        px[0] = float(c.c[0]), px[1] = float(c.c[1]), px[2] = float(c.c[2]), px[3] = float(c.scale);
      }
      l.spectral = 1;
      continue;
    }
    l.radiance = coefficients(fit, rgb_of(l.radiance));
    l.spectral = 1;
  }
  st.ground.spectral = st.ground.present;  // a reflectance: the albedo's spectrum (kernels/ground.h)
  if (st.ground.present) st.ground.albedo = coefficients(fit, rgb_of(st.ground.albedo));
  st.color = ST_FILM_COLOR_SPECTRAL;
  packed.features |= ST_FEATURE_SPECTRAL;
}

}  // namespace spectrack
