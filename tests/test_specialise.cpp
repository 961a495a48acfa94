// test_specialise.cpp: what a scene lacks costs nothing, and skipping it changes no image.
//   - the specialised kernels render the same image, bit for bit, as the generic kernel on every
//     scene of data/scenes and bench/scenes (globbed now, so scenes added later are covered; film
//     and spp shrunk to keep the test short);
//   - the feature mask follows the scene, and a scene without lights or visible lights at
//     infinity gets no shadow and no escape launch;
//   - the two-level majorant grid skips empty blocks (fewer DDA steps) and keeps the estimate;
//   - the ring of batches in flight changes the schedule, never the image.
#include <filesystem>

#include "test_util.h"

#ifndef SPECTRACK_SOURCE_DIR
#error "SPECTRACK_SOURCE_DIR must be defined (the repository root)"
#endif

using namespace spectrack;
using namespace st_test;
using nlohmann::json;

namespace {

std::vector<std::string> benchmark_scenes() {
  std::vector<std::string> out;
  for (const char* dir : {"data/scenes", "bench/scenes"}) {
    std::filesystem::path d = std::filesystem::path(SPECTRACK_SOURCE_DIR) / dir;
    if (!std::filesystem::is_directory(d)) continue;
    for (auto& e : std::filesystem::directory_iterator(d))
      if (e.path().extension() == ".json") out.push_back(e.path().string());
  }
  std::sort(out.begin(), out.end());
  return out;
}

TEST(Specialisation, GenericAndSpecialisedKernelsRenderTheSameImageOnEveryBenchmarkScene) {
  auto scenes = benchmark_scenes();
  ASSERT_GE(scenes.size(), 3u) << "the benchmark scenes were not found under " << SPECTRACK_SOURCE_DIR;
  for (auto& path : scenes) {
    SCOPED_TRACE(path);
    SceneDesc s;
    try {
      s = load_scene(path);
    } catch (const Error& e) {
      // third-party volumes live outside the repository; only their absence may skip a scene
      if (!std::filesystem::exists(SHARED_DATA_DIR)) continue;
      FAIL() << e.what();
    }
    s.film.width = 20;
    s.film.height = 14;
    RenderOptions spec = quiet_options(2), gen = quiet_options(2);
    gen.generic_kernels = true;
    RenderResult a = Renderer(s, spec).render();
    RenderResult b = Renderer(s, gen).render();
    EXPECT_NE(a.features, uint32_t(ST_FEATURES_ALL)) << "a benchmark scene that needs every feature tests nothing";
    // the generic kernel has every feature, and the render modes outside them (adaptive sampling:
    // the default scene asks for it) as the specialised one has them
    EXPECT_EQ(b.features, uint32_t(ST_FEATURES_ALL) | (a.features & ~uint32_t(ST_FEATURES_ALL)));
    ASSERT_EQ(a.rgb.size(), b.rgb.size());
    EXPECT_TRUE(a.rgb == b.rgb) << "specialised and generic kernels give different images";
    double sum = 0;
    for (float v : a.rgb) sum += v;
    EXPECT_GT(sum, 0.0) << "a black image would compare equal for the wrong reason";
    EXPECT_EQ(a.stats.real_collisions, b.stats.real_collisions);
    EXPECT_EQ(a.stats.lookups_track + a.stats.lookups_shadow, b.stats.lookups_track + b.stats.lookups_shadow);
  }
}

json box_scene(const std::string& tracker) {
  return json{{"format", "spectrack-scene/1"},
              {"camera", {{"type", "orthographic"}, {"position", {0, 0, -3}}, {"look_at", {0, 0, 0}}, {"up", {0, 1, 0}}, {"height", 1.0}}},
              {"film", {{"width", 8}, {"height", 8}, {"spp", 4}}},
              {"render", {{"tracker", tracker}, {"seed", 3}}},
              {"lights", json::array()},
              {"media", json::array({{{"type", "homogeneous"},
                                      {"bounds", {{-1, -1, -1}, {1, 1, 1}}},
                                      {"sigma_a", {0.5, 0.5, 0.5}},
                                      {"sigma_s", {0.5, 0.5, 0.5}},
                                      {"emission", {{"radiance", {1, 1, 1}}}}}})}};
}

TEST(Specialisation, FeatureMaskFollowsTheSceneAndUnusedStagesAreNotLaunched) {
  std::string dir = temp_dir("features");
  // emissive gray homogeneous box, isotropic, no lights: no shadow rays, no escape stage, no grid
  json s = box_scene("spectral");
  RenderResult r = Renderer(scene_from_json(s, dir), quiet_options()).render();
  EXPECT_EQ(r.features, uint32_t(ST_FEATURE_EMISSION));
  EXPECT_EQ(r.stats.kernels.count("k_shadow"), 0u) << "no lights: no shadow launch";
  EXPECT_EQ(r.stats.kernels.count("k_escape"), 0u) << "no light at infinity: no escape launch";
  EXPECT_GT(r.stats.kernels.count("k_track"), 0u);
  EXPECT_EQ(r.stats.lookups_track, 0u) << "homogeneous media need no density lookup";
  // the generic kernel takes the escape stage and gives the same image
  RenderOptions g = quiet_options();
  g.generic_kernels = true;
  RenderResult rg = Renderer(scene_from_json(s, dir), g).render();
  EXPECT_GT(rg.stats.kernels.count("k_escape"), 0u);
  EXPECT_TRUE(r.rgb == rg.rgb);
  // each feature a scene adds shows in the mask
  s["lights"].push_back({{"type", "directional"}, {"to_light", {0, 1, 0}}, {"irradiance", {1, 1, 1}}});
  s["media"][0]["sigma_s"] = {0.5, 0.4, 0.3};
  s["media"][0]["phase"] = {{"type", "hg"}, {"g", 0.5}};
  Renderer r2(scene_from_json(s, dir), quiet_options());
  EXPECT_EQ(r2.features(), uint32_t(ST_FEATURE_EMISSION | ST_FEATURE_CHROMATIC | ST_FEATURE_HG));
  RenderResult rr2 = r2.render();
  EXPECT_GT(rr2.stats.kernels.count("k_shadow"), 0u) << "a light needs next-event estimation";
  EXPECT_EQ(rr2.stats.kernels.count("k_escape"), 0u) << "a delta sun is never seen by escaping rays";
  s["lights"][0]["angle_deg"] = 2.0;
  s["render"]["tracker"] = "spectral-decomposition";
  Renderer r3(scene_from_json(s, dir), quiet_options());
  EXPECT_TRUE(r3.features() & ST_FEATURE_ESCAPE) << "a sun disc is seen by escaping rays";
  EXPECT_TRUE(r3.features() & ST_FEATURE_DECOMPOSITION);
}

// A sparse volume: two slabs of density 1 at the ends of a long, otherwise empty grid.
class SparseVolume : public ::testing::Test {
 protected:
  std::string dir;
  void SetUp() override {
    dir = temp_dir("sparse");
    write_vdb(dir + "/sparse.vdb", "density", openvdb::Coord(0, 0, 0), openvdb::Coord(255, 15, 15),
              [](int i, int, int) { return (i < 8 || i >= 248) ? 1.0f : 0.0f; }, 1.0 / 16.0);
  }
  Renderer make(int block) {
    json s = {{"format", "spectrack-scene/1"},
              {"camera", {{"type", "orthographic"}, {"position", {8, 0.5, -3}}, {"look_at", {8, 0.5, 0}}, {"up", {0, 1, 0}}, {"height", 1.0}}},
              {"film", {{"width", 4}, {"height", 4}, {"spp", 1}}},
              {"render", {{"tracker", "spectral"}, {"seed", 5}}},
              {"lights", json::array()},
              {"media", json::array({{{"type", "vdb"}, {"file", "sparse.vdb"}, {"sigma_a", {0.7, 0.7, 0.7}}, {"sigma_s", {0, 0, 0}}}})}};
    RenderOptions o = quiet_options();
    o.majorant_cell = 4;
    o.majorant_block = block;
    return Renderer(scene_from_json(s, dir), o);
  }
};

TEST_F(SparseVolume, TwoLevelGridSkipsEmptyBlocksAndKeepsTheEstimate) {
  const int n = 20000;
  std::array<float, 3> o{-1.0f, 8.0f / 16.0f, 7.5f / 16.0f}, d{1, 0, 0};
  Renderer one = make(0), two = make(4);
  EXPECT_FALSE(one.features() & ST_FEATURE_COARSE_MAJORANT);
  EXPECT_TRUE(two.features() & ST_FEATURE_COARSE_MAJORANT);
  auto T1 = Probe(one).transmittance(o, d, n), T2 = Probe(two).transmittance(o, d, n);
  auto stats = [&](const std::vector<std::array<float, 4>>& v) {
    std::vector<double> x;
    for (auto& t : v) x.push_back(t[0]);
    return mean_se(x);
  };
  Stats s1 = stats(T1), s2 = stats(T2);
  // each slab: 7 voxels at density 1 plus two linear ramps of one voxel (trilinear), 1/16 long each
  double tau = 2 * 0.7 * 8.0 / 16.0;
  EXPECT_NEAR(s1.mean, std::exp(-tau), 4 * s1.se + 1e-3);
  EXPECT_NEAR(s2.mean, s1.mean, 4 * std::sqrt(s1.se * s1.se + s2.se * s2.se) + 1e-6) << "the skip changed the estimate";
  // free flights: the DDA steps of rays that cross everything (escapes) drop with the skip
  auto tr1 = Probe(one).track(o, d, -1, 2000), tr2 = Probe(two).track(o, d, -1, 2000);
  double steps1 = 0, steps2 = 0;
  int esc1 = 0, esc2 = 0;
  for (auto& x : tr1)
    if (std::isinf(x[0])) steps1 += x[3], ++esc1;
  for (auto& x : tr2)
    if (std::isinf(x[0])) steps2 += x[3], ++esc2;
  ASSERT_GT(esc1, 100);
  // the escape probability is the same (walking a non-empty block whole changes the draws, not
  // their law): binomial counts within 4 SE
  const double p1 = esc1 / 2000.0, p2 = esc2 / 2000.0;
  EXPECT_NEAR(p1, p2, 4 * std::sqrt((p1 * (1 - p1) + p2 * (1 - p2)) / 2000.0) + 1e-9) << "escape probabilities differ";
  steps1 /= esc1;
  steps2 /= esc2;
  // one level: 64 cells along x; two levels: the 2 x 2 non-empty cells + 14 empty blocks or so
  EXPECT_GT(steps1, 60.0);
  EXPECT_LT(steps2, 0.5 * steps1) << "empty blocks were walked cell by cell";
}

TEST(WorkDistribution, RingOfBatchesKeepsTheImageAndFillsTheSlots) {
  std::string dir = temp_dir("ring");
  json s = box_scene("spectral");
  s["media"][0]["sigma_s"] = {8.0, 8.0, 8.0};  // long, varied path lengths
  s["media"][0]["sigma_a"] = {0.2, 0.2, 0.2};
  s["film"]["spp"] = 24;
  RenderOptions o2 = quiet_options(), o8 = quiet_options();
  o2.path_slots = o8.path_slots = 64;
  o2.batches_in_flight = 2;
  o8.batches_in_flight = 8;
  RenderResult a = Renderer(scene_from_json(s, dir), o2).render();
  RenderResult b = Renderer(scene_from_json(s, dir), o8).render();
  EXPECT_TRUE(a.rgb == b.rgb) << "the ring of batches changed the image";
  EXPECT_GT(b.stats.occupancy_mean, a.stats.occupancy_mean) << "more batches in flight must keep more slots busy";
  EXPECT_LT(b.stats.iterations, a.stats.iterations);
  EXPECT_GT(a.seconds_first_pass, 0.0);
  EXPECT_LE(a.seconds_first_pass, a.seconds_setup + a.seconds_render + 1.0);
}

}  // namespace
