// test_blackbody.cpp: blackbody emission (docs/scene-format.md "Blackbody emission"):
// Planck's law and its colour against published CIE values, the kernels' colour table through
// whole renders, the scene fields and their errors, and the fire scene's trackers against each
// other.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

#include "color/blackbody.h"
#include "color/spectrum.h"
#include "test_util.h"
#include "util/error.h"

using namespace spectrack;
using namespace st_test;
using json = nlohmann::json;

namespace {

// CIE 1931 chromaticity of XYZ
std::array<double, 2> xy(const Rgb& c) {
  const double s = c[0] + c[1] + c[2];
  return {c[0] / s, c[1] / s};
}
// CIE 1960 UCS (u, v) of a chromaticity (x, y)
std::array<double, 2> uv1960(double x, double y) {
  const double d = -2 * x + 12 * y + 3;
  return {4 * x / d, 6 * y / d};
}

json scene_base(int w, int h, int spp, const std::string& tracker) {
  return json{{"format", "spectrack-scene/1"},
              {"camera", {{"type", "orthographic"}, {"position", {0, 0, -3}}, {"look_at", {0, 0, 0}}, {"up", {0, 1, 0}}, {"height", 1.0}}},
              {"film", {{"width", w}, {"height", h}, {"spp", spp}}},
              {"render", {{"tracker", tracker}, {"seed", 11}}},
              {"lights", json::array()},
              {"media", json::array()}};
}

// The fire scene's medium (coefficients given) on the project's fire volume
// (data/volumes/fire.vdb, made by make_cloud --style fire), under a dim sky.
const std::string kFireVdb = std::string(SPECTRACK_SOURCE_DIR) + "/data/volumes/fire.vdb";
json fire_scene(const std::string& tracker, int spp, const json& sigma_s, const json& sigma_a) {
  json s = scene_base(12, 16, spp, tracker);
  s["camera"] = {{"type", "perspective"}, {"position", {0.0, 0.1, -4.4}}, {"look_at", {0, 0, 0}}, {"up", {0, 1, 0}}, {"fov_deg", 34}};
  s["lights"].push_back({{"type", "environment"}, {"radiance", {0.01, 0.012, 0.02}}});
  s["media"].push_back({{"type", "vdb"}, {"file", kFireVdb}, {"density_scale", 6.0}, {"sigma_s", sigma_s},
                        {"sigma_a", sigma_a}, {"phase", {{"type", "hg"}, {"g", 0.3}}},
                        {"emission", {{"type", "blackbody"}, {"normalization", "none"}}}});
  return s;
}

// The reference render's largest pixel value; every pixel must be finite.
double finite_peak(const RenderResult& r) {
  double peak = 0;
  for (int c = 0; c < 3; ++c)
    for (double v : channel(r, c)) {
      EXPECT_TRUE(std::isfinite(v));
      peak = std::max(peak, v);
    }
  return peak;
}

// A slab 3 x 3 x 2 units (voxel 1/32) of density 1 with a "heat" grid (no "temperature": found
// by name) of 2 on the slab; one voxel of heat 3 at a corner out of view makes the table reach
// higher, so the slab's temperature falls between entries.
void write_heat_slab(const std::string& path) {
  write_vdb_grids(path, openvdb::Coord(-49, -49, -33), openvdb::Coord(48, 48, 32),
                  {{"density", [](int i, int j, int k) { return (std::abs(i + 0.5) < 48 && std::abs(j + 0.5) < 48 && std::abs(k + 0.5) < 32) ? 1.0f : 0.0f; }},
                   {"heat", [](int i, int j, int k) { return (i == 48 && j == 48 && k == 32) ? 3.0f : 2.0f; }}},
                  1.0 / 32.0);
}

std::string parse_error(const json& j, const std::string& dir = ".") {
  try {
    SceneDesc s = parse_scene(j.dump(), "fire.json", dir);
    (void)s;
  } catch (const Error& e) {
    return e.what();
  }
  return "accepted";
}

}  // namespace

TEST(Blackbody, PlanckIntegratesToStefanBoltzmann) {
  // integral over all wavelengths of B(lambda, T) = sigma T^4 / pi (the units: W sr^-1 m^-2 nm^-1)
  const double sigma = 5.670374419e-8;
  for (double T : {800.0, 1500.0, 5772.0}) {
    // log-spaced trapezoid rule from 10 nm to 1 mm
    const int n = 200000;
    const double a = std::log(10.0), b = std::log(1e6);
    double sum = 0;
    for (int i = 0; i <= n; ++i) {
      const double l = std::exp(a + (b - a) * i / n);
      sum += (i == 0 || i == n ? 0.5 : 1.0) * planck(l, T) * l;
    }
    sum *= (b - a) / n;
    EXPECT_NEAR(sum / (sigma * std::pow(T, 4) / M_PI), 1.0, 1e-6) << T << " K";
  }
  EXPECT_EQ(planck(550, 0), 0.0);
  EXPECT_EQ(planck(550, -5), 0.0);
  EXPECT_NEAR(planck_peak_nm(5000), 579.55, 0.01);  // Wien
}

TEST(Blackbody, CieTableIsTheCie1931Observer) {
  ASSERT_EQ(kCie1931[0].lambda_nm, 360);
  ASSERT_EQ(kCie1931[kCieSamples - 1].lambda_nm, 830);
  EXPECT_NEAR(cie_y_integral(), 106.8569, 1e-3);  // sum of y-bar at 1 nm (pbrt-v4's CIE_Y_integral)
  EXPECT_EQ(kCie1931[555 - 360].y, 1.0);         // the photopic peak
  // sRGB's white (1, 1, 1) is D65 with Y = 1, and its primaries' luminances are Rec.709's
  const Rgb w = linear_srgb_to_xyz({1, 1, 1});
  EXPECT_NEAR(xy(w)[0], 0.3127, 1e-9);
  EXPECT_NEAR(xy(w)[1], 0.3290, 1e-9);
  EXPECT_NEAR(linear_srgb_to_xyz({1, 0, 0})[1], 0.2126, 1e-4);
  EXPECT_NEAR(linear_srgb_to_xyz({0, 1, 0})[1], 0.7152, 1e-4);
  const Rgb back = xyz_to_linear_srgb(w);
  for (double v : back) EXPECT_NEAR(v, 1.0, 1e-12);
}

TEST(Blackbody, IlluminantAIsPlanckAt2856K) {
  // CIE standard illuminant A is a Planckian radiator at 2848 K with c2 = 1.435e-2 m K, i.e.
  // 2855.5 K with today's c2 = hc/k; its published chromaticity is (0.44757, 0.40745).
  const double c2 = 6.62607015e-34 * 299792458.0 / 1.380649e-23;
  const auto c = xy(blackbody_xyz(2848.0 * c2 / 1.435e-2, BlackbodyNorm::None));
  EXPECT_NEAR(c[0], 0.44757, 5e-5);
  EXPECT_NEAR(c[1], 0.40745, 5e-5);
}

TEST(Blackbody, Planck6504KIsD65sCorrelatedColourTemperature) {
  // D65 has a correlated colour temperature of 6504 K but lies above the Planckian locus by
  // Duv = +0.0032 (CIE 1960 uv): the blackbody's x is within 0.003 of D65's, its distance to D65
  // in uv is D65's Duv, and its y is below D65's (the locus is below the daylight locus).
  const auto c = xy(blackbody_xyz(6504, BlackbodyNorm::None));
  const double x65 = 0.31271, y65 = 0.32902;
  EXPECT_NEAR(c[0], x65, 0.003);
  const auto p = uv1960(c[0], c[1]), d = uv1960(x65, y65);
  EXPECT_NEAR(std::hypot(p[0] - d[0], p[1] - d[1]), 0.0032, 0.0002);
  EXPECT_LT(c[1], y65);
  // in linear sRGB (D65 white) the 6504 K blackbody is nearly neutral
  const Rgb rgb = blackbody_linear_srgb(6504, BlackbodyNorm::Luminance);
  for (double v : rgb) EXPECT_NEAR(v, 1.0, 0.05);
}

TEST(Blackbody, LuminanceRatioIsPlancksLawAgainstTheObserver) {
  // an independent integral: Simpson's rule over the observer's 1 nm table, Planck written out
  const double h = 6.62607015e-34, c = 299792458.0, k = 1.380649e-23;
  auto Y = [&](double T) {
    double s = 0;
    for (int i = 0; i < kCieSamples; ++i) {
      const double l = kCie1931[i].lambda_nm * 1e-9;
      const double b = 2 * h * c * c / std::pow(l, 5) / (std::exp(h * c / (l * k * T)) - 1);
      const double w = (i == 0 || i == kCieSamples - 1) ? 1 : (i % 2 ? 4 : 2);
      s += w * b * kCie1931[i].y;
    }
    return s / 3;
  };
  const double expected = Y(1000) / Y(6500);
  const double got = blackbody_xyz(1000, BlackbodyNorm::None)[1] / blackbody_xyz(6500, BlackbodyNorm::None)[1];
  EXPECT_NEAR(got / expected, 1.0, 1e-3);
  EXPECT_GT(expected, 5e-10);
  EXPECT_LT(expected, 2e-9);
  // normalisations: luminance gives Y = 1; peak divides by B(lambda_max) (pbrt-v4)
  EXPECT_NEAR(blackbody_xyz(1800, BlackbodyNorm::Luminance)[1], 1.0, 1e-12);
  const double peak = planck(planck_peak_nm(1800), 1800);
  EXPECT_NEAR(blackbody_xyz(1800, BlackbodyNorm::Peak)[1] * peak / blackbody_xyz(1800, BlackbodyNorm::None)[1], 1.0, 1e-12);
}

TEST(Blackbody, TableInterpolatesTheIntegral) {
  // the kernels' table: linear in the warped temperature between entries; within 2e-4 of the
  // integral (relative to the brightest channel) at temperatures between entries, from the
  // table's 100 K floor to 1e9 K
  for (BlackbodyNorm norm : {BlackbodyNorm::Peak, BlackbodyNorm::Luminance, BlackbodyNorm::None})
    for (double T_hi : {4000.0, 1e9}) {
      const BlackbodyTable t = make_blackbody_table(100, T_hi, norm, 16384);
      ASSERT_EQ(t.rgbn.size(), 16384u * 4);
      for (double T : {150.3, 700.7, 1000.0, 1234.5, 1899.9, 2500.1, 3999.0, 12345.6, 1.1e5, 3.3e5, 7.7e6, 9.9e8}) {
        if (T > T_hi) continue;
        const double u = (blackbody_warp(T) - t.warp_first) * t.entries_per_warp;
        const int i = std::min(int(u), t.entries - 2);
        const double f = u - i;
        const Rgb exact = blackbody_linear_srgb(T, norm);
        const double top = std::max({exact[0], exact[1], exact[2]});
        for (int ch = 0; ch < 3; ++ch) {
          const double v = (1 - f) * t.rgbn[size_t(i) * 4 + ch] + f * t.rgbn[size_t(i + 1) * 4 + ch];
          EXPECT_NEAR(v, exact[ch], 2e-4 * top + 1e-30) << T << " K (table to " << T_hi << " K), channel " << ch;
        }
      }
    }
  // cold blackbodies keep their colour when normalised by luminance (no underflow to 0)
  const Rgb cold = blackbody_linear_srgb(20, BlackbodyNorm::Luminance);
  EXPECT_GT(cold[0], 1.0);
  EXPECT_TRUE(std::isfinite(cold[0]));
}

TEST(Blackbody, OutOfGamutComponentsAreClippedOnlyBelow1900K) {
  const Rgb cold = xyz_to_linear_srgb(blackbody_xyz(1000, BlackbodyNorm::Luminance));
  EXPECT_LT(cold[2], 0.0);  // a 1000 K blackbody is outside sRGB: its blue is negative
  const Rgb clipped = blackbody_linear_srgb(1000, BlackbodyNorm::Luminance);
  EXPECT_EQ(clipped[2], 0.0);
  EXPECT_EQ(clipped[0], cold[0]);
  const Rgb warm = xyz_to_linear_srgb(blackbody_xyz(2000, BlackbodyNorm::Luminance));
  for (double v : warm) EXPECT_GT(v, 0.0);
}

// ---- renders ----

// A thick, purely absorbing slab viewed head-on: every path is absorbed inside (optical depth
// 60), so each sample is Le at its absorption point exactly, and the image is Le(T).
TEST(BlackbodyRender, ThickSlabShowsTheBlackbodyColour) {
  std::string dir = temp_dir("blackbody_slab");
  write_heat_slab(dir + "/slab.vdb");
  for (const std::string tracker : {"delta-per-channel", "spectral-decomposition"})
    for (double T : {1000.0, 1900.0, 6500.0}) {
      SCOPED_TRACE(tracker + ", " + std::to_string(T) + " K");
      json s = scene_base(6, 6, 8, tracker);
      s["camera"]["height"] = 1.5;
      // heat 2 -> T = (2 - 0.5) * T / 1.5; the grid has no "temperature": "heat" is found by name
      json e = {{"type", "blackbody"}, {"temperature_offset", 0.5}, {"temperature_scale", T / 1.5},
                {"normalization", "none"}, {"scale", 3.0}};
      s["media"].push_back({{"type", "vdb"}, {"file", "slab.vdb"}, {"sigma_a", {30, 30, 30}}, {"sigma_s", {0, 0, 0}},
                            {"emission", e}});
      RenderResult r = Renderer(scene_from_json(s, dir), quiet_options()).render();
      EXPECT_GT(r.stats.lookups_emission, 0u);
      const Rgb want = blackbody_linear_srgb(T, BlackbodyNorm::None);
      const double top = 3.0 * std::max({want[0], want[1], want[2]});
      for (int c = 0; c < 3; ++c) {
        Stats st = mean_se(channel(r, c));
        EXPECT_NEAR(st.mean, 3.0 * want[c], 3e-4 * top) << "channel " << c;
      }
      // the same medium at a constant temperature (no grid, no table) gives the same image
      s["media"][0]["emission"] = {{"type", "blackbody"}, {"temperature", T}, {"normalization", "none"}, {"scale", 3.0}};
      RenderResult k = Renderer(scene_from_json(s, dir), quiet_options()).render();
      EXPECT_EQ(k.stats.lookups_emission, 0u);
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(mean_se(channel(k, c)).mean, 3.0 * want[c], 3e-4 * top) << "channel " << c;
    }
}

TEST(BlackbodyRender, HomogeneousBoxAtAConstantTemperatureMatchesItsRadianceTwin) {
  // emission {type: blackbody, temperature: T} is emission {radiance: the blackbody colour}
  const Rgb c = blackbody_linear_srgb(1500, BlackbodyNorm::Peak);
  auto scene = [&](json emission) {
    json s = scene_base(8, 8, 32, "spectral");
    s["lights"].push_back({{"type", "environment"}, {"radiance", {0.2, 0.3, 0.4}}});
    s["media"].push_back({{"type", "homogeneous"}, {"bounds", {{-1, -1, -0.3}, {1, 1, 0.3}}}, {"sigma_a", {0.8, 0.8, 0.8}},
                          {"sigma_s", {0.5, 0.5, 0.5}}, {"emission", emission}});
    return scene_from_json(s, ".");
  };
  RenderResult a = Renderer(scene({{"type", "blackbody"}, {"temperature", 1500}, {"scale", 2.0}}), quiet_options()).render();
  RenderResult b = Renderer(scene({{"radiance", {c[0], c[1], c[2]}}, {"scale", 2.0}}), quiet_options()).render();
  for (int ch = 0; ch < 3; ++ch) {
    const auto pa = channel(a, ch), pb = channel(b, ch);
    for (size_t i = 0; i < pa.size(); ++i) EXPECT_NEAR(pa[i], pb[i], 1e-5 * (1 + std::abs(pb[i])));
  }
  // below the cutoff nothing emits: the image is that of the medium without emission
  RenderResult cold = Renderer(scene({{"type", "blackbody"}, {"temperature", 90}}), quiet_options()).render();
  RenderResult dark = Renderer(scene({{"radiance", {0, 0, 0}}}), quiet_options()).render();
  for (int ch = 0; ch < 3; ++ch) {
    const auto pc = channel(cold, ch), pd = channel(dark, ch);
    for (size_t i = 0; i < pc.size(); ++i) EXPECT_EQ(pc[i], pd[i]);
  }
  EXPECT_GT(mean_se(channel(a, 0)).mean, mean_se(channel(dark, 0)).mean + 0.005);  // 1500 K glows red
}

TEST(BlackbodyRender, FireSceneTrackersAgree) {
  // the project's fire volume (data/volumes/fire.vdb, made by make_cloud --style fire) with the
  // fire scene's medium: every tracker estimates the same image within 4 SE of the per-pixel
  // differences, and the image is finite and glows
  ASSERT_TRUE(std::filesystem::exists(kFireVdb)) << kFireVdb << " (built by the bench_volumes target)";
  auto render = [&](const std::string& tracker, int spp) {
    return Renderer(scene_from_json(fire_scene(tracker, spp, {0.5, 0.5, 0.5}, {1.0, 1.0, 1.0}), "."), quiet_options()).render();
  };
  RenderResult ref = render("delta-per-channel", 256);
  EXPECT_GT(finite_peak(ref), 0.05);  // the core glows well above the sky
  for (const std::string tracker : {"delta", "spectral", "decomposition", "spectral-decomposition", "spectral-mis"}) {
    RenderResult r = render(tracker, 128);
    EXPECT_LT(max_z(r, ref), 4.0) << tracker;
    // the twin that must fail: a 5% brighter reference is seen
    if (tracker == "spectral-decomposition") EXPECT_GT(max_z(r, ref, 1.05), 4.0) << tracker;
  }
}

// ---- scene fields ----

TEST(BlackbodyScene, FieldsAndErrors) {
  json s = scene_base(4, 4, 1, "spectral");
  json m = {{"type", "homogeneous"}, {"bounds", {{-1, -1, -1}, {1, 1, 1}}}, {"sigma_a", {1, 1, 1}}, {"sigma_s", {0, 0, 0}}};
  auto with = [&](json medium_patch) {
    json t = s;
    json mm = m;
    mm.merge_patch(medium_patch);
    t["media"].push_back(mm);
    return t;
  };
  using ::testing::HasSubstr;
  EXPECT_THAT(parse_error(with({{"emission", {{"type", "blackbody"}}}})),
              HasSubstr("/media/0/emission/temperature: required"));
  EXPECT_THAT(parse_error(with({{"emission", {{"type", "blackbody"}, {"temperature", 1500}, {"normalization", "max"}}}})),
              HasSubstr("/media/0/emission/normalization: unknown normalization \"max\""));
  EXPECT_THAT(parse_error(with({{"emission", {{"type", "blackbody"}, {"temperature", -3}}}})),
              HasSubstr("/media/0/emission/temperature"));
  EXPECT_THAT(parse_error(with({{"emission", {{"type", "blackbody"}, {"temperature", 1500}, {"temperature_grid", "heat"}}}})),
              HasSubstr("/media/0/emission/temperature_grid: field not allowed"));
  EXPECT_THAT(parse_error(with({{"emission", {{"type", "blackbody"}, {"temperature", 1500}, {"scale", 1e39}}}})),
              HasSubstr("/media/0/emission/scale"));
  EXPECT_THAT(parse_error(with({{"emission", {{"type", "glow"}, {"radiance", {1, 1, 1}}}}})),
              HasSubstr("/media/0/emission/type: unknown emission type \"glow\""));
  EXPECT_THAT(parse_error(with({{"emission", {{"type", "blackbody"}, {"temperature", 1500}, {"radiance", {1, 1, 1}}}}})),
              HasSubstr("/media/0/emission"));
  EXPECT_EQ(parse_error(with({{"emission", {{"type", "blackbody"}, {"temperature", 1500}, {"normalization", "luminance"}}}})),
            "accepted");
  EXPECT_THAT(parse_error(with({{"emission", {{"type", "blackbody"}, {"temperature", 1e300}}}})),
              HasSubstr("/media/0/emission/temperature"));
  // a VDB without a temperature, heat or flame grid: the error lists the file's grids
  std::string dir = temp_dir("blackbody_scene");
  write_vdb(dir + "/smoke.vdb", "density", openvdb::Coord(-2), openvdb::Coord(2), [](int, int, int) { return 1.0f; });
  json v = s;
  v["media"].push_back({{"type", "vdb"}, {"file", "smoke.vdb"}, {"sigma_a", {1, 1, 1}}, {"emission", {{"type", "blackbody"}}}});
  // on a vdb medium, a constant temperature excludes the grid's mapping
  json c = v;
  c["media"][0]["emission"] = {{"type", "blackbody"}, {"temperature", 1500}, {"temperature_scale", 2}};
  EXPECT_THAT(parse_error(c, dir), HasSubstr("/media/0/emission/temperature: a constant temperature excludes"));
  // the message of the error that loading a scene onto the device raises
  auto render_error = [&](const json& scene) -> std::string {
    try {
      Renderer(scene_from_json(scene, dir), quiet_options()).render();
    } catch (const Error& e) {
      return e.what();
    }
    ADD_FAILURE() << "no error";
    return "";
  };
  const std::string missing = render_error(v);
  EXPECT_THAT(missing, HasSubstr("/media/0/emission/temperature_grid"));
  EXPECT_THAT(missing, HasSubstr("no grid named temperature, heat or flame"));
  EXPECT_THAT(missing, HasSubstr("density"));
  // a grid mapped beyond 1e9 K is refused, naming the grid and the fields
  v["media"][0]["emission"] = {{"type", "blackbody"}, {"temperature_grid", "density"}, {"temperature_scale", 1e38}};
  const std::string hot = render_error(v);
  EXPECT_THAT(hot, HasSubstr("/media/0/emission/temperature_grid: grid 'density'"));
  EXPECT_THAT(hot, HasSubstr("at most 1e+09 K"));
}

// ---- spectral mode (render.color "spectral": Planck's law at each path's wavelengths) ----

namespace {

// The film's linear sRGB of blackbody emission scale * k B(lambda, T) / N(T) (k: the film's
// emission scale), summed over the observer's 1 nm grid: what a spectral render estimates.
Rgb spectral_film_of_blackbody(double T, BlackbodyNorm norm, double scale) {
  double log_norm = 0;
  blackbody_xyz(T, norm, &log_norm);
  return film_of([&](double l) { return scale * film_emission_scale() * std::exp(log_planck(l, T) - log_norm); });
}

}  // namespace

// The spectrum the kernels evaluate, S = k B / N, is read by the film as the rgb mode's colour:
// the same normaliser, and k turns blackbody.h's Y convention into the film's unit. Equal within
// the film's white balance (2e-4), including out-of-gamut components, which rgb mode then clips.
TEST(BlackbodySpectral, TheFilmOfTheSpectrumIsTheRgbColour) {
  EXPECT_NEAR(film_emission_scale(), 98.89, 0.01);  // sum(y-bar D65) / sum(y-bar)
  for (BlackbodyNorm norm : {BlackbodyNorm::Peak, BlackbodyNorm::Luminance, BlackbodyNorm::None})
    for (double T : {150.0, 800.0, 1000.0, 1500.0, 1900.0, 3000.0, 6504.0, 1e4, 1e6}) {
      const Rgb film = spectral_film_of_blackbody(T, norm, 1.0);
      const Rgb rgb = xyz_to_linear_srgb(blackbody_xyz(T, norm));
      const double top = std::max({std::abs(rgb[0]), std::abs(rgb[1]), std::abs(rgb[2])});
      ASSERT_GT(top, 0.0) << T;
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(film[c], rgb[c], 3e-4 * top) << T << " K, channel " << c;
    }
  // blackbody_spectrum_max: the spectrum's largest value on the 1 nm grid, attained within it
  for (BlackbodyNorm norm : {BlackbodyNorm::Peak, BlackbodyNorm::Luminance, BlackbodyNorm::None})
    for (double T : {100.0, 1000.0, 5000.0, 1e5}) {
      double log_norm = 0, top = 0;
      blackbody_xyz(T, norm, &log_norm);
      for (int l = 360; l <= 830; ++l) top = std::max(top, std::exp(log_planck(l, T) - log_norm));
      const double m = blackbody_spectrum_max(T, norm);
      EXPECT_GE(m, top * (1 - 1e-12)) << T;
      EXPECT_LE(m, top * (1 + 1e-4)) << T;
    }
  EXPECT_NEAR(blackbody_spectrum_max(5000, BlackbodyNorm::Peak), 1.0, 1e-12);  // the peak lies inside
}

// The thick absorbing slab of ThickSlabShowsTheBlackbodyColour in spectral mode: the image is
// the film of the spectrum, through the heat grid (table normaliser, T between its entries) and
// through the constant form (no grid, no table); at 1000 K its blue is negative, which the rgb
// mode's clipped colour (0) is not.
TEST(BlackbodySpectral, ThickSlabShowsTheFilmOfPlancksLaw) {
  std::string dir = temp_dir("blackbody_spectral_slab");
  write_heat_slab(dir + "/slab.vdb");
  for (const std::string tracker : {"delta-per-channel", "spectral-decomposition"})
    for (double T : {1000.0, 1900.0, 6500.0}) {
      SCOPED_TRACE(tracker + ", " + std::to_string(T) + " K");
      // the film's wavelength sampling is the only noise (every path is absorbed): 24 x 24 x 128
      // samples bring its SE to ~0.2% of the deep-red 1000 K, so a 1% error is seen
      json s = scene_base(24, 24, 128, tracker);
      s["render"]["color"] = "spectral";
      s["camera"]["height"] = 1.5;
      json e = {{"type", "blackbody"}, {"temperature_offset", 0.5}, {"temperature_scale", T / 1.5},
                {"normalization", "luminance"}, {"scale", 3.0}};
      s["media"].push_back({{"type", "vdb"}, {"file", "slab.vdb"}, {"sigma_a", {30, 30, 30}}, {"sigma_s", {0, 0, 0}},
                            {"emission", e}});
      const Rgb want = spectral_film_of_blackbody(T, BlackbodyNorm::Luminance, 3.0);
      const double top = std::max({want[0], want[1], want[2]});
      auto check = [&](const RenderResult& r, const char* form) {
        for (int c = 0; c < 3; ++c) {
          Stats st = mean_se(channel(r, c));
          EXPECT_NEAR(st.mean, want[c], 4 * st.se + 3e-4 * top) << form << ", channel " << c << " (SE " << st.se << ")";
        }
        if (T == 1000.0) EXPECT_LT(mean_se(channel(r, 2)).mean, -0.01) << form;  // out of gamut, not clipped
      };
      RenderResult r = Renderer(scene_from_json(s, dir), quiet_options()).render();
      EXPECT_GT(r.stats.lookups_emission, 0u);
      check(r, "heat grid");
      s["media"][0]["emission"] = {{"type", "blackbody"}, {"temperature", T}, {"normalization", "luminance"}, {"scale", 3.0}};
      RenderResult k = Renderer(scene_from_json(s, dir), quiet_options()).render();
      EXPECT_EQ(k.stats.lookups_emission, 0u);
      check(k, "constant");
    }
}

// Below the cutoff nothing emits in spectral mode either: the image is the emission-less twin's.
TEST(BlackbodySpectral, BelowTheCutoffNothingEmits) {
  auto scene = [&](json emission) {
    json s = scene_base(8, 8, 16, "spectral-mis");
    s["render"]["color"] = "spectral";
    s["lights"].push_back({{"type", "environment"}, {"radiance", {0.2, 0.3, 0.4}}});
    s["media"].push_back({{"type", "homogeneous"}, {"bounds", {{-1, -1, -0.3}, {1, 1, 0.3}}}, {"sigma_a", {0.8, 0.6, 0.8}},
                          {"sigma_s", {0.5, 0.5, 0.7}}, {"emission", emission}});
    return scene_from_json(s, ".");
  };
  RenderResult cold = Renderer(scene({{"type", "blackbody"}, {"temperature", 90}}), quiet_options()).render();
  RenderResult dark = Renderer(scene({{"radiance", {0, 0, 0}}}), quiet_options()).render();
  RenderResult hot = Renderer(scene({{"type", "blackbody"}, {"temperature", 1500}, {"scale", 2.0}}), quiet_options()).render();
  for (int ch = 0; ch < 3; ++ch) {
    const auto pc = channel(cold, ch), pd = channel(dark, ch);
    for (size_t i = 0; i < pc.size(); ++i) EXPECT_EQ(pc[i], pd[i]);
  }
  EXPECT_GT(mean_se(channel(hot, 0)).mean, mean_se(channel(dark, 0)).mean + 0.005);  // 1500 K glows red
}

// The fire volume in spectral mode: the spectral trackers agree with per-channel delta tracking
// (one wavelength per path) within 4 SE of the per-pixel differences; a 5% twin is told apart.
TEST(BlackbodySpectral, FireSceneTrackersAgree) {
  ASSERT_TRUE(std::filesystem::exists(kFireVdb)) << kFireVdb << " (built by the bench_volumes target)";
  auto render = [&](const std::string& tracker, int spp) {
    json s = fire_scene(tracker, spp, {0.5, 0.45, 0.4}, {1.0, 1.1, 1.2});
    s["render"]["color"] = "spectral";
    return Renderer(scene_from_json(s, "."), quiet_options()).render();
  };
  RenderResult ref = render("delta-per-channel", 256);
  EXPECT_GT(finite_peak(ref), 0.05);
  for (const std::string tracker : {"spectral", "spectral-decomposition", "spectral-mis"}) {
    RenderResult r = render(tracker, 128);
    EXPECT_LT(max_z(r, ref), 4.0) << tracker;
    if (tracker == "spectral-decomposition") EXPECT_GT(max_z(r, ref, 1.05), 4.0) << tracker;
  }
}

// Spectral mode checks the spectrum's own bound: a luminance-normalised blackbody near the
// cutoff is bright in the deep red (S(830 nm) ~ 1e9 at 150 K for Y = 1), which rgb mode's colour
// does not show.
TEST(BlackbodySpectral, SpectralRadianceBoundIsChecked) {
  json s = scene_base(4, 4, 1, "spectral");
  s["media"].push_back({{"type", "homogeneous"}, {"bounds", {{-1, -1, -1}, {1, 1, 1}}}, {"sigma_a", {1, 1, 1}},
                        {"sigma_s", {0, 0, 0}},
                        {"emission", {{"type", "blackbody"}, {"temperature", 150}, {"normalization", "luminance"},
                                      {"scale", 1e12}}}});
  EXPECT_NO_THROW(Renderer(scene_from_json(s, "."), quiet_options()));  // rgb
  s["render"]["color"] = "spectral";
  const std::string msg = error_of([&] { Renderer(scene_from_json(s, "."), quiet_options()); });
  EXPECT_NE(msg.find("/media/0/emission/scale"), std::string::npos) << msg;
  EXPECT_NE(msg.find("spectral radiance"), std::string::npos) << msg;
}

// emission.normalization's names: one table read both ways (the parser and the messages)
TEST(Blackbody, NormalizationNamesRoundTrip) {
  for (BlackbodyNorm n : {BlackbodyNorm::Peak, BlackbodyNorm::Luminance, BlackbodyNorm::None}) {
    BlackbodyNorm back = BlackbodyNorm::Peak == n ? BlackbodyNorm::None : BlackbodyNorm::Peak;
    EXPECT_TRUE(blackbody_norm_from_name(blackbody_norm_name(n), &back)) << blackbody_norm_name(n);
    EXPECT_EQ(back, n);
  }
  BlackbodyNorm n = BlackbodyNorm::Luminance;
  EXPECT_FALSE(blackbody_norm_from_name("max", &n));
  EXPECT_EQ(n, BlackbodyNorm::Luminance);
  EXPECT_EQ(blackbody_norm_names(), "peak, luminance, none");
}
