// test_stress.cpp: numerical stress cases (docs/estimators.md, 'Tests that catch bias') for every tracker: densities from
// 1e-6 to 1e6 per unit length, 1:1000 chromatic ratios, HG g = +-0.999, majorants 10x too low
// and minorants 10x too high, the camera inside a medium, rays along cell faces and grazing the
// bounds, voxel sizes 1e-4 and 1e4, an all-background volume, a degenerate transform. Every
// render must be finite (nonfinite_samples == 0, every pixel finite), finish in bounded time,
// and match the analytic answer within 4 standard errors where one exists.
#include <chrono>

#include <OpenImageIO/imageio.h>
#include <nanovdb/util/IO.h>
#include <nanovdb/util/OpenToNanoVDB.h>

#include "device/opencl.h"
#include "cli_util.h"
#include "test_util.h"

using namespace spectrack;
using namespace st_test;
using nlohmann::json;

namespace {

const int kAllTrackers[] = {ST_TRACKER_DELTA_PER_CHANNEL, ST_TRACKER_DELTA, ST_TRACKER_SPECTRAL, ST_TRACKER_DECOMPOSITION,
                            ST_TRACKER_SPECTRAL_DECOMPOSITION, ST_TRACKER_SPECTRAL_MIS};

bool is_chromatic(const json& medium) { return medium["sigma_a"][0] != medium["sigma_a"][1] || medium["sigma_a"][1] != medium["sigma_a"][2]; }

json ortho_scene(int spp, double z_camera = -3) {
  return json{{"format", "spectrack-scene/1"},
              {"camera", {{"type", "orthographic"}, {"position", {0, 0, z_camera}}, {"look_at", {0, 0, z_camera + 1}}, {"up", {0, 1, 0}}, {"height", 1.0}}},
              {"film", {{"width", 8}, {"height", 8}, {"spp", spp}}},
              {"render", {{"seed", 11}}},
              {"lights", {{{"type", "environment"}, {"radiance", {1, 1, 1}}}}},
              {"media", json::array()}};
}

RenderResult render_checked(const json& s, const std::string& dir, int tracker, const std::string& what) {
  RenderOptions o = quiet_options();
  o.tracker = tracker;
  auto t0 = std::chrono::steady_clock::now();
  RenderResult r = Renderer(scene_from_json(s, dir), o).render();
  double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(r.stats.nonfinite_samples, 0u) << what << " / " << tracker_name(tracker);
  for (float v : r.rgb) {
    EXPECT_TRUE(std::isfinite(v)) << what << " / " << tracker_name(tracker);
    if (!std::isfinite(v)) break;
  }
  EXPECT_LT(secs, 120.0) << what << " / " << tracker_name(tracker) << ": run time must stay bounded";
  return r;
}

void expect_near_channels(const RenderResult& r, const double expected[3], const std::string& what) {
  for (int c = 0; c < 3; ++c) {
    Stats s = mean_se(channel(r, c));
    EXPECT_NEAR(s.mean, expected[c], 4.0 * s.se + 1e-5 * std::max(1.0, expected[c])) << what << ", channel " << c;
  }
}

// Absorbing-and-scattering-free slab of thickness 2: T = exp(-2 sigma_a) per channel.
void check_absorbing_slab(double scale, const double sigma_a[3], const std::string& name, double majorant_scale = 1.0,
                          double minorant_scale = 1.0, double z_camera = -3, double thickness_seen = 2.0) {
  std::string dir = temp_dir(name);
  json s = ortho_scene(64, z_camera);
  json m = {{"type", "homogeneous"}, {"bounds", {{-1, -1, -1}, {1, 1, 1}}},
            {"sigma_a", {sigma_a[0] * scale, sigma_a[1] * scale, sigma_a[2] * scale}}, {"sigma_s", {0, 0, 0}},
            {"majorant_scale", majorant_scale}, {"minorant_scale", minorant_scale}};
  s["media"].push_back(m);
  double expected[3];
  for (int c = 0; c < 3; ++c) expected[c] = std::exp(-sigma_a[c] * scale * thickness_seen);
  for (int tracker : kAllTrackers) {
    if (tracker == ST_TRACKER_DELTA && is_chromatic(m)) continue;
    RenderResult r = render_checked(s, dir, tracker, name);
    expect_near_channels(r, expected, name + " / " + tracker_name(tracker));
  }
}

TEST(Stress, DensityScalesFromOneMillionthToOneMillion) {
  const double gray[3] = {1, 1, 1};
  for (double scale : {1e-6, 1e-3, 1.0, 1e3, 1e6}) check_absorbing_slab(scale, gray, "scale_" + std::to_string(scale));
}

TEST(Stress, ChromaticRatioOneToThousand) {
  const double chroma[3] = {1.0, 1e-3, 1e-6};
  check_absorbing_slab(0.5, chroma, "chroma_1000");
  const double chroma2[3] = {1e-3, 1.0, 1e3};
  check_absorbing_slab(1.0, chroma2, "chroma_1000b");
}

TEST(Stress, MajorantTenTimesTooLow) {
  const double sig[3] = {0.3, 0.6, 0.9};
  check_absorbing_slab(1.0, sig, "majorant_low", 0.1, 1.0);
}

TEST(Stress, MinorantTenTimesTooHighStaysFinite) {
  // Unbiased but of practically infinite variance: per channel, control collisions absorb ten
  // times too often and residual null collisions compensate with weights of 3 each; in this slab
  // E[w^2] is about e^21 per sample, so a sample standard error means nothing (docs/estimators.md, 'Tests that catch bias').
  // Unbiasedness of non-bounding minorants is tested at a 2x overshoot in Estimators.*; here
  // only finiteness and bounded time.
  std::string dir = temp_dir("minorant_high");
  json s = ortho_scene(64);
  s["media"].push_back({{"type", "homogeneous"}, {"bounds", {{-1, -1, -1}, {1, 1, 1}}}, {"sigma_a", {0.3, 0.6, 0.9}},
                        {"sigma_s", {0.2, 0.2, 0.2}}, {"minorant_scale", 10.0}});
  for (int tracker : {ST_TRACKER_DECOMPOSITION, ST_TRACKER_SPECTRAL_DECOMPOSITION}) {
    RenderResult r = render_checked(s, dir, tracker, "minorant 10x");
    EXPECT_GT(r.stats.control_collisions, 0u);
  }
}

TEST(Stress, CameraInsideTheMedium) {
  const double sig[3] = {0.3, 0.6, 0.9};
  // camera at z = 0 looking along +z: the rays cross 1 unit of the slab
  check_absorbing_slab(1.0, sig, "camera_inside", 1.0, 1.0, 0.0, 1.0);
}

TEST(Stress, ExtremeAnisotropyWhiteFurnace) {
  std::string dir = temp_dir("hg999");
  write_lumpy(dir + "/lumpy.vdb");
  for (double g : {0.999, -0.999}) {
    json s = ortho_scene(32);
    s["camera"]["height"] = 2.2;
    s["media"].push_back({{"type", "vdb"}, {"file", "lumpy.vdb"}, {"density_scale", 8.0}, {"sigma_a", {0, 0, 0}},
                          {"sigma_s", {1.0, 2.0, 4.0}}, {"phase", {{"type", "hg"}, {"g", g}}}});
    const double one[3] = {1, 1, 1};
    for (int tracker : kAllTrackers) {
      if (tracker == ST_TRACKER_DELTA) continue;  // chromatic
      RenderResult r = render_checked(s, dir, tracker, "g=" + std::to_string(g));
      expect_near_channels(r, one, "white furnace g=" + std::to_string(g) + " / " + tracker_name(tracker));
    }
  }
}

// A constant VDB slab of 64 voxels in z at the given voxel size: along axis-parallel rays the
// optical depth is 64 * voxel * sigma (the trilinear ramps integrate to half a voxel per face).
void check_voxel_size(double voxel, const std::string& name) {
  std::string dir = temp_dir(name);
  write_vdb(dir + "/slab.vdb", "density", openvdb::Coord(-48, -48, -32), openvdb::Coord(47, 47, 31),
            [](int, int, int) { return 1.0f; }, voxel);
  json s = ortho_scene(64, -100 * 64 * voxel);
  s["camera"]["height"] = 60 * voxel;
  double sigma[3] = {0.3, 0.8, 1.6};
  for (double& x : sigma) x /= (64 * voxel);
  s["media"].push_back({{"type", "vdb"}, {"file", "slab.vdb"}, {"sigma_a", {sigma[0], sigma[1], sigma[2]}}, {"sigma_s", {0, 0, 0}}});
  const double expected[3] = {std::exp(-0.3), std::exp(-0.8), std::exp(-1.6)};
  for (int tracker : kAllTrackers) {
    if (tracker == ST_TRACKER_DELTA) continue;
    RenderResult r = render_checked(s, dir, tracker, name);
    expect_near_channels(r, expected, name + " / " + tracker_name(tracker));
  }
}

TEST(Stress, VoxelSizeOneTenThousandth) { check_voxel_size(1e-4, "voxel_1e-4"); }
TEST(Stress, VoxelSizeTenThousand) { check_voxel_size(1e4, "voxel_1e4"); }

TEST(Stress, RaysAlongCellFacesAndGrazingTheBounds) {
  // constant density 1 in voxels [0, 63]^3 of size 1/32: cell faces of the 8^3 majorant grid lie at
  // index -1 + 8k; rays along x exactly on such faces and edges, and on the bounding faces.
  std::string dir = temp_dir("faces");
  const double v = 1.0 / 32.0;
  write_vdb(dir + "/cube.vdb", "density", openvdb::Coord(0, 0, 0), openvdb::Coord(63, 63, 63), [](int, int, int) { return 1.0f; }, v);
  json s = ortho_scene(1);
  s["media"].push_back({{"type", "vdb"}, {"file", "cube.vdb"}, {"sigma_a", {0.5, 0.5, 0.5}}, {"sigma_s", {0, 0, 0}}});
  for (int mode : {ST_TRANSMITTANCE_RATIO, ST_TRANSMITTANCE_RAY_MARCHING})
  for (int tracker : kAllTrackers) {
    RenderOptions o = quiet_options();
    o.tracker = tracker;
    o.transmittance = mode;
    Renderer r(scene_from_json(s, dir), o);
    // index y, z on cell faces (-1 + 8k) inside the constant region: optical depth 64 v 0.5 along x
    for (double iy : {7.0, 15.0, 31.0}) {
      for (double iz : {7.0, 23.0}) {
        auto T = Probe(r).transmittance({float(-1.0), float(iy * v), float(iz * v)}, {1, 0, 0}, 2000);
        std::vector<double> vals;
        for (auto& x : T) {
          ASSERT_TRUE(std::isfinite(x[0]));
          vals.push_back(x[0]);
        }
        Stats m = mean_se(vals);
        EXPECT_NEAR(m.mean, std::exp(-64 * v * 0.5), 4 * m.se + 1e-5)
            << tracker_name(tracker) << ", " << transmittance_name(mode) << " face y=" << iy << " z=" << iz;
      }
    }
    // grazing: rays in the planes of the majorant box's faces, and along its edges
    double lo = -1 * v, hi = (-1 + 72) * v;  // majorant box [-1, 71] in index space (9 cells of 8)
    for (auto yz : {std::array<double, 2>{lo, 0.5}, {hi, 0.5}, {0.5, lo}, {lo, lo}, {hi, hi}}) {
      auto T = Probe(r).transmittance({-1.0f, float(yz[0]), float(yz[1])}, {1, 0, 0}, 200);
      // ratio tracking's estimates lie in [0, 1]; ray marching's are signed sums (finite)
      for (auto& x : T)
        ASSERT_TRUE(std::isfinite(x[0]) && (mode == ST_TRANSMITTANCE_RAY_MARCHING || (x[0] >= 0.0f && x[0] <= 1.0f)))
            << tracker_name(tracker) << ", " << transmittance_name(mode);
      auto F = Probe(r).track({-1.0f, float(yz[0]), float(yz[1])}, {1, 0, 0}, tracker == ST_TRACKER_DELTA_PER_CHANNEL ? 0 : -1, 200);
      for (auto& x : F) ASSERT_TRUE(!std::isnan(x[0])) << tracker_name(tracker);
    }
    // diagonal ray through cell corners
    auto D = Probe(r).transmittance({float(-v), float(-v), float(-v)}, {1, 1, 1}, 2000);
    for (auto& x : D) ASSERT_TRUE(std::isfinite(x[0]));
  }
}

TEST(Stress, AllBackgroundVolumeShowsTheEnvironment) {
  std::string dir = temp_dir("empty");
  write_vdb(dir + "/empty.vdb", "density", openvdb::Coord(0, 0, 0), openvdb::Coord(7, 7, 7), [](int, int, int) { return 0.0f; });
  json s = ortho_scene(4);
  s["lights"] = json::array({{{"type", "environment"}, {"radiance", {0.25, 0.5, 0.75}}}});
  s["media"].push_back({{"type", "vdb"}, {"file", "empty.vdb"}, {"sigma_a", {1, 1, 1}}, {"sigma_s", {1, 1, 1}}});
  for (int tracker : kAllTrackers) {
    RenderResult r = render_checked(s, dir, tracker, "all background");
    for (size_t i = 0; i < r.rgb.size(); ++i) ASSERT_FLOAT_EQ(r.rgb[i], 0.25f * float(1 + i % 3)) << tracker_name(tracker);
    EXPECT_EQ(r.stats.lookups_track, 0u) << "an empty volume needs no lookups";
  }
}

TEST(Stress, ZeroExtentTransformIsAClearError) {
  std::string dir = temp_dir("zero_extent");
  write_lumpy(dir + "/lumpy.vdb");
  json s = ortho_scene(1);
  s["media"].push_back({{"type", "vdb"}, {"file", "lumpy.vdb"}, {"transform", {{"scale", {1, 0, 1}}}}});
  try {
    Renderer r(scene_from_json(s, dir), quiet_options());
    ADD_FAILURE() << "a zero scale must be refused";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("/media/0"), std::string::npos) << e.what();
  }
  json b = ortho_scene(1);
  b["media"].push_back({{"type", "homogeneous"}, {"bounds", {{-1, -1, 0}, {1, 1, 0}}}});
  EXPECT_THROW(scene_from_json(b, dir), Error) << "a box of zero thickness must be refused";
}

TEST(Stress, DenseScatteringStaysFiniteAndBounded) {
  // sigma_t 1e4 per unit with albedo 0.95 under a sun and sky: long walks near the surface
  std::string dir = temp_dir("dense");
  write_lumpy(dir + "/lumpy.vdb");
  json s = ortho_scene(4);
  s["camera"]["height"] = 2.2;
  s["lights"].push_back({{"type", "directional"}, {"to_light", {0.3, 1, -0.4}}, {"irradiance", {3, 3, 3}}, {"angle_deg", 1}});
  s["media"].push_back({{"type", "vdb"}, {"file", "lumpy.vdb"}, {"density_scale", 1e4}, {"sigma_a", {0.05, 0.1, 0.2}},
                        {"sigma_s", {0.95, 0.9, 0.8}}, {"phase", {{"type", "hg"}, {"g", 0.8}}}});
  for (int tracker : kAllTrackers) {
    if (tracker == ST_TRACKER_DELTA) continue;
    RenderResult r = render_checked(s, dir, tracker, "dense");
    EXPECT_GT(r.stats.scatter_events, 0u);
  }
}

}  // namespace

namespace {

TEST(Stress, AbsurdFilmIsRefusedBeforeAllocation) {
  // 2^28 pixels pass scene validation; with three paths per sample (per-channel tracking) their
  // batch results and film need about 30 GiB, more than this machine's device has
  std::string dir = temp_dir("huge_film");
  json s = ortho_scene(1);
  s["render"]["tracker"] = "delta-per-channel";
  if (select_device("").global_mem > (uint64_t(28) << 30)) GTEST_SKIP() << "the device could hold this film";
  s["film"]["width"] = 16384;
  s["film"]["height"] = 16384;
  s["media"].push_back({{"type", "homogeneous"}, {"bounds", {{-1, -1, -1}, {1, 1, 1}}}, {"sigma_a", {1, 1, 1}}});
  auto t0 = std::chrono::steady_clock::now();
  try {
    Renderer(scene_from_json(s, dir), quiet_options()).render();
    ADD_FAILURE() << "a film of 2^28 pixels must be refused on this device";
  } catch (const Error& e) {
    std::string msg = e.what();
    EXPECT_NE(msg.find("MiB"), std::string::npos) << msg;
    EXPECT_NE(msg.find("--device"), std::string::npos) << "the message must hint at another device: " << msg;
  }
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 30.0);
}

}  // namespace

// ---- docs/limits.md, float range: what a float kernel cannot represent, and flights below the float spacing of t

namespace {

// An 8^3 block of density 0.5 with one voxel of `hot`, as .vdb and (converted) .nvdb.
void write_hot_voxel(const std::string& dir, float hot) {
  write_vdb(dir + "/hot.vdb", "density", openvdb::Coord(0), openvdb::Coord(7),
            [hot](int i, int j, int k) { return (i == 3 && j == 4 && k == 5) ? hot : 0.5f; }, 0.2);
  openvdb::io::File f(dir + "/hot.vdb");
  f.open();
  auto grid = openvdb::gridPtrCast<openvdb::FloatGrid>(f.readGrid("density"));
  f.close();
  nanovdb::io::writeGrid(dir + "/hot.nvdb", nanovdb::openToNanoVDB(*grid));
}

std::string refusal(const json& s, const std::string& dir) {
  try {
    Renderer r(scene_from_json(s, dir), quiet_options());
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(Stress, VoxelOf1e30IsRefusedNamingTheVoxel) {
  // Rays crossing the majorant cell of that voxel would take about 1e30 * 0.2 tentative
  // collisions each (a cost blowup, not rounding): refused at load, whatever the format.
  std::string dir = temp_dir("hot_voxel");
  write_hot_voxel(dir, 1e30f);
  for (const char* file : {"hot.vdb", "hot.nvdb"}) {
    json s = ortho_scene(1);
    s["media"].push_back({{"type", "vdb"}, {"file", file}, {"sigma_a", {0.1, 0.1, 0.1}}, {"sigma_s", {0.9, 0.9, 0.9}}});
    std::string msg = refusal(s, dir);
    ASSERT_FALSE(msg.empty()) << file << ": a voxel of 1e30 must be refused";
    EXPECT_NE(msg.find("/media/0"), std::string::npos) << msg;
    EXPECT_NE(msg.find("voxel (3, 4, 5)"), std::string::npos) << msg;
    EXPECT_NE(msg.find("1e+30"), std::string::npos) << msg;
  }
  // a hot voxel the floats can track (optical depth 2e3 across it) still renders
  write_hot_voxel(dir, 1e4f);
  json s = ortho_scene(1);
  s["media"].push_back({{"type", "vdb"}, {"file", "hot.nvdb"}, {"sigma_a", {0.1, 0.1, 0.1}}, {"sigma_s", {0.9, 0.9, 0.9}}});
  EXPECT_EQ(refusal(s, dir), "");
}

TEST(Stress, CoefficientsBeyondFloatAreRefusedNamingTheField) {
  std::string dir = temp_dir("beyond_float");
  const std::string smoke1 = std::string(SHARED_DATA_DIR) + "/smoke1.vdb";
  json s = ortho_scene(1);
  s["media"].push_back({{"type", "vdb"}, {"file", smoke1}, {"density_scale", 1e30}, {"sigma_a", {0.03, 0.03, 0.03}},
                        {"sigma_s", {0.3, 0.3, 0.3}}});
  std::string msg = refusal(s, dir);
  EXPECT_NE(msg.find("/media/0"), std::string::npos) << msg;
  EXPECT_NE(msg.find("density_scale 1e+30"), std::string::npos) << msg;
  json h = ortho_scene(1);
  h["media"].push_back({{"type", "homogeneous"}, {"bounds", {{-1, -1, -1}, {1, 1, 1}}}, {"sigma_s", {1e308, 1e308, 1e308}}});
  msg = refusal(h, dir);
  EXPECT_NE(msg.find("/media/0/sigma_s"), std::string::npos) << msg;
  EXPECT_NE(msg.find("largest float"), std::string::npos) << msg;
  h["media"][0]["sigma_s"] = {1e30, 1e30, 1e30};  // finite as a float, but its products overflow
  msg = refusal(h, dir);
  EXPECT_NE(msg.find("2^60"), std::string::npos) << msg;
  // a homogeneous box far from the origin whose mean free path (3e-8) is below the float spacing
  // of its coordinates (1.2e-4 at x = 1000): scattering points could not move
  h["media"][0]["bounds"] = {{1000, -1, -1}, {1002, 1, 1}};
  h["media"][0]["sigma_s"] = {3e7, 3e7, 3e7};
  msg = refusal(h, dir);
  EXPECT_NE(msg.find("float spacing"), std::string::npos) << msg;
  // the same box around the origin resolves its flights; so does an "infinite" medium (a box of
  // half-width 1e6, mean free path 0.1: a tight majorant, no null collisions, whatever its size)
  h["media"][0]["bounds"] = {{-1, -1, -1}, {1, 1, 1}};
  EXPECT_EQ(refusal(h, dir), "");
  h["media"][0]["bounds"] = {{-1e6, -1e6, -1e6}, {1e6, 1e6, 1e6}};
  h["media"][0]["sigma_s"] = {10, 10, 10};
  EXPECT_EQ(refusal(h, dir), "");
  // the stress cases stay inside the limits
  h["media"][0]["bounds"] = {{-1, -1, -1}, {1, 1, 1}};
  h["media"][0]["sigma_s"] = {1e6, 1e6, 1e6};
  EXPECT_EQ(refusal(h, dir), "");
  s["media"][0]["density_scale"] = 1e6;
  EXPECT_EQ(refusal(s, dir), "");
}

// Mean of the pixels of an EXR written by the CLI (rgb), and its standard error.
Stats exr_mean(const std::string& path) {
  auto in = OIIO::ImageInput::open(path);
  EXPECT_TRUE(in) << path;
  if (!in) return {};
  const auto& spec = in->spec();
  std::vector<float> px(size_t(spec.width) * spec.height * spec.nchannels);
  in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, px.data());
  std::vector<double> v;
  for (size_t i = 0; i < px.size(); i += spec.nchannels) {
    for (int c = 0; c < 3; ++c) EXPECT_TRUE(std::isfinite(px[i + c])) << path;
    v.push_back((px[i] + px[i + 1] + px[i + 2]) / 3.0);
  }
  return mean_se(v);
}

// Renders `scene` with the CLI under a wall-clock bound (a regression fails, not hangs).
void render_bounded(const std::string& dir, const json& scene, const std::string& out, double limit_s,
                    std::vector<std::string> extra = {}) {
  std::string path = st_cli::write_scene(dir, "scene_" + out + ".json", scene);
  std::vector<std::string> args = {"render", path, "-o", dir + "/" + out, "--quiet"};
  args.insert(args.end(), extra.begin(), extra.end());
  st_cli::RunOptions o;
  o.timeout_s = limit_s;
  st_cli::Proc p = st_cli::run(args, o);
  ASSERT_FALSE(p.timed_out) << "the render must finish in bounded time\n" << p.describe();
  ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
}

TEST(Stress, FlightsBelowTheFloatSpacingOfTStillAdvance) {
  // A thick block (albedo 0.91) 200 units from the camera: at density 1e7 per unit the mean free
  // flight (1e-7) is far below half the float spacing of t (7.6e-6), so without exact summation
  // no flight moves t: every collision of a camera ray lands on the first float point of the
  // ramp where the block's density rises from 0 (0.74 instead of 0.44 here), and where that
  // density is 0 the null collisions repeat forever. Any thick block of this albedo under a uniform sky of radiance 1 looks the same;
  // at density 1e3 the flights are resolved: the images must agree. (Hapke's approximation of
  // Chandrasekhar's H function for a half-space seen face-on: 1 - sqrt(1 - 0.91) * 3 / 1.6 = 0.44.)
  std::string dir = temp_dir("far_thick");
  write_vdb(dir + "/block.vdb", "density", openvdb::Coord(0), openvdb::Coord(15), [](int, int, int) { return 1.0f; }, 0.1,
            openvdb::Vec3d(200, 0, 0));
  json s = ortho_scene(16, 0);
  s["camera"] = {{"type", "orthographic"}, {"position", {0, 0.75, 0.75}}, {"look_at", {1, 0.75, 0.75}}, {"up", {0, 1, 0}}, {"height", 0.8}};
  s["film"]["width"] = s["film"]["height"] = 4;
  s["render"]["tracker"] = "spectral";
  s["media"].push_back({{"type", "vdb"}, {"file", "block.vdb"}, {"sigma_a", {0.09, 0.09, 0.09}}, {"sigma_s", {0.91, 0.91, 0.91}},
                        {"density_scale", 1e7}});
  render_bounded(dir, s, "dense.exr", 300);
  s["media"][0]["density_scale"] = 1e3;
  render_bounded(dir, s, "resolved.exr", 300);
  Stats dense = exr_mean(dir + "/dense.exr"), resolved = exr_mean(dir + "/resolved.exr");
  EXPECT_GT(dense.mean, 0.2) << "a thick medium of albedo 0.91 under a white sky is not black";
  EXPECT_NEAR(dense.mean, resolved.mean, 4 * std::hypot(dense.se, resolved.se) + 0.02);
  EXPECT_NEAR(resolved.mean, 0.44, 0.1);
}

TEST(Stress, DensityScaleOneMillionOnSmoke1FarFromTheOrigin) {
  // A real case: smoke1 (world coordinates around 40) seen from 190 units away at
  // density_scale 1e6 (9e5 per voxel). With 8-voxel majorant cells a ray crossing the empty part
  // of a cell that holds dense voxels takes mu_bar * length (about 1e7) tentative collisions: the
  // whole silhouette would take longer than minutes. The majorant cells shrink with the optical
  // depth (float_limits.h), so the render is bounded; its core must look like a thick medium of
  // albedo 0.91, as at density_scale 1e4 (also thick there).
  std::string dir = temp_dir("smoke1_1e6");
  const std::string smoke1 = std::string(SHARED_DATA_DIR) + "/smoke1.vdb";
  json view = ortho_scene(1, 0);
  view["camera"] = {{"type", "perspective"}, {"position", {26.5, 55.0, -190.0}}, {"look_at", {26.5, 53.0, 27.0}}, {"up", {0, 1, 0}}, {"fov_deg", 34}};
  view["film"]["width"] = 16;
  view["film"]["height"] = 24;
  view["render"]["tracker"] = "delta";
  view["media"].push_back({{"type", "vdb"}, {"file", smoke1}, {"density_scale", 1e6}, {"sigma_a", {0.03, 0.03, 0.03}},
                           {"sigma_s", {0.3, 0.3, 0.3}}});
  render_bounded(dir, view, "silhouette.exr", 240);
  exr_mean(dir + "/silhouette.exr");  // every pixel finite
  json s = ortho_scene(8, 0);
  s["camera"] = {{"type", "orthographic"}, {"position", {-6.5, 42, -190}}, {"look_at", {-6.5, 42, 0}}, {"up", {0, 1, 0}}, {"height", 4}};
  s["film"]["width"] = s["film"]["height"] = 4;
  s["render"]["tracker"] = "delta";
  s["media"] = view["media"];
  render_bounded(dir, s, "1e6.exr", 240);
  s["media"][0]["density_scale"] = 1e4;
  render_bounded(dir, s, "1e4.exr", 240);
  Stats a = exr_mean(dir + "/1e6.exr"), b = exr_mean(dir + "/1e4.exr");
  EXPECT_GT(a.mean, 0.2) << "smoke1 at albedo 0.91 under a white sky is not black";
  EXPECT_NEAR(a.mean, b.mean, 4 * std::hypot(a.se, b.se) + 0.03);
}

}  // namespace
