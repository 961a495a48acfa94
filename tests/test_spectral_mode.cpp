// test_spectral_mode.cpp: the renderer's spectral mode (render.color "spectral", --spectral;
// docs/spectral.md) against analytic answers, on the default OpenCL device, with tolerances of 4
// standard errors from the renders' own pixels plus the film estimator's 2e-4 (its expectation is
// the integral with F and D65 interpolated linearly, within ~1e-4 of the fitter's 1 nm sums):
//   - the absorbing slab per wavelength: the film of D65 exp(-d sigma_a(lambda)), with sigma_a the
//     upsampled spectrum of the scene's rgb, summed on the host over the 1 nm grid, for every
//     tracker; and the rgb answer exp(-d sigma_a,rgb) is told apart (the test can fail);
//   - white and emissive furnaces (per wavelength, so the film of D65 times the light's spectrum);
//   - a gray medium under a coloured light renders the rgb mode's expectation;
//   - every tracker agrees with per-channel delta tracking on a chromatic scattering medium;
//   - stratified wavelengths: a block's samples spread 16 wavelengths evenly (the pixel variance of
//     that estimate, told apart from independent samples'), and both samplings estimate one image;
//   - environment maps: a texel seen directly is the film of its spectrum times D65, a white map
//     keeps a white furnace white, a gray medium under a chromatic map renders the rgb expectation;
//   - the scene field and the stats (film layers in spectral mode: tests/test_aov.cpp AovSpectral).
#include <cmath>
#include <functional>
#include <utility>

#include <fmt/format.h>

#include "color/spectrum.h"
#include "image/image.h"
#include "scene/spectral_pack.h"
#include "test_util.h"

using namespace spectrack;
using namespace st_test;
using nlohmann::json;

namespace {

json spectral_scene(int w, int h, int spp, const std::string& tracker) {
  return json{{"format", "spectrack-scene/1"},
              {"camera", {{"type", "orthographic"}, {"position", {0, 0, -3}}, {"look_at", {0, 0, 0}}, {"up", {0, 1, 0}}, {"height", 1.0}}},
              {"film", {{"width", w}, {"height", h}, {"spp", spp}}},
              {"render", {{"tracker", tracker}, {"seed", 11}, {"color", "spectral"}}},
              {"lights", json::array()},
              {"media", json::array()}};
}

struct Mode {
  std::string tracker;
  int absorption;
  std::string name() const { return tracker + " / absorption " + absorption_name(absorption); }
};
const Mode kModes[] = {{"delta-per-channel", ST_ABSORPTION_EVENT}, {"spectral", ST_ABSORPTION_EVENT},
                       {"spectral", ST_ABSORPTION_WEIGHT},         {"decomposition", ST_ABSORPTION_WEIGHT},
                       {"spectral-decomposition", ST_ABSORPTION_WEIGHT}, {"spectral-mis", ST_ABSORPTION_WEIGHT}};

RenderOptions mode_options(const Mode& m, int spp = -1) {
  RenderOptions o = quiet_options(spp);
  o.absorption = m.absorption;
  return o;
}


RgbSpectrum upsampled(const Rgb& rgb) { return rgb2spec_unbounded(Rgb2SpecFit(), rgb2spec_srgb(), rgb); }

void expect_image(const RenderResult& r, const Rgb& expected, const std::string& what, double extra = 2e-4) {
  for (int c = 0; c < 3; ++c) {
    Stats s = mean_se(channel(r, c));
    EXPECT_NEAR(s.mean, expected[c], 4.0 * s.se + extra) << what << ", channel " << c << " (SE " << s.se << ")";
  }
}

// The gray lumpy medium added to scene j (spectral), rendered in spectral mode and in rgb mode with
// another seed: the two estimate one image when the lights' spectra come back as their colours.
std::pair<RenderResult, RenderResult> gray_medium_both_modes(json j, const std::string& dir) {
  j["media"].push_back({{"type", "vdb"}, {"file", "lumpy.vdb"}, {"density_scale", 3.0}, {"sigma_a", {0.5, 0.5, 0.5}},
                        {"sigma_s", {2.0, 2.0, 2.0}}, {"phase", {{"type", "hg"}, {"g", 0.3}}}});
  RenderResult spectral = Renderer(scene_from_json(j, dir), quiet_options()).render();
  j["render"]["color"] = "rgb";
  j["render"]["seed"] = 12;
  RenderResult rgb = Renderer(scene_from_json(j, dir), quiet_options()).render();
  EXPECT_EQ(spectral.stats.nonfinite_samples, 0u);
  return {spectral, rgb};
}

// The film estimate of `lanes` wavelengths evenly spaced in the CDF from u (a sample's four lanes, or
// a block's 4n), channel c, of a white light seen directly.
double film_estimate(double u, int lanes, int c) {
  double g = 0;
  for (int i = 0; i < lanes; ++i) {
    const double ui = u + double(i) / lanes;
    const double l = sample_visible_wavelength(ui >= 1.0 ? ui - 1.0 : ui);
    g += film_rgb_weight(l)[c] * cie_d65(l) / visible_wavelength_pdf(l);
  }
  return g / lanes;
}

// The mean, variance and fourth central moment of film_estimate(u, lanes, c) over a uniform u, by the
// midpoint rule of K points (its error is far below the tests' tolerances).
struct Moments {
  double mean = 0, var = 0, m4 = 0;
};
Moments film_estimate_moments(int lanes, int c, int K) {
  Moments m;
  for (int k = 0; k < K; ++k) m.mean += film_estimate((k + 0.5) / K, lanes, c) / K;
  for (int k = 0; k < K; ++k) {
    const double d = film_estimate((k + 0.5) / K, lanes, c) - m.mean;
    m.var += d * d / K;
    m.m4 += d * d * d * d / K;
  }
  return m;
}

}  // namespace

// A slab of thickness 2 absorbing sigma_a = (0.5, 1, 2) seen against a white environment: each
// wavelength is attenuated by exp(-2 sigma_a(lambda)) of the upsampled spectrum, which is not the
// rgb answer exp(-2 sigma_a,rgb) (the exponential does not commute with the film).
TEST(SpectralMode, AbsorbingSlabPerWavelength) {
  const std::string dir = temp_dir("spectral_slab");
  const Rgb sigma_a{0.5, 1.0, 2.0};
  const RgbSpectrum s = upsampled(sigma_a);
  const Rgb expected = film_of([&](double l) { return cie_d65(l) * std::exp(-2.0 * s(l)); });
  const Rgb rgb_answer{std::exp(-1.0), std::exp(-2.0), std::exp(-4.0)};
  std::cout << "[ info ] spectral slab: expected " << expected[0] << " " << expected[1] << " " << expected[2]
            << " (rgb mode: " << rgb_answer[0] << " " << rgb_answer[1] << " " << rgb_answer[2] << ")\n";
  for (const Mode& m : kModes) {
    json j = spectral_scene(16, 16, 256, m.tracker);
    j["lights"].push_back({{"type", "environment"}, {"radiance", {1, 1, 1}}});
    j["media"].push_back({{"type", "homogeneous"}, {"bounds", {{-1, -1, -1}, {1, 1, 1}}}, {"sigma_a", {0.5, 1.0, 2.0}},
                          {"sigma_s", {0, 0, 0}}});
    RenderResult r = Renderer(scene_from_json(j, dir), mode_options(m)).render();
    EXPECT_EQ(r.stats.nonfinite_samples, 0u);
    EXPECT_EQ(r.color, ST_FILM_COLOR_SPECTRAL);
    expect_image(r, expected, "spectral slab " + m.name());
    if (m.tracker == "delta-per-channel") {  // the twin: the rgb answer is told apart
      double worst = 0;
      for (int c = 0; c < 3; ++c) {
        Stats st = mean_se(channel(r, c));
        worst = std::max(worst, std::abs(st.mean - rgb_answer[c]) / st.se);
      }
      EXPECT_GT(worst, 4.0) << "the spectral slab must differ from the rgb answer";
    }
  }
}

// White furnace: no absorption at any wavelength, so every pixel is the film of D65: white.
TEST(SpectralMode, WhiteFurnace) {
  const std::string dir = temp_dir("spectral_furnace");
  write_lumpy(dir + "/lumpy.vdb");
  for (const Mode& m : kModes) {
    json j = spectral_scene(12, 12, 48, m.tracker);
    j["camera"] = {{"type", "perspective"}, {"position", {0.2, 0.1, -3}}, {"look_at", {0, 0, 0}}, {"up", {0, 1, 0}}, {"fov_deg", 30}};
    j["lights"].push_back({{"type", "environment"}, {"radiance", {1, 1, 1}}});
    j["media"].push_back({{"type", "vdb"}, {"file", "lumpy.vdb"}, {"density_scale", 4.0}, {"sigma_a", {0, 0, 0}},
                          {"sigma_s", {1.0, 3.0, 9.0}}, {"phase", {{"type", "hg"}, {"g", 0.4}}}});
    RenderResult r = Renderer(scene_from_json(j, dir), mode_options(m)).render();
    EXPECT_GT(r.stats.scatter_events, 1000u);
    EXPECT_EQ(r.stats.nonfinite_samples, 0u);
    expect_image(r, film_of([](double l) { return cie_d65(l); }), "spectral white furnace " + m.name());
  }
}

// Emissive furnace: the medium emits the environment's radiance, so each wavelength is in
// equilibrium and every pixel is the light's colour (both are the same upsampled spectrum times D65).
TEST(SpectralMode, EmissiveFurnace) {
  const std::string dir = temp_dir("spectral_efurnace");
  write_lumpy(dir + "/lumpy.vdb");
  const Rgb c{0.3, 0.6, 0.9};
  for (const Mode& m : kModes) {
    json j = spectral_scene(12, 12, m.tracker == "spectral-mis" ? 192 : 64, m.tracker);
    j["camera"] = {{"type", "perspective"}, {"position", {0.2, 0.1, -3}}, {"look_at", {0, 0, 0}}, {"up", {0, 1, 0}}, {"fov_deg", 30}};
    j["lights"].push_back({{"type", "environment"}, {"radiance", {0.3, 0.6, 0.9}}});
    j["media"].push_back({{"type", "vdb"}, {"file", "lumpy.vdb"}, {"density_scale", 4.0}, {"sigma_a", {1.0, 2.0, 4.0}},
                          {"sigma_s", {3.0, 1.0, 0.5}}, {"emission", {{"radiance", {0.3, 0.6, 0.9}}}}});
    RenderResult r = Renderer(scene_from_json(j, dir), mode_options(m)).render();
    EXPECT_GT(r.stats.real_collisions, 1000u);
    EXPECT_EQ(r.stats.nonfinite_samples, 0u);
    expect_image(r, c, "spectral emissive furnace " + m.name());
  }
}

// A gray medium under a coloured sun and sky: every wavelength sees the same transport, so the
// film gives the rgb mode's expectation (the lights' spectra come back as their colours).
TEST(SpectralMode, GrayMediumMatchesRgb) {
  const std::string dir = temp_dir("spectral_gray");
  write_lumpy(dir + "/lumpy.vdb");
  json j = spectral_scene(16, 16, 128, "spectral-decomposition");
  j["camera"] = {{"type", "perspective"}, {"position", {0.2, 0.1, -3}}, {"look_at", {0, 0, 0}}, {"up", {0, 1, 0}}, {"fov_deg", 30}};
  j["lights"].push_back({{"type", "environment"}, {"radiance", {0.2, 0.3, 0.6}}});
  j["lights"].push_back({{"type", "directional"}, {"to_light", {0.3, 1, -0.4}}, {"irradiance", {3.0, 2.0, 1.0}}});
  auto [spectral, rgb] = gray_medium_both_modes(j, dir);
  const double z = max_z(spectral, rgb);
  EXPECT_LT(z, 4.0) << "gray medium: spectral and rgb modes differ by " << z << " SE";
  // the twin: a 3% change of the light is seen
  EXPECT_GT(max_z(spectral, rgb, 1.03), 4.0) << "a 3% difference must be detectable";
}

// Every tracker renders the expectation of per-channel delta tracking (one path per wavelength)
// on a strongly chromatic scattering medium with a sun, a sky and emission.
TEST(SpectralMode, EveryTrackerAgreesWithPerChannelDelta) {
  const std::string dir = temp_dir("spectral_agree");
  write_lumpy(dir + "/lumpy.vdb");
  auto scene = [&](const std::string& tracker) {
    json j = spectral_scene(16, 16, 96, tracker);
    j["camera"] = {{"type", "perspective"}, {"position", {0.2, 0.1, -3}}, {"look_at", {0, 0, 0}}, {"up", {0, 1, 0}}, {"fov_deg", 30}};
    j["lights"].push_back({{"type", "environment"}, {"radiance", {0.1, 0.2, 0.4}}});
    j["lights"].push_back({{"type", "directional"}, {"to_light", {0.3, 1, -0.4}}, {"irradiance", {3.0, 2.0, 1.0}}});
    j["media"].push_back({{"type", "vdb"}, {"file", "lumpy.vdb"}, {"density_scale", 3.0}, {"sigma_a", {0.2, 0.6, 1.5}},
                          {"sigma_s", {3.0, 1.5, 0.5}}, {"phase", {{"type", "hg"}, {"g", 0.3}}},
                          {"emission", {{"radiance", {0.5, 0.2, 0.05}}}}});
    return scene_from_json(j, dir);
  };
  RenderOptions ref_opt = quiet_options(256);
  RenderResult ref = Renderer(scene("delta-per-channel"), ref_opt).render();
  EXPECT_EQ(ref.stats.nonfinite_samples, 0u);
  for (const Mode& m : kModes) {
    if (m.tracker == "delta-per-channel") continue;
    RenderOptions o = mode_options(m, 128);
    o.seed = 99;
    RenderResult r = Renderer(scene(m.tracker), o).render();
    EXPECT_EQ(r.stats.nonfinite_samples, 0u) << m.name();
    const double z = max_z(r, ref);
    EXPECT_LT(z, 4.0) << m.name() << " differs from delta-per-channel by " << z << " SE";
  }
}

// Stratified wavelengths (the default; types.h st_wavelength_sampling): the n = 2 or 4 samples of a
// pixel's block take u = r + j/16 (j = 0, 2, 1, 3), so with no medium their mean under a white
// environment is the film estimate of 4n wavelengths evenly spaced from one uniform r; independent
// samples' mean is that of n four-wavelength estimates. The variance over 64 x 64 pixels must match
// each model's (the host integrates it over u, midpoint rule) within 4 of its standard errors (from
// the fourth central moment), the other model's variance must be told apart, and the means agree.
TEST(SpectralMode, StratifiedWavelengthsSpreadABlockEvenly) {
  const std::string dir = temp_dir("spectral_strata");
  const int n_side = 64, N = n_side * n_side, K = 50000;
  for (int spp : {2, 4}) {
    Moments block[3], indep[3];
    for (int c = 0; c < 3; ++c) {
      const Moments four = film_estimate_moments(4, c, K);
      block[c] = film_estimate_moments(4 * spp, c, K);
      // the mean of spp independent four-wavelength estimates: variance and fourth central moment
      indep[c] = {four.mean, four.var / spp, (four.m4 + 3.0 * (spp - 1) * four.var * four.var) / (spp * spp * spp)};
    }
    for (const std::string sampling : {"stratified", "independent"}) {
      json j = spectral_scene(n_side, n_side, spp, "spectral-decomposition");
      j["render"]["wavelength_sampling"] = sampling;
      j["lights"].push_back({{"type", "environment"}, {"radiance", {1, 1, 1}}});
      const RenderResult r = Renderer(scene_from_json(j, dir), quiet_options()).render();
      for (int c = 0; c < 3; ++c) {
        const std::vector<double> v = channel(r, c);
        const Stats s = mean_se(v);
        double var = 0;
        for (double x : v) var += (x - s.mean) * (x - s.mean) / (N - 1);
        const Moments& want = sampling == "stratified" ? block[c] : indep[c];
        const Moments& other = sampling == "stratified" ? indep[c] : block[c];
        const double se = std::sqrt((want.m4 - want.var * want.var) / N);
        const std::string what = fmt::format("{} spp {} channel {}", sampling, spp, c);
        std::cout << "[ info ] " << what << ": pixel variance " << var << ", expected " << want.var << " (SE " << se
                  << "), the other sampling's " << other.var << "\n";
        EXPECT_NEAR(s.mean, want.mean, 4.0 * s.se + 2e-4) << what;
        EXPECT_NEAR(var, want.var, 4.0 * se) << what;
        EXPECT_GT(std::abs(var - other.var), 4.0 * se) << what << ": the other sampling's variance must be told apart";
      }
    }
  }
}

// Stratified and independent wavelengths estimate one image on a chromatic scattering medium under a
// sky and a sun (a 3% difference is told apart), for the tracker kinds that use the wavelengths
// differently: one path per wavelength, one path for all four, a hero wavelength.
TEST(SpectralMode, StratifiedAndIndependentWavelengthsAgree) {
  const std::string dir = temp_dir("spectral_strata_agree");
  write_lumpy(dir + "/lumpy.vdb");
  for (const std::string tracker : {"delta-per-channel", "spectral-decomposition", "spectral-mis"}) {
    auto render = [&](const std::string& sampling, int64_t seed) {
      json j = spectral_scene(16, 16, 64, tracker);
      j["render"]["wavelength_sampling"] = sampling;
      j["camera"] = {{"type", "perspective"}, {"position", {0.2, 0.1, -3}}, {"look_at", {0, 0, 0}}, {"up", {0, 1, 0}}, {"fov_deg", 30}};
      j["lights"].push_back({{"type", "environment"}, {"radiance", {0.1, 0.2, 0.4}}});
      j["lights"].push_back({{"type", "directional"}, {"to_light", {0.3, 1, -0.4}}, {"irradiance", {3.0, 2.0, 1.0}}});
      j["media"].push_back({{"type", "vdb"}, {"file", "lumpy.vdb"}, {"density_scale", 3.0}, {"sigma_a", {0.2, 0.6, 1.5}},
                            {"sigma_s", {3.0, 1.5, 0.5}}, {"phase", {{"type", "hg"}, {"g", 0.3}}}});
      RenderOptions o = quiet_options();
      o.seed = seed;
      RenderResult r = Renderer(scene_from_json(j, dir), o).render();
      EXPECT_EQ(r.stats.nonfinite_samples, 0u) << tracker << " " << sampling;
      return r;
    };
    const RenderResult stratified = render("stratified", 21), independent = render("independent", 22);
    EXPECT_LT(max_z(stratified, independent), 4.0) << tracker;
    EXPECT_GT(max_z(stratified, independent, 1.03), 4.0) << tracker << ": a 3% difference must be detectable";
  }
}

// The flag and the scene field agree, and seeds make spectral renders bit-identical.
TEST(SpectralMode, OptionOverridesSceneAndIsReproducible) {
  const std::string dir = temp_dir("spectral_option");
  json j = spectral_scene(8, 8, 16, "spectral-decomposition");
  j["render"].erase("color");
  j["lights"].push_back({{"type", "environment"}, {"radiance", {1, 0.5, 0.25}}});
  j["media"].push_back({{"type", "homogeneous"}, {"bounds", {{-1, -1, -1}, {1, 1, 1}}}, {"sigma_a", {0.5, 1.0, 2.0}},
                        {"sigma_s", {1, 1, 0.5}}});
  RenderOptions o = quiet_options();
  o.color = ST_FILM_COLOR_SPECTRAL;
  RenderResult a = Renderer(scene_from_json(j, dir), o).render();
  j["render"]["color"] = "spectral";
  RenderResult b = Renderer(scene_from_json(j, dir), quiet_options()).render();
  EXPECT_EQ(a.color, ST_FILM_COLOR_SPECTRAL);
  EXPECT_EQ(a.rgb, b.rgb) << "the option and the scene field render the same image, bit for bit";
  j["render"]["color"] = "rgb";
  RenderResult c = Renderer(scene_from_json(j, dir), quiet_options()).render();
  EXPECT_EQ(c.color, ST_FILM_COLOR_RGB);
  EXPECT_NE(a.rgb, c.rgb);
}

TEST(SpectralMode, SceneFieldErrors) {
  const std::string dir = temp_dir("spectral_errors");
  json j = spectral_scene(4, 4, 1, "spectral");
  j["render"]["color"] = "hyperspectral";
  const std::string msg = error_of([&] { scene_from_json(j, dir); });
  EXPECT_NE(msg.find("/render/color"), std::string::npos) << msg;
  EXPECT_NE(msg.find("rgb, spectral"), std::string::npos) << msg;
  j["render"]["color"] = "spectral";
  j["render"]["wavelength_sampling"] = "sobol";
  const std::string ws = error_of([&] { scene_from_json(j, dir); });
  EXPECT_NE(ws.find("/render/wavelength_sampling"), std::string::npos) << ws;
  EXPECT_NE(ws.find("independent, stratified"), std::string::npos) << ws;
}

// spectrum_max: the spectrum's largest value over 360..830 nm, exactly (spectral_pack.cpp checks it stays a float).
TEST(SpectralMode, SpectrumMaxBoundsTheSpectrum) {
  const Rgb2SpecFit fit;
  for (const Rgb& rgb : {Rgb{0.5, 1.0, 2.0}, Rgb{3.0, 1.5, 0.5}, Rgb{0.1, 0.9, 0.1}, Rgb{1, 1, 1}, Rgb{0, 0, 0}}) {
    const RgbSpectrum s = rgb2spec_unbounded(fit, rgb2spec_srgb(), rgb);
    const st_float4 c{float(s.c[0]), float(s.c[1]), float(s.c[2]), float(s.scale)};
    const RgbSpectrum sf{{double(c.x), double(c.y), double(c.z)}, double(c.w)};
    double grid_max = 0;
    for (double l = kSpectrumLambdaMin; l <= kSpectrumLambdaMax; l += 0.25) grid_max = std::max(grid_max, sf(l));
    const double m = spectrum_max(c);
    EXPECT_GE(m, grid_max * (1 - 1e-12)) << rgb[0] << " " << rgb[1] << " " << rgb[2];
    EXPECT_LE(m, grid_max * (1 + 1e-4) + 1e-12) << "tight: " << rgb[0] << " " << rgb[1] << " " << rgb[2];
  }
}

// ---- environment maps (each texel's colour upsampled from the table, times D65) ----

namespace {

// An 8 x 4 lat-long map of chromatic texels, some above 1 (radiances are unbounded).
void write_chromatic_map(const std::string& path) {
  std::vector<float> px(8 * 4 * 3);
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 8; ++x) {
      const float rgb[3] = {0.1f + 0.3f * float(x % 3), 0.2f + 0.5f * float(y) / 3.0f, 1.5f - 0.15f * float(x)};
      for (int c = 0; c < 3; ++c) px[size_t(y * 8 + x) * 3 + c] = rgb[c];
    }
  write_image(path, 8, 4, px, {});
}

}  // namespace

// Seen directly (no media), the map is the film of its texel's spectrum times D65, and that film
// is the texel's colour within the table's accuracy; the texels' sampling pdf is the rgb mode's.
TEST(SpectralMode, EnvironmentMapSeenDirectly) {
  const std::string dir = temp_dir("spectral_envmap");
  write_chromatic_map(dir + "/sky.exr");
  json j = spectral_scene(4, 4, 64, "spectral");
  j["lights"].push_back({{"type", "environment"}, {"map", "sky.exr"}, {"scale", 2.0}});
  RenderResult r = Renderer(scene_from_json(j, dir), quiet_options()).render();
  // direction +z: column 0, row 2 (Render.EnvironmentMapSeenDirectly)
  const Rgb texel{0.1, 0.2 + 0.5 * 2.0 / 3.0, 1.5};
  const RgbSpectrum s = rgb2spec_unbounded_lookup(rgb2spec_srgb(), texel);
  EXPECT_DOUBLE_EQ(s.scale, 2 * 1.5);
  const Rgb want = film_of([&](double l) { return 2.0 * s(l) * cie_d65(l); });
  expect_image(r, want, "texel seen directly", 2e-4 * 3);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(want[c], 2.0 * texel[c], 2e-3 * 2.0 * 1.5) << "channel " << c;
}

// A white map lights a white furnace: every pixel is 1 (sampling the map and its pdf agree);
// a gray medium under a chromatic map renders the rgb mode's expectation.
TEST(SpectralMode, EnvironmentMapLightsMedia) {
  const std::string dir = temp_dir("spectral_envmap_media");
  write_lumpy(dir + "/lumpy.vdb");
  write_image(dir + "/white.exr", 32, 16, std::vector<float>(32 * 16 * 3, 1.0f), {});
  write_chromatic_map(dir + "/sky.exr");
  for (const std::string tracker : {"spectral-decomposition", "spectral-mis"}) {
    json j = spectral_scene(12, 12, 48, tracker);
    j["camera"] = {{"type", "perspective"}, {"position", {0.2, 0.1, -3}}, {"look_at", {0, 0, 0}}, {"up", {0, 1, 0}}, {"fov_deg", 30}};
    j["lights"].push_back({{"type", "environment"}, {"map", "white.exr"}});
    j["media"].push_back({{"type", "vdb"}, {"file", "lumpy.vdb"}, {"density_scale", 4.0}, {"sigma_a", {0, 0, 0}},
                          {"sigma_s", {1.0, 3.0, 9.0}}, {"phase", {{"type", "hg"}, {"g", 0.4}}}});
    RenderResult r = Renderer(scene_from_json(j, dir), quiet_options()).render();
    EXPECT_EQ(r.stats.nonfinite_samples, 0u);
    expect_image(r, film_of([](double l) { return cie_d65(l); }), "white furnace under a white map, " + tracker);
  }
  json j = spectral_scene(16, 16, 128, "spectral-decomposition");
  j["camera"] = {{"type", "perspective"}, {"position", {0.2, 0.1, -3}}, {"look_at", {0, 0, 0}}, {"up", {0, 1, 0}}, {"fov_deg", 30}};
  j["lights"].push_back({{"type", "environment"}, {"map", "sky.exr"}, {"scale", 0.5}});
  auto [spectral, rgb] = gray_medium_both_modes(j, dir);
  EXPECT_LT(max_z(spectral, rgb), 4.0) << "gray medium under a map";
  EXPECT_GT(max_z(spectral, rgb, 1.03), 4.0) << "a 3% difference must be detectable";
}

// Four wavelengths per sample (pbrt-v4's count): with no medium, a pixel's sample under a white
// environment is the film estimate g(u) = (1/4) sum_i F(lambda_i) D65(lambda_i) / p(lambda_i) of
// one uniform u, whose mean is white and whose variance the host integrates over u (midpoint rule,
// the same interpolated F and D65). The variance over 64 x 64 one-sample pixels must match the
// four-wavelength variance within 4 of its standard errors (from the fourth central moment), and
// be told apart from three wavelengths' (2-8x larger per channel). delta-per-channel traces one
// path per wavelength: four per sample, which sum to the same estimate.
TEST(SpectralMode, FourWavelengthsPerSample) {
  const std::string dir = temp_dir("spectral_lanes");
  const int n_side = 64, N = n_side * n_side, K = 200000;
  for (const std::string tracker : {"spectral-decomposition", "delta-per-channel"}) {
    json j = spectral_scene(n_side, n_side, 1, tracker);
    j["lights"].push_back({{"type", "environment"}, {"radiance", {1, 1, 1}}});
    RenderResult r = Renderer(scene_from_json(j, dir), quiet_options()).render();
    EXPECT_EQ(r.stats.nonfinite_samples, 0u);
    EXPECT_EQ(r.stats.paths, uint64_t(N) * (tracker == "delta-per-channel" ? 4u : 1u)) << tracker;
    for (int c = 0; c < 3; ++c) {
      const Moments four = film_estimate_moments(4, c, K), three = film_estimate_moments(3, c, K);
      const std::vector<double> v = channel(r, c);
      Stats s = mean_se(v);
      double var = 0;
      for (double x : v) var += (x - s.mean) * (x - s.mean);
      var /= (N - 1);
      const double se_var = std::sqrt((four.m4 - four.var * four.var) / N);
      std::cout << "[ info ] " << tracker << " channel " << c << ": per-sample variance " << var << ", four wavelengths "
                << four.var << " (SE " << se_var << "), three " << three.var << "\n";
      EXPECT_NEAR(s.mean, four.mean, 4.0 * s.se + 2e-4) << tracker << " channel " << c;
      EXPECT_NEAR(var, four.var, 4.0 * se_var) << tracker << " channel " << c;
      EXPECT_GT(std::abs(var - three.var), 4.0 * se_var) << tracker << ": three wavelengths' variance must be told apart";
    }
  }
}
