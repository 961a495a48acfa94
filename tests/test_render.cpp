// test_render.cpp: kernel-level tests on the default OpenCL device (PoCL in CI). Each compares
// the renderer with an analytic answer, with tolerances of 4 standard errors taken from the
// estimator's own samples, so a biased tracker, a wrong weight or a lost contribution fails.
//   - free-path distances along a heterogeneous ray: KS test of the probability integral
//     transform (1 - exp(-tau(t))) / (1 - T(d)) and the escape fraction against T(d);
//   - absorbing slab, white furnace, emissive furnace;
//   - device lookups against host OpenVDB, majorant/minorant bounds against device lookups;
//   - a constant VDB against the homogeneous box it fills;
//   - bit-identical renders for one seed, whatever the number of paths in flight;
//   - stochastic one-voxel lookups (docs/stochastic-lookup.md): the free-path KS test, ratio
//     tracking, the furnaces and the constant VDB again, with the same analytic answers.
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <gmock/gmock.h>
#include <openvdb/tools/Interpolation.h>

#include <algorithm>
#include <atomic>
#include <random>

#include "api/render_call.h"
#include "api/render_stats.h"
#include "image/image.h"
#include "test_util.h"
#include "util/warning.h"

using namespace spectrack;
using namespace st_test;
using nlohmann::json;

namespace {

json base_scene(int w, int h, int spp, const std::string& tracker) {
  return json{{"format", "spectrack-scene/1"},
              {"camera", {{"type", "orthographic"}, {"position", {0, 0, -3}}, {"look_at", {0, 0, 0}}, {"up", {0, 1, 0}}, {"height", 1.0}}},
              {"film", {{"width", w}, {"height", h}, {"spp", spp}}},
              {"render", {{"tracker", tracker}, {"seed", 7}}},
              {"lights", json::array()},
              {"media", json::array()}};
}

// density(i) along x of the 1D profile volume (constant in y and z)
float profile(int i) { return 0.2f + 0.8f * (0.5f + 0.5f * std::sin(0.3f * float(i))); }

// Optical depth from t = 0 to t along the probe ray of ProfileVolume (piecewise linear density
// between integer index coordinates, 0 outside the active range [0, 63]).
double profile_tau(double t, double sigma_t) {
  const double vox = 1.0 / 16.0;
  auto dens = [&](double x) {
    double f = std::floor(x);
    int i = int(f);
    auto v = [&](int k) { return (k >= 0 && k <= 63) ? double(profile(k)) : 0.0; };
    return v(i) + (x - f) * (v(i + 1) - v(i));
  };
  // index x = (t - 1) / vox; integrate with fine trapezoids (the density is piecewise linear in
  // x with kinks at integers, so splitting at integers makes the trapezoid rule exact)
  double x0 = -1.0 / vox, x1 = (t - 1.0) / vox;
  double tau = 0;
  double a = x0;
  while (a < x1) {
    double b = std::min(x1, std::floor(a) + 1.0);
    tau += 0.5 * (dens(a) + dens(b - 1e-12)) * (b - a);
    a = b;
  }
  return tau * vox * sigma_t;
}

class ProfileVolume : public ::testing::Test {
 protected:
  std::string dir;
  void SetUp() override {
    dir = temp_dir("profile");
    write_vdb(dir + "/profile.vdb", "density", openvdb::Coord(0, 0, 0), openvdb::Coord(63, 7, 7),
              [](int i, int, int) { return profile(i); }, 1.0 / 16.0);
  }
  json scene(const std::string& tracker, json sigma_a) {
    json s = base_scene(4, 4, 1, tracker);
    s["media"].push_back({{"type", "vdb"}, {"file", "profile.vdb"}, {"sigma_a", sigma_a}, {"sigma_s", {0, 0, 0}}});
    return s;
  }
  // Runs the probe and checks the distance distribution of channel `c` (-1: all, achromatic).
  void check_distances(Renderer& r, int channel, double sigma_t) {
    const int n = 20000;
    std::array<float, 3> o{-1.0f, 3.5f / 16.0f, 3.5f / 16.0f}, d{1, 0, 0};
    auto res = Probe(r).track(o, d, channel, n);
    double d_end = 1.0 + 64.0 / 16.0;  // beyond the last non-zero density
    double T = std::exp(-profile_tau(d_end, sigma_t));
    std::vector<double> u;
    int escapes = 0;
    for (auto& x : res) {
      if (std::isinf(x[0])) {
        ++escapes;
        continue;
      }
      ASSERT_EQ(int(x[1]), 2) << "absorbing-only medium must end in absorption";
      u.push_back((1.0 - std::exp(-profile_tau(x[0], sigma_t))) / (1.0 - T));
    }
    double p_esc = double(escapes) / n;
    EXPECT_NEAR(p_esc, T, 4.0 * std::sqrt(T * (1 - T) / n)) << "escape probability";
    std::sort(u.begin(), u.end());
    double D = 0;
    for (size_t i = 0; i < u.size(); ++i)
      D = std::max({D, std::abs(u[i] - double(i) / u.size()), std::abs(u[i] - double(i + 1) / u.size())});
    double crit = 1.95 / std::sqrt(double(u.size()));  // KS at alpha = 0.001
    EXPECT_LT(D, crit) << "KS statistic of the free-path distribution (" << u.size() << " collisions)";
  }
  // Transmittance through the whole profile by the renderer's estimator, per channel (sigma_t 0.4,
  // 1, 2.5), against the closed form; the twin: a 3% error is seen on channel 0.
  void check_transmittance(Renderer& r) {
    auto res = Probe(r).transmittance({-1.0f, 3.5f / 16.0f, 3.5f / 16.0f}, {1, 0, 0}, 20000);
    double sig[3] = {0.4, 1.0, 2.5};
    for (int c = 0; c < 3; ++c) {
      std::vector<double> v;
      for (auto& x : res) v.push_back(x[c]);
      Stats s = mean_se(v);
      double T = std::exp(-profile_tau(5.0, sig[c]));
      EXPECT_NEAR(s.mean, T, 4.0 * s.se + 1e-7) << "channel " << c;
      if (c == 0) EXPECT_GT(std::abs(s.mean - 1.03 * T), 4.0 * s.se) << "a 3% error must be detectable";
    }
  }
};

TEST_F(ProfileVolume, DeltaTrackingDistancesFollowOpticalDepth) {
  Renderer r(scene_from_json(scene("delta", {1.0, 1.0, 1.0}), dir), quiet_options());
  check_distances(r, -1, 1.0);
}

TEST_F(ProfileVolume, PerChannelDeltaTrackingDistancesFollowEachChannel) {
  Renderer r(scene_from_json(scene("delta-per-channel", {0.4, 1.0, 2.5}), dir), quiet_options());
  check_distances(r, 0, 0.4);
  check_distances(r, 2, 2.5);
}

TEST_F(ProfileVolume, WrongOpticalDepthIsDetected) {
  // the same check must fail when the reference is off by 10%: the test can fail
  Renderer r(scene_from_json(scene("delta", {1.0, 1.0, 1.0}), dir), quiet_options());
  const int n = 20000;
  auto res = Probe(r).track({-1.0f, 3.5f / 16.0f, 3.5f / 16.0f}, {1, 0, 0}, -1, n);
  double T_wrong = std::exp(-profile_tau(5.0, 1.1));
  int escapes = 0;
  for (auto& x : res) escapes += std::isinf(x[0]);
  EXPECT_GT(std::abs(double(escapes) / n - T_wrong), 4.0 * std::sqrt(T_wrong * (1 - T_wrong) / n));
}

TEST_F(ProfileVolume, RatioTrackingTransmittanceMatchesOpticalDepth) {
  Renderer r(scene_from_json(scene("delta-per-channel", {0.4, 1.0, 2.5}), dir), quiet_options());
  check_transmittance(r);
}

// ---------------------------------------------------------------------------------------------

json slab_scene(const std::string& tracker, int spp) {
  json s = base_scene(16, 16, spp, tracker);
  s["lights"].push_back({{"type", "environment"}, {"radiance", {1, 1, 1}}});
  s["media"].push_back({{"type", "homogeneous"}, {"bounds", {{-1, -1, -1}, {1, 1, 1}}}, {"sigma_a", {0.5, 1.0, 2.0}},
                        {"sigma_s", {0, 0, 0}}});
  return s;
}

void expect_channels(const RenderResult& r, const double expected[3], const std::string& what) {
  for (int c = 0; c < 3; ++c) {
    Stats s = mean_se(channel(r, c));
    EXPECT_NEAR(s.mean, expected[c], 4.0 * s.se + 1e-5) << what << ", channel " << c << " (SE " << s.se << ")";
  }
}

// The estimators of the analytic tests: the analog baseline, the spectral tracker and spectral MIS, each with
// absorption as an event and as a weight (kernels/tracking.h).
struct TrackerMode {
  std::string tracker;
  int absorption;
  std::string name() const { return tracker + " / absorption " + absorption_name(absorption); }
};
const TrackerMode kModes[] = {{"delta-per-channel", ST_ABSORPTION_EVENT},
                              {"delta-per-channel", ST_ABSORPTION_WEIGHT},
                              {"spectral", ST_ABSORPTION_EVENT},
                              {"spectral", ST_ABSORPTION_WEIGHT},
                              {"spectral-mis", ST_ABSORPTION_EVENT},
                              {"spectral-mis", ST_ABSORPTION_WEIGHT}};
RenderOptions mode_options(const TrackerMode& m) {
  RenderOptions o = quiet_options();
  o.absorption = m.absorption;
  return o;
}

TEST(Render, AbsorbingSlabOrthographic) {
  std::string dir = temp_dir("slab");
  const double expected[3] = {std::exp(-1.0), std::exp(-2.0), std::exp(-4.0)};
  for (const TrackerMode& m : kModes) {
    Renderer r(scene_from_json(slab_scene(m.tracker, 256), dir), mode_options(m));
    RenderResult res = r.render();
    EXPECT_EQ(res.spp_done, 256);
    EXPECT_EQ(res.stats.nonfinite_samples, 0u);
    expect_channels(res, expected, m.name());
  }
}

// Regression: the DDA treated an axis-parallel ray beside a medium's box (an orthographic camera
// looking along an axis) as inside it on that axis, so it walked the box's depth: only null
// collisions for the plain trackers, but the decomposition trackers' closed-form control
// attenuated those rays (the image beside the box was dark). Pixels beside the box see the
// environment exactly, with every tracker.
TEST(Render, AxisParallelRaysBesideABoxSeeTheEnvironment) {
  std::string dir = temp_dir("slab_beside");
  for (const char* tracker : {"delta-per-channel", "spectral", "decomposition", "spectral-decomposition", "spectral-mis"}) {
    json s = slab_scene(tracker, 4);
    s["camera"]["height"] = 4.0;  // 4 units across: the box [-1, 1] covers the middle half
    Renderer r(scene_from_json(s, dir), quiet_options());
    RenderResult res = r.render();
    int beside = 0;
    for (int y = 0; y < res.height; ++y)
      for (int x = 0; x < res.width; ++x) {
        if (x >= 3 && x < 13 && y >= 3 && y < 13) continue;  // pixels that may touch the box
        for (int c = 0; c < 3; ++c) EXPECT_EQ(res.rgb[(size_t(y) * res.width + x) * 3 + c], 1.0f) << tracker << " " << x << "," << y;
        ++beside;
      }
    EXPECT_GT(beside, 100);
  }
}

TEST(Render, AbsorbingSlabWrongAnswerIsDetected) {
  std::string dir = temp_dir("slab_wrong");
  Renderer r(scene_from_json(slab_scene("delta-per-channel", 256), dir), quiet_options());
  RenderResult res = r.render();
  Stats s = mean_se(channel(res, 1));
  EXPECT_GT(std::abs(s.mean - std::exp(-2.0) * 1.05), 4.0 * s.se) << "a 5% error must be detectable";
}

json furnace_scene(const std::string& tracker, const std::string& dir, bool emissive) {
  write_lumpy(dir + "/lumpy.vdb");
  json s = base_scene(12, 12, 48, tracker);
  s["camera"] = {{"type", "perspective"}, {"position", {0.2, 0.1, -3}}, {"look_at", {0, 0, 0}}, {"up", {0, 1, 0}}, {"fov_deg", 30}};
  json m = {{"type", "vdb"}, {"file", "lumpy.vdb"}, {"density_scale", 4.0}, {"phase", {{"type", "hg"}, {"g", 0.4}}}};
  if (emissive) {
    m["sigma_a"] = {1.0, 2.0, 4.0};
    m["sigma_s"] = {3.0, 1.0, 0.5};
    m["emission"] = {{"radiance", {0.3, 0.6, 0.9}}};
    s["lights"].push_back({{"type", "environment"}, {"radiance", {0.3, 0.6, 0.9}}});
  } else {
    m["sigma_a"] = {0, 0, 0};
    m["sigma_s"] = {1.0, 3.0, 9.0};
    s["lights"].push_back({{"type", "environment"}, {"radiance", {1, 1, 1}}});
  }
  s["media"].push_back(m);
  return s;
}

TEST(Render, WhiteFurnaceChromaticHeterogeneous) {
  std::string dir = temp_dir("furnace");
  const double one[3] = {1, 1, 1};
  for (const TrackerMode& m : kModes) {
    Renderer r(scene_from_json(furnace_scene(m.tracker, dir, false), dir), mode_options(m));
    RenderResult res = r.render();
    EXPECT_EQ(res.stats.nonfinite_samples, 0u);
    EXPECT_GT(res.stats.scatter_events, 1000u) << "the furnace must scatter";
    expect_channels(res, one, "white furnace " + m.name());
  }
}

TEST(Render, EmissiveFurnace) {
  std::string dir = temp_dir("efurnace");
  const double c[3] = {0.3, 0.6, 0.9};
  for (const TrackerMode& m : kModes) {
    RenderOptions o = mode_options(m);
    // spectral MIS scores emission at every tentative collision with channel weights that vary:
    // noisier here than spectral tracking (48 spp leave 4 SE above 3% of channels 1 and 2)
    if (m.tracker == "spectral-mis") o.spp = 192;
    Renderer r(scene_from_json(furnace_scene(m.tracker, dir, true), dir), o);
    RenderResult res = r.render();
    EXPECT_GT(res.stats.real_collisions, 1000u);
    EXPECT_EQ(res.stats.nonfinite_samples, 0u);
    expect_channels(res, c, "emissive furnace " + m.name());
    if (m.absorption == ST_ABSORPTION_WEIGHT)
      for (int ch = 0; ch < 3; ++ch) {  // the twin: the same check sees a 3% error
        Stats s = mean_se(channel(res, ch));
        EXPECT_GT(std::abs(s.mean - 1.03 * c[ch]), 4.0 * s.se) << m.name() << ": a 3% error must be detectable, channel " << ch;
      }
  }
}

// Stochastic one-voxel lookups: each tentative collision reads one voxel of the trilinear support,
// chosen with its trilinear weight, so its acceptance probability has the trilinear density as its
// expectation: the free-path distribution and the transmittance are those of the trilinear
// density, to the same KS and 4-SE checks.
TEST_F(ProfileVolume, StochasticLookupsKeepFreePathsAndTransmittance) {
  json s = scene("delta", {1.0, 1.0, 1.0});
  s["render"]["lookup"] = "stochastic";
  Renderer r(scene_from_json(s, dir), quiet_options());
  check_distances(r, -1, 1.0);
  json t = scene("delta-per-channel", {0.4, 1.0, 2.5});
  t["render"]["lookup"] = "stochastic";
  Renderer q(scene_from_json(t, dir), quiet_options());
  check_distances(q, 2, 2.5);
  check_transmittance(q);
}

// The furnaces with stochastic lookups: the analog baseline, spectral tracking and spectral MIS.
TEST(Render, FurnacesWithStochasticLookups) {
  std::string dir = temp_dir("furnace_stochastic");
  const double one[3] = {1, 1, 1}, c[3] = {0.3, 0.6, 0.9};
  const TrackerMode modes[] = {{"delta-per-channel", ST_ABSORPTION_EVENT},
                               {"spectral-decomposition", ST_ABSORPTION_WEIGHT},
                               {"spectral-mis", ST_ABSORPTION_WEIGHT}};
  for (const TrackerMode& m : modes) {
    RenderOptions o = mode_options(m);
    o.lookup = ST_LOOKUP_STOCHASTIC;
    RenderResult white = Renderer(scene_from_json(furnace_scene(m.tracker, dir, false), dir), o).render();
    EXPECT_EQ(white.stats.nonfinite_samples, 0u);
    EXPECT_GT(white.stats.scatter_events, 1000u);
    expect_channels(white, one, "white furnace, stochastic lookups, " + m.name());
    if (m.tracker == "spectral-mis") o.spp = 192;  // as in EmissiveFurnace
    RenderResult hot = Renderer(scene_from_json(furnace_scene(m.tracker, dir, true), dir), o).render();
    EXPECT_EQ(hot.stats.nonfinite_samples, 0u);
    EXPECT_GT(hot.stats.lookups_track, 1000u);
    expect_channels(hot, c, "emissive furnace, stochastic lookups, " + m.name());
  }
}

// ---------------------------------------------------------------------------------------------

TEST(Volume, DeviceLookupsMatchHostOpenVDBWithTransform) {
  std::string dir = temp_dir("lookup");
  write_lumpy(dir + "/lumpy.vdb");
  json s = base_scene(4, 4, 1, "delta-per-channel");
  s["media"].push_back({{"type", "vdb"}, {"file", "lumpy.vdb"},
                        {"transform", {{"scale", {1.5, 0.7, 1.1}}, {"rotate_deg", {20, -35, 60}}, {"translate", {0.3, -0.2, 0.5}}}}});
  Renderer r(scene_from_json(s, dir), quiet_options());

  openvdb::io::File f(dir + "/lumpy.vdb");
  f.open();
  auto grid = openvdb::gridPtrCast<openvdb::FloatGrid>(f.readGrid("density"));
  openvdb::tools::GridSampler<openvdb::FloatGrid, openvdb::tools::BoxSampler> sampler(*grid);
  // inverse user transform: S^-1 Rx^-1 Ry^-1 Rz^-1 (p - T)
  openvdb::math::Mat4d U = openvdb::math::Mat4d::identity();
  U.preScale(openvdb::Vec3d(1.5, 0.7, 1.1));
  U.postRotate(openvdb::math::X_AXIS, 20 * M_PI / 180);
  U.postRotate(openvdb::math::Y_AXIS, -35 * M_PI / 180);
  U.postRotate(openvdb::math::Z_AXIS, 60 * M_PI / 180);
  U.postTranslate(openvdb::Vec3d(0.3, -0.2, 0.5));
  openvdb::math::Mat4d Uinv = U.inverse();

  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1.6f, 1.6f);
  std::vector<std::array<float, 3>> pts(4000);
  for (auto& p : pts) p = {u(rng), u(rng), u(rng)};
  auto dev = Probe(r).density(0, pts);
  int nonzero = 0;
  for (size_t i = 0; i < pts.size(); ++i) {
    openvdb::Vec3d p(pts[i][0], pts[i][1], pts[i][2]);
    double host = sampler.wsSample(Uinv.transform(p));
    ASSERT_NEAR(dev[i], host, 2e-4 + 1e-4 * std::abs(host)) << "point " << i;
    nonzero += host > 0;
  }
  EXPECT_GT(nonzero, 400) << "the points must hit the volume";
}

TEST(Volume, DeviceLookupsMatchHostOnDisneyCloud) {
  std::string file = std::string(SHARED_DATA_DIR) + "/wdas_cloud_sixteenth.vdb";
  if (!std::filesystem::exists(file)) GTEST_SKIP() << file << " not present";
  std::string dir = temp_dir("disney_lookup");
  json s = base_scene(4, 4, 1, "delta-per-channel");
  s["media"].push_back({{"type", "vdb"}, {"file", file}});
  Renderer r(scene_from_json(s, dir), quiet_options());
  openvdb::initialize();
  openvdb::io::File f(file);
  f.open();
  auto grid = openvdb::gridPtrCast<openvdb::FloatGrid>(f.readGrid("density"));
  openvdb::tools::GridSampler<openvdb::FloatGrid, openvdb::tools::BoxSampler> sampler(*grid);
  auto bbox = grid->evalActiveVoxelBoundingBox();
  auto lo = grid->indexToWorld(bbox.min()), hi = grid->indexToWorld(bbox.max());
  std::mt19937 rng(5);
  std::vector<std::array<float, 3>> pts(5000);
  for (auto& p : pts)
    for (int a = 0; a < 3; ++a) p[a] = float(std::uniform_real_distribution<double>(lo[a], hi[a])(rng));
  auto dev = Probe(r).density(0, pts);
  int nonzero = 0;
  for (size_t i = 0; i < pts.size(); ++i) {
    double host = sampler.wsSample(openvdb::Vec3d(pts[i][0], pts[i][1], pts[i][2]));
    ASSERT_NEAR(dev[i], host, 1e-4 + 1e-4 * std::abs(host)) << "point " << i;
    nonzero += host > 0;
  }
  EXPECT_GT(nonzero, 500);
}

TEST(Volume, MajorantAndMinorantBoundDeviceLookups) {
  std::string dir = temp_dir("majorant");
  // a thin shell of high density in empty space plus random speckle: a missing apron fails
  std::mt19937 gen(11);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  std::vector<float> speckle(40 * 40 * 40);
  for (auto& v : speckle) v = U(gen) < 0.05f ? U(gen) * 3.0f : 0.0f;
  write_vdb(dir + "/shell.vdb", "density", openvdb::Coord(0, 0, 0), openvdb::Coord(39, 39, 39),
            [&](int i, int j, int k) {
              double r = std::sqrt(double((i - 20) * (i - 20) + (j - 20) * (j - 20) + (k - 20) * (k - 20)));
              return std::abs(r - 14.0) < 0.7 ? 5.0f : speckle[size_t(i + 40 * (j + 40 * k))];
            },
            0.05);
  json s = base_scene(4, 4, 1, "delta-per-channel");
  s["media"].push_back({{"type", "vdb"}, {"file", "shell.vdb"}, {"transform", {{"rotate_deg", {10, 20, 30}}}}});
  Renderer r(scene_from_json(s, dir), quiet_options());
  std::mt19937 rng(13);
  std::uniform_real_distribution<float> u(-0.6f, 2.6f);
  std::vector<std::array<float, 3>> pts(30000);
  for (auto& p : pts) p = {u(rng), u(rng), u(rng)};
  auto dens = Probe(r).density(0, pts);
  auto maj = Probe(r).majorant(0, pts);
  int inside = 0, positive = 0;
  for (size_t i = 0; i < pts.size(); ++i) {
    if (maj[i][0] < 0) {
      EXPECT_EQ(dens[i], 0.0f) << "density outside the majorant box at point " << i;
      continue;
    }
    ++inside;
    positive += dens[i] > 0;
    ASSERT_LE(dens[i], maj[i][0]) << "majorant below the density at point " << i;
    ASSERT_GE(dens[i], maj[i][1]) << "minorant above the density at point " << i;
  }
  EXPECT_GT(inside, 5000);
  EXPECT_GT(positive, 1000);
}

// ---------------------------------------------------------------------------------------------

TEST(Render, ConstantVdbEqualsHomogeneousBox) {
  // An emissive, absorbing slab: L = Le (1 - T) + T L_env depends only on the optical depth
  // along each (axis-parallel) ray, and the trilinear ramp at each face of a constant VDB
  // integrates to half a voxel, so the VDB equals the box of its voxel cells [-0.5, N - 0.5] v.
  std::string dir = temp_dir("constant");
  const double v = 1.0 / 32.0;
  write_vdb(dir + "/const.vdb", "density", openvdb::Coord(-48, -48, -32), openvdb::Coord(47, 47, 31),
            [](int, int, int) { return 1.0f; }, v);
  auto scene_with = [&](json medium) {
    json s = base_scene(10, 10, 96, "delta-per-channel");
    s["camera"]["height"] = 1.5;  // rays stay inside the constant interior transversally
    s["lights"].push_back({{"type", "environment"}, {"radiance", {0.2, 0.5, 1.0}}});
    medium["sigma_a"] = {0.3, 0.8, 1.6};
    medium["sigma_s"] = {0, 0, 0};
    medium["emission"] = {{"radiance", {1.0, 0.7, 0.2}}};
    s["media"].push_back(medium);
    return s;
  };
  double z0 = -32.5 * v, z1 = 31.5 * v, xy = 48 * v;
  json vdb = {{"type", "vdb"}, {"file", "const.vdb"}};
  json box = {{"type", "homogeneous"}, {"bounds", {{-xy, -xy, z0}, {xy, xy, z1}}}};
  RenderResult a = Renderer(scene_from_json(scene_with(vdb), dir), quiet_options()).render();
  RenderResult b = Renderer(scene_from_json(scene_with(box), dir), quiet_options()).render();
  // stochastic lookups: inside, every voxel is 1; at the faces a voxel of 0 or 1 is read with the
  // ramp's weights, whose expectation is the same half voxel
  RenderOptions so = quiet_options();
  so.lookup = ST_LOOKUP_STOCHASTIC;
  RenderResult st = Renderer(scene_from_json(scene_with(vdb), dir), so).render();
  double sig[3] = {0.3, 0.8, 1.6}, Le[3] = {1.0, 0.7, 0.2}, env[3] = {0.2, 0.5, 1.0};
  for (int c = 0; c < 3; ++c) {
    Stats sa = mean_se(channel(a, c)), sb = mean_se(channel(b, c)), ss = mean_se(channel(st, c));
    EXPECT_NEAR(sa.mean, sb.mean, 4.0 * std::hypot(sa.se, sb.se) + 1e-6) << "channel " << c;
    EXPECT_NEAR(ss.mean, sb.mean, 4.0 * std::hypot(ss.se, sb.se) + 1e-6) << "stochastic lookups, channel " << c;
    double T = std::exp(-sig[c] * (z1 - z0));
    EXPECT_NEAR(sb.mean, Le[c] * (1 - T) + T * env[c], 4.0 * sb.se + 1e-6) << "analytic, channel " << c;
  }
}

TEST(Render, EmissionGridScalesRadiance) {
  // an emissive absorbing slab whose emission grid holds 0.5 everywhere the density is
  // non-zero (it is one voxel wider): L = 0.5 Le (1 - T) + T L_env
  std::string dir = temp_dir("emission_grid");
  const double v = 1.0 / 32.0;
  write_vdb_grids(dir + "/fire.vdb", openvdb::Coord(-49, -49, -33), openvdb::Coord(48, 48, 32),
                  {{"density", [](int i, int j, int k) { return (std::abs(i + 0.5) < 48 && std::abs(j + 0.5) < 48 && std::abs(k + 0.5) < 32) ? 1.0f : 0.0f; }},
                   {"heat", [](int, int, int) { return 0.5f; }}},
                  v);
  json s = base_scene(10, 10, 128, "spectral");
  s["camera"]["height"] = 1.5;
  s["lights"].push_back({{"type", "environment"}, {"radiance", {0.2, 0.5, 1.0}}});
  s["media"].push_back({{"type", "vdb"}, {"file", "fire.vdb"}, {"sigma_a", {0.3, 0.8, 1.6}}, {"sigma_s", {0, 0, 0}},
                        {"emission", {{"grid", "heat"}, {"radiance", {1.0, 0.7, 0.2}}, {"scale", 2.0}}}});
  RenderResult r = Renderer(scene_from_json(s, dir), quiet_options()).render();
  EXPECT_GT(r.stats.lookups_emission, 0u);
  double sig[3] = {0.3, 0.8, 1.6}, Le[3] = {1.0, 0.7, 0.2}, env[3] = {0.2, 0.5, 1.0};
  for (int c = 0; c < 3; ++c) {
    Stats st = mean_se(channel(r, c));
    double T = std::exp(-sig[c] * 64 * v);
    EXPECT_NEAR(st.mean, 2.0 * 0.5 * Le[c] * (1 - T) + T * env[c], 4.0 * st.se + 1e-6) << "channel " << c;
  }
}

TEST(Render, WhiteFurnaceUnderConstantEnvironmentMap) {
  // the map is sampled by its own distribution and MIS-weighted against phase sampling: any
  // inconsistency between sampling and pdf breaks L = 1
  std::string dir = temp_dir("envmap");
  std::vector<float> px(32 * 16 * 3, 1.0f);
  write_image(dir + "/white.exr", 32, 16, px, {});
  json s = furnace_scene("spectral", dir, false);
  s["lights"] = json::array({{{"type", "environment"}, {"map", "white.exr"}}});
  RenderResult r = Renderer(scene_from_json(s, dir), quiet_options()).render();
  const double one[3] = {1, 1, 1};
  expect_channels(r, one, "white furnace under a map");
}

TEST(Render, EnvironmentMapSeenDirectly) {
  // no media: an orthographic camera looking along +z sees the texel of direction +z: atan2(0, -1) =
  // pi, u = 1 (column 0 after wrapping), v = 0.5 (row 2); rotate_deg turns the map right-handedly
  // about +y, so +z reads u = 1 + rotate_deg/360, at texel centres here (8 columns of 45 degrees)
  // but for the wrap at 0 and 360
  std::string dir = temp_dir("envmap_direct");
  std::vector<float> px(8 * 4 * 3, 0.0f);
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 8; ++x)
      for (int c = 0; c < 3; ++c) px[(y * 8 + x) * 3 + c] = float(x + 10 * y + c);
  write_image(dir + "/ramp.exr", 8, 4, px, {});
  for (auto [turn, column] : std::vector<std::pair<double, int>>{
           {0, 0}, {67.5, 1}, {157.5, 3}, {-112.5, 5}, {-22.5, 7}, {360, 0}, {-360, 0}}) {
    json s = base_scene(4, 4, 4, "spectral");
    s["lights"] = json::array({{{"type", "environment"}, {"map", "ramp.exr"}, {"scale", 2.0}}});
    if (turn != 0) s["lights"][0]["rotate_deg"] = turn;
    RenderResult r = Renderer(scene_from_json(s, dir), quiet_options()).render();
    for (int c = 0; c < 3; ++c)
      EXPECT_FLOAT_EQ(r.rgb[c], 2.0f * float(column + 10 * 2 + c)) << "rotate_deg " << turn << ", channel " << c;
  }
}

TEST(Render, EnvironmentMapsThatAreNotTwoToOneAreWarnedOf) {
  // read as lat-long all the same (unbiased at any size), with a warning naming the file and field; a
  // square map may be pbrt-v4's equal-area layout
  std::string dir = temp_dir("envmap_aspect");
  std::vector<std::string> warnings;
  set_warning_sink([&](const std::string& text) { warnings.push_back(text); });
  for (auto [w, h] : std::vector<std::pair<int, int>>{{8, 4}, {4, 4}, {6, 4}}) {
    const std::string name = fmt::format("map_{}x{}.exr", w, h);
    write_image(dir + "/" + name, w, h, std::vector<float>(size_t(w) * h * 3, 0.5f), {});
    json s = base_scene(2, 2, 1, "spectral");
    s["lights"] = json::array({{{"type", "environment"}, {"map", name}}});
    Renderer(scene_from_json(s, dir), quiet_options()).render();
  }
  set_warning_sink({});
  ASSERT_EQ(warnings.size(), 2u) << fmt::format("{}", fmt::join(warnings, "\n"));
  EXPECT_THAT(warnings[0], testing::HasSubstr("/lights/0/map: " + dir + "/map_4x4.exr is 4x4"));
  EXPECT_THAT(warnings[0], testing::HasSubstr("pbrt-v4's equal-area layout"));
  EXPECT_THAT(warnings[1], testing::HasSubstr("map_6x4.exr is 6x4"));
  EXPECT_THAT(warnings[1], testing::Not(testing::HasSubstr("equal-area")));
}

TEST(Render, TurnedEnvironmentMapLightsAsTheMapRolled) {
  // a wide slab lit by a map whose bright patch faces the camera (-z): turned by 90 degrees, it lights
  // the slab as the same map rolled by three quarters of its width does unturned (the patch along -x).
  // Next-event estimation samples the turned map and MIS weighs it by its pdf, so a sampler or pdf
  // that missed the turn would not agree; the twin, the rolled map 3% brighter, must not agree.
  std::string dir = temp_dir("envmap_turned_lights");
  const int W = 32, H = 16;
  auto write_map = [&](const std::string& name, int shift, float gain) {
    std::vector<float> px(size_t(W) * H * 3, 0.05f * gain);
    for (int y = 4; y < 12; ++y)
      for (int x = 12; x < 20; ++x)
        for (int c = 0; c < 3; ++c) px[(size_t(y) * W + size_t((x + shift) % W)) * 3 + c] = (4.0f + 1.0f * c) * gain;
    write_image(dir + "/" + name, W, H, px, {});
  };
  write_map("patch.exr", 0, 1.0f);
  write_map("rolled.exr", 3 * W / 4, 1.0f);
  write_map("rolled_bright.exr", 3 * W / 4, 1.03f);
  auto render = [&](const std::string& map, double turn, int seed) {  // independent renders: seeds of their own
    json s = base_scene(32, 32, 256, "spectral-decomposition");
    s["render"]["seed"] = seed;
    s["camera"]["height"] = 4.0;
    s["lights"] = json::array({{{"type", "environment"}, {"map", map}, {"rotate_deg", turn}}});
    s["media"].push_back({{"type", "homogeneous"}, {"bounds", {{-20, -20, -0.5}, {20, 20, 0.5}}},
                          {"sigma_a", {0.1, 0.1, 0.1}}, {"sigma_s", {1.0, 1.0, 1.0}}, {"phase", {{"type", "hg"}, {"g", 0.5}}}});
    return Renderer(scene_from_json(s, dir), quiet_options()).render();
  };
  RenderResult turned = render("patch.exr", 90, 1), rolled = render("rolled.exr", 0, 2),
               bright = render("rolled_bright.exr", 0, 3), facing = render("patch.exr", 0, 4);
  for (int c = 0; c < 3; ++c) {
    Stats a = mean_se(channel(turned, c)), b = mean_se(channel(rolled, c)), t = mean_se(channel(bright, c)),
          f = mean_se(channel(facing, c));
    EXPECT_NEAR(a.mean, b.mean, 4.0 * std::hypot(a.se, b.se)) << "channel " << c;
    EXPECT_GT(std::abs(a.mean - t.mean), 4.0 * std::hypot(a.se, t.se)) << "the 3% twin, channel " << c;
    EXPECT_GT(std::abs(a.mean - f.mean), 4.0 * std::hypot(a.se, f.se)) << "unturned, channel " << c;
  }
}

TEST(Render, OverlappingMediaAddTheirCoefficients) {
  std::string dir = temp_dir("overlap");
  // absorbing: two overlapping boxes = one box with summed coefficients where they overlap
  json s = base_scene(12, 12, 128, "delta-per-channel");
  s["lights"].push_back({{"type", "environment"}, {"radiance", {1, 1, 1}}});
  s["media"].push_back({{"type", "homogeneous"}, {"bounds", {{-1, -1, -1}, {1, 1, 1}}}, {"sigma_a", {0.2, 0.4, 0.6}}, {"sigma_s", {0, 0, 0}}});
  s["media"].push_back({{"type", "homogeneous"}, {"bounds", {{-1, -1, 0}, {1, 1, 2}}}, {"sigma_a", {0.5, 0.3, 0.1}}, {"sigma_s", {0, 0, 0}}});
  RenderResult r = Renderer(scene_from_json(s, dir), quiet_options()).render();
  double tau[3] = {0.2 * 2 + 0.5 * 2, 0.4 * 2 + 0.3 * 2, 0.6 * 2 + 0.1 * 2};
  const double expected[3] = {std::exp(-tau[0]), std::exp(-tau[1]), std::exp(-tau[2])};
  expect_channels(r, expected, "overlapping absorbers");
  // scattering: two overlapping chromatic media with different phase functions in a white furnace
  write_lumpy(dir + "/lumpy.vdb");
  json f = furnace_scene("spectral", dir, false);
  f["media"].push_back({{"type", "homogeneous"}, {"bounds", {{-0.5, -0.8, -0.6}, {0.9, 0.4, 0.7}}}, {"sigma_a", {0, 0, 0}},
                        {"sigma_s", {2.0, 0.5, 1.0}}, {"phase", {{"type", "hg"}, {"g", -0.5}}}});
  RenderResult w = Renderer(scene_from_json(f, dir), quiet_options()).render();
  const double one[3] = {1, 1, 1};
  expect_channels(w, one, "overlapping white furnace");
}

TEST(Render, DirectionalLightSingleScattering) {
  // sun behind the camera, a wide slab, single scattering only (max_depth 1), no environment:
  // L = sigma_s p(180 deg) E (1 - exp(-2 sigma_t d)) / (2 sigma_t)
  std::string dir = temp_dir("sun");
  for (std::string tracker : {"delta-per-channel", "spectral"}) {
    json s = base_scene(8, 8, 256, tracker);
    s["render"]["max_depth"] = 1;
    s["lights"].push_back({{"type", "directional"}, {"to_light", {0, 0, -1}}, {"irradiance", {2.0, 3.0, 4.0}}});
    s["media"].push_back({{"type", "homogeneous"}, {"bounds", {{-20, -20, -1}, {20, 20, 1}}}, {"sigma_a", {0.3, 0.2, 0.1}},
                          {"sigma_s", {0.5, 1.0, 2.0}}, {"phase", {{"type", "hg"}, {"g", 0.3}}}});
    RenderResult r = Renderer(scene_from_json(s, dir), quiet_options()).render();
    double E[3] = {2, 3, 4}, sa[3] = {0.3, 0.2, 0.1}, ss[3] = {0.5, 1.0, 2.0};
    double g = 0.3, p180 = (1 - g * g) / (4 * M_PI * std::pow(1 + g * g + 2 * g, 1.5));
    for (int c = 0; c < 3; ++c) {
      double st = sa[c] + ss[c];
      double expected = ss[c] * p180 * E[c] * (1 - std::exp(-2 * st * 2.0)) / (2 * st);
      Stats m = mean_se(channel(r, c));
      EXPECT_NEAR(m.mean, expected, 4.0 * m.se + 1e-6) << tracker << " channel " << c;
    }
  }
}

// Henyey-Greenstein CDF of cos theta (cos from -1 to 1).
double hg_cdf(double g, double c) {
  if (std::abs(g) < 1e-3) return 0.5 * (c + 1);
  return (1 - g * g) / (2 * g) * (1 / std::sqrt(1 + g * g - 2 * g * c) - 1 / (1 + g));
}

TEST(Sampling, PhaseSamplingFollowsHenyeyGreenstein) {
  std::string dir = temp_dir("phase");
  json s = base_scene(4, 4, 1, "spectral");
  Renderer r(scene_from_json(s, dir), quiet_options());
  const int n = 40000;
  for (double g : {0.0, 0.3, -0.6, 0.9, 0.999, -0.999}) {
    auto v = Probe(r).phase(ST_PHASE_HG, float(g), n);
    std::vector<double> u;
    for (auto& x : v) {
      ASSERT_TRUE(std::isfinite(x[0]) && x[0] >= -1.0f && x[0] <= 1.0f) << "g " << g;
      ASSERT_NEAR(x[3], 0.0f, 1e-5f) << "unit direction, g " << g;
      ASSERT_NEAR(x[1], x[2], 1e-6f * std::max(1.0f, x[2])) << "pdf = phase value of the sampled direction, g " << g;
      u.push_back(hg_cdf(g, x[0]));
    }
    std::sort(u.begin(), u.end());
    double D = 0;
    for (size_t i = 0; i < u.size(); ++i)
      D = std::max({D, std::abs(u[i] - double(i) / u.size()), std::abs(u[i] - double(i + 1) / u.size())});
    // directions are floats: cos near +-1 moves in steps of 2^-24, over which the CDF rises by
    // at most 2 pi * peak density * 2^-24 (6% at |g| = 0.999, 1e-5 at 0.9); allow that step
    double peak = (1 - g * g) / (4 * M_PI * std::pow(1 - std::abs(g), 3));
    double slack = 2 * M_PI * peak * std::ldexp(1.0, -24);
    EXPECT_LT(D, 1.95 / std::sqrt(double(n)) + slack) << "KS statistic of HG sampling, g " << g;
  }
  // the test can fail: the wrong g is detected
  auto v = Probe(r).phase(ST_PHASE_HG, 0.3f, n);
  std::vector<double> u;
  for (auto& x : v) u.push_back(hg_cdf(0.33, x[0]));
  std::sort(u.begin(), u.end());
  double D = 0;
  for (size_t i = 0; i < u.size(); ++i) D = std::max(D, std::abs(u[i] - double(i) / u.size()));
  EXPECT_GT(D, 1.95 / std::sqrt(double(n)));
}

TEST(Render, SameSeedIsBitIdenticalWhateverTheSchedule) {
  std::string dir = temp_dir("determinism");
  json s = furnace_scene("spectral", dir, true);
  s["film"]["spp"] = 8;
  RenderOptions o1 = quiet_options(), o2 = quiet_options();
  o2.path_slots = 777;  // a different number of paths in flight changes every launch and batch
  RenderResult a = Renderer(scene_from_json(s, dir), o1).render();
  RenderResult b = Renderer(scene_from_json(s, dir), o1).render();
  RenderResult c = Renderer(scene_from_json(s, dir), o2).render();
  ASSERT_EQ(a.rgb.size(), b.rgb.size());
  EXPECT_TRUE(a.rgb == b.rgb) << "two renders with one seed differ";
  EXPECT_TRUE(a.rgb == c.rgb) << "the image depends on the schedule";
  RenderOptions o3 = quiet_options();
  o3.seed = 99;
  RenderResult d = Renderer(scene_from_json(s, dir), o3).render();
  EXPECT_FALSE(a.rgb == d.rgb) << "another seed must give another image";
}

// The shadow-ray ring (RenderOptions::shadow_ring, queues.h): a path scatters again while the
// shadow rays of its last R - 1 bounces run, and each light's accumulator adds them in bounce
// order, so the image does not depend on when they finish nor on R. Two lights, and a budget of 2
// steps per launch, so that shadow rays of several bounces of one path are in flight at once and
// paths wait for a ring entry; rings 1, 2 and 3 under three schedules (paths in flight) give the
// same image bit for bit, and a deeper ring waits less.
TEST(Render, ShadowRaysOfSeveralBouncesInFlightKeepTheImageBitIdentical) {
  std::string dir = temp_dir("shadow_ring");
  json s = furnace_scene("spectral", dir, true);
  s["film"]["spp"] = 4;
  s["lights"].push_back({{"type", "directional"}, {"to_light", {-1, 1, -0.5}}, {"irradiance", {3, 2.5, 2}}, {"angle_deg", 5}});
  auto render = [&](int ring, int slots) {
    RenderOptions o = quiet_options();
    o.iteration_budget = 2;
    if (slots > 0) o.path_slots = slots;  // 0: the device's default
    o.shadow_ring = ring;
    return Renderer(scene_from_json(s, dir), o).render();
  };
  RenderResult a = render(1, 0);
  EXPECT_GT(a.stats.waits, 0u) << "no path ever waited: the test does not reach that code";
  EXPECT_EQ(a.stats.nonfinite_samples, 0u);
  for (int ring : {1, 2, 3})
    for (int slots : {0, 777, 61}) {
      if (ring == 1 && slots == 0) continue;
      RenderResult b = render(ring, slots);
      EXPECT_TRUE(a.rgb == b.rgb) << "the image depends on the shadow ring (" << ring << ") or the schedule (" << slots
                                  << " paths in flight)";
      if (slots == 0) EXPECT_LT(b.stats.waits, a.stats.waits) << "ring " << ring << " waits as often as ring 1";
    }
  // and it is the image: the same scene at the full budget agrees within 4 SE
  RenderOptions o = quiet_options();
  o.seed = 5;
  RenderResult ref = Renderer(scene_from_json(s, dir), o).render();
  EXPECT_LT(max_z(a, ref), 4.0);
}

TEST(Render, StatisticsCountPathsAndLookups) {
  std::string dir = temp_dir("stats");
  json s = furnace_scene("delta-per-channel", dir, false);
  s["film"]["spp"] = 4;
  RenderResult r = Renderer(scene_from_json(s, dir), quiet_options()).render();
  EXPECT_EQ(r.stats.paths, uint64_t(12 * 12 * 4 * 3));
  EXPECT_GT(r.stats.lookups_track, 0u);
  EXPECT_GT(r.stats.lookups_shadow, 0u);
  EXPECT_GT(r.stats.dda_steps, 0u);
  EXPECT_GT(r.stats.kernels.count("k_track"), 0u);
  EXPECT_GT(r.stats.kernels.at("k_track").launches, 0u);
}

}  // namespace

// A stop that comes once every sample has finished (a Python progress callback that raises at its
// last call, fraction 1) cuts nothing short: the image is the whole render, not interrupted. The
// twin: a stop part-way leaves the render interrupted, with its reason.
TEST(Render, AStopAfterTheLastSampleLeavesTheRenderWhole) {
  const std::string dir = temp_dir("stop_at_the_end");
  const json j = slab_scene("spectral-decomposition", 64);
  const SceneDesc scene = scene_from_json(j, dir);
  for (const double stop_at : {1.0, 0.2}) {
    SCOPED_TRACE(stop_at == 1.0 ? "stopped at the end" : "the twin: stopped part-way");
    std::atomic<bool> stop{false};
    RenderOptions o = quiet_options(64);
    o.path_slots = 64;  // many batches, so that the progress passes 0.2 before the end
    o.batches_in_flight = 1;
    o.stop = &stop;
    o.progress = [&](double f) {
      if (f >= stop_at) stop = true;
    };
    const MultiDeviceResult r = render_call(scene, o, "", 0, j.dump());  // the text: the scene's hash
    if (stop_at == 1.0) {
      EXPECT_EQ(r.piece.samples(), 64);
      EXPECT_FALSE(r.piece.interrupted);
      EXPECT_EQ(render_stop_reason(r), "");
    } else {
      EXPECT_LT(r.piece.samples(), 64);
      EXPECT_TRUE(r.piece.interrupted);
      EXPECT_EQ(render_stop_reason(r), "signal");
    }
  }
}

// Directions the scene gives by two points or a vector of any length (a directional light's
// to_light, a spot's look_at - position, the camera's up) render as their unit vectors: the same
// image, bit for bit, at lengths 2^-990 and 2^510 (whose squares once vanished or overflowed: a
// spot went dark, a sun came from elsewhere). The twin: another direction renders another image.
TEST(Render, DirectionsOfAnyLengthRenderAsTheirUnitVectors) {
  const std::string dir = temp_dir("direction_lengths");
  auto scene = [&](double s, double turn) {
    json j = slab_scene("spectral-decomposition", 4);
    j["camera"] = {{"type", "perspective"}, {"position", {0.3, 0.2, -4}}, {"look_at", {0, 0, 0}}, {"up", {0, s, 0.1 * s}},
                   {"fov_deg", 40}};
    j["media"][0]["sigma_s"] = {1, 1, 1};
    j["lights"] = json::array();
    j["lights"].push_back({{"type", "directional"}, {"to_light", {s, 0.5 * s, turn * s}}, {"irradiance", {1, 1, 1}}});
    j["lights"].push_back({{"type", "spot"}, {"position", {0, 0, 0}}, {"look_at", {0, -s, 0.2 * s}},
                           {"intensity", {5, 5, 5}}, {"cone_angle_deg", 30}});
    return scene_from_json(j, dir);
  };
  const RenderResult unit = Renderer(scene(1, -0.2), quiet_options()).render();
  for (double s : {std::ldexp(1.0, -990), std::ldexp(1.0, 510)}) {  // powers of 2: the same directions exactly
    const RenderResult r = Renderer(scene(s, -0.2), quiet_options()).render();
    EXPECT_TRUE(r.rgb == unit.rgb) << "directions scaled by " << s;
  }
  EXPECT_FALSE(Renderer(scene(1, 0.2), quiet_options()).render().rgb == unit.rgb) << "twin: another sun direction";
}
