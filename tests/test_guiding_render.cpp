// test_guiding_render.cpp: volume path guiding in the renderer (docs/guiding.md). Guided renders
// are compared with unguided ones by the per-pixel difference image (test_util.h max_z: the mean
// within 4 standard errors of 0 over the image and its quadrants), each with a twin that must see
// a 3% error:
//   - guided and unguided renders agree for several trackers in both absorption modes, and for
//     every tracker in RGB and spectral mode, on a chromatic, emissive scene of two overlapping
//     media under a sun disc and an environment (delta on an achromatic copy);
//   - a deliberately wrong cache (every region's lobes pointing away from the sun) still agrees;
//   - the same seed gives the same image twice, and generic and specialised kernels agree bit for
//     bit with guiding on; the cache is reported and bounded;
//   - tiles and sample ranges of a guided render add up to the whole render (every part trains
//     the same cache over the full film); only ranges that cut the training samples are refused;
//   - ground vertices make no records (none lies outside the grid), shadow-catcher paths none either;
//   - the training passes' vertex ring credits a path's later radiance to its first vertex exactly,
//     and in spectral mode in the film's unit (the unit of the pixel estimates guided roulette
//     compares with);
//   - guiding every scatter event (RenderOptions::guide_depth), with and without guided roulette
//     and splitting, agrees with the unguided render, and its image does not depend on the number
//     of path slots (bit for bit).
#include <algorithm>
#include <cmath>
#include <cstring>
#include <tuple>

#include "film/film.h"
#include "guiding/guide_cache.h"
#include "integrator/multi_device.h"
#include "test_util.h"

using namespace spectrack;
using namespace st_test;
using nlohmann::json;

namespace {

const double kToSun[3] = {-1, 1, -0.5};

json guiding_scene(const std::string& dir) {
  write_lumpy(dir + "/lumps.vdb");
  json s = {{"format", "spectrack-scene/1"},
            {"camera", {{"type", "perspective"}, {"position", {0.3, 0.2, -3}}, {"look_at", {0, 0, 0}}, {"up", {0, 1, 0}}, {"fov_deg", 32}}},
            {"film", {{"width", 16}, {"height", 16}, {"spp", 48}}},
            {"render", {{"seed", 3}, {"light_sampling", "all"}}},
            {"lights", {{{"type", "environment"}, {"radiance", {0.3, 0.4, 0.6}}},
                        {{"type", "directional"}, {"to_light", {kToSun[0], kToSun[1], kToSun[2]}}, {"irradiance", {3, 2.5, 2}}, {"angle_deg", 5}}}},
            {"media", json::array()}};
  s["media"].push_back({{"type", "vdb"}, {"file", "lumps.vdb"}, {"density_scale", 6.0}, {"sigma_a", {0.2, 0.5, 1.0}},
                        {"sigma_s", {2.0, 1.0, 0.4}}, {"phase", {{"type", "hg"}, {"g", 0.5}}},
                        {"emission", {{"radiance", {2.0, 0.8, 0.2}}}}});
  s["media"].push_back({{"type", "homogeneous"}, {"bounds", {{-0.8, -0.3, -0.5}, {0.6, 0.2, 0.9}}}, {"sigma_a", {0.5, 0.2, 0.1}},
                        {"sigma_s", {0.5, 1.5, 2.5}}, {"phase", {{"type", "isotropic"}}}});
  return s;
}

RenderResult render_guided(const json& s, const std::string& dir, int tracker, int absorption, uint32_t seed, bool guiding,
                           std::function<void(GuideCache&)> hook = {}, bool generic = false,
                           std::function<void(RenderOptions&)> more = {}) {
  RenderOptions o = quiet_options();
  o.tracker = tracker;
  o.absorption = absorption;
  o.seed = seed;
  o.guiding = guiding ? kGuidingOn : kGuidingOff;
  o.guide_cache_hook = std::move(hook);
  o.generic_kernels = generic;
  o.guide_grid_cells = 2;  // a 16 x 16 film trains few records: few, well-filled regions
  o.guide_alpha = kGuideAlpha;  // every fitted region guides (the learned alpha: test_guiding_oracle.cpp)
  if (more) more(o);
  return Renderer(scene_from_json(s, dir), o).render();
}

// Every region guides with alpha 0.5 toward the side away from the sun (a sharp lobe).
void point_away_from_sun(GuideCache& c) {
  const double n = std::sqrt(kToSun[0] * kToSun[0] + kToSun[1] * kToSun[1] + kToSun[2] * kToSun[2]);
  for (st_guide_region& g : c.regions) {
    g = st_guide_region{};
    for (int k = 0; k < ST_VMF_LOBES; ++k)
      g.mix.lobe[k] = st_float4{float(-kToSun[0] / n), float(-kToSun[1] / n), float(-kToSun[2] / n), 20.0f};
    g.mix.weight[0] = 1.0f;
    g.alpha = 0.5f;
  }
}

}  // namespace

TEST(GuidingRender, GuidedAgreesWithUnguided) {
  const std::string dir = temp_dir("guided_agree");
  json s = guiding_scene(dir);
  s["film"]["spp"] = 96;  // the twin's 3% must stand out of the noise by 4 standard errors
  RenderResult ref = render_guided(s, dir, ST_TRACKER_DELTA_PER_CHANNEL, ST_ABSORPTION_EVENT, 100, false);
  for (int t : {ST_TRACKER_SPECTRAL, ST_TRACKER_SPECTRAL_DECOMPOSITION, ST_TRACKER_DELTA_PER_CHANNEL})
    for (int a : {ST_ABSORPTION_WEIGHT, ST_ABSORPTION_EVENT}) {
      RenderResult r = render_guided(s, dir, t, a, 200, true);
      const std::string what = std::string(tracker_name(t)) + " / absorption " + absorption_name(a);
      EXPECT_TRUE(r.guide.used) << what;
      EXPECT_GT(r.guide.regions_guided, 0) << what << ": the cache must guide somewhere";
      EXPECT_EQ(r.stats.nonfinite_samples, 0u) << what;
      EXPECT_LT(max_z(r, ref), 4.0) << what;
      if (t == ST_TRACKER_SPECTRAL && a == ST_ABSORPTION_WEIGHT)
        EXPECT_GT(max_z(r, ref, 1.03), 4.0) << "twin: a 3% error must be detected";
    }
}

// The trackers the test above leaves out (decomposition, spectral-mis; delta on an achromatic copy
// of the scene, which it needs) in RGB mode, and every tracker in spectral mode (wavelength samples
// through the film's colour-matching weights), each in its own default absorption mode: guided and
// unguided renders agree within 4 SE, against an unguided reference of the same colour mode.
TEST(GuidingRender, GuidedAgreesWithUnguidedForEveryTrackerInRgbAndSpectralMode) {
  const std::string dir = temp_dir("guided_every_tracker");
  json chromatic = guiding_scene(dir);
  chromatic["film"]["spp"] = 96;
  json achromatic = chromatic;  // the delta tracker's: equal coefficients in every channel, no emission
  achromatic["media"][0]["sigma_a"] = {0.4, 0.4, 0.4};
  achromatic["media"][0]["sigma_s"] = {1.5, 1.5, 1.5};
  achromatic["media"][0].erase("emission");
  achromatic["media"][1]["sigma_a"] = {0.3, 0.3, 0.3};
  achromatic["media"][1]["sigma_s"] = {1.2, 1.2, 1.2};
  for (int color : {ST_FILM_COLOR_RGB, ST_FILM_COLOR_SPECTRAL}) {
    auto in_mode = [&](RenderOptions& o) { o.color = color; };
    const RenderResult ref = render_guided(chromatic, dir, ST_TRACKER_DELTA_PER_CHANNEL, ST_ABSORPTION_EVENT, 100, false,
                                           {}, false, in_mode);
    const RenderResult ref_achromatic =
        render_guided(achromatic, dir, ST_TRACKER_SPECTRAL, ST_ABSORPTION_WEIGHT, 100, false, {}, false, in_mode);
    std::vector<int> trackers = {ST_TRACKER_DECOMPOSITION, ST_TRACKER_SPECTRAL_MIS, ST_TRACKER_DELTA};
    if (color == ST_FILM_COLOR_SPECTRAL)
      trackers.insert(trackers.end(), {ST_TRACKER_DELTA_PER_CHANNEL, ST_TRACKER_SPECTRAL, ST_TRACKER_SPECTRAL_DECOMPOSITION});
    for (int t : trackers) {
      const bool delta = t == ST_TRACKER_DELTA;
      const RenderResult r = render_guided(delta ? achromatic : chromatic, dir, t, st_tracker_default_absorption(t), 200,
                                           true, {}, false, in_mode);
      const std::string what = std::string(tracker_name(t)) + (color == ST_FILM_COLOR_SPECTRAL ? ", spectral" : ", rgb");
      EXPECT_GT(r.guide.regions_guided, 0) << what << ": the cache must guide somewhere";
      EXPECT_EQ(r.stats.nonfinite_samples, 0u) << what;
      EXPECT_LT(max_z(r, delta ? ref_achromatic : ref), 4.0) << what;
      EXPECT_GT(max_z(r, delta ? ref_achromatic : ref, 1.03), 4.0) << what << ": twin, a 3% error must be detected";
    }
  }
}

TEST(GuidingRender, CachePointingAwayFromTheSunStaysUnbiased) {
  const std::string dir = temp_dir("guided_away");
  json s = guiding_scene(dir);
  s["film"]["spp"] = 128;  // a cache pointing away adds variance: more samples for the twin
  RenderResult ref = render_guided(s, dir, ST_TRACKER_SPECTRAL, ST_ABSORPTION_WEIGHT, 100, false);
  for (int a : {ST_ABSORPTION_WEIGHT, ST_ABSORPTION_EVENT}) {
    RenderResult r = render_guided(s, dir, ST_TRACKER_SPECTRAL_DECOMPOSITION, a, 300, true, point_away_from_sun);
    EXPECT_LT(max_z(r, ref), 4.0) << "absorption " << absorption_name(a);
    if (a == ST_ABSORPTION_WEIGHT) EXPECT_GT(max_z(r, ref, 1.03), 4.0) << "twin: a 3% error must be detected";
  }
}

TEST(GuidingRender, DeterministicAndGenericKernelsAgree) {
  const std::string dir = temp_dir("guided_bits");
  json s = guiding_scene(dir);
  s["film"]["spp"] = 8;  // the training passes' samples and the render's
  RenderResult a = render_guided(s, dir, ST_TRACKER_SPECTRAL, ST_ABSORPTION_WEIGHT, 7, true);
  RenderResult b = render_guided(s, dir, ST_TRACKER_SPECTRAL, ST_ABSORPTION_WEIGHT, 7, true);
  RenderResult g = render_guided(s, dir, ST_TRACKER_SPECTRAL, ST_ABSORPTION_WEIGHT, 7, true, {}, true);
  RenderResult off = render_guided(s, dir, ST_TRACKER_SPECTRAL, ST_ABSORPTION_WEIGHT, 7, false);
  ASSERT_EQ(a.rgb.size(), b.rgb.size());
  EXPECT_EQ(std::memcmp(a.rgb.data(), b.rgb.data(), a.rgb.size() * 4), 0) << "same seed, same image";
  EXPECT_EQ(std::memcmp(a.rgb.data(), g.rgb.data(), a.rgb.size() * 4), 0) << "generic and specialised kernels";
  EXPECT_NE(std::memcmp(a.rgb.data(), off.rgb.data(), a.rgb.size() * 4), 0) << "guiding changes the samples";
  EXPECT_TRUE(a.features & ST_FEATURE_GUIDING);
  EXPECT_FALSE(off.features & ST_FEATURE_GUIDING);
  EXPECT_FALSE(off.guide.used);
  EXPECT_EQ(a.guide.training_passes, kGuideTrainingPasses);
  EXPECT_EQ(a.spp_done, 8) << "the training passes' samples are part of the image";
  EXPECT_GT(a.guide.records, 0u);
  // the header, the regions, the kd-trees' nodes (one per cell and two per region refinement
  // added) and one pixel estimate per film pixel; a 2-cell grid along the longest axis: 1-8 cells
  const size_t fixed = sizeof(st_guide_header) + size_t(a.guide.regions) * sizeof(st_guide_region) + 16 * 16 * 4;
  ASSERT_GT(a.guide.bytes, fixed);
  const int64_t cells = 2 * int64_t(a.guide.regions) - int64_t((a.guide.bytes - fixed) / sizeof(st_guide_node));
  EXPECT_EQ((a.guide.bytes - fixed) % sizeof(st_guide_node), 0u);
  EXPECT_GE(cells, 1);
  EXPECT_LE(cells, 8);
  EXPECT_LE(size_t(a.guide.regions), kGuideMaxRegions);
  EXPECT_GT(a.guide.seconds_training, 0.0);
  EXPECT_GE(a.seconds_render, a.guide.seconds_training) << "training is part of seconds_render";
}

// The training pass leaves the render at least one sample (a render of few samples trains spp - 1),
// and the render's statistics count the pass's paths, iterations and kernels with its own.
TEST(GuidingRender, TrainingLeavesASampleAndItsStatisticsCount) {
  const std::string dir = temp_dir("guided_schedule");
  json s = guiding_scene(dir);
  for (int spp : {2, 3, kGuideTrainingSpp[0] + 2}) {
    s["film"]["spp"] = spp;
    RenderResult a = render_guided(s, dir, ST_TRACKER_SPECTRAL, ST_ABSORPTION_WEIGHT, 7, true);
    RenderResult off = render_guided(s, dir, ST_TRACKER_SPECTRAL, ST_ABSORPTION_WEIGHT, 7, false);
    EXPECT_EQ(a.spp_done, spp);
    EXPECT_EQ(a.guide.training_passes, 1) << spp << " spp";
    EXPECT_EQ(a.stats.paths, off.stats.paths) << spp << " spp: every sample's paths, the training's too";
    EXPECT_GE(a.stats.iterations, a.guide.training_iterations + 1) << spp << " spp";
    EXPECT_GT(a.guide.training_iterations, 0u);
    EXPECT_GE(a.guide.drains, a.guide.training_iterations) << "one drain per training iteration";
    ASSERT_TRUE(a.stats.kernels.count("k_scatter"));
    EXPECT_GT(a.stats.kernels.at("k_scatter").launches, a.guide.training_kernels.at("k_scatter").launches);
    EXPECT_GT(a.cpu_seconds_render, 0.0);
  }
}

// `auto` guides where a lamp (a medium that emits and does not scatter: light next-event
// estimation does not sample) lights a medium that scatters and no scattering medium emits,
// without guided roulette and splitting, and stays off elsewhere and where the render asks for
// what guiding refuses.
TEST(GuidingRender, AutoGuidesWhereALampLightsAScatteringMedium) {
  const std::string dir = temp_dir("guided_auto");
  SceneDesc plain = scene_from_json(guiding_scene(dir), dir);  // 48 spp, a sun and a sky
  ASSERT_FALSE(plain.media.empty());
  RenderOptions o = quiet_options();
  EXPECT_FALSE(guiding_pays(plain)) << "its emission is in a medium that scatters";
  plain.media[0].emission = EmissionDesc{};
  EXPECT_FALSE(guiding_pays(plain));
  EXPECT_FALSE(resolve_settings(plain, o).guiding) << "every light is sampled by next-event estimation";
  EXPECT_EQ(resolve_settings(plain, o).guide_training_samples, 0);
  SceneDesc lit = plain;
  MediumDesc lamp = plain.media[0];
  lamp.name = "lamp", lamp.sigma_s = Vec3{0, 0, 0}, lamp.sigma_a = Vec3{5, 5, 5};
  lamp.emission.present = true, lamp.emission.radiance = Vec3{4, 4, 4};
  lit.media.push_back(lamp);
  EXPECT_TRUE(guiding_pays(lit));
  const RenderSettings on = resolve_settings(lit, o);
  EXPECT_TRUE(on.guiding);
  EXPECT_EQ(on.guiding_requested, kGuidingAuto);
  EXPECT_FALSE(on.guide_splitting) << "auto guides directions alone";
  EXPECT_EQ(on.guide_training_samples, kGuideTrainingSpp[0]);
  RenderOptions asked = o;
  asked.guiding = kGuidingOn;
  EXPECT_TRUE(resolve_settings(lit, asked).guide_splitting) << "--guiding on keeps --guide-splitting's default";
  // an explicit --guide-splitting is obeyed where guiding runs (auto included), and "on" without
  // guiding is refused rather than ignored
  RenderOptions split = o;
  split.guide_splitting = true;
  EXPECT_TRUE(resolve_settings(lit, split).guide_splitting) << "auto splits when asked";
  asked.guide_splitting = false;
  EXPECT_FALSE(resolve_settings(lit, asked).guide_splitting);
  EXPECT_THROW(resolve_settings(plain, split), UsageError) << "auto leaves the plain scene unguided";
  split.guiding = kGuidingOff;
  EXPECT_THROW(resolve_settings(lit, split), UsageError);
  split.guide_splitting = false;
  EXPECT_FALSE(resolve_settings(lit, split).guide_splitting);
  // the twins: a lamp that also scatters (fire in its smoke), a lamp inside a fireball that emits
  // too, a lamp alone, a lamp of no power
  SceneDesc fire = plain;
  fire.media[0].emission = lamp.emission;
  EXPECT_FALSE(guiding_pays(fire));
  SceneDesc fireball = lit;
  fireball.media[0].emission = lamp.emission;
  EXPECT_FALSE(guiding_pays(fireball));
  SceneDesc alone = plain;
  alone.media = {lamp};
  EXPECT_FALSE(guiding_pays(alone));
  SceneDesc dark = lit;
  dark.media.back().emission.scale = 0;
  EXPECT_FALSE(guiding_pays(dark));
  SceneDesc black = lit;  // a colour of 0, a blackbody below its cutoff: no source term
  black.media.back().emission.radiance = Vec3{0, 0, 0};
  EXPECT_FALSE(guiding_pays(black));
  black.media.back().emission.blackbody = true, black.media.back().emission.temperature = 50;
  EXPECT_FALSE(guiding_pays(black));
  black.media.back().emission.temperature = 1500;
  EXPECT_TRUE(guiding_pays(black));
  SceneDesc off_fire = lit;  // a fireball of density scale 0 neither scatters nor emits
  off_fire.media[0].emission = lamp.emission, off_fire.media[0].density_scale = 0;
  EXPECT_TRUE(guiding_pays(off_fire));
  SceneDesc tinted = lit;  // an albedo colour grid makes a medium of sigma_s 0 scatter
  tinted.media[0].sigma_s = Vec3{0, 0, 0}, tinted.media[1].sigma_s = Vec3{0, 0, 0};
  EXPECT_FALSE(guiding_pays(tinted));
  tinted.media[0].color.present = true, tinted.media[0].color.mode = ST_COLOR_ALBEDO;
  EXPECT_TRUE(guiding_pays(tinted));
  // what guiding refuses turns auto off instead of failing: film states, equi-angular sampling;
  // an explicit --guiding off too. Adaptive sampling of a window is refused whatever guiding does
  RenderOptions state = o, equiangular = o, adaptive_tile = o, off = o;
  state.film_state = true;
  equiangular.equiangular = kEquiangularOn;
  adaptive_tile.noise_target = 0.05, adaptive_tile.adaptive = true;
  adaptive_tile.pixel_bounds = std::array<int, 4>{0, 8, 0, 8};
  off.guiding = kGuidingOff;
  for (const RenderOptions* r : {&state, &equiangular, &off}) EXPECT_FALSE(resolve_settings(lit, *r).guiding);
  EXPECT_THROW(resolve_settings(lit, adaptive_tile), UsageError);
  RenderOptions one = o;  // a whole render of one sample has no training sample
  one.spp = 1;
  EXPECT_FALSE(resolve_settings(lit, one).guiding);
  SceneDesc point_lit = lit;  // equi-angular auto with a point light: auto leaves it to equi-angular sampling
  LightDesc point;
  point.type = ST_LIGHT_POINT;
  point_lit.lights.push_back(point);
  RenderOptions ea_auto = o;
  ea_auto.equiangular = kEquiangularAuto;
  EXPECT_FALSE(resolve_settings(point_lit, ea_auto).guiding);
  EXPECT_TRUE(resolve_settings(point_lit, o).guiding) << "equi-angular sampling is off by default";
  EXPECT_EQ(render_identity(on).guided, "on") << "a film records whether guiding ran (merge compares it)";
  EXPECT_EQ(render_identity(resolve_settings(lit, state)).guided, "off");
  // a shard of an auto-guided render obeys the training samples like any guided one
  RenderOptions shard = o;
  shard.sample_range = true, shard.sample_begin = 2, shard.spp = 8;
  try {
    resolve_settings(lit, shard);
    ADD_FAILURE() << "a range that cuts the training samples";
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("on by auto"), std::string::npos) << e.what();
  }
  EXPECT_NO_THROW(resolve_settings(plain, shard)) << "no guiding, no training samples to cut";
}

TEST(GuidingRender, OnlyRangesThatCutTheTrainingSamplesAreRefused) {
  const std::string dir = temp_dir("guided_refuse");
  const SceneDesc scene = scene_from_json(guiding_scene(dir), dir);  // 48 spp
  RenderOptions o = quiet_options();
  o.guiding = kGuidingOn;
  EXPECT_TRUE(resolve_settings(scene, o).guiding);
  const int T = kGuideTrainingSpp[0];
  EXPECT_EQ(resolve_settings(scene, o).guide_training_samples, T);
  RenderOptions tile = o;  // a tile trains over the full film
  tile.pixel_bounds = std::array<int, 4>{0, 8, 0, 8};
  EXPECT_EQ(resolve_settings(scene, tile).guide_training_samples, T);
  RenderOptions few = o;  // a whole render of T samples trains T - 1 and renders one of its own
  few.spp = T;
  EXPECT_EQ(resolve_settings(scene, few).guide_training_samples, T - 1);
  RenderOptions shard = o;
  shard.sample_range = true;
  shard.spp = 3;
  for (int64_t begin : {int64_t(T), int64_t(T + 5)}) {  // holds none of the training samples
    shard.sample_begin = begin;
    EXPECT_EQ(resolve_settings(scene, shard).guide_training_samples, T) << begin;
  }
  shard.sample_begin = 0;
  shard.spp = T + 1;  // holds them all and one more
  EXPECT_EQ(resolve_settings(scene, shard).guide_training_samples, T);
  shard.spp = T;  // a shard of T samples from 0: the whole render's training might be longer
  EXPECT_THROW(resolve_settings(scene, shard), UsageError);
  for (int64_t begin = 1; begin < T; ++begin) {  // cuts them
    shard.sample_begin = begin;
    shard.spp = 8;
    EXPECT_THROW(resolve_settings(scene, shard), UsageError) << begin;
  }
  RenderOptions adaptive_tile = tile;  // adaptive sampling trains in its first round, over the film
  adaptive_tile.noise_target = 0.05;
  adaptive_tile.adaptive = true;
  EXPECT_THROW(resolve_settings(scene, adaptive_tile), UsageError);
}

// Every part of a guided render trains the same cache over the full film and keeps the training
// samples only where its range holds them, so tiles are those pixels of the full render bit for
// bit and sample ranges add up to it (film sums; relative 1e-6). The twin: the same parts rendered
// unguided differ from the guided render (so the comparison sees the guide), and a range whose
// Renderer is asked for samples that cut the training samples is an error.
TEST(GuidingRender, TilesAndSampleRangesAddUpToTheWholeRender) {
  const std::string dir = temp_dir("guided_parts");
  json s = guiding_scene(dir);
  s["film"]["spp"] = 10;
  const SceneDesc scene = scene_from_json(s, dir);
  auto options = [](bool guiding) {
    RenderOptions o = quiet_options();
    o.seed = 9;
    o.guiding = guiding ? kGuidingOn : kGuidingOff;
    o.guide_grid_cells = 2;
    o.guide_alpha = kGuideAlpha;
    return o;
  };
  const RenderResult whole = Renderer(scene, options(true)).render();
  const RenderResult unguided = Renderer(scene, options(false)).render();
  ASSERT_TRUE(whole.guide.used);
  ASSERT_EQ(whole.spp_done, 10);
  const int W = 16;
  // tiles: the left 5 columns and the rest
  for (auto b : {std::array<int, 4>{0, 5, 0, 16}, std::array<int, 4>{5, 16, 0, 16}}) {
    RenderOptions o = options(true);
    o.pixel_bounds = b;
    const RenderResult t = Renderer(scene, o).render();
    ASSERT_EQ(t.spp_done, 10);
    ASSERT_EQ(t.sum.size(), size_t(3 * (b[1] - b[0]) * (b[3] - b[2])));
    int differ = 0;
    for (int y = b[2]; y < b[3]; ++y)
      for (int x = b[0]; x < b[1]; ++x)
        for (int k = 0; k < 3; ++k)
          differ += t.sum[3 * ((y - b[2]) * (b[1] - b[0]) + (x - b[0])) + k] != whole.sum[3 * (y * W + x) + k];
    EXPECT_EQ(differ, 0) << "tile x " << b[0] << ".." << b[1];
  }
  // sample ranges 0:6 (the 4 training samples and 2 of the render's own) and 6:10
  std::vector<double> sum(whole.sum.size(), 0.0), sum_unguided(whole.sum.size(), 0.0);
  for (auto [begin, end] : {std::pair<int, int>{0, 6}, std::pair<int, int>{6, 10}}) {
    for (bool guiding : {true, false}) {
      RenderOptions o = options(guiding);
      o.sample_begin = begin;
      o.spp = end - begin;
      o.sample_range = true;
      const RenderResult r = Renderer(scene, o).render();
      ASSERT_EQ(r.spp_done, end - begin);
      EXPECT_EQ(r.sample_begin, begin);
      for (size_t i = 0; i < sum.size(); ++i) (guiding ? sum : sum_unguided)[i] += r.sum[i];
    }
  }
  auto differing = [&](const std::vector<double>& a, const std::vector<double>& b, double rel) {
    int n = 0;
    for (size_t i = 0; i < a.size(); ++i) n += std::abs(a[i] - b[i]) > rel * std::max(std::abs(a[i]), std::abs(b[i]));
    return n;
  };
  EXPECT_EQ(differing(sum, whole.sum, 1e-6), 0);
  EXPECT_GT(differing(sum_unguided, whole.sum, 1e-6), int(whole.sum.size()) / 2) << "the twin: unguided parts";
  EXPECT_EQ(differing(sum_unguided, unguided.sum, 1e-6), 0);
  // a Renderer asked for samples that cut the training samples 0:4 refuses
  Renderer r(scene, options(true));
  EXPECT_THROW(r.render(2, 4), Error);
  EXPECT_EQ(differing(r.render(0, 10).sum, whole.sum, 0.0), 0) << "the same range again gives the same image";
}

// A white furnace cut after the first scatter event (a uniform sky of radiance 1 around a thin,
// non-absorbing, isotropic medium; max_depth 1): a first-event vertex's scattered ray either leaves
// the medium and sees the sky, weighted by the power heuristic of two equal pdfs (the phase
// function's and the uniform sky's, 1 / 4 pi): 1/2, or scatters and ends with nothing. The ring
// credits the escape to the vertex through the path's radiance at k_finish. Returns the first
// training pass's regions.
namespace {

std::vector<st_guide_region> furnace_regions(const std::string& name, int color, int tracker = ST_TRACKER_SPECTRAL,
                                             Vec3 sky = {1, 1, 1}, int size = 32) {
  const std::string dir = temp_dir(name);
  json s = {{"format", "spectrack-scene/1"},
            {"camera", {{"type", "perspective"}, {"position", {0, 0, -4.5}}, {"look_at", {0, 0, 0}}, {"up", {0, 1, 0}}, {"fov_deg", 26}}},
            {"film", {{"width", size}, {"height", size}, {"spp", 8}}},
            {"render", {{"seed", 5}, {"light_sampling", "all"}, {"max_depth", 1}}},
            {"lights", {{{"type", "environment"}, {"radiance", {sky[0], sky[1], sky[2]}}}}},
            {"media", json::array()}};
  s["media"].push_back({{"type", "homogeneous"}, {"bounds", {{-1, -1, -1}, {1, 1, 1}}}, {"sigma_a", {0, 0, 0}},
                        {"sigma_s", {0.3, 0.3, 0.3}}, {"phase", {{"type", "isotropic"}}}});
  std::vector<st_guide_region> first;
  auto hook = [&](GuideCache& c) {
    if (first.empty()) first = c.regions;
  };
  render_guided(s, dir, tracker, ST_ABSORPTION_WEIGHT, 11, true, hook, false, [&](RenderOptions& o) { o.color = color; });
  return first;
}

}  // namespace

// In RGB mode every record (only positive ones are kept) weighs exactly 1/2, and so does every
// region's mean of the fit's records. The twin asks for 3% more and must fail.
TEST(GuidingRender, RingRecordsCreditTheEscapeToTheFirstVertex) {
  int regions = 0;
  for (const st_guide_region& g : furnace_regions("guided_furnace", ST_FILM_COLOR_RGB))
    if (g.alpha > 0) {
      ++regions;
      EXPECT_NEAR(g.weight, 0.5, 1e-5) << "records " << g.records;
      EXPECT_GT(std::abs(g.weight - 0.5 * 1.03), 1e-5) << "twin: a 3% error must be detected";
    }
  EXPECT_GE(regions, 4) << "the first pass must fill most of the 2 x 2 x 2 regions";
}

// The same furnace in spectral mode under a red sky (1, 1/4, 1/4): a lane carries the sky's
// radiance at its wavelength (the upsampled colour times D65, about 100 at 560 nm), and the guide
// keeps radiance in the film's unit (guide_paths.h guide_lane_weights), so a record is 1/2 times the
// lanes' mean of s D65 (F_R + F_G + F_B) / (3 p), whose expectation is 1/2 times the mean of R, G and
// B of the sky, 1/4, as in RGB mode (a weighting by one channel, or by the luminance, gives another
// value). For a tracker of four lanes (spectral) and one of one lane per path (delta-per-channel)
// the regions' means of their records agree with 1/4 within 4 standard errors, taken from the
// spread of at least 8 distinct region means (their records come from different paths; a pooled
// sparse region repeats its pool's mean and counts once), and a 3% error is detected. The regions'
// radiance (what guided roulette compares with the pixel estimates; half the probability that a
// scattered ray escapes, the same in both modes for a gray medium) is within 10% of the RGB
// render's: a guard against the lanes' own unit (D65's scale), about 90 times larger, not a
// statistical bound.
TEST(GuidingRender, SpectralRecordsAreInTheFilmsUnit) {
  const Vec3 sky = {1, 0.25, 0.25};
  const double expect = 0.5 * (sky[0] + sky[1] + sky[2]) / 3;
  double radiance_rgb = 0, n_rgb = 0;
  for (const st_guide_region& g : furnace_regions("guided_furnace_red", ST_FILM_COLOR_RGB, ST_TRACKER_SPECTRAL, sky, 96)) {
    if (g.alpha > 0) EXPECT_NEAR(g.weight, expect, 1e-5) << "rgb: every record weighs exactly the sky's mean over 2";
    if (g.records > 0) radiance_rgb += g.radiance * g.records, n_rgb += g.records;
  }
  ASSERT_GT(n_rgb, 0);
  for (int tracker : {ST_TRACKER_SPECTRAL, ST_TRACKER_DELTA_PER_CHANNEL}) {
    const std::string what = tracker_name(tracker);
    std::vector<double> weights;
    double radiance = 0, n = 0;
    // one lane per record: 10 times the spread of four lanes' mean, so four times the film (at 96 x 96
    // its 4 SE were 0.007 against the twin's 0.0075)
    const int size = tracker == ST_TRACKER_DELTA_PER_CHANNEL ? 192 : 96;
    for (const st_guide_region& g : furnace_regions("guided_furnace_spectral", ST_FILM_COLOR_SPECTRAL, tracker, sky, size)) {
      if (g.alpha > 0) weights.push_back(g.weight);
      if (g.records > 0) radiance += g.radiance * g.records, n += g.records;
    }
    std::sort(weights.begin(), weights.end());
    weights.erase(std::unique(weights.begin(), weights.end()), weights.end());
    ASSERT_GE(weights.size(), 8u) << what << ": the first pass must fill the 2 x 2 x 2 regions";
    const double k = double(weights.size());
    double mean = 0, var = 0;
    for (double w : weights) mean += w / k;
    for (double w : weights) var += (w - mean) * (w - mean) / (k - 1);
    const double se = std::sqrt(var / k);
    std::cout << "[ info ] " << what << ": mean of " << k << " region means " << mean << " (expected " << expect
              << "), SE " << se << "\n";
    EXPECT_LT(std::abs(mean - expect), 4 * se) << what << ": mean of " << k << " regions' record means " << mean << ", SE " << se;
    EXPECT_GT(std::abs(mean - expect * 1.03), 4 * se) << what << ": twin, a 3% error must be detected (SE " << se << ")";
    ASSERT_GT(n, 0);
    EXPECT_NEAR((radiance / n) / (radiance_rgb / n_rgb), 1.0, 0.1) << what << ": region radiance, spectral over RGB";
  }
}

// A ground vertex (a bounce off the ground, outside every medium) is neither guided nor split, so it
// makes no record: its records would fall outside the grid, be binned into the nearest cell by
// clamping, and pull that cell's kd-tree and fit towards light the medium never sees. A thin slab
// above a bright ground seen from above: most training vertices are on the ground, and none of the
// pass's radiance records lies outside the grid (GuideCache::records_outside; the twin: records
// below the grid are counted).
TEST(GuidingRender, GroundVerticesMakeNoRecords) {
  const std::string dir = temp_dir("guided_ground");
  json s = {{"format", "spectrack-scene/1"},
            {"camera", {{"type", "perspective"}, {"position", {0, 4, -3}}, {"look_at", {0, 0.5, 0}}, {"up", {0, 1, 0}}, {"fov_deg", 50}}},
            {"film", {{"width", 24}, {"height", 24}, {"spp", 8}}},
            {"render", {{"seed", 7}, {"light_sampling", "all"}}},
            {"lights", {{{"type", "environment"}, {"radiance", {0.4, 0.5, 0.7}}},
                        {{"type", "directional"}, {"to_light", {-0.3, 1, 0.2}}, {"irradiance", {3, 3, 3}}, {"angle_deg", 1}}}},
            {"ground", {{"height", 0}, {"albedo", {0.9, 0.9, 0.9}}, {"mode", "diffuse"}}},
            {"media", json::array()}};
  s["media"].push_back({{"type", "homogeneous"}, {"bounds", {{-2, 0.5, -2}, {2, 1.5, 2}}}, {"sigma_a", {0.02, 0.02, 0.02}},
                        {"sigma_s", {0.4, 0.4, 0.4}}, {"phase", {{"type", "isotropic"}}}});
  GuideCache first;
  int passes = 0;
  auto hook = [&](GuideCache& c) {
    if (passes++ == 0) first = c;
  };
  render_guided(s, dir, ST_TRACKER_SPECTRAL, ST_ABSORPTION_WEIGHT, 3, true, hook);
  ASSERT_EQ(passes, 1);
  double slab_records = 0;
  for (const st_guide_region& g : first.regions) slab_records += g.records;
  EXPECT_GT(slab_records, 1000) << "the slab's vertices must make records";
  EXPECT_EQ(first.records_outside, 0u);
  GuideCache twin = first;
  std::vector<st_guide_record> below(100);
  for (size_t k = 0; k < below.size(); ++k) {
    below[k].pos = st_float4{0.1f * float(k % 10) - 0.5f, k < 30 ? 0.0f : 1.0f, 0.3f, 0.0f};  // 30 on the ground
    below[k].key[3] = ST_GUIDE_RECORD_RADIANCE;
  }
  refine_guide_regions(twin, below);
  EXPECT_EQ(twin.records_outside, 30u) << "twin: records below the grid must be counted";
  // guided paths that bounce off the ground (guided roulette and splitting on) agree with unguided ones
  s["film"]["spp"] = 64;
  const RenderResult ref = render_guided(s, dir, ST_TRACKER_SPECTRAL, ST_ABSORPTION_WEIGHT, 30, false);
  const RenderResult guided = render_guided(s, dir, ST_TRACKER_SPECTRAL, ST_ABSORPTION_WEIGHT, 31, true, {}, false,
                                            [](RenderOptions& o) { o.guide_splitting = true; });
  EXPECT_GT(guided.guide.regions_guided, 0) << "the cache must guide somewhere";
  EXPECT_LT(max_z(guided, ref), 4.0);
  EXPECT_GT(max_z(guided, ref, 1.03), 4.0) << "twin: a 3% error must be detected";
}

// A camera ray that ends on a shadow catcher makes its ground point vertex 0 of the training ring,
// which makes no record: before, k_finish credited and recorded the ring vertex an earlier path had
// left in the slot. The camera sees only the catcher (the medium casts its shadow from outside the
// view), so no path scatters in a medium and the training's only records are the paths' end
// records, one per training sample of every pixel (an exact count: with the stale vertices, 2647
// records where 1280 paths ended).
TEST(GuidingRender, ShadowCatcherPathsMakeNoVertexRecords) {
  const std::string dir = temp_dir("guided_catcher");
  const int w = 20, h = 16;
  json s = {{"format", "spectrack-scene/1"},
            {"camera", {{"type", "perspective"}, {"position", {0, 3, 0}}, {"look_at", {0, 0, 0.01}}, {"up", {0, 0, 1}}, {"fov_deg", 40}}},
            {"film", {{"width", w}, {"height", h}, {"spp", 8}}},
            {"render", {{"seed", 9}, {"light_sampling", "all"}}},
            {"lights", {{{"type", "environment"}, {"radiance", {0.3, 0.4, 0.6}}},
                        {{"type", "directional"}, {"to_light", {1, 1, 0}}, {"irradiance", {3, 3, 3}}, {"angle_deg", 1}}}},
            {"ground", {{"height", 0}, {"albedo", {0.5, 0.5, 0.5}}, {"mode", "shadow_catcher"}}},
            {"media", json::array()}};
  s["media"].push_back({{"type", "homogeneous"}, {"bounds", {{-2.5, 1.5, -0.5}, {-1.5, 2.5, 0.5}}}, {"sigma_a", {0.1, 0.1, 0.1}},
                        {"sigma_s", {2, 2, 2}}, {"phase", {{"type", "isotropic"}}}});
  const RenderResult r = render_guided(s, dir, ST_TRACKER_SPECTRAL, ST_ABSORPTION_WEIGHT, 4, true);
  ASSERT_TRUE(r.guide.used);
  ASSERT_EQ(r.guide.training_passes, 1);
  const size_t end_records = size_t(w) * h * size_t(kGuideTrainingSpp[0]);
  EXPECT_EQ(r.guide.records, end_records) << "only the paths' end records";
}

// Every scatter event guided (guide_depth < 0): the product of the guided weights over a path's
// bounces is unbiased, with guided roulette and splitting holding it in the window and without.
TEST(GuidingRender, EveryScatterEventGuidedAgreesWithUnguided) {
  const std::string dir = temp_dir("guided_every");
  json s = guiding_scene(dir);
  s["film"]["spp"] = 96;
  RenderResult ref = render_guided(s, dir, ST_TRACKER_DELTA_PER_CHANNEL, ST_ABSORPTION_EVENT, 100, false);
  for (bool splitting : {true, false}) {
    RenderResult r = render_guided(s, dir, ST_TRACKER_SPECTRAL, ST_ABSORPTION_WEIGHT, 400, true, {}, false,
                                   [&](RenderOptions& o) {
                                     o.guide_depth = -1;
                                     o.guide_splitting = splitting;
                                   });
    const std::string what = splitting ? "with roulette and splitting" : "without";
    EXPECT_GT(r.guide.regions_guided, 0) << what;
    EXPECT_EQ(r.stats.nonfinite_samples, 0u) << what;
    EXPECT_LT(max_z(r, ref), 4.0) << what;
    EXPECT_GT(max_z(r, ref, 1.03), 4.0) << what << ": twin, a 3% error must be detected";
  }
}

// The image of a render that guides every scatter event and splits paths is the same, bit for bit,
// whatever the number of path slots (the children's keys and the slot's depth-first order).
TEST(GuidingRender, EveryScatterEventGuidedDoesNotDependOnPathSlots) {
  const std::string dir = temp_dir("guided_every_slots");
  json s = guiding_scene(dir);
  s["film"]["spp"] = 8;
  // the fit of f_phase L (the default) splits paths here; the phase product (SPECTRACK_GUIDE_PRODUCT=1)
  // keeps the weights near 1 and splits none: both must be schedule-exact
  const RenderResult first = render_guided(s, dir, ST_TRACKER_SPECTRAL, ST_ABSORPTION_WEIGHT, 9, true, {}, false,
                                           [](RenderOptions& o) { o.guide_depth = 1; });
  for (const char* product : {"0", "1"}) {
    SCOPED_TRACE(testing::Message() << "SPECTRACK_GUIDE_PRODUCT=" << product);
    ::setenv("SPECTRACK_GUIDE_PRODUCT", product, 1);
    std::vector<RenderResult> r;
    for (int slots : {0, 97, 1000})
      r.push_back(render_guided(s, dir, ST_TRACKER_SPECTRAL, ST_ABSORPTION_WEIGHT, 9, true, {}, false, [&](RenderOptions& o) {
        o.guide_depth = -1;
        if (slots > 0) o.path_slots = slots;
      }));
    ::unsetenv("SPECTRACK_GUIDE_PRODUCT");
    if (product[0] == '0') EXPECT_GT(r[0].stats.split_paths, 0u) << "paths must split";
    EXPECT_NE(r[0].path_slots, r[1].path_slots);
    for (size_t k = 1; k < r.size(); ++k) {
      ASSERT_EQ(r[0].rgb.size(), r[k].rgb.size());
      EXPECT_EQ(std::memcmp(r[0].rgb.data(), r[k].rgb.data(), r[0].rgb.size() * 4), 0) << r[k].path_slots << " path slots";
      EXPECT_EQ(r[0].stats.split_paths, r[k].stats.split_paths);
    }
    EXPECT_NE(std::memcmp(r[0].rgb.data(), first.rgb.data(), r[0].rgb.size() * 4), 0)
        << "guiding every event changes the samples of a first-event render";
  }
}

// A training pass makes records from at most its budget of camera samples (guide_cache.h
// kGuideRecordSamples): the hashed set of (pixel, sample) that guide_sample_records picks. The
// other samples render the same paths, so the bounded pass's records are exactly those that the
// pass recording every sample makes at the picked samples.
TEST(GuidingRender, TrainingRecordsComeFromABoundedSetOfSamples) {
  {  // the set's share of a large film's samples is the fraction within 4 SE; 3% off is seen
    const uint32_t pixels = 1024 * 1024;
    const float f = guide_record_fraction(pixels, 4, int64_t(1) << 20);
    ASSERT_EQ(f, 0.25f);
    double picked = 0;
    for (uint32_t px = 0; px < pixels; ++px)
      for (uint32_t s = 0; s < 4; ++s) picked += guide_sample_records(f, px, s);
    const double n = 4.0 * pixels, share = picked / n, se = std::sqrt(0.25 * 0.75 / n);
    EXPECT_LT(std::abs(share - 0.25) / se, 4.0) << share;
    EXPECT_GT(std::abs(share - 0.25 * 1.03) / se, 4.0) << "the twin: a share 3% off must be seen";
  }
  EXPECT_EQ(guide_record_fraction(128 * 96, 4, kGuideRecordSamples), 1.0f) << "a bench film's pass records every sample";
  EXPECT_EQ(guide_record_fraction(1920 * 1080, 4, 0), 1.0f) << "a budget of 0 records every sample";
  const std::string dir = temp_dir("guided_record_budget");
  json s = guiding_scene(dir);
  s["film"]["width"] = 32;
  s["film"]["height"] = 32;
  auto key_of = [](const st_guide_record& r) { return std::make_tuple(r.key[0], r.key[1], r.key[2], r.key[3]); };
  auto records_of = [&](int64_t budget) {
    std::vector<st_guide_record> pass;
    int passes = 0;
    render_guided(s, dir, ST_TRACKER_SPECTRAL, ST_ABSORPTION_WEIGHT, 5, true, {}, false, [&](RenderOptions& o) {
      o.spp = 6;
      o.guide_record_samples = budget;
      o.guide_records_hook = [&](const std::vector<st_guide_record>& r) { pass = r, ++passes; };
    });
    EXPECT_EQ(passes, 1);
    std::sort(pass.begin(), pass.end(), [&](const st_guide_record& a, const st_guide_record& b) { return key_of(a) < key_of(b); });
    return pass;
  };
  const std::vector<st_guide_record> every = records_of(0), bounded = records_of(1024);
  const float f = guide_record_fraction(32 * 32, 4, 1024);
  ASSERT_EQ(f, 0.25f);
  std::vector<st_guide_record> picked;
  for (const st_guide_record& r : every)
    if (guide_sample_records(f, r.key[0], r.key[1])) picked.push_back(r);
  EXPECT_GT(every.size(), 10000u);
  EXPECT_LT(picked.size(), every.size() / 2) << "the twin: the bounded pass must record fewer";
  ASSERT_EQ(bounded.size(), picked.size());
  for (size_t i = 0; i < picked.size(); ++i)
    ASSERT_EQ(std::memcmp(&bounded[i], &picked[i], sizeof(st_guide_record)), 0) << "record " << i;
}
