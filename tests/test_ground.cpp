// test_ground.cpp: the ground plane (kernels/ground.h): a white ground under a uniform environment
// is the furnace; a ground under a sun or a point light reflects albedo / pi times the irradiance
// cos theta; media below it are hidden and shadow rays below its horizon blocked; the shadow
// catcher's layer is 1 unshadowed and a slab's transmittance behind it; a holdout is transparent
// (alpha 1 - T of what lies before it) and black; a cloud over a ground agrees across trackers and
// colour modes; shards of a shadow-catcher render merge to the full render; refusals; the feature
// mask and the generic kernel.
//
// Design: each pixel's mean is one independent estimate, so the image mean must lie within 4
// standard errors of the closed form, and a twin check shows that the same statistic sees the
// answer scaled by 1.03. Where an estimate has no variance (a delta sun on a bare ground) a small
// relative tolerance stands in for the standard error, and the twin still applies.
#include <OpenImageIO/imageio.h>

#include <cmath>

#include "cli_util.h"
#include "image/image.h"
#include "scene/scene_pack.h"
#include "test_util.h"

using namespace spectrack;
using namespace st_test;
using nlohmann::json;

namespace {

const double kAlbedo[3] = {0.5, 0.6, 0.7};

// A camera looking down at the ground y = 0 (perspective: a patch around the origin), no media.
json ground_scene(const json& lights, const json& ground, int spp) {
  return {{"format", "spectrack-scene/1"},
          {"camera", {{"type", "perspective"}, {"position", {0, 3, -1}}, {"look_at", {0, 0, 0}}, {"up", {0, 1, 0}}, {"fov_deg", 30}}},
          {"film", {{"width", 16}, {"height", 16}, {"spp", spp}}},
          {"render", {{"seed", 11}}},
          {"lights", lights},
          {"ground", ground}};
}

json colored_ground(const char* mode = "diffuse") {
  return {{"height", 0.0}, {"albedo", {kAlbedo[0], kAlbedo[1], kAlbedo[2]}}, {"mode", mode}};
}

// The image mean per channel against expected[c]: within 4 SE (+ rel of it), and with twin the
// same statistic must see 1.03 x expected.
void expect_mean(const RenderResult& r, const double expected[3], bool twin, const std::string& what,
                 double rel = 1e-5) {
  EXPECT_EQ(r.stats.nonfinite_samples, 0u) << what;
  for (int c = 0; c < 3; ++c) {
    Stats m = mean_se(channel(r, c));
    const double tol = 4 * m.se + rel * std::abs(expected[c]);
    EXPECT_NEAR(m.mean, expected[c], tol) << what << ", channel " << c << " (SE " << m.se << ")";
    if (twin) EXPECT_GT(std::abs(m.mean - 1.03 * expected[c]), tol) << what << ": must detect a 3% error, channel " << c;
  }
}

// Per pixel sum of layer channel `name` (aov_sum_channels) over the pixel's samples.
std::vector<double> layer_sums(const RenderResult& r, const std::string& name) {
  const size_t na = r.aov_channels.size();
  const size_t col = size_t(std::find(r.aov_channels.begin(), r.aov_channels.end(), name) - r.aov_channels.begin());
  EXPECT_LT(col, na) << name;
  std::vector<double> v;
  for (size_t i = 0; col < na && i < r.aov_sum.size() / na; ++i) v.push_back(r.aov_sum[i * na + col]);
  return v;
}

// The shadow layer per pixel and channel: shadowed over unshadowed sums (1 where that is 0).
std::vector<double> shadow_ratio(const RenderResult& r, int c) {
  const char* ch[3] = {"R", "G", "B"};
  std::vector<double> num = layer_sums(r, std::string("shadow.") + ch[c]);
  std::vector<double> den = layer_sums(r, std::string("unshadowed.") + ch[c]);
  std::vector<double> out;
  for (size_t i = 0; i < num.size() && i < den.size(); ++i) out.push_back(den[i] != 0 ? num[i] / den[i] : 1.0);
  return out;
}

// White ground, uniform environment L, no media: every pixel sees L (the furnace), in every
// tracker and in spectral mode (a gray L: the film colour of L D65 is L).
TEST(Ground, WhiteGroundUnderAUniformEnvironmentIsTheFurnace) {
  const std::string dir = temp_dir("ground_furnace");
  struct Case {
    const char* tracker;
    bool spectral;
    int light_sampling;
  } cases[] = {{"spectral-decomposition", false, ST_LIGHT_SAMPLING_ALL},
               {"delta-per-channel", false, ST_LIGHT_SAMPLING_ALL},
               {"spectral-mis", false, ST_LIGHT_SAMPLING_CONTRIBUTION},
               {"spectral", true, ST_LIGHT_SAMPLING_ALL}};
  for (const Case& c : cases) {
    const double L[3] = {c.spectral ? 0.7 : 0.5, 0.7, c.spectral ? 0.7 : 0.9};
    json s = ground_scene({{{"type", "environment"}, {"radiance", {L[0], L[1], L[2]}}}},
                          {{"height", 0.0}, {"albedo", {1, 1, 1}}}, 64);
    s["render"]["tracker"] = c.tracker;
    if (c.spectral) s["render"]["color"] = "spectral";
    RenderOptions o = quiet_options();
    o.light_sampling = c.light_sampling;
    RenderResult r = Renderer(scene_from_json(s, dir), o).render();
    EXPECT_TRUE(r.features & ST_FEATURE_GROUND);
    expect_mean(r, L, &c == &cases[0], std::string(c.tracker) + (c.spectral ? ", spectral" : ""));
  }
}

// The same furnace under constant maps a few texels high: a texel spans a wide range of theta, so
// light sampling's pdf must take sin(theta) of the direction drawn, with the texel's weight from
// its row's centre as the CDFs are built (a pdf with the direction's sin(theta) in both made the
// one-row map 3.3% too bright, three rows 0.2%). Twin: the 3% error is seen.
TEST(Ground, WhiteGroundUnderCoarseConstantMapsIsTheFurnace) {
  const std::string dir = temp_dir("ground_coarse_maps");
  const double L[3] = {0.5, 0.5, 0.5};
  for (const auto& [w, h] : {std::pair<int, int>{2, 1}, {1, 3}, {8, 4}}) {
    const std::string map = fmt::format("map_{}x{}.exr", w, h);
    write_image(dir + "/" + map, w, h, std::vector<float>(size_t(w) * h * 3, 0.5f), {});
    json s = ground_scene({{{"type", "environment"}, {"map", map}}}, {{"height", 0.0}, {"albedo", {1, 1, 1}}}, 1024);
    s["camera"] = {{"type", "orthographic"}, {"position", {0, 3, 0}}, {"look_at", {0, 0, 0}}, {"up", {0, 0, 1}}, {"height", 2.0}};
    RenderResult r = Renderer(scene_from_json(s, dir), quiet_options()).render();
    expect_mean(r, L, true, map);
  }
}

// A sun of irradiance E at angle theta from the zenith: L = albedo / pi E cos theta (a delta light:
// no variance). A point light of intensity I at distance r: albedo / pi I cos theta / r^2. A dense
// medium below the ground changes nothing (hidden).
TEST(Ground, SunAndPointLightGiveAlbedoOverPiTimesTheIrradiance) {
  const std::string dir = temp_dir("ground_sun");
  const double to_light[3] = {0.3, 1.0, 0.5}, E[3] = {1.0, 2.0, 3.0};
  const double cos_sun = 1.0 / std::sqrt(0.09 + 1.0 + 0.25);
  json sun = {{"type", "directional"}, {"to_light", {to_light[0], to_light[1], to_light[2]}}, {"irradiance", {E[0], E[1], E[2]}}};
  json below = {{"type", "homogeneous"}, {"bounds", {{-2, -3, -2}, {2, -0.1, 2}}}, {"sigma_a", {0.1, 0.1, 0.1}},
                {"sigma_s", {5.0, 5.0, 5.0}}};
  for (const char* tracker : {"spectral-decomposition", "delta-per-channel", "spectral-mis"}) {
    json s = ground_scene(json::array({sun}), colored_ground(), 4);
    s["render"]["tracker"] = tracker;
    s["media"] = json::array({below});
    RenderResult r = Renderer(scene_from_json(s, dir), quiet_options()).render();
    double expected[3];
    for (int c = 0; c < 3; ++c) expected[c] = kAlbedo[c] / M_PI * E[c] * cos_sun;
    expect_mean(r, expected, true, std::string("sun, ") + tracker);
  }
  // a point light: an orthographic camera of tiny extent looks straight down at the origin
  const double P[3] = {0.6, 1.2, -0.3}, I[3] = {2, 3, 4};
  json s = ground_scene({{{"type", "point"}, {"position", {P[0], P[1], P[2]}}, {"intensity", {I[0], I[1], I[2]}}}},
                        colored_ground(), 4);
  s["camera"] = {{"type", "orthographic"}, {"position", {0, 2, 0}}, {"look_at", {0, 0, 0}}, {"up", {0, 0, 1}}, {"height", 1e-4}};
  RenderResult r = Renderer(scene_from_json(s, dir), quiet_options()).render();
  const double r2 = P[0] * P[0] + P[1] * P[1] + P[2] * P[2], cos_p = P[1] / std::sqrt(r2);
  double expected[3];
  for (int c = 0; c < 3; ++c) expected[c] = kAlbedo[c] / M_PI * I[c] * cos_p / r2;
  expect_mean(r, expected, true, "point light", 1e-3);  // the pixels' points lie within 1e-4 of the origin
}

// A slab of absorbing medium between a sun at the zenith and the ground: the shadow catcher's
// layer is the slab's transmittance exp(-sigma_a d) per channel (the camera ray passes under the
// slab), 1 exactly without the slab; the catcher is transparent and black (alpha 0, beauty 0).
TEST(Ground, ShadowCatcherIsOneUnshadowedAndTheSlabTransmittanceBehindIt) {
  const std::string dir = temp_dir("ground_catcher");
  const double sigma_a[3] = {0.4, 1.0, 2.0}, d = 0.5;
  json s = ground_scene({{{"type", "directional"}, {"to_light", {0, 1, 0}}, {"irradiance", {1, 2, 3}}}},
                        colored_ground("shadow_catcher"), 256);
  s["camera"] = {{"type", "orthographic"}, {"position", {0, 0.5, -3}}, {"look_at", {0, 0, 0}}, {"up", {0, 1, 0}}, {"height", 1e-3}};
  s["media"] = {{{"type", "homogeneous"}, {"bounds", {{-1, 1, -1}, {1, 1 + d, 1}}},
                 {"sigma_a", {sigma_a[0], sigma_a[1], sigma_a[2]}}, {"sigma_s", {0, 0, 0}}}};
  for (const char* tracker : {"spectral", "delta-per-channel"}) {
    s["render"]["tracker"] = tracker;
    RenderOptions o = quiet_options();
    o.transmittance = std::string(tracker) == "spectral" ? ST_TRANSMITTANCE_RATIO : ST_TRANSMITTANCE_RAY_MARCHING;
    RenderResult r = Renderer(scene_from_json(s, dir), o).render();
    ASSERT_EQ(r.aov_channels.size(), 6u) << "a shadow catcher writes the shadow layer";
    for (int c = 0; c < 3; ++c) {
      Stats m = mean_se(shadow_ratio(r, c));
      const double T = std::exp(-sigma_a[c] * d);
      EXPECT_NEAR(m.mean, T, 4 * m.se + 1e-6) << tracker << ", channel " << c;
      EXPECT_GT(std::abs(m.mean - 1.03 * T), 4 * m.se + 1e-6) << tracker << ": must detect a 3% error, channel " << c;
    }
    for (float v : r.rgb) EXPECT_EQ(v, 0.0f) << "the catcher adds nothing to the beauty";
  }
  json bare = s;
  bare.erase("media");
  RenderOptions o = quiet_options();
  o.aovs = ST_AOV_BIT(SHADOW) | ST_AOV_BIT(ALPHA) | ST_AOV_BIT(ENVIRONMENT);
  RenderResult r = Renderer(scene_from_json(bare, dir), o).render();
  for (int c = 0; c < 3; ++c)
    for (double v : shadow_ratio(r, c)) EXPECT_EQ(v, 1.0) << "nothing shadows the bare ground";
  for (double a : layer_sums(r, "AR")) EXPECT_EQ(a, 0.0) << "a shadow catcher is transparent";
}

// A holdout seen through an absorbing slab: alpha = 1 - exp(-sigma_a d) per channel, beauty 0;
// without the slab alpha is 0 exactly, and a diffuse ground there is opaque (alpha 1).
TEST(Ground, HoldoutIsTransparentBlackAndOccludes) {
  const std::string dir = temp_dir("ground_holdout");
  const double sigma_a[3] = {0.4, 1.0, 2.0}, d = 0.5;
  json s = ground_scene({{{"type", "environment"}, {"radiance", {1, 1, 1}}}}, colored_ground("holdout"), 256);
  s["camera"] = {{"type", "orthographic"}, {"position", {0, 2, 0}}, {"look_at", {0, 0, 0}}, {"up", {0, 0, 1}}, {"height", 1e-3}};
  s["render"]["tracker"] = "spectral";
  s["media"] = {{{"type", "homogeneous"}, {"bounds", {{-1, 1, -1}, {1, 1 + d, 1}}},
                 {"sigma_a", {sigma_a[0], sigma_a[1], sigma_a[2]}}, {"sigma_s", {0, 0, 0}}}};
  RenderOptions o = quiet_options();
  o.aovs = ST_AOV_BIT(ALPHA) | ST_AOV_BIT(ENVIRONMENT);
  RenderResult r = Renderer(scene_from_json(s, dir), o).render();
  const char* ch[3] = {"AR", "AG", "AB"};
  for (int c = 0; c < 3; ++c) {
    std::vector<double> a = layer_sums(r, ch[c]);
    for (double& v : a) v /= r.spp_done;
    Stats m = mean_se(a);
    const double alpha = 1 - std::exp(-sigma_a[c] * d);
    EXPECT_NEAR(m.mean, alpha, 4 * m.se + 1e-6) << "channel " << c;
    EXPECT_GT(std::abs(m.mean - 1.03 * alpha), 4 * m.se + 1e-6) << "must detect a 3% error, channel " << c;
  }
  for (double v : r.sum) EXPECT_EQ(v, 0.0) << "nothing scatters: the holdout is black";
  for (double v : layer_sums(r, "environment.R")) EXPECT_EQ(v, 0.0) << "the holdout occludes the environment";
  s.erase("media");
  for (const char* mode : {"holdout", "diffuse"}) {
    s["ground"]["mode"] = mode;
    RenderResult b = Renderer(scene_from_json(s, dir), o).render();
    const double want = std::string(mode) == "diffuse" ? double(b.spp_done) : 0.0;
    for (double v : layer_sums(b, "AG")) EXPECT_EQ(v, want) << mode;
  }
}

// A box above the ground lit by a sun below the ground's horizon, single scattering: the ground
// blocks every shadow ray (black); without the ground the box is lit.
TEST(Ground, ShadowRaysBelowTheHorizonAreBlocked) {
  const std::string dir = temp_dir("ground_horizon");
  json s = ground_scene({{{"type", "directional"}, {"to_light", {0.2, -1, 0.1}}, {"irradiance", {2, 2, 2}}}},
                        colored_ground(), 4);
  s["camera"] = {{"type", "perspective"}, {"position", {0, 1, -4}}, {"look_at", {0, 1, 0}}, {"up", {0, 1, 0}}, {"fov_deg", 20}};
  s["render"]["max_depth"] = 1;
  s["media"] = {{{"type", "homogeneous"}, {"bounds", {{-1, 0.5, -1}, {1, 1.5, 1}}}, {"sigma_a", {0.1, 0.1, 0.1}},
                 {"sigma_s", {1, 1, 1}}}};
  RenderResult r = Renderer(scene_from_json(s, dir), quiet_options()).render();
  for (float v : r.rgb) EXPECT_EQ(v, 0.0f);
  s.erase("ground");
  RenderResult lit = Renderer(scene_from_json(s, dir), quiet_options()).render();
  EXPECT_GT(*std::max_element(lit.rgb.begin(), lit.rgb.end()), 0.01f) << "without the ground the box is lit";
}

// A scattering box over a diffuse ground under a sun and an environment, multiple scattering:
// every tracker agrees with delta-per-channel, and spectral mode with rgb mode on a gray scene.
TEST(Ground, CloudOverAGroundAgreesAcrossTrackersAndColourModes) {
  const std::string dir = temp_dir("ground_cloud");
  json s = ground_scene({{{"type", "directional"}, {"to_light", {-0.5, 1, -0.3}}, {"irradiance", {3, 3, 3}}},
                         {{"type", "environment"}, {"radiance", {0.3, 0.4, 0.6}}}},
                        colored_ground(), 32);
  s["camera"] = {{"type", "perspective"}, {"position", {0, 1.5, -4}}, {"look_at", {0, 0.3, 0}}, {"up", {0, 1, 0}}, {"fov_deg", 40}};
  s["media"] = {{{"type", "homogeneous"}, {"bounds", {{-0.7, 0.2, -0.7}, {0.7, 1.2, 0.7}}}, {"sigma_a", {0.05, 0.1, 0.2}},
                 {"sigma_s", {1.5, 1.0, 0.6}}, {"phase", {{"type", "hg"}, {"g", 0.4}}}}};
  RenderOptions ro = quiet_options(256);
  ro.tracker = ST_TRACKER_DELTA_PER_CHANNEL;
  ro.seed = 3;
  RenderResult ref = Renderer(scene_from_json(s, dir), ro).render();
  for (int tracker : {ST_TRACKER_SPECTRAL_DECOMPOSITION, ST_TRACKER_SPECTRAL_MIS, ST_TRACKER_SPECTRAL}) {
    const bool twin = tracker == ST_TRACKER_SPECTRAL_DECOMPOSITION;
    RenderOptions o = quiet_options(twin ? 256 : 64);
    o.tracker = tracker;
    o.seed = 4;
    o.absorption = ST_ABSORPTION_WEIGHT;
    RenderResult r = Renderer(scene_from_json(s, dir), o).render();
    EXPECT_EQ(r.stats.nonfinite_samples, 0u);
    EXPECT_LT(max_z(r, ref), 4.0) << tracker_name(tracker);
    if (twin) EXPECT_GT(max_z(r, ref, 1.03), 4.0) << "the comparison must detect a 3% error";
  }
  json gray = s;
  gray["lights"][1]["radiance"] = {0.4, 0.4, 0.4};
  gray["ground"]["albedo"] = {0.6, 0.6, 0.6};
  gray["media"][0]["sigma_a"] = {0.1, 0.1, 0.1};
  gray["media"][0]["sigma_s"] = {1.0, 1.0, 1.0};
  RenderOptions og = quiet_options(128);
  og.seed = 5;
  RenderResult rgb = Renderer(scene_from_json(gray, dir), og).render();
  og.color = ST_FILM_COLOR_SPECTRAL;
  og.seed = 6;
  RenderResult spectral = Renderer(scene_from_json(gray, dir), og).render();
  EXPECT_LT(max_z(spectral, rgb), 4.0) << "spectral mode against rgb mode";
  EXPECT_GT(max_z(spectral, rgb, 1.03), 4.0) << "the comparison must detect a 3% error";
}

// The feature mask's contract (features.h): specialised and generic kernels render the same bits;
// a scene without a ground compiles no ground code.
TEST(Ground, FeatureBitAndGenericKernelsAgreeBitForBit) {
  const std::string dir = temp_dir("ground_generic");
  json s = ground_scene({{{"type", "directional"}, {"to_light", {-0.5, 1, -0.3}}, {"irradiance", {3, 3, 3}}},
                         {{"type", "point"}, {"position", {0.3, 1.0, 0.2}}, {"intensity", {1, 2, 3}}},
                         {{"type", "environment"}, {"radiance", {0.3, 0.4, 0.6}}}},
                        colored_ground(), 4);
  s["media"] = {{{"type", "homogeneous"}, {"bounds", {{-0.7, -0.2, -0.7}, {0.7, 0.8, 0.7}}}, {"sigma_a", {0.05, 0.1, 0.2}},
                 {"sigma_s", {1.5, 1.0, 0.6}}}};
  RenderOptions a = quiet_options();
  a.light_sampling = ST_LIGHT_SAMPLING_CONTRIBUTION;
  a.aovs = ST_AOV_BIT(ALPHA) | ST_AOV_BIT(ENVIRONMENT) | ST_AOV_BIT(DIRECT) | ST_AOV_BIT(ALBEDO);
  RenderOptions b = a;
  b.generic_kernels = true;
  RenderResult ra = Renderer(scene_from_json(s, dir), a).render();
  RenderResult rb = Renderer(scene_from_json(s, dir), b).render();
  EXPECT_TRUE(ra.features & ST_FEATURE_GROUND);
  EXPECT_EQ(rb.features, uint32_t(ST_FEATURES_ALL));
  EXPECT_EQ(ra.rgb, rb.rgb);
  EXPECT_EQ(ra.aov_sum, rb.aov_sum);
  json none = s;
  none.erase("ground");
  SceneDesc d = scene_from_json(none, dir);
  EXPECT_FALSE(pack_scene(d, resolve_settings(d, quiet_options()), PackOptions{}).features & ST_FEATURE_GROUND);
}

// Bad fields are refused with the file, their JSON path and the reason.
TEST(Ground, BadFieldsAreRefusedByPath) {
  const std::string dir = temp_dir("ground_bad");
  auto error = [&](const json& ground) {
    return error_of([&] { scene_from_json(ground_scene({{{"type", "environment"}}}, ground, 1), dir); });
  };
  EXPECT_NE(error({{"albedo", {0.5, 1.5, 0.5}}}).find("scene.json: /ground/albedo: value 1.5 is out of range"),
            std::string::npos);
  EXPECT_NE(error({{"mode", "mirror"}}).find("/ground/mode: unknown ground mode \"mirror\" (expected one of: diffuse, "
                                             "shadow_catcher, holdout)"),
            std::string::npos);
  EXPECT_NE(error({{"hieght", 1}}).find("/ground/hieght: unknown field"), std::string::npos);
  EXPECT_NE(error({{"height", "low"}}).find("/ground/height: expected a number"), std::string::npos);
  EXPECT_NE(error(json::array()).find("/ground: expected an object"), std::string::npos);
}

// Four sample-range shards of a shadow-catcher render with a cloud merge to the full render: the
// beauty, alpha and the shadow layer (its ratio and its weight) to 1e-5.
TEST(Ground, ShadowCatcherShardsMergeToTheFullRender) {
  using namespace st_cli;
  const std::string dir = test_dir();
  json s = ground_scene({{{"type", "directional"}, {"to_light", {-0.5, 1, -0.3}}, {"irradiance", {3, 3, 3}}},
                         {{"type", "environment"}, {"radiance", {0.3, 0.4, 0.6}}},
                         {{"type", "sphere"}, {"position", {0.9, 0.5, -0.8}}, {"radius", 0.15}, {"radiance", {4, 3, 2}}}},
                        colored_ground("shadow_catcher"), 8);
  s["camera"] = {{"type", "perspective"}, {"position", {0, 1.5, -4}}, {"look_at", {0, 0.3, 0}}, {"up", {0, 1, 0}}, {"fov_deg", 40}};
  s["media"] = {{{"type", "homogeneous"}, {"bounds", {{-0.7, 0.2, -0.7}, {0.7, 1.2, 0.7}}}, {"sigma_a", {0.05, 0.1, 0.2}},
                 {"sigma_s", {1.5, 1.0, 0.6}}}};
  const std::string scene = write_scene(dir, "scene.json", s);
  auto render = [&](const std::vector<std::string>& extra, const std::string& out) {
    std::vector<std::string> a = {"render", scene, "-o", out, "--quiet"};
    a.insert(a.end(), extra.begin(), extra.end());
    Proc p = run(a);
    EXPECT_TRUE(p.exited && p.code == 0) << p.describe();
    return read_image(out, ImageUse::kFilmPiece);
  };
  RgbImage full = render({}, dir + "/full.exr");
  std::vector<std::string> shards;
  for (int k = 0; k < 4; ++k) {
    shards.push_back(dir + "/shard" + std::to_string(k) + ".exr");
    render({"--spp-range", std::to_string(2 * k) + ":" + std::to_string(2 * k + 2)}, shards.back());
  }
  Proc m = run({"merge", dir + "/merged.exr", shards[1], shards[3], shards[0], shards[2]});
  ASSERT_TRUE(m.exited && m.code == 0) << m.describe();
  RgbImage merged = read_image(dir + "/merged.exr", ImageUse::kFilmPiece);
  ASSERT_EQ(merged.extra_names, full.extra_names);
  ASSERT_NE(std::find(full.extra_names.begin(), full.extra_names.end(), "shadow.G"), full.extra_names.end());
  int shadowed = 0;
  const size_t ne = full.extra_names.size();
  for (size_t i = 0; i < full.extra.size(); ++i) {
    const double a = merged.extra[i], b = full.extra[i];
    EXPECT_NEAR(a, b, 1e-5 * std::max(1.0, std::abs(b))) << full.extra_names[i % ne];
    if (full.extra_names[i % ne] == "shadow.G" && b < 0.9) ++shadowed;
  }
  EXPECT_GT(shadowed, 0) << "the cloud's shadow is on the catcher";
  for (size_t i = 0; i < full.rgb.size(); ++i) EXPECT_NEAR(merged.rgb[i], full.rgb[i], 1e-5 * std::max(1.0f, full.rgb[i]));
}

}  // namespace
