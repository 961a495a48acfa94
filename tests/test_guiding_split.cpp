// test_guiding_split.cpp: guided Russian roulette and splitting (docs/guiding.md, kernels/guiding.h
// guide_rrs). The caches here are forced wrong on purpose (every other region claims a radiance
// 20 times the pixel's, the others 1/20 of it), so that roulette and splitting both act on most
// scatter events whatever the training learned; the estimator must stay unbiased for any cache:
//   - an emissive furnace (emission equal to the sky: the radiance is the sky's everywhere) and a
//     white furnace keep their analytic values with every tracker and absorption mode, within 4
//     standard errors; the emissive furnace's twin must see a 3% error (the white furnace's spectral
//     paths are too noisy at this size for a 3% twin);
//   - the same seed gives the same image twice, and generic and specialised kernels agree bit for
//     bit, with paths split (the children's random keys and the slot's depth-first order);
//   - the host joins a vertex's radiance record with its path's end record exactly.
#include <cstring>

#include "guiding/guide_cache.h"
#include "test_util.h"

using namespace spectrack;
using namespace st_test;
using nlohmann::json;

namespace {

// The furnaces of test_render.cpp: a lumpy HG medium under a uniform sky, white (no absorption)
// or emissive (emission equal to the sky, so the radiance is the sky's everywhere).
json furnace(const std::string& dir, bool emissive) {
  write_lumpy(dir + "/lumpy.vdb");
  const json sky = emissive ? json{0.3, 0.6, 0.9} : json{1, 1, 1};
  json medium = {{"type", "vdb"}, {"file", "lumpy.vdb"}, {"density_scale", 4.0}, {"phase", {{"type", "hg"}, {"g", 0.4}}},
                 {"sigma_a", emissive ? json{1.0, 2.0, 4.0} : json{0, 0, 0}},
                 {"sigma_s", emissive ? json{3.0, 1.0, 0.5} : json{1.0, 3.0, 9.0}}};
  if (emissive) medium["emission"] = {{"radiance", sky}};
  return {{"format", "spectrack-scene/1"},
          {"camera", {{"type", "perspective"}, {"position", {0.2, 0.1, -3}}, {"look_at", {0, 0, 0}}, {"up", {0, 1, 0}}, {"fov_deg", 30}}},
          {"film", {{"width", 12}, {"height", 12}, {"spp", 48}}},
          {"render", {{"seed", 3}, {"light_sampling", "all"}}},
          {"lights", {{{"type", "environment"}, {"radiance", sky}}}},
          {"media", {medium}}};
}

// Every region gets a radiance estimate, alternately 20 times and 1/20 of `level` (about the
// furnaces' pixel values): paths in regions of the first kind split, the others go through roulette.
std::function<void(GuideCache&)> wrong_radiance(double level) {
  return [level](GuideCache& c) {
    for (size_t i = 0; i < c.regions.size(); ++i) {
      c.regions[i].records = 100.0f;
      c.regions[i].radiance = float(i % 2 ? level * 20.0 : level / 20.0);
    }
  };
}

RenderResult render_split(const json& s, const std::string& dir, int tracker, int absorption, uint32_t seed, double level,
                          bool generic = false) {
  RenderOptions o = quiet_options();
  o.tracker = tracker;
  o.absorption = absorption;
  o.seed = seed;
  o.guiding = kGuidingOn;
  o.guide_cache_hook = wrong_radiance(level);
  o.generic_kernels = generic;
  o.guide_grid_cells = 3;
  return Renderer(scene_from_json(s, dir), o).render();
}

void expect_value(const RenderResult& r, const double expected[3], const std::string& what, bool twin) {
  for (int c = 0; c < 3; ++c) {
    Stats s = mean_se(channel(r, c));
    EXPECT_NEAR(s.mean, expected[c], 4.0 * s.se + 1e-5) << what << ", channel " << c << " (SE " << s.se << ")";
    if (twin && c == 1)
      EXPECT_GT(std::abs(s.mean - 1.03 * expected[c]), 4.0 * s.se) << what << ": twin, a 3% error must be detected";
  }
}

}  // namespace

TEST(GuidingSplit, FurnacesStayAnalyticWithRouletteAndSplitting) {
  const std::string dir = temp_dir("guided_split_furnace");
  const json white = furnace(dir, false), emissive = furnace(dir, true);
  const double one[3] = {1, 1, 1}, sky[3] = {0.3, 0.6, 0.9};
  for (int t : {ST_TRACKER_DELTA_PER_CHANNEL, ST_TRACKER_SPECTRAL, ST_TRACKER_SPECTRAL_MIS, ST_TRACKER_SPECTRAL_DECOMPOSITION})
    for (int a : {ST_ABSORPTION_EVENT, ST_ABSORPTION_WEIGHT}) {
      const std::string what = std::string(tracker_name(t)) + " / absorption " + absorption_name(a);
      RenderResult e = render_split(emissive, dir, t, a, 21, 0.6);
      EXPECT_GT(e.stats.split_paths, 100u) << what << ": paths must split";
      EXPECT_EQ(e.stats.nonfinite_samples, 0u) << what;
      expect_value(e, sky, "emissive furnace " + what, t == ST_TRACKER_SPECTRAL && a == ST_ABSORPTION_WEIGHT);
      if (a == ST_ABSORPTION_EVENT) {  // no absorption in the white furnace: one mode is enough
        RenderResult w = render_split(white, dir, t, a, 22, 1.0);
        EXPECT_GT(w.stats.split_paths, 100u) << what << ": paths must split";
        expect_value(w, one, "white furnace " + what, false);
      }
    }
}

TEST(GuidingSplit, DeterministicAndGenericKernelsAgree) {
  const std::string dir = temp_dir("guided_split_bits");
  json s = furnace(dir, true);
  s["film"]["spp"] = 4;
  RenderResult a = render_split(s, dir, ST_TRACKER_SPECTRAL, ST_ABSORPTION_WEIGHT, 7, 0.6);
  RenderResult b = render_split(s, dir, ST_TRACKER_SPECTRAL, ST_ABSORPTION_WEIGHT, 7, 0.6);
  RenderResult g = render_split(s, dir, ST_TRACKER_SPECTRAL, ST_ABSORPTION_WEIGHT, 7, 0.6, true);
  ASSERT_EQ(a.rgb.size(), b.rgb.size());
  EXPECT_GT(a.stats.split_paths, 0u);
  EXPECT_EQ(a.stats.split_paths, b.stats.split_paths);
  EXPECT_EQ(std::memcmp(a.rgb.data(), b.rgb.data(), a.rgb.size() * 4), 0) << "same seed, same image";
  EXPECT_EQ(std::memcmp(a.rgb.data(), g.rgb.data(), a.rgb.size() * 4), 0) << "generic and specialised kernels";
  RenderOptions o = quiet_options();
  o.seed = 7;
  o.guiding = kGuidingOn;
  o.guide_splitting = false;
  o.guide_cache_hook = wrong_radiance(0.6);
  o.guide_grid_cells = 3;
  RenderResult off = Renderer(scene_from_json(s, dir), o).render();
  EXPECT_EQ(off.stats.split_paths, 0u);
  EXPECT_NE(std::memcmp(a.rgb.data(), off.rgb.data(), a.rgb.size() * 4), 0) << "splitting changes the samples";
}

// Two paths of one region: vertex radiance records (dir.x the path's radiance when the vertex
// entered, dir.y its throughput) and their paths' end records (dir.x the path's radiance at its end).
TEST(GuidingSplit, RadianceRecordsJoinTheirPathsEnd) {
  st_scene st{};
  st.camera.width = 4;
  st.camera.height = 4;
  GuideCache c = make_guide_cache(st, 1);
  ASSERT_EQ(c.regions.size(), 1u);
  ASSERT_EQ(c.pixel_estimate.size(), 16u);
  auto record = [](int32_t region, uint32_t pixel, uint32_t key3, float x, float y) {
    st_guide_record r{};
    std::memcpy(&r.pos.w, &region, 4);
    r.dir = st_float4{x, y, 0, 0};
    r.key[0] = pixel, r.key[1] = 0, r.key[2] = 0, r.key[3] = key3;
    return r;
  };
  std::vector<st_guide_record> records;
  double expected = 0;
  for (uint32_t path = 0; path < uint32_t(kGuideMinRecords); ++path) {
    const float end = 2.0f + float(path), total = 0.5f, beta = 0.25f + 0.01f * float(path);
    records.push_back(record(-1, path, ST_GUIDE_RECORD_END, end, 0));
    records.push_back(record(0, path, 3u | ST_GUIDE_RECORD_RADIANCE, total, beta));
    expected += (end - total) / beta;
  }
  expected /= kGuideMinRecords;
  fit_guide_cache(c, records);
  EXPECT_EQ(c.regions[0].records, float(kGuideMinRecords));
  EXPECT_NEAR(c.regions[0].radiance, expected, 1e-4 * expected);
  EXPECT_GT(std::abs(c.regions[0].radiance - 1.03 * expected), 1e-4 * expected) << "twin: a 3% error must be detected";
  EXPECT_EQ(c.regions[0].alpha, 0.0f) << "radiance records alone do not fit a mixture";
  std::vector<double> sums(16, 0.0);
  sums[5] = 8.0;  // 8 over 4 samples: 2; the others raised to the floor, a fraction of the film's mean
  set_pixel_estimates(c, sums, 4.0);
  EXPECT_FLOAT_EQ(c.pixel_estimate[5], 2.0f);
  EXPECT_FLOAT_EQ(c.pixel_estimate[0], float(kGuidePixelFloor * 2.0 / 16.0));
}
