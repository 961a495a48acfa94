// test_fire.cpp: the fire controls (docs/scene-format.md "Emission models", "Ramp emission",
// "Presets") and `spectrack info`'s warning for an emission grid the file lacks:
//   - the "density" emission model: a homogeneous emitting absorber against its closed form
//     L = density scale Le (1 - exp(-sigma_a d)) / sigma_a for two sigma_a (twin: 3% off is seen);
//   - a one-stop ramp renders the image of constant emission, bit for bit; a linear ramp agrees
//     with the grid-scaled radiance emission within 4 SE (twin: 3% off is seen); bad ramps and a
//     ramp in spectral mode are refused by JSON path;
//   - houdini-pyro renders OpenUSD's densityAndHeat.vdb (Houdini: density, heat) with no other
//     field: no error, every sample finite, light only where the heat is (no other light: pixels
//     whose rays miss the heat grid's box are black, the heat's pixels glow);
//   - blender renders Blender's smoke_000002.vdb (density only: smoke, with a warning) and a
//     Blender-like cache with a flame grid (glowing only where the flame is);
//   - fields the scene gives override the preset; an unknown preset is refused by JSON path;
//   - info warns (text and JSON) when an emission grid is missing, and says nothing otherwise.
#include <cmath>

#include "cli_util.h"
#include "test_util.h"
#include "volume/inspect.h"

using namespace spectrack;
using namespace st_test;
using nlohmann::json;

namespace {

struct Box2 {
  double x0, y0, x1, y1;
};

// An orthographic view along +z framing `frame` (x, y), no light and no scattering (max_depth 0):
// only emission seen straight along the camera rays shows.
json emission_only_scene(const std::string& file, const std::string& preset, const Box2& frame, double z) {
  const double cx = 0.5 * (frame.x0 + frame.x1), cy = 0.5 * (frame.y0 + frame.y1);
  const double h = 1.1 * std::max(frame.x1 - frame.x0, frame.y1 - frame.y0);
  return {{"format", "spectrack-scene/1"},
          {"camera", {{"type", "orthographic"}, {"position", {cx, cy, z}}, {"look_at", {cx, cy, z + 1}}, {"up", {0, 1, 0}},
                      {"height", h}}},
          {"film", {{"width", 24}, {"height", 24}, {"spp", 4}}},
          {"render", {{"seed", 3}, {"max_depth", 0}}},
          {"lights", json::array()},
          {"media", {{{"type", "vdb"}, {"file", file}, {"preset", preset}}}}};
}

GridInfo grid_named(const std::string& file, const std::string& name) {
  for (const GridInfo& g : inspect_volume(file))
    if (g.name == name) return g;
  ADD_FAILURE() << file << " has no grid " << name;
  return {};
}

// A pure absorber slab seen head on by an orthographic camera, emitting `emission`.
json slab_scene(double sigma_a, const json& emission, const std::string& tracker) {
  return {{"format", "spectrack-scene/1"},
          {"camera", {{"type", "orthographic"}, {"position", {0, 0, -3}}, {"look_at", {0, 0, 0}}, {"up", {0, 1, 0}}, {"height", 1.0}}},
          {"film", {{"width", 8}, {"height", 8}, {"spp", 1024}}},
          {"render", {{"seed", 5}, {"tracker", tracker}}},
          {"lights", json::array()},
          {"media", {{{"type", "homogeneous"}, {"bounds", {{-5, -5, -1}, {5, 5, 1}}}, {"sigma_a", {sigma_a, sigma_a, sigma_a}},
                      {"sigma_s", {0, 0, 0}}, {"density_scale", 1.5}, {"emission", emission}}}}};
}

// Pixel (x, y)'s world point on the film plane of emission_only_scene (image columns go along the
// camera's right, rows along -up).
std::array<double, 2> pixel_world(const json& s, int x, int y) {
  const double h = s["camera"]["height"].get<double>(), cx = s["camera"]["position"][0].get<double>(),
               cy = s["camera"]["position"][1].get<double>();
  const int n = s["film"]["width"].get<int>();
  // looking along +z with up +y, the camera's right is -x
  return {cx - ((x + 0.5) / n - 0.5) * h, cy - ((y + 0.5) / n - 0.5) * h};
}

// Checks: finite, emission inside the fire grid's (x, y) box, none outside it (a margin of a voxel).
void expect_glow_where(const RenderResult& r, const json& s, const GridInfo& fire, const std::string& what) {
  EXPECT_EQ(r.stats.nonfinite_samples, 0u) << what;
  double inside = 0, outside = 0;
  const double mx = fire.voxel_size[0] * 2, my = fire.voxel_size[1] * 2;
  for (int y = 0; y < r.height; ++y)
    for (int x = 0; x < r.width; ++x) {
      const auto p = pixel_world(s, x, y);
      const size_t i = (size_t(y) * r.width + x) * 3;
      const double v = r.rgb[i] + r.rgb[i + 1] + r.rgb[i + 2];
      ASSERT_TRUE(std::isfinite(v)) << what;
      const bool in = p[0] >= fire.world_min[0] - mx && p[0] <= fire.world_max[0] + mx && p[1] >= fire.world_min[1] - my &&
                      p[1] <= fire.world_max[1] + my;
      (in ? inside : outside) += v;
    }
  EXPECT_GT(inside, 0.0) << what << ": no glow where the fire grid is";
  EXPECT_EQ(outside, 0.0) << what << ": light where the fire grid is not";
}

}  // namespace

TEST(FirePresets, HoudiniPyroRendersDensityAndHeat) {
  const std::string dir = temp_dir("preset_houdini");
  const std::string file = st_cli::kShared + "/usd/densityAndHeat.vdb";
  const GridInfo density = grid_named(file, "density"), heat = grid_named(file, "heat");
  json s = emission_only_scene(file, "houdini-pyro",
                               {density.world_min[0], density.world_min[1], density.world_max[0], density.world_max[1]},
                               density.world_min[2] - 10);
  SceneDesc d = scene_from_json(s, dir);
  EXPECT_DOUBLE_EQ(d.media[0].sigma_a[0], 0.3);
  EXPECT_EQ(d.media[0].phase.type, ST_PHASE_HG);
  RenderResult r = Renderer(d, quiet_options()).render();
  EXPECT_TRUE(r.features & ST_FEATURE_EMISSION) << "the preset's fire must emit";
  expect_glow_where(r, s, heat, "houdini-pyro");
  // the fields the scene gives override the preset: an emission of zero radiance replaces its fire
  s["media"][0]["sigma_a"] = {0, 0, 0};
  s["media"][0]["emission"] = {{"type", "radiance"}, {"radiance", {0, 0, 0}}};
  RenderResult dark = Renderer(scene_from_json(s, dir), quiet_options()).render();
  double sum = 0;
  for (float v : dark.rgb) sum += v;
  EXPECT_EQ(sum, 0.0) << "the scene's fields must override the preset (twin of the glow)";
}

TEST(FirePresets, BlenderRendersSmokeAndFlame) {
  const std::string dir = temp_dir("preset_blender");
  // Blender's smoke cache (density only): smoke, lit by a sky, no error
  const std::string smoke = st_cli::kShared + "/usd/smoke_000002.vdb";
  const GridInfo density = grid_named(smoke, "density");
  json s = emission_only_scene(smoke, "blender",
                               {density.world_min[0], density.world_min[1], density.world_max[0], density.world_max[1]},
                               density.world_min[2] - 10);
  s["lights"].push_back({{"type", "environment"}, {"radiance", {1, 1, 1}}});
  s["render"]["max_depth"] = -1;
  RenderResult r = Renderer(scene_from_json(s, dir), quiet_options()).render();
  EXPECT_EQ(r.stats.nonfinite_samples, 0u);
  EXPECT_FALSE(r.features & ST_FEATURE_EMISSION) << "no fire grid: no emission";
  double lo = 1e30;
  for (float v : r.rgb) lo = std::min(lo, double(v));
  EXPECT_LT(lo, 0.99) << "the smoke must attenuate the sky somewhere";
  // a Blender-like cache: density everywhere in a cube, flame in its +x half only
  const std::string cache = dir + "/blender_fire.vdb";
  write_vdb_grids(cache, openvdb::Coord(-8, -8, -8), openvdb::Coord(7, 7, 7),
                  {{"density", [](int, int, int) { return 1.0f; }},
                   {"flame", [](int i, int, int) { return i >= 2 ? 0.9f : 0.0f; }}},
                  1.0 / 8);
  json f = emission_only_scene(cache, "blender", {-1, -1, 1, 1}, -5);
  RenderResult g = Renderer(scene_from_json(f, dir), quiet_options()).render();
  EXPECT_TRUE(g.features & ST_FEATURE_EMISSION);
  GridInfo flame = grid_named(cache, "flame");
  expect_glow_where(g, f, flame, "blender flame");
  // unknown presets are refused by path
  f["media"][0]["preset"] = "maya";
  const std::string err = error_of([&] { scene_from_json(f, dir); });
  EXPECT_NE(err.find("/media/0/preset"), std::string::npos) << err;
  EXPECT_NE(err.find("houdini-pyro, blender"), std::string::npos) << err;
}

TEST(FirePresets, InfoRefusesAMissingEmissionGridAsRenderDoes) {
  const std::string dir = st_cli::test_dir();
  const std::string file = st_cli::kShared + "/usd/densityAndHeat.vdb";
  json s = st_cli::vdb_scene(file);
  s["media"][0]["sigma_a"] = {0.5, 0.5, 0.5};
  s["media"][0]["emission"] = {{"type", "radiance"}, {"radiance", {1, 1, 1}}, {"grid", "flame"}};
  const std::string missing = st_cli::write_scene(dir, "missing.json", s);
  for (const std::vector<std::string>& cmd : {std::vector<std::string>{"info", missing},
                                              std::vector<std::string>{"render", missing, "-q", "-o", dir + "/m.exr"}}) {
    st_cli::Proc p = st_cli::run(cmd);
    EXPECT_TRUE(p.exited && p.code == 1) << p.describe();
    EXPECT_NE(p.out.find("/media/0/emission/grid"), std::string::npos) << p.out;
    EXPECT_NE(p.out.find("\"flame\""), std::string::npos) << p.out;
  }
  st_cli::Proc p = st_cli::run({"info", "--json", missing});
  EXPECT_NE(p.out.find("\"renders\": false"), std::string::npos) << p.out;
  s["media"][0]["emission"] = {{"type", "blackbody"}, {"temperature_grid", "temperature"}};
  p = st_cli::run({"info", st_cli::write_scene(dir, "missing_t.json", s)});
  EXPECT_TRUE(p.exited && p.code == 1) << p.describe();
  EXPECT_NE(p.out.find("/media/0/emission/temperature_grid"), std::string::npos) << p.out;
  // twin: the grid the file has passes, with no warning
  s["media"][0]["emission"] = {{"type", "radiance"}, {"radiance", {1, 1, 1}}, {"grid", "heat"}};
  p = st_cli::run({"info", "--json", st_cli::write_scene(dir, "present.json", s)});
  EXPECT_TRUE(p.exited && p.code == 0) << p.describe();
  EXPECT_EQ(p.out.find("warning:"), std::string::npos) << p.out;
  EXPECT_NE(p.out.find("\"renders\": true"), std::string::npos) << p.out;
  // a preset that finds none of its fire grids renders without emission: a warning, exit 0
  s = st_cli::vdb_scene(st_cli::kShared + "/smoke1.vdb");
  s["media"][0]["preset"] = "houdini-pyro";
  s["media"][0]["sigma_a"] = {0.5, 0.5, 0.5};
  p = st_cli::run({"info", "--json", st_cli::write_scene(dir, "preset.json", s)});
  EXPECT_TRUE(p.exited && p.code == 0) << p.describe();
  EXPECT_NE(p.out.find("none of the preset's fire grids"), std::string::npos) << p.out;
  EXPECT_NE(p.out.find("\"warnings\""), std::string::npos) << p.out;
}

TEST(FireControls, DensityModelMatchesItsClosedForm) {
  const std::string dir = temp_dir("fire_density_model");
  const json emission = {{"radiance", {0.4, 0.8, 1.2}}, {"scale", 2.0}, {"model", "density"}};
  for (const char* tracker : {"delta-per-channel", "spectral"})
    for (double sigma_a : {0.5, 2.0}) {
      RenderResult r = Renderer(scene_from_json(slab_scene(sigma_a, emission, tracker), dir), quiet_options()).render();
      EXPECT_EQ(r.stats.nonfinite_samples, 0u);
      const double st = sigma_a * 1.5, d = 2.0, Le[3] = {0.4, 0.8, 1.2};
      for (int c = 0; c < 3; ++c) {
        // source density * scale * Le (density 1.5): L = 1.5 * 2 Le (1 - exp(-st d)) / st
        const double expected = 1.5 * 2.0 * Le[c] * (1 - std::exp(-st * d)) / st;
        Stats m = mean_se(channel(r, c));
        EXPECT_NEAR(m.mean, expected, 4 * m.se + 1e-6) << tracker << " sigma_a " << sigma_a << " channel " << c;
        EXPECT_GT(std::abs(m.mean - 1.03 * expected), 4 * m.se) << "twin: " << tracker << " channel " << c;
      }
    }
  // refused: a chromatic sigma_a (the division would colour the fire)
  json s = slab_scene(0.5, emission, "spectral");
  s["media"][0]["sigma_a"] = {0.5, 0.6, 0.5};
  const std::string err = error_of([&] { scene_from_json(s, dir); });
  EXPECT_NE(err.find("/media/0/emission/model"), std::string::npos) << err;
}

namespace {
// A vdb medium of lumpy density with a heat grid in [0, 1] over its +x side, no light: the image
// is the emission and its scattering.
json heat_scene(const std::string& dir, const json& emission) {
  write_vdb_grids(dir + "/heat.vdb", openvdb::Coord(-8, -8, -8), openvdb::Coord(7, 7, 7),
                  {{"density", [](int i, int j, int k) { return 0.6f + 0.4f * std::sin(0.7f * i + 0.3f * j - 0.2f * k); }},
                   {"heat", [](int i, int j, int) { return i < 0 ? 0.0f : std::min(1.0f, 0.12f * float(i + j + 8) / 2.0f); }}},
                  1.0 / 8);
  return {{"format", "spectrack-scene/1"},
          {"camera", {{"type", "orthographic"}, {"position", {0, 0, -3}}, {"look_at", {0, 0, 0}}, {"up", {0, 1, 0}}, {"height", 2.2}}},
          {"film", {{"width", 16}, {"height", 16}, {"spp", 256}}},
          {"render", {{"seed", 5}}},
          {"lights", json::array()},
          {"media", {{{"type", "vdb"}, {"file", "heat.vdb"}, {"sigma_a", {1.0, 1.0, 1.0}}, {"sigma_s", {1.0, 1.0, 1.0}},
                      {"emission", emission}}}}};
}
}  // namespace

TEST(FireControls, OneStopRampIsConstantEmissionAndALinearRampIsTheGrid) {
  const std::string dir = temp_dir("fire_ramp");
  RenderResult constant = Renderer(scene_from_json(heat_scene(dir, {{"radiance", {0.9, 0.5, 0.2}}}), dir), quiet_options()).render();
  json one = {{"type", "ramp"}, {"grid", "heat"}, {"stops", {{0.5, {0.9, 0.5, 0.2}}}}};
  RenderResult ramp = Renderer(scene_from_json(heat_scene(dir, one), dir), quiet_options()).render();
  EXPECT_TRUE(ramp.rgb == constant.rgb) << "a one-stop ramp must render constant emission's image";
  one["stops"][0][1] = {0.9 * 1.03, 0.5 * 1.03, 0.2 * 1.03};
  RenderResult off = Renderer(scene_from_json(heat_scene(dir, one), dir), quiet_options()).render();
  EXPECT_GT(max_z(off, constant), 4.0) << "twin: a 3% brighter stop must be seen";
  // a linear ramp from black at 0 to a colour at 1 is the radiance times the heat grid
  RenderOptions o = quiet_options();
  o.seed = 11;
  RenderResult grid = Renderer(scene_from_json(heat_scene(dir, {{"radiance", {3, 2, 1}}, {"grid", "heat"}}), dir), o).render();
  json linear = {{"type", "ramp"}, {"grid", "heat"}, {"stops", {{0.0, {0, 0, 0}}, {1.0, {3, 2, 1}}}}};
  RenderResult lin = Renderer(scene_from_json(heat_scene(dir, linear), dir), quiet_options()).render();
  EXPECT_EQ(lin.stats.nonfinite_samples, 0u);
  EXPECT_LT(max_z(lin, grid), 4.0) << "linear ramp vs grid-scaled radiance";
  EXPECT_GT(max_z(lin, grid, 1.03), 4.0) << "twin: 3% off must be seen";
  // refused: unsorted stops, no grid, a homogeneous medium, spectral mode
  auto err = [&](const json& e, bool spectral = false) {
    json s = heat_scene(dir, e);
    if (spectral) s["render"]["color"] = "spectral";
    return error_of([&] { Renderer(scene_from_json(s, dir), quiet_options()).render(); });
  };
  EXPECT_NE(err({{"type", "ramp"}, {"grid", "heat"}, {"stops", {{1.0, {1, 1, 1}}, {0.5, {1, 1, 1}}}}}).find("/media/0/emission/stops/1/0"),
            std::string::npos);
  EXPECT_NE(err({{"type", "ramp"}, {"stops", {{1.0, {1, 1, 1}}}}}).find("/media/0/emission/grid"), std::string::npos);
  // stops whose span overflows a double would divide by infinity (no emission, silently): refused;
  // the twin, spans within the doubles, renders
  EXPECT_NE(err({{"type", "ramp"}, {"grid", "heat"}, {"stops", {{-1e308, {0, 0, 0}}, {1e308, {1, 1, 1}}}}})
                .find("/media/0/emission/stops/1/0: value 1e+308 is too far from the first stop's"),
            std::string::npos);
  EXPECT_NO_THROW(scene_from_json(heat_scene(dir, {{"type", "ramp"}, {"grid", "heat"},
                                                    {"stops", {{-1e300, {0, 0, 0}}, {1e300, {1, 1, 1}}}}}), dir));
  EXPECT_NE(err(linear, true).find("/media/0/emission/type"), std::string::npos);
  json h = slab_scene(1.0, linear, "spectral");
  EXPECT_NE(error_of([&] { scene_from_json(h, dir); }).find("vdb media only"), std::string::npos);
}
