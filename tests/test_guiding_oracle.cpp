// test_guiding_oracle.cpp: where guiding must win (docs/guiding.md, "The oracle scene and the
// learned selection probability"). A thin, bright-albedo isotropic slab lit only by an emissive
// box outside the camera's view: emission is scored at collisions, never by next-event
// estimation, so the light that reaches a scatter event comes from the box's small solid angle,
// which phase sampling finds by chance. Tests:
//   - the selection probability learned from records: a region whose records bring light back from
//     a narrow cone guides (alpha > 0), its twin of the same records' weights spread over every
//     direction does not (alpha 0), and sparse regions (few lit records, also among many dim ones)
//     take the fit of the subtree around them;
//   - the oracle render (single scattering, guided by `--guiding auto`, which the lamp turns on):
//     the guided variance is at most kOracleVarianceRatio of the unguided one, and the means agree within 4
//     standard errors, with a twin that must see a 3% error.
// The variance of a render is estimated from two renders of different seeds: the mean over pixels
// of (a - b)^2 / 2 (no variance layer needed; the image's structure cancels).
#include <cmath>
#include <random>

#include "guiding/guide_cache.h"
#include "test_util.h"

using namespace spectrack;
using namespace st_test;
using nlohmann::json;

namespace {

// Guided over unguided variance per sample of the oracle render (64 x 64, single scattering):
// measured 0.16-0.23 over six seed pairs at 128 spp (4 of them the unguided training's); the
// bound leaves a margin of 1.5.
constexpr double kOracleVarianceRatio = 0.35;
constexpr float kIsotropic = float(1.0 / (4.0 * 3.14159265358979323846));

// A fit record at (x, y, z) of direction w (unit), weight r, drawn by the isotropic phase function.
st_guide_record fit_record(float x, float y, float z, const float w[3], float r, uint32_t key) {
  st_guide_record rec{};
  rec.pos = st_float4{x, y, z, kIsotropic};
  rec.dir = st_float4{w[0], w[1], w[2], r};
  rec.key[0] = key;
  return rec;
}

// n records at uniform directions in the unit box: those within the cone cos > cos_cone around +y
// bring back radiance 1 (a narrow light), the others 0; with `spread`, every record brings back
// the same mean instead (a uniform light of equal power).
std::vector<st_guide_record> cone_records(int n, double cos_cone, bool spread, uint32_t seed) {
  std::mt19937 gen(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<st_guide_record> out;
  const float fraction = float((1 - cos_cone) / 2);  // of the sphere's directions in the cone
  for (int i = 0; i < n; ++i) {
    const float c = 1 - 2 * u(gen), phi = 6.2831853f * u(gen), s = std::sqrt(std::max(0.0f, 1 - c * c));
    const float w[3] = {s * std::cos(phi), c, s * std::sin(phi)};
    const float r = spread ? fraction : (c > cos_cone ? 1.0f : 0.0f);
    out.push_back(fit_record(u(gen), u(gen), u(gen), w, r, uint32_t(i)));
  }
  return out;
}

GuideCache unit_cache(int cells) {
  st_scene st{};  // no media: the unit box
  st.camera.width = st.camera.height = 4;
  return make_guide_cache(st, cells);
}

// The oracle scene (bench/scenes/guide_oracle.json, smaller, single scattering).
json oracle_scene() {
  json s = {{"format", "spectrack-scene/1"},
            {"camera", {{"type", "perspective"}, {"position", {0, 0, -4}}, {"look_at", {0, 0, 0}}, {"up", {0, 1, 0}}, {"fov_deg", 30}}},
            {"film", {{"width", 64}, {"height", 64}, {"spp", 64}}},
            {"render", {{"seed", 3}, {"max_depth", 1}}},
            {"media", json::array()}};
  s["media"].push_back({{"type", "homogeneous"}, {"bounds", {{-1, -1, -0.1}, {1, 1, 0.1}}}, {"sigma_s", {2.5, 2.5, 2.5}},
                        {"sigma_a", {0.05, 0.05, 0.05}}, {"phase", {{"type", "isotropic"}}}});
  s["media"].push_back({{"type", "homogeneous"}, {"bounds", {{-0.4, 1.1, -1.9}, {0.4, 1.9, -1.1}}}, {"sigma_s", {0, 0, 0}},
                        {"sigma_a", {20, 20, 20}}, {"emission", {{"radiance", {10, 10, 10}}}}});
  return s;
}

RenderResult render_oracle(const json& s, const std::string& dir, uint32_t seed, bool guiding) {
  RenderOptions o = quiet_options();
  o.seed = seed;
  o.guiding = guiding ? kGuidingAuto : kGuidingOff;  // auto: on for the lamp, without roulette and splitting
  return Renderer(scene_from_json(s, dir), o).render();
}

// The mean over pixels and channels of (a - b)^2 / 2: the variance of one render's pixel means.
double pixel_variance(const RenderResult& a, const RenderResult& b) {
  double sum = 0;
  for (size_t i = 0; i < a.rgb.size(); ++i) sum += 0.5 * double(a.rgb[i] - b.rgb[i]) * double(a.rgb[i] - b.rgb[i]);
  return sum / double(a.rgb.size());
}

}  // namespace

TEST(GuidingOracle, TheLearnedAlphaGuidesANarrowLightAndNotAUniformOne) {
  for (bool spread : {false, true}) {
    GuideCache c = unit_cache(1);
    fit_guide_cache(c, cone_records(4000, 0.95, spread, 5));
    ASSERT_EQ(c.regions.size(), 1u);
    if (!spread)
      EXPECT_GE(c.regions[0].alpha, 0.5f) << "a light from 2.5% of the directions: the guide pays";
    else
      EXPECT_EQ(c.regions[0].alpha, 0.0f) << "twin: the same power from every direction, nothing to gain";
  }
  GuideCache fixed = unit_cache(1);  // a fixed selection probability (SPECTRACK_GUIDE_ALPHA) is kept
  fixed.fixed_alpha = 0.3f;
  fit_guide_cache(fixed, cone_records(4000, 0.95, true, 5));
  EXPECT_EQ(fixed.regions[0].alpha, 0.3f);
}

TEST(GuidingOracle, SparseRegionsTakeThePooledFit) {
  GuideCache c = unit_cache(4);  // 64 cells of about 60 records each, 1.5 lit: none fits alone
  const std::vector<st_guide_record> records = cone_records(4000, 0.95, false, 7);
  const int guided = fit_guide_cache(c, records);
  EXPECT_EQ(guided, 64) << "every cell takes a fit pooled from the blocks around it";
  const st_guide_region& g = c.regions[0];
  int lobe = 0;
  for (int k = 1; k < ST_VMF_LOBES; ++k)
    if (g.mix.weight[k] > g.mix.weight[lobe]) lobe = k;
  EXPECT_GT(g.mix.lobe[lobe].y, 0.9f) << "the pooled mixture points at the light";
  GuideCache few = unit_cache(4);  // the twin: too few lit records anywhere, nothing guides
  std::vector<st_guide_record> sparse = records;
  size_t lit = 0;
  for (st_guide_record& r : sparse)
    if (r.dir.w > 0 && ++lit >= size_t(kGuideMinRecords)) r.dir.w = 0;
  EXPECT_EQ(fit_guide_cache(few, sparse), 0);
}

// A dim sky behind a narrow light: every record has weight, so each cell holds ~60 records but
// only ~1.5 lit ones. What a fit learns from is the records' effective count, so a cell whose few
// lit records carry nearly all its weight takes the pooled fit, which points at the light and
// guides (counted by records, each such cell fitted its own one to three lit records, whose
// held-out half could not show a gain: it did not guide). A cell with no lit record is a uniform
// sky of ~60 effective records: it fits itself and does not guide.
TEST(GuidingOracle, ADimSkyDoesNotHideASparseLight) {
  std::vector<st_guide_record> records = cone_records(4000, 0.95, false, 7);
  for (st_guide_record& r : records)
    if (r.dir.w == 0) r.dir.w = 1e-4f;
  GuideCache c = unit_cache(4);
  fit_guide_cache(c, records);
  std::vector<int> lit(c.regions.size(), 0);
  for (const st_guide_record& r : records)
    if (r.dir.w > 0.5f) ++lit[size_t(guide_region_of(c, r.pos.x, r.pos.y, r.pos.z))];
  int cells_lit = 0, guided = 0, toward = 0;
  for (size_t i = 0; i < c.regions.size(); ++i) {
    if (lit[i] == 0) continue;
    const st_guide_region& g = c.regions[i];
    int lobe = 0;
    for (int k = 1; k < ST_VMF_LOBES; ++k)
      if (g.mix.weight[k] > g.mix.weight[lobe]) lobe = k;
    ++cells_lit, guided += g.alpha > 0, toward += g.mix.lobe[lobe].y > 0.9f;
  }
  ASSERT_GT(cells_lit, 32);
  EXPECT_EQ(guided, cells_lit) << "every cell with a lit record guides, by the pooled fit";
  EXPECT_EQ(toward, cells_lit) << "and its main lobe points at the light";
}

TEST(GuidingOracle, GuidingWinsWhereTheLightIsNarrowAndStaysUnbiased) {
  const std::string dir = temp_dir("guided_oracle");
  json s = oracle_scene();
  const RenderResult off1 = render_oracle(s, dir, 11, false), off2 = render_oracle(s, dir, 12, false);
  s["film"]["spp"] = 512;  // the guided side of the means' test below (its 4 training samples unguided)
  const RenderResult on1 = render_oracle(s, dir, 21, true), on2 = render_oracle(s, dir, 22, true);
  EXPECT_TRUE(on1.guide.used) << "auto guides where a lamp lights the slab";
  EXPECT_GT(on1.guide.regions_guided, 0) << "the learned alpha guides toward the lamp";
  EXPECT_EQ(on1.stats.split_paths, 0u) << "auto does not split";
  const double ratio = pixel_variance(on1, on2) * 512 / (pixel_variance(off1, off2) * 64);
  EXPECT_LT(ratio, kOracleVarianceRatio) << "guided / unguided variance per sample";
  // the means: the guided renders, and their mean, against a long unguided reference (its rare hits
  // of the lamp make it the noisier side per sample)
  RenderResult both = on1;  // 1024 samples
  for (size_t i = 0; i < both.rgb.size(); ++i) both.rgb[i] = 0.5f * (on1.rgb[i] + on2.rgb[i]);
  s["film"]["spp"] = 4096;
  const RenderResult ref = render_oracle(s, dir, 31, false);
  for (const RenderResult* r : {&on1, &on2, static_cast<const RenderResult*>(&both)}) EXPECT_LT(max_z(*r, ref), 4.0);
  EXPECT_EQ(on1.stats.nonfinite_samples + on2.stats.nonfinite_samples, 0u);
  EXPECT_GT(max_z(both, ref, 1.03), 4.0) << "twin: a 3% error must be detected";
}
