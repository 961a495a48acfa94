// test_shards.cpp: exact pieces of one render, end to end through the CLI: sample-range shards
// (--spp-range), tiles (--pixel-bounds), `spectrack merge` and its refusals, several devices in
// one process (--device A,B) and MPI ranks (mpirun -np 2 ... --mpi).
//
// Design: every merged or distributed image is compared with one full render of the same scene,
// seed and spp, pixel by pixel, with a relative tolerance of 1e-5 (the bound; compensated
// film sums put the real difference near 1e-7). Each comparison is paired with a check that the
// tolerance is sharp: a render missing a quarter of the samples must fail it on most pixels, so
// a merge that dropped or doubled a shard could not pass. The scene is a small chromatic,
// heterogeneous VDB with an environment and a sun, so every path type contributes.
#include <sys/stat.h>

#include <OpenImageIO/imageio.h>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <cstdlib>

#include "cli_util.h"
#include "image/image.h"

namespace {

using namespace st_cli;
using json = nlohmann::json;

constexpr int kW = 24, kH = 16, kSpp = 16;

// The lumpy test volume under an environment and a sun, chromatic.
std::string shard_scene(const std::string& dir, const std::string& name = "scene.json",
                        const std::function<void(json&)>& edit = nullptr) {
  std::string vdb = dir + "/lumpy.vdb";
  if (!fs::exists(vdb)) st_test::write_lumpy(vdb);
  json s = lumpy_sky_scene(vdb);
  s["film"]["width"] = kW;
  s["film"]["height"] = kH;
  s["film"]["spp"] = kSpp;
  if (edit) edit(s);
  return write_scene(dir, name, s);
}

// spectrack EXRs, tiles included (an environment map must be a whole image, a film piece need not)
spectrack::RgbImage read(const std::string& path) { return spectrack::read_image(path, spectrack::ImageUse::kFilmPiece); }

// Pixels of `a` (whose window may be a tile) that differ from the same pixels of the full image
// `full` by more than `rel` of the pixel value; `worst` gets the largest relative difference.
int count_differing(const spectrack::RgbImage& a, const spectrack::RgbImage& full, double rel, double* worst = nullptr) {
  int bad = 0;
  double w = 0;
  for (int y = 0; y < a.height; ++y)
    for (int x = 0; x < a.width; ++x)
      for (int c = 0; c < 3; ++c) {
        double u = a.rgb[(size_t(y) * a.width + x) * 3 + c];
        size_t fi = (size_t(y + a.window.y0) * full.width + (x + a.window.x0)) * 3 + c;
        double v = full.rgb[fi];
        double d = std::abs(u - v), m = std::max(std::abs(u), std::abs(v));
        if (m > 0) w = std::max(w, d / m);
        if (d > rel * m || !std::isfinite(u)) ++bad;
      }
  if (worst) *worst = w;
  return bad;
}

Proc render_ok(const std::vector<std::string>& args) {
  RunOptions o;
  o.timeout_s = 240;  // may include a cold kernel build
  std::vector<std::string> a = {"render"};
  a.insert(a.end(), args.begin(), args.end());
  a.push_back("--quiet");
  Proc p = run(a, o);
  EXPECT_TRUE(p.exited && p.code == 0) << p.describe();
  return p;
}

Proc merge(const std::string& out, const std::vector<std::string>& inputs) {
  std::vector<std::string> a = {"merge", out};
  a.insert(a.end(), inputs.begin(), inputs.end());
  return run(a);
}

// A full render of the test scene (spp kSpp) with `tracker`, for the comparisons.
spectrack::RgbImage full_render(const std::string& dir, const std::string& scene, const std::string& tracker) {
  std::string out = dir + "/full_" + tracker + ".exr";
  render_ok({scene, "--tracker", tracker, "-o", out});
  return read(out);
}

// ---- shards ------------------------------------------------------------------------------------

void check_four_shards(const std::string& tracker, const std::function<void(json&)>& edit = nullptr) {
  std::string dir = test_dir();
  std::string scene = shard_scene(dir, "scene.json", edit);
  spectrack::RgbImage full = full_render(dir, scene, tracker);
  std::vector<std::string> shards;
  for (int k = 0; k < 4; ++k) {
    std::string out = dir + "/shard" + std::to_string(k) + ".exr";
    render_ok({scene, "--tracker", tracker, "--spp-range", fmt::format("{}:{}", 4 * k, 4 * k + 4), "-o", out});
    spectrack::RgbImage s = read(out);
    EXPECT_EQ(meta_string(s, "spp"), "4");
    EXPECT_EQ(meta_string(s, "spp_begin"), std::to_string(4 * k));
    EXPECT_EQ(meta_string(s, "spp_end"), std::to_string(4 * k + 4));
    EXPECT_EQ(meta_string(s, "spp_ranges"), fmt::format("{}:{}", 4 * k, 4 * k + 4));
    EXPECT_EQ(meta_string(s, "scene_hash").size(), 40u);
    shards.push_back(out);
  }
  std::string merged = dir + "/merged.exr";
  Proc m = merge(merged, {shards[2], shards[0], shards[3], shards[1]});  // order must not matter
  ASSERT_TRUE(m.exited && m.code == 0) << m.describe();
  spectrack::RgbImage img = read(merged);
  ASSERT_EQ(img.width, kW);
  ASSERT_EQ(img.height, kH);
  EXPECT_EQ(meta_string(img, "spp"), std::to_string(kSpp));
  EXPECT_EQ(meta_string(img, "spp_ranges"), fmt::format("0:{}", kSpp));
  EXPECT_EQ(meta_string(img, "tracker"), tracker);
  double worst = 0;
  EXPECT_EQ(count_differing(img, full, 1e-5, &worst), 0) << "worst relative difference " << worst;
  // The tolerance is sharp: three shards of four (12 of 16 samples) differ on every pixel the
  // volume covers (background pixels see the constant environment in every sample).
  std::string three = dir + "/three.exr";
  ASSERT_EQ(merge(three, {shards[0], shards[1], shards[2]}).code, 0);
  EXPECT_GT(count_differing(read(three), full, 1e-5), kW * kH * 3 / 4);
}

TEST(CliShards, FourShardsMergeToTheFullRenderSpectral) { check_four_shards("spectral"); }
TEST(CliShards, FourShardsMergeToTheFullRenderDeltaPerChannel) { check_four_shards("delta-per-channel"); }
TEST(CliShards, FourShardsMergeToTheFullRenderSpectralDecomposition) { check_four_shards("spectral-decomposition"); }
// point and spot lights (shadow rays of finite length) with one light per event
TEST(CliShards, FourShardsMergeToTheFullRenderWithLocalLights) {
  check_four_shards("spectral-decomposition", [](json& s) {
    s["render"]["light_sampling"] = "contribution";
    s["lights"].push_back({{"type", "point"}, {"position", {0.1, 0.2, -0.1}}, {"intensity", {2, 1.5, 1}}});
    s["lights"].push_back({{"type", "spot"}, {"position", {-0.6, 1.2, 0}}, {"look_at", {0, 0, 0}},
                           {"intensity", {3, 3, 4}}, {"cone_angle_deg", 25}, {"cone_delta_deg", 6}});
  });
}

// a diffuse ground (surface vertices, shadow rays it blocks) and a sphere light (rays that end at it)
TEST(CliShards, FourShardsMergeToTheFullRenderWithAGroundAndASphereLight) {
  check_four_shards("spectral-decomposition", [](json& s) {
    s["ground"] = {{"height", -0.7}, {"albedo", {0.4, 0.35, 0.3}}};
    s["lights"].push_back({{"type", "sphere"}, {"position", {0.9, 0.1, -0.9}}, {"radius", 0.15}, {"radiance", {4, 3, 2}}});
  });
}

// ---- tiles -------------------------------------------------------------------------------------

TEST(CliShards, TilesEqualThosePixelsOfTheFullRenderAndMergeToIt) {
  std::string dir = test_dir();
  std::string scene = shard_scene(dir);
  spectrack::RgbImage full = full_render(dir, scene, "spectral");
  // uneven tiles: a left column, and the right part cut in two rows
  const std::vector<std::string> bounds = {"0,7,0,16", "7,24,0,5", "7,24,5,16"};
  std::vector<std::string> tiles;
  for (size_t k = 0; k < bounds.size(); ++k) {
    std::string out = dir + "/tile" + std::to_string(k) + ".exr";
    render_ok({scene, "--tracker", "spectral", "--pixel-bounds", bounds[k], "-o", out});
    spectrack::RgbImage t = read(out);
    EXPECT_EQ(meta_string(t, "pixel_bounds"), bounds[k]);
    EXPECT_EQ(t.window.full_width, kW);
    EXPECT_EQ(t.window.full_height, kH);
    // a tile is those pixels of the full render, to the bit
    EXPECT_EQ(count_differing(t, full, 0.0), 0) << bounds[k];
    tiles.push_back(out);
  }
  spectrack::RgbImage t1 = read(tiles[1]);
  EXPECT_EQ(t1.width, 17);
  EXPECT_EQ(t1.height, 5);
  EXPECT_EQ(t1.window.x0, 7);
  EXPECT_EQ(t1.window.y0, 0);
  std::string merged = dir + "/merged.exr";
  Proc m = merge(merged, tiles);
  ASSERT_TRUE(m.exited && m.code == 0) << m.describe();
  spectrack::RgbImage img = read(merged);
  ASSERT_EQ(img.width, kW);
  ASSERT_EQ(img.height, kH);
  EXPECT_EQ(count_differing(img, full, 0.0), 0);

  // tiles of shards: two tiles times two sample ranges
  std::vector<std::string> pieces;
  for (const char* b : {"0,12,0,16", "12,24,0,16"})
    for (const char* r : {"0:5", "5:16"}) {
      std::string out = dir + "/piece_" + std::to_string(pieces.size()) + ".exr";
      render_ok({scene, "--tracker", "spectral", "--pixel-bounds", b, "--spp-range", r, "-o", out});
      pieces.push_back(out);
    }
  std::string mixed = dir + "/mixed.exr";
  ASSERT_EQ(merge(mixed, pieces).code, 0);
  double worst = 0;
  EXPECT_EQ(count_differing(read(mixed), full, 1e-5, &worst), 0) << "worst relative difference " << worst;
}

// Guiding (docs/guiding.md, "Determinism across shards"): every part trains the same cache over
// the full film, and the training pass's samples 0-3 stay whole in one part. Shards, tiles, tiles
// of shards, two devices (chunks of 3 samples: the first is stretched to hold the training samples)
// give the single guided render (MPI ranks: CliMpi.GuidedRanksGiveTheGuidedShard); the guided render
// differs from the unguided one on most pixels (so the comparisons see the guide); ranges that cut
// the training samples are refused.
TEST(CliShards, GuidedShardsTilesAndDevicesMergeToTheFullRender) {
  std::string dir = test_dir();
  std::string scene = shard_scene(dir);
  auto guided = [](std::vector<std::string> a) {
    a.insert(a.end(), {"--tracker", "spectral", "--guiding", "on"});
    return a;
  };
  render_ok(guided({scene, "-o", dir + "/full.exr"}));
  const spectrack::RgbImage full = read(dir + "/full.exr");
  EXPECT_GT(count_differing(full_render(dir, scene, "spectral"), full, 1e-5), kW * kH * 3 / 4) << "guiding changes the image";
  double worst = 0;
  std::vector<std::string> shards;
  for (const char* r : {"11:16", "0:6", "6:11"}) {
    shards.push_back(dir + "/g_shard_" + std::string(r).substr(0, std::string(r).find(':')) + ".exr");
    render_ok(guided({scene, "--spp-range", r, "-o", shards.back()}));
  }
  ASSERT_EQ(merge(dir + "/g_merged.exr", shards).code, 0);
  EXPECT_EQ(count_differing(read(dir + "/g_merged.exr"), full, 1e-5, &worst), 0) << "shards: worst " << worst;
  std::vector<std::string> pieces;
  for (const char* b : {"0,7,0,16", "7,24,0,16"}) {
    const std::string tile = dir + "/g_tile_" + std::to_string(pieces.size()) + ".exr";
    render_ok(guided({scene, "--pixel-bounds", b, "-o", tile}));
    EXPECT_EQ(count_differing(read(tile), full, 0.0), 0) << "a tile is those pixels of the full render: " << b;
    for (const char* r : {"0:5", "5:16"}) {
      pieces.push_back(dir + "/g_piece_" + std::to_string(pieces.size()) + ".exr");
      render_ok(guided({scene, "--pixel-bounds", b, "--spp-range", r, "-o", pieces.back()}));
    }
  }
  ASSERT_EQ(merge(dir + "/g_pieces.exr", pieces).code, 0);
  EXPECT_EQ(count_differing(read(dir + "/g_pieces.exr"), full, 1e-5, &worst), 0) << "tiles of shards: worst " << worst;
  const std::string two = dir + "/g_two.exr", stats = dir + "/g_two.json";
  render_ok(guided({scene, "--device", "0:0,0:0", "--chunk-spp", "3", "-o", two, "--stats-json", stats}));
  EXPECT_EQ(count_differing(read(two), full, 1e-5, &worst), 0) << "two devices: worst " << worst;
  json j = json::parse(std::ifstream(stats));
  ASSERT_EQ(j["samples_per_device"].size(), 2u) << j.dump(2);
  EXPECT_EQ(j["samples_per_device"][0].get<int>() + j["samples_per_device"][1].get<int>(), kSpp) << j.dump(2);
  for (const char* r : {"2:8", "0:4"}) {  // cuts the training samples 0:4, or may (a shard 0:4 of a longer render)
    Proc p = run({"render", scene, "--guiding", "on", "--spp-range", r, "-o", dir + "/cut.exr", "--quiet"});
    expect_error_exit(p, 2);  // a usage error
    EXPECT_THAT(p.out, HasSubstr("cut the training pass's samples 0:4")) << p.describe();
    EXPECT_THAT(p.out, HasSubstr("at most 5 samples is not cut")) << p.describe();
    EXPECT_FALSE(fs::exists(dir + "/cut.exr"));
  }
  // a whole render of one sample has no sample to train on: --guiding on is refused, auto stays off
  Proc one = run({"render", scene, "--guiding", "on", "--spp", "1", "-o", dir + "/one.exr", "--quiet"});
  expect_error_exit(one, 2);
  EXPECT_THAT(one.out, HasSubstr("needs at least 2 samples per pixel")) << one.describe();
  EXPECT_FALSE(fs::exists(dir + "/one.exr"));
}

// --guide-cache FILE: the first render trains and writes the cache, every later part reads it (no
// training) and renders the training pass's samples of its own window only where its range holds
// them: tiles are those pixels of the full render bit for bit, shards, devices and MPI ranks merge
// to it. A file of another render (another seed), a truncated, a foreign or a damaged file, and
// the option without guiding are refused naming the file and the reason; nothing is written then.
TEST(CliShards, GuideCacheFileIsTrainedOnceAndReadByEveryPart) {
  std::string dir = test_dir();
  std::string scene = shard_scene(dir);
  const std::string cache = dir + "/guide.cache";
  auto guided = [&](std::vector<std::string> a) {
    a.insert(a.end(), {"--tracker", "spectral", "--guiding", "on", "--guide-cache", cache});
    return a;
  };
  auto stats = [](const std::string& path) { return json::parse(std::ifstream(path)); };
  render_ok(guided({scene, "-o", dir + "/full.exr", "--stats-json", dir + "/full.json"}));
  EXPECT_EQ(stats(dir + "/full.json")["guide_cache_file"], "written");
  EXPECT_EQ(stats(dir + "/full.json")["guide_training_passes"], 1);
  ASSERT_TRUE(fs::exists(cache));
  const auto written = fs::last_write_time(cache);
  const spectrack::RgbImage full = read(dir + "/full.exr");
  for (const char* b : {"0,7,0,16", "7,24,0,16"}) {
    const std::string tile = dir + "/tile.exr", js = dir + "/tile.json";
    render_ok(guided({scene, "--pixel-bounds", b, "-o", tile, "--stats-json", js}));
    EXPECT_EQ(count_differing(read(tile), full, 0.0), 0) << "a tile is those pixels of the full render: " << b;
    EXPECT_EQ(stats(js)["guide_cache_file"], "read");
    EXPECT_EQ(stats(js)["guide_training_passes"], 0) << "read, not trained";
  }
  double worst = 0;
  std::vector<std::string> shards;
  for (const char* r : {"0:6", "6:11", "11:16"}) {
    shards.push_back(dir + "/shard_" + std::to_string(shards.size()) + ".exr");
    render_ok(guided({scene, "--spp-range", r, "-o", shards.back()}));
  }
  ASSERT_EQ(merge(dir + "/merged.exr", shards).code, 0);
  EXPECT_EQ(count_differing(read(dir + "/merged.exr"), full, 1e-5, &worst), 0) << "shards: worst " << worst;
  render_ok(guided({scene, "--device", "0:0,0:0", "--chunk-spp", "3", "-o", dir + "/two.exr"}));
  EXPECT_EQ(count_differing(read(dir + "/two.exr"), full, 1e-5, &worst), 0) << "two devices: worst " << worst;
  EXPECT_EQ(fs::last_write_time(cache), written) << "a read cache is not written again";
  // the twin: without the cache file, a tile trains on its own, over the full film: the same image
  render_ok({scene, "--tracker", "spectral", "--guiding", "on", "--pixel-bounds", "0,7,0,16", "-o", dir + "/own.exr"});
  EXPECT_EQ(count_differing(read(dir + "/own.exr"), full, 0.0), 0);

  // refusals: nothing is rendered or written, the cache stays as it was
  auto refused = [&](const std::string& file, std::vector<std::string> extra, const std::vector<std::string>& words,
                     int code = 1) {
    std::vector<std::string> a = {"render", scene, "--tracker", "spectral", "--guiding", "on", "--guide-cache", file,
                                  "-o", dir + "/refused.exr", "--quiet"};
    a.insert(a.end(), extra.begin(), extra.end());
    Proc p = run(a);
    expect_error_exit(p, code);
    for (const std::string& w : words) EXPECT_THAT(p.out, HasSubstr(w)) << p.describe();
    EXPECT_FALSE(fs::exists(dir + "/refused.exr")) << p.describe();
  };
  refused(cache, {"--seed", "12"}, {cache, "key field 'seed'", "trained for another render"});
  refused(cache, {"--no-alpha"}, {cache, "key field 'alpha'"});  // the pixel estimates then hold the seen sky
  std::string bytes;
  {
    std::ifstream in(cache, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  auto write_file = [&](const std::string& name, const std::string& content) {
    std::ofstream(dir + "/" + name, std::ios::binary) << content;
    return dir + "/" + name;
  };
  refused(write_file("short.cache", bytes.substr(0, bytes.size() - 100)), {}, {"short.cache", "truncated or damaged"});
  refused(write_file("foreign.cache", "P6\n4 4\n255\n"), {}, {"foreign.cache", "not a spectrack guide cache"});
  refused(write_file("nokey.cache", "spectrack-guide-cache 1\n{\"seed\": \n"), {}, {"nokey.cache", "not JSON"});
  // a damaged node: the first cell's root made an inner node whose children do not exist
  const size_t body = bytes.find('\n', bytes.find('\n') + 1) + 1;
  const json key = json::parse(bytes.substr(bytes.find('\n') + 1, body - bytes.find('\n') - 2));
  const size_t first_node = body + key["layout"]["header_bytes"].get<size_t>() +
                            key["layout"]["regions"].get<size_t>() * key["layout"]["region_bytes"].get<size_t>();
  std::string damaged = bytes;
  const uint32_t bad = 0x7ffffff0u;  // axis 0, children at node 0x1ffffffc: beyond the nodes
  std::memcpy(&damaged[first_node + 4], &bad, 4);
  refused(write_file("damaged.cache", damaged), {}, {"damaged.cache", "does not lead to a region"});
  std::string nan_alpha = bytes;  // a region's alpha (after its 8 lobes and 8 weights) not finite
  const float nan = std::nanf("");
  std::memcpy(&nan_alpha[body + key["layout"]["header_bytes"].get<size_t>() + 8 * 16 + 8 * 4], &nan, 4);
  refused(write_file("nan.cache", nan_alpha), {}, {"nan.cache", "region 0 holds a value out of range"});
  // a FIFO would block the reader for ever, a folder is no cache
  ASSERT_EQ(::mkfifo((dir + "/fifo.cache").c_str(), 0600), 0);
  refused(dir + "/fifo.cache", {}, {"fifo.cache", "not a regular file"});
  fs::create_directories(dir + "/folder.cache");
  refused(dir + "/folder.cache", {}, {"folder.cache", "not a regular file"});
  Proc p = run({"render", scene, "--guiding", "off", "--guide-cache", cache, "-o", dir + "/off.exr", "--quiet"});
  expect_error_exit(p, 2);
  EXPECT_THAT(p.out, HasSubstr("--guide-cache")) << p.describe();
  EXPECT_EQ(fs::last_write_time(cache), written);
}

// ---- refusals ----------------------------------------------------------------------------------

void expect_merge_refused(const std::string& dir, const std::vector<std::string>& inputs,
                          const std::vector<std::string>& words) {
  std::string out = dir + "/refused.exr";
  Proc p = merge(out, inputs);
  expect_error_exit(p);
  EXPECT_THAT(p.out, HasSubstr("error:")) << p.describe();
  for (auto& w : words) EXPECT_THAT(p.out, HasSubstr(w)) << p.describe();
  EXPECT_FALSE(fs::exists(out)) << "a merged image was written despite the error\n" << p.describe();
}

TEST(CliMerge, RefusesInputsOfDifferentRendersOverlapsAndGaps) {
  std::string dir = test_dir();
  std::string scene = shard_scene(dir);
  auto piece = [&](const std::string& name, std::vector<std::string> extra, const std::string& sc = "") {
    std::string out = dir + "/" + name;
    std::vector<std::string> a = {sc.empty() ? scene : sc, "--tracker", "spectral", "--spp", "2", "-o", out};
    if (std::find(extra.begin(), extra.end(), "--spp-range") != extra.end()) a.erase(a.begin() + 3, a.begin() + 5);
    a.insert(a.end(), extra.begin(), extra.end());
    render_ok(a);
    return out;
  };
  std::string a = piece("a.exr", {"--spp-range", "0:2"});
  std::string b = piece("b.exr", {"--spp-range", "2:4"});
  std::string ab = piece("ab.exr", {"--spp-range", "1:3"});
  std::string other_seed = piece("seed.exr", {"--spp-range", "2:4", "--seed", "99"});
  std::string other_tracker = dir + "/tracker.exr";
  render_ok({scene, "--tracker", "delta-per-channel", "--spp-range", "2:4", "-o", other_tracker});
  std::string other_lookup = piece("lookup.exr", {"--spp-range", "2:4", "--lookup", "stochastic"});
  // the budget and the majorant grid change which random numbers a sample draws: other renders
  std::string other_budget = piece("budget.exr", {"--spp-range", "2:4", "--budget", "7"});
  std::string other_majorant = piece("majorant.exr", {"--spp-range", "2:4", "--majorant-cell", "4"});
  // a time limit in the scene changes no image: the same scene
  std::string limited = piece("limited.exr", {"--spp-range", "2:4"},
                              shard_scene(dir, "scene_tl.json", [](json& s) { s["render"]["time_limit"] = 86400; }));
  std::string other_scene = piece("scene2.exr", {"--spp-range", "2:4"},
                                  shard_scene(dir, "scene2.json", [](json& s) { s["media"][0]["sigma_a"][0] = 0.06; }));
  std::string other_res = piece("res.exr", {"--spp-range", "2:4"},
                                shard_scene(dir, "scene3.json", [](json& s) { s["film"]["width"] = kW + 2; }));
  // the same scene text elsewhere (other folder, other output, other spp) is the same scene
  fs::create_directories(dir + "/moved");
  fs::copy_file(dir + "/lumpy.vdb", dir + "/moved/lumpy.vdb");
  std::string moved = piece("moved.exr", {"--spp-range", "2:4"}, shard_scene(dir + "/moved", "scene.json", [&](json& s) {
                              s["media"][0]["file"] = "lumpy.vdb";
                              s["film"]["output"] = "elsewhere.exr";
                              s["film"]["spp"] = 3;
                            }));
  EXPECT_EQ(merge(dir + "/ok.exr", {a, b}).code, 0);
  EXPECT_EQ(merge(dir + "/ok2.exr", {a, moved}).code, 0) << "a moved scene must keep its hash";
  EXPECT_EQ(merge(dir + "/ok3.exr", {a, limited}).code, 0) << "render.time_limit changes no image";
  expect_merge_refused(dir, {a, other_budget}, {"iteration budget (--budget)", "256 vs 7"});
  expect_merge_refused(dir, {a, other_majorant}, {"majorant grid", "cell auto", "cell 4"});

  expect_merge_refused(dir, {a, other_seed}, {"seed", "a.exr", "seed.exr"});
  expect_merge_refused(dir, {a, other_tracker}, {"tracker", "delta-per-channel"});
  expect_merge_refused(dir, {a, other_lookup}, {"density lookup mode", "trilinear", "stochastic"});
  expect_merge_refused(dir, {a, other_scene}, {"scene", "scene2.exr"});
  expect_merge_refused(dir, {a, other_res}, {"resolution", "24x16", "26x16"});
  expect_merge_refused(dir, {a, b, ab}, {"overlap", "ab.exr", "samples 1:2"});
  expect_merge_refused(dir, {a, a}, {"overlap"});

  // a volume with other contents under the same name is another scene
  std::string changed = dir + "/changed";
  fs::create_directories(changed);
  st_test::write_vdb(changed + "/lumpy.vdb", "density", openvdb::Coord(-8), openvdb::Coord(7),
                     [](int, int, int) { return 0.3f; }, 1.0 / 8.0);
  std::string changed_vdb = piece("changed.exr", {"--spp-range", "2:4"}, shard_scene(changed));
  expect_merge_refused(dir, {a, changed_vdb}, {"scene", "scene_hash"});

  // tiles: a gap, and tiles whose pixels would end with different samples
  std::string t0 = piece("t0.exr", {"--pixel-bounds", "0,12,0,16"});
  std::string t1 = piece("t1.exr", {"--pixel-bounds", "12,24,0,8"});
  std::string t2 = piece("t2.exr", {"--pixel-bounds", "12,24,8,16", "--spp-range", "0:3"});
  expect_merge_refused(dir, {t0, t1}, {"no input", "x 12..23, y 8..15"});
  expect_merge_refused(dir, {t0, t1, t2}, {"same samples", "0:3", "0:2"});

  // not mergeable at all
  std::string png = dir + "/a.png";
  render_ok({scene, "--tracker", "spectral", "--spp", "1", "-o", png});
  expect_merge_refused(dir, {a, png}, {"a.png", "png", "cannot be merged"});
  std::string foreign = dir + "/foreign.exr";
  spectrack::write_image(foreign, kW, kH, std::vector<float>(kW * kH * 3, 0.5f), {});
  expect_merge_refused(dir, {a, foreign}, {"foreign.exr", "not a spectrack render", "scene_hash"});
  expect_merge_refused(dir, {a, dir + "/missing.exr"}, {"missing.exr"});
  Proc p = merge(a, {a, b});
  expect_error_exit(p);
  EXPECT_THAT(p.out, HasSubstr("both an input and the output")) << p.describe();
  p = merge(dir + "/out.png", {a, b});
  expect_error_exit(p);
  EXPECT_THAT(p.out, HasSubstr("must be an EXR")) << p.describe();
  p = run({"merge", dir + "/out.exr"});
  expect_error_exit(p, 2);
}

// Spectral mode's stratified wavelengths (a pixel's aligned blocks of 4 samples share a rotation):
// shards that cut blocks merge to the full render, and pieces of the two wavelength samplings, which
// draw other wavelengths for the same samples, are refused.
TEST(CliShards, SpectralShardsThatCutBlocksOfWavelengthsMergeToTheFullRender) {
  std::string dir = test_dir();
  std::string scene = shard_scene(dir, "scene.json", [](json& s) { s["render"]["color"] = "spectral"; });
  spectrack::RgbImage full = full_render(dir, scene, "spectral-decomposition");
  EXPECT_EQ(meta_string(full, "wavelength_sampling"), "stratified");
  std::vector<std::string> shards;
  for (const char* range : {"0:3", "3:6", "6:13", "13:16"}) {
    std::string name = range;
    name[name.find(':')] = '_';
    shards.push_back(dir + "/shard_" + name + ".exr");
    render_ok({scene, "--tracker", "spectral-decomposition", "--spp-range", range, "-o", shards.back()});
  }
  std::string merged = dir + "/merged.exr";
  Proc m = merge(merged, shards);
  ASSERT_TRUE(m.exited && m.code == 0) << m.describe();
  double worst = 0;
  EXPECT_EQ(count_differing(read(merged), full, 1e-5, &worst), 0) << "worst relative difference " << worst;
  std::string independent = dir + "/independent.exr";
  render_ok({scene, "--tracker", "spectral-decomposition", "--spp-range", "13:16", "--wavelength-sampling", "independent",
             "-o", independent});
  EXPECT_EQ(meta_string(read(independent), "wavelength_sampling"), "independent");
  // the film is transparent (EXR alpha): R, G, B are 0 where the camera sees the environment alone
  const spectrack::RgbImage last = read(shards[3]);
  const int covered = int(std::count_if(last.rgb.begin(), last.rgb.end(), [](float v) { return v != 0.0f; }));
  EXPECT_GT(covered, kW * kH / 2);
  EXPECT_GT(count_differing(read(independent), last, 1e-5), covered * 9 / 10) << "other wavelengths, other pixels";
  expect_merge_refused(dir, {shards[0], shards[1], shards[2], independent},
                       {"wavelength sampling", "stratified", "independent"});
}

TEST(CliShardFlags, SppRangeAndPixelBoundsAreChecked) {
  std::string dir = test_dir();
  std::string scene = shard_scene(dir);
  for (std::string bad : {"4:2", "3:3", "a:b", "-1:4", "1:2:3", "5", "0:99999999999"}) {
    Proc p = run({"render", scene, "--spp-range", bad, "-o", dir + "/x.exr", "--quiet"});
    expect_error_exit(p, 2);
    EXPECT_THAT(p.out, HasSubstr("A:B")) << p.describe();
  }
  Proc p = run({"render", scene, "--spp", "4", "--spp-range", "0:4", "-o", dir + "/x.exr", "--quiet"});
  expect_error_exit(p, 2);
  EXPECT_THAT(p.out, HasSubstr("excludes")) << p.describe();
  for (std::string bad : {"0,0,0,4", "5,2,0,4", "0,4,0", "0,4,-1,4", "a,b,c,d"}) {
    p = run({"render", scene, "--pixel-bounds", bad, "-o", dir + "/x.exr", "--quiet"});
    expect_error_exit(p, 2);
    EXPECT_THAT(p.out, HasSubstr("x0,x1,y0,y1")) << p.describe();
  }
  p = run({"render", scene, "--pixel-bounds", "0,25,0,16", "-o", dir + "/x.exr", "--quiet"});
  expect_error_exit(p, 1);
  EXPECT_THAT(p.out, HasSubstr("24x16")) << p.describe();
  EXPECT_THAT(p.out, HasSubstr("/film/width")) << p.describe();
  EXPECT_FALSE(fs::exists(dir + "/x.exr"));
  p = run({"render", scene, "--device", "0:0,", "-o", dir + "/x.exr", "--quiet"});
  expect_error_exit(p, 1);
  EXPECT_THAT(p.out, HasSubstr("empty device")) << p.describe();
}

// ---- several devices in one process ------------------------------------------------------------

TEST(CliMultiDevice, TwoDevicesShareTheSamplesOfOneFilm) {
  // The same OpenCL device twice is two contexts, two renderers and two host threads: the
  // scheduling, the chunk hand-out and the film combination are those of two real devices.
  std::string dir = test_dir();
  std::string scene = shard_scene(dir);
  for (std::string tracker : {"spectral", "delta-per-channel"}) {
    spectrack::RgbImage full = full_render(dir, scene, tracker);
    std::string out = dir + "/two_" + tracker + ".exr", stats = dir + "/two_" + tracker + ".json";
    render_ok({scene, "--tracker", tracker, "--device", "0:0,0:0", "--chunk-spp", "3", "-o", out, "--stats-json", stats});
    spectrack::RgbImage img = read(out);
    double worst = 0;
    EXPECT_EQ(count_differing(img, full, 1e-5, &worst), 0) << tracker << ": worst relative difference " << worst;
    EXPECT_EQ(meta_string(img, "spp_ranges"), fmt::format("0:{}", kSpp));
    json j = json::parse(std::ifstream(stats));
    ASSERT_EQ(j["devices"].size(), 2u) << j.dump(2);
    ASSERT_EQ(j["samples_per_device"].size(), 2u);
    EXPECT_EQ(j["samples_per_device"][0].get<int>() + j["samples_per_device"][1].get<int>(), kSpp) << j.dump(2);
    EXPECT_EQ(j["spp"].get<int>(), kSpp);
    EXPECT_EQ(j["paths"].get<uint64_t>(), uint64_t(kW * kH * kSpp * (tracker == "spectral" ? 1 : 3)));
  }
  // --device all: every device of the machine (at least PoCL's CPU device)
  render_ok({scene, "--tracker", "spectral", "--device", "all", "--spp", "2", "-o", dir + "/all.exr",
             "--stats-json", dir + "/all.json"});
  json j = json::parse(std::ifstream(dir + "/all.json"));
  EXPECT_GE(j["devices"].size(), 1u);
  EXPECT_EQ(j["spp"].get<int>(), 2);
}

// ---- MPI ---------------------------------------------------------------------------------------

#ifdef SPECTRACK_HAVE_MPI
// mpirun's options: Open MPI as root in a container allowed explicitly, no shared-memory single
// copy (CMA needs ptrace rights containers lack), oversubscribed in case the machine reports one
// slot; time for a cold kernel build.
RunOptions mpirun_options() {
  ::setenv("OMPI_ALLOW_RUN_AS_ROOT", "1", 1);
  ::setenv("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1", 1);
  ::setenv("OMPI_MCA_btl_vader_single_copy_mechanism", "none", 1);
  ::setenv("OMPI_MCA_rmaps_base_oversubscribe", "1", 1);
  RunOptions o;
  o.timeout_s = 240;
  return o;
}
#endif

TEST(CliMpi, TwoRanksEqualTheSingleProcessRender) {
#ifndef SPECTRACK_HAVE_MPI
  GTEST_SKIP() << "spectrack was built without MPI (libopenmpi-dev not found by CMake)";
#else
  std::string dir = test_dir();
  std::string scene = shard_scene(dir);
  spectrack::RgbImage full = full_render(dir, scene, "spectral");
  const RunOptions o = mpirun_options();
  std::string out = dir + "/mpi.exr", stats = dir + "/mpi.json";
  Proc p = run_command({MPIRUN, "-np", "2", kBinary, "render", scene, "--tracker", "spectral", "--mpi", "-o", out,
                        "--stats-json", stats, "--quiet"},
                       o);
  ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
  spectrack::RgbImage img = read(out);
  double worst = 0;
  EXPECT_EQ(count_differing(img, full, 1e-5, &worst), 0) << "worst relative difference " << worst;
  EXPECT_EQ(meta_string(img, "spp_ranges"), fmt::format("0:{}", kSpp));
  EXPECT_EQ(meta_string(img, "mpi_ranks"), "2");
  json j = json::parse(std::ifstream(stats));
  EXPECT_EQ(j["mpi_ranks"].get<int>(), 2);
  ASSERT_EQ(j["samples_per_device"].size(), 2u) << j.dump(2);
  EXPECT_EQ(j["samples_per_device"][0].get<int>(), kSpp / 2);
  EXPECT_EQ(j["samples_per_device"][1].get<int>(), kSpp / 2);
  EXPECT_EQ(j["paths"].get<uint64_t>(), uint64_t(kW * kH * kSpp));
  // A sample range split over ranks: 3 ranks over samples 5:12 give the shard 5:12.
  std::string shard = dir + "/shard.exr", shard_mpi = dir + "/shard_mpi.exr";
  render_ok({scene, "--tracker", "spectral", "--spp-range", "5:12", "-o", shard});
  p = run_command({MPIRUN, "-np", "3", kBinary, "render", scene, "--tracker", "spectral", "--spp-range", "5:12",
                   "--mpi", "-o", shard_mpi, "--quiet"},
                  o);
  ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
  EXPECT_EQ(count_differing(read(shard_mpi), read(shard), 1e-5, &worst), 0) << "worst relative difference " << worst;
  EXPECT_EQ(meta_string(read(shard_mpi), "spp_ranges"), "5:12");
#endif
}

// Guided MPI ranks (docs/guiding.md, "Determinism across shards"): 3 ranks over samples 0:6, whose
// shares 0:2, 2:4, 4:6 become 0:4, none and 4:6 (the training samples stay in one share), give the
// shard 0:6 rendered by one process.
TEST(CliMpi, GuidedRanksGiveTheGuidedShard) {
#ifndef SPECTRACK_HAVE_MPI
  GTEST_SKIP() << "spectrack was built without MPI (libopenmpi-dev not found by CMake)";
#else
  std::string dir = test_dir();
  std::string scene = shard_scene(dir);
  const RunOptions o = mpirun_options();
  double worst = 0;
  const std::string shard = dir + "/g_0_6.exr", mpi = dir + "/g_mpi.exr";
  render_ok({scene, "--tracker", "spectral", "--guiding", "on", "--spp-range", "0:6", "-o", shard});
  Proc p = run_command({MPIRUN, "-np", "3", kBinary, "render", scene, "--tracker", "spectral", "--guiding", "on",
                        "--spp-range", "0:6", "--mpi", "-o", mpi, "--quiet"},
                       o);
  ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
  EXPECT_EQ(count_differing(read(mpi), read(shard), 1e-5, &worst), 0) << "MPI ranks: worst " << worst;
  render_ok({scene, "--tracker", "spectral", "--guiding", "off", "--spp-range", "0:6", "-o", dir + "/u_0_6.exr"});
  EXPECT_GT(count_differing(read(mpi), read(dir + "/u_0_6.exr"), 1e-5), kW * kH * 3 / 4)
      << "twin: the unguided shard differs";
#endif
}

TEST(CliMpi, MpiFlagOutsideMpirunIsOneRankOrAClearError) {
  std::string dir = test_dir();
  std::string scene = shard_scene(dir);
  RunOptions o;
  o.timeout_s = 240;
  Proc p = run({"render", scene, "--tracker", "spectral", "--mpi", "-o", dir + "/x.exr", "--quiet"}, o);
#ifdef SPECTRACK_HAVE_MPI
  // a singleton MPI job: one rank holding every sample, the full render itself
  ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
  double worst = 0;
  EXPECT_EQ(count_differing(read(dir + "/x.exr"), full_render(dir, scene, "spectral"), 1e-5, &worst), 0) << worst;
#else
  expect_error_exit(p, 1);
  EXPECT_THAT(p.out, HasSubstr("without MPI")) << p.describe();
#endif
}

}  // namespace
