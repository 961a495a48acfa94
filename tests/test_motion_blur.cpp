// test_motion_blur.cpp: Eulerian motion blur from velocity grids (kernels/medium.h
// medium_lookup_index, src/scene/pack_velocity.cpp, src/volume/velocity_grid.cpp,
// build_majorant_grid's margin; docs/scene-format.md, "Motion blur").
//
// The analytic scene: a box of constant density (voxels of 1/16, 1 unit wide in x, 0.5 deep in z,
// tall in y) moving along +x at u units per second, a pure absorber, seen through an orthographic
// camera along +z against a uniform environment of radiance 1. The trilinear box is separable, so
// the optical depth of the ray at x is tau0 f(x), f the 1D hat-edged profile of the voxels
// (0 below -1 voxel, a linear ramp to 1 at voxel 0, 1 to voxel N-1, a ramp to 0 at voxel N); the
// pixel's value is the mean over the shutter and the pixel of exp(-tau0 f(x - u t)). Every column
// is checked within 4 SE (every tracker, both absorption modes), and two pooled statistics per
// row: the mean difference, whose twin with values 3% high must fail, and the difference weighted
// by the blur's own change of the profile, whose twin with a 10% longer displacement must fail (a
// 3% one moves the ramps by a fifth of a pixel: z of about 3 at 256 spp).
// Further: a blurred render equals the mean of renders at fixed times of the shutter (zero-length
// shutters); a fixed-time lookup equals the lookup of the grid shifted by whole voxels; a
// staggered grid is read half a voxel up; density at random points and times of a real smoke
// frame with a swirling velocity stays within the dilated cells' bounds; a grid of zeros (Blender's
// own, empty, staggered velocity) and no shutter keep the kernels and the image of a still medium;
// shards add up; bad grids and fields are refused by name; `info` lists velocity grids.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <functional>
#include <limits>
#include <random>
#include <string>

#include "cli_util.h"
#include "device/probe.h"
#include "test_util.h"
#include "volume/velocity_grid.h"

using namespace spectrack;
using namespace st_test;
using json = nlohmann::json;

namespace {

const std::string kShared = SHARED_DATA_DIR;
constexpr double kVoxel = 1.0 / 16.0;
constexpr int kNx = 16, kNz = 8;  // the box's voxels along x and z (y: -48 .. 47)
constexpr double kSigma = 1.5;    // sigma_a
constexpr double kShutter = 0.01; // the shutter is [-kShutter, kShutter]
constexpr int kSize = 32;
constexpr double kCentre = (kNx - 1) * kVoxel / 2, kHalf = 1.0;  // the frame: x in kCentre +- kHalf

// The box of density 1 with a velocity grid "vel" (vec3s, background and active voxels = v; a
// staggered grid when asked) and, optionally, extra grids.
void write_moving_box(const std::string& path, openvdb::Vec3s v, bool staggered = false, double vel_voxel = kVoxel) {
  openvdb::initialize();
  auto d = openvdb::FloatGrid::create(0.0f);
  d->setName("density");
  d->setGridClass(openvdb::GRID_FOG_VOLUME);
  d->setTransform(openvdb::math::Transform::createLinearTransform(kVoxel));
  auto vel = openvdb::Vec3SGrid::create(v);
  vel->setName("vel");
  vel->setTransform(openvdb::math::Transform::createLinearTransform(vel_voxel));
  if (staggered) vel->setGridClass(openvdb::GRID_STAGGERED);
  auto da = d->getAccessor();
  auto va = vel->getAccessor();
  for (int k = 0; k < kNz; ++k)
    for (int j = -48; j < 48; ++j)
      for (int i = 0; i < kNx; ++i) {
        da.setValue(openvdb::Coord(i, j, k), 1.0f);
        va.setValue(openvdb::Coord(i, j, k), v);
      }
  openvdb::io::File f(path);
  f.write({d, vel});
  f.close();
}

json box_scene(const std::string& file, int spp) {
  return json{{"format", "spectrack-scene/1"},
              {"camera", {{"type", "orthographic"}, {"position", {kCentre, 0, -3}}, {"look_at", {kCentre, 0, 0}},
                          {"up", {0, 1, 0}}, {"height", 2 * kHalf}, {"shutter", {-kShutter, kShutter}}}},
              {"film", {{"width", kSize}, {"height", kSize}, {"spp", spp}}},
              {"render", {{"seed", 5}, {"max_depth", 0}}},
              {"lights", {{{"type", "environment"}, {"radiance", {1, 1, 1}}}}},
              {"media", {{{"type", "vdb"}, {"file", file}, {"sigma_a", {kSigma, kSigma, kSigma}}, {"sigma_s", {0, 0, 0}},
                          {"velocity", {{"grid", "vel"}}}}}}};
}

// The box's trilinear profile along x at world x (voxel centres at i * kVoxel).
double hat(double x) {
  const double i = x / kVoxel;
  if (i <= -1 || i >= kNx) return 0.0;
  if (i < 0) return i + 1;
  if (i > kNx - 1) return kNx - i;
  return 1.0;
}

// The expected value of column c for a displacement u t over t in the shutter, |u| kShutter = a.
// The camera's right is world -x (it looks along +z with y up), so column c sees world x =
// kCentre + kHalf - (c + 0.5) * pixel.
double column_expected(int c, double a) {
  const double tau0 = kSigma * kNz * kVoxel, pixel = 2 * kHalf / kSize;
  const int nx = 32, nt = 256;
  double sum = 0;
  for (int k = 0; k < nx; ++k) {
    const double x = kCentre + kHalf - (c + (k + 0.5) / nx) * pixel;
    for (int s = 0; s < nt; ++s) {
      const double shift = a == 0 ? 0.0 : a * (2.0 * (s + 0.5) / nt - 1.0);
      sum += std::exp(-tau0 * hat(x - shift));
    }
  }
  return sum / (nx * nt);
}

// |mean| / SE over the rows of sum over columns of w(c) (value - expected(c)).
double pooled_z(const RenderResult& r, const std::vector<double>& expected, const std::vector<double>& w) {
  std::vector<double> rows;
  for (int y = 0; y < r.height; ++y) {
    double s = 0;
    for (int x = 0; x < r.width; ++x) s += w[size_t(x)] * (r.rgb[(size_t(y) * r.width + x) * 3 + 1] - expected[size_t(x)]);
    rows.push_back(s);
  }
  const Stats st = mean_se(rows);
  return std::abs(st.mean) / std::max(st.se, 1e-12);
}

RenderResult render(const json& s, const std::string& dir, RenderOptions o = quiet_options()) {
  return Renderer(scene_from_json(s, dir), o).render();
}

std::string add_velocity(const std::string& in, const std::string& out, const std::string& args) {
  const std::string cmd = std::string(ADD_VELOCITY_BINARY) + " '" + in + "' '" + out + "' " + args;
  EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd;
  return out;
}

}  // namespace

// tools/add_velocity sets the flow on every voxel of the density grown by 2, dense interiors
// included (a dense 24^3 cube: OpenVDB keeps its interior as active tiles, to which the tool once
// gave a velocity at one voxel each, so most of the cube never moved); off the swirl's axis every
// voxel moves.
TEST(MotionBlur, AddVelocityMovesEveryVoxelOfADenseMedium) {
  const std::string dir = temp_dir("blur_dense_velocity");
  st_test::write_vdb(dir + "/cube.vdb", "density", openvdb::Coord(-12), openvdb::Coord(11), [](int, int, int) { return 1.0f; });
  add_velocity(dir + "/cube.vdb", dir + "/cube_vel.vdb", "--speed 5");
  openvdb::io::File f(dir + "/cube_vel.vdb");
  f.open();
  const auto d = openvdb::gridPtrCast<openvdb::FloatGrid>(f.readGrid("density"));
  const auto v = openvdb::gridPtrCast<openvdb::Vec3SGrid>(f.readGrid("vel"));
  f.close();
  ASSERT_TRUE(d && v);
  auto acc = v->getConstAccessor();
  int64_t still = 0;
  for (auto it = d->tree().cbeginValueOn(); it; ++it) {
    const openvdb::CoordBBox box = it.getBoundingBox();
    for (auto c = box.begin(); c; ++c) still += !acc.isValueOn(*c) || acc.getValue(*c).length() == 0.0f;
  }
  EXPECT_EQ(d->activeVoxelCount(), 24u * 24u * 24u);
  EXPECT_LE(still, 24) << "only voxels on the swirl's axis may be still";
  EXPECT_GE(v->activeVoxelCount(), 28u * 28u * 28u);  // grown by 2 on each side
}

TEST(MotionBlur, MovingBoxIsTheTimeAverageForEveryTrackerAndAbsorption) {
  const std::string dir = temp_dir("blur_box");
  const double u = 40.0, a = u * kShutter;  // a: the displacement at shutter close, 0.4 units
  write_moving_box(dir + "/box.vdb", openvdb::Vec3s(float(u), 0, 0));
  std::vector<double> E(kSize), E0(kSize), E3(kSize), ones(kSize, 1.0), dE(kSize), E_high(kSize);
  for (int c = 0; c < kSize; ++c) {
    E[size_t(c)] = column_expected(c, a);
    E0[size_t(c)] = column_expected(c, 0);
    E3[size_t(c)] = column_expected(c, 1.1 * a);
    dE[size_t(c)] = E[size_t(c)] - E0[size_t(c)];
    E_high[size_t(c)] = 1.03 * E[size_t(c)];
  }
  for (int tracker : {ST_TRACKER_DELTA_PER_CHANNEL, ST_TRACKER_DELTA, ST_TRACKER_SPECTRAL, ST_TRACKER_DECOMPOSITION,
                      ST_TRACKER_SPECTRAL_DECOMPOSITION, ST_TRACKER_SPECTRAL_MIS})
    for (int absorption : {ST_ABSORPTION_EVENT, ST_ABSORPTION_WEIGHT}) {
      SCOPED_TRACE(std::string(tracker_name(tracker)) + (absorption == ST_ABSORPTION_EVENT ? ", event" : ", weight"));
      RenderOptions o = quiet_options(256);
      o.tracker = tracker;
      o.absorption = absorption;
      const RenderResult r = render(box_scene(dir + "/box.vdb", 256), dir, o);
      EXPECT_NE(r.features & ST_FEATURE_VELOCITY, 0u);
      EXPECT_NE(r.features & ST_FEATURE_TIME, 0u);
      double worst = 0, worst_still = 0;
      for (int x = 0; x < r.width; ++x) {
        std::vector<double> col;
        for (int y = 0; y < r.height; ++y) col.push_back(r.rgb[(size_t(y) * r.width + x) * 3 + 1]);
        const Stats s = mean_se(col);
        worst = std::max(worst, std::abs(s.mean - E[size_t(x)]) / std::max(s.se, 1e-4));
        worst_still = std::max(worst_still, std::abs(s.mean - E0[size_t(x)]) / std::max(s.se, 1e-4));
      }
      EXPECT_LT(worst, 4.0);
      EXPECT_GT(worst_still, 4.0) << "the still box's profile must not pass";
      EXPECT_LT(pooled_z(r, E, ones), 4.0);
      EXPECT_LT(pooled_z(r, E, dE), 4.0);
      EXPECT_GT(pooled_z(r, E_high, ones), 4.0) << "values 3% high must be detectable";
      EXPECT_GT(pooled_z(r, E3, dE), 4.0) << "a 10% longer displacement must be detectable";
    }
}

// The blurred render (stratified times over the shutter) equals the mean of renders of the
// advected density at fixed times (zero-length shutters at the midpoints of 16 equal parts),
// with scattering, shadow rays and a rotating flow, so every lookup of a path (camera ray,
// scattering, shadow rays) must be at the path's one time.
TEST(MotionBlur, BlurredRenderIsTheMeanOfFixedTimeRenders) {
  const std::string dir = temp_dir("blur_mean");
  write_lumpy(dir + "/lumpy.vdb");
  const std::string file = add_velocity(dir + "/lumpy.vdb", dir + "/moving.vdb", "--speed 12");
  json s = {{"format", "spectrack-scene/1"},
            {"camera", {{"type", "perspective"}, {"position", {0, 0.3, -3.5}}, {"look_at", {0, 0, 0}}, {"fov_deg", 40},
                        {"shutter", {0, 0.02}}}},
            {"film", {{"width", 24}, {"height", 24}, {"spp", 256}}},
            {"render", {{"seed", 9}, {"max_depth", 8}}},
            {"lights", {{{"type", "environment"}, {"radiance", {0.3, 0.4, 0.5}}},
                        {{"type", "directional"}, {"to_light", {1, 1, -0.5}}, {"irradiance", {3, 3, 3}}}}},
            {"media", {{{"type", "vdb"}, {"file", file}, {"sigma_a", {0.5, 1, 2}}, {"sigma_s", {6, 5, 4}},
                        {"velocity", {{"grid", "vel"}}}}}}};
  const RenderResult blurred = render(s, dir);
  RenderResult mean;
  for (int k = 0; k < 16; ++k) {
    const double t = 0.02 * (k + 0.5) / 16;
    json sk = s;
    sk["camera"]["shutter"] = {t, t};
    sk["film"]["spp"] = 256 / 16;
    sk["render"]["seed"] = 100 + k;
    const RenderResult r = render(sk, dir);
    if (k == 0) mean = r;
    else
      for (size_t i = 0; i < r.rgb.size(); ++i) mean.rgb[i] += r.rgb[i];
  }
  for (float& v : mean.rgb) v /= 16;
  EXPECT_LT(max_z(blurred, mean), 4.0);
  EXPECT_GT(max_z(blurred, mean, 1.03), 4.0) << "a 3% error must be detectable";
  json still = s;
  still["camera"]["shutter"] = {0.02, 0.02};
  EXPECT_GT(max_z(blurred, render(still, dir)), 4.0) << "the blur must be visible against the shutter's close";
}

// At a fixed time a uniform flow of whole voxels shifts the grid exactly: the lookups equal those
// of the shifted grid; a staggered grid's component a is read half a voxel up along a.
TEST(MotionBlur, FixedTimeLookupsShiftTheGridAndStaggeredGridsReadHalfAVoxelUp) {
  const std::string dir = temp_dir("blur_shift");
  auto density = [](int i, int j, int k) { return float(1.0 + 0.01 * i + 0.02 * j - 0.015 * k); };
  auto shifted = [&](int i, int j, int k) { return density(i - 3, j, k); };
  write_vdb(dir + "/shifted.vdb", "density", openvdb::Coord(-8), openvdb::Coord(16), shifted, kVoxel);
  openvdb::initialize();
  auto write = [&](const std::string& path, bool staggered, bool ramp) {
    auto d = openvdb::FloatGrid::create(0.0f);
    d->setName("density");
    d->setTransform(openvdb::math::Transform::createLinearTransform(kVoxel));
    auto vel = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f));
    vel->setName("vel");
    vel->setTransform(openvdb::math::Transform::createLinearTransform(kVoxel));
    if (staggered) vel->setGridClass(openvdb::GRID_STAGGERED);
    auto da = d->getAccessor();
    auto va = vel->getAccessor();
    for (int k = -12; k <= 12; ++k)
      for (int j = -12; j <= 12; ++j)
        for (int i = -12; i <= 12; ++i) {
          da.setValue(openvdb::Coord(i, j, k), density(i, j, k));
          // 3 voxels per 0.01 s, or a ramp v_x = i voxels per 0.01 s (world: * kVoxel / 0.01)
          va.setValue(openvdb::Coord(i, j, k), openvdb::Vec3s(float((ramp ? i : 3) * kVoxel / 0.01), 0, 0));
        }
    openvdb::io::File f(path);
    f.write({d, vel});
    f.close();
  };
  write(dir + "/uniform.vdb", false, false);
  write(dir + "/ramp.vdb", false, true);
  write(dir + "/ramp_staggered.vdb", true, true);
  auto scene = [&](const std::string& file, bool velocity) {
    json s = box_scene(file, 1);
    s["camera"]["shutter"] = {0.01, 0.01};
    s["media"][0]["sigma_a"] = {1, 1, 1};
    if (!velocity) s["media"][0].erase("velocity");
    return s;
  };
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> U(-4 * kVoxel, 4 * kVoxel);
  std::vector<std::array<float, 3>> pts;
  for (int n = 0; n < 200; ++n) pts.push_back({U(rng), U(rng), U(rng)});
  const std::vector<float> times(pts.size(), 0.01f);
  Renderer moving(scene_from_json(scene(dir + "/uniform.vdb", true), dir), quiet_options());
  Renderer still(scene_from_json(scene(dir + "/shifted.vdb", false), dir), quiet_options());
  const std::vector<float> a = Probe(moving).density(0, pts, times), b = Probe(still).density(0, pts);
  for (size_t i = 0; i < pts.size(); ++i) EXPECT_NEAR(a[i], b[i], 2e-5) << i;
  for (bool staggered : {false, true}) {
    Renderer r(scene_from_json(scene(dir + (staggered ? "/ramp_staggered.vdb" : "/ramp.vdb"), true), dir),
               quiet_options());
    const std::vector<float> d = Probe(r).density(0, pts, times);
    for (size_t i = 0; i < pts.size(); ++i) {
      const double x = pts[i][0] / kVoxel, y = pts[i][1] / kVoxel, z = pts[i][2] / kVoxel;
      const double xs = x - (x + (staggered ? 0.5 : 0.0));  // v_x t = (x + 1/2) voxels at t = 0.01
      EXPECT_NEAR(d[i], 1.0 + 0.01 * xs + 0.02 * y - 0.015 * z, 2e-5) << i << (staggered ? " staggered" : "");
    }
  }
}

// Density at random points and times of the shutter stays within [minorant, majorant] of the
// cell the walk uses there (the hierarchy and the one-level grid; trilinear and one-voxel
// lookups), on Blender's smoke frame with a swirling velocity (staggered and not), whose speed
// and so each cell's reach grow with the distance from its axis; the twin without the margin must
// fail.
TEST(MotionBlur, DilatedCellsBoundTheDensityOverTheShutter) {
  const std::string dir = temp_dir("blur_bounds");
  const std::string smoke = kShared + "/usd/smoke_000002.vdb";
  struct Case {
    std::string args;
    int block;
    bool stochastic;  // one-voxel lookups: the cells bound whole voxels within the reach
  };
  for (const Case& k : {Case{"--speed 40", 8, false}, Case{"--speed 40", 0, false}, Case{"--speed 40 --staggered", 8, false},
                        Case{"--speed 40 --staggered", 0, false}, Case{"--speed 40", 8, true}}) {
    {
      const std::string& args = k.args;
      const int block = k.block;
      SCOPED_TRACE(args + ", block " + std::to_string(block) + (k.stochastic ? ", stochastic" : ""));
      const std::string file = add_velocity(smoke, dir + "/smoke_vel.vdb", args);
      json s = box_scene(file, 1);
      s["camera"]["shutter"] = {-0.01, 0.02};
      if (k.stochastic) s["render"]["lookup"] = "stochastic";
      RenderOptions o = quiet_options();
      o.majorant_block = block;
      Renderer r(scene_from_json(s, dir), o);
      Probe probe(r);
      std::mt19937 rng(7);
      std::uniform_real_distribution<float> X(-3.6f, 3.6f), Y(-3.5f, 3.5f), Z(-1.6f, 9.6f), T(-0.01f, 0.02f);
      std::vector<std::array<float, 3>> pts;
      std::vector<float> times;
      for (int n = 0; n < 40000; ++n) pts.push_back({X(rng), Y(rng), Z(rng)}), times.push_back(T(rng));
      const std::vector<float> d = probe.density(0, pts, times);
      const std::vector<std::array<float, 2>> m = probe.majorant(0, pts);
      int outside = 0, moved = 0;
      for (size_t i = 0; i < pts.size(); ++i) {
        if (m[i][0] < 0) {
          EXPECT_EQ(d[i], 0.0f) << i;
          continue;
        }
        if (d[i] > m[i][0] || d[i] < m[i][1]) ++outside;
        if (d[i] > 0) ++moved;
      }
      EXPECT_EQ(outside, 0);
      EXPECT_GT(moved, 1000);
      // the twin: the same lookups against the still medium's cells
      json still = s;
      still["media"][0].erase("velocity");
      Renderer r0(scene_from_json(still, dir), o);
      const std::vector<std::array<float, 2>> m0 = Probe(r0).majorant(0, pts);
      int outside0 = 0;
      for (size_t i = 0; i < pts.size(); ++i)
        if (d[i] > (m0[i][0] < 0 ? 0.0f : m0[i][0])) ++outside0;
      EXPECT_GT(outside0, 10) << "without the margin the moving density must leave its cells";
    }
  }
}

// build_majorant_grid's per-cell reach on Blender's smoke frame, on the host: every cell bounds
// the trilinear density (sample_index_trilinear) at random points of the cell displaced by up to
// its own fractional reach along each axis (the points at the corners of that box included, where
// the exact bound is attained), and the cells are tighter than those of the global margin
// somewhere. The twin: cells built for 85% of the reach must miss some of those points.
TEST(MotionBlur, PerCellReachBoundsTheTrilinearDensityExactly) {
  const GridData g = load_float_grid(kShared + "/usd/smoke_000002.vdb", "density", -1, "smoke");
  const int cell = 2;
  const std::array<int, 3> margin{3, 3, 3};
  // a reach that varies from cell to cell: 0 .. 2.6 voxels, fractional, by the cell's position
  auto reach = [](const std::array<int, 3>& lo, const std::array<int, 3>&) {
    std::array<double, 3> r{};
    for (size_t a = 0; a < 3; ++a) r[a] = double((lo[a] * 7 + int(a) * 3) & 15) / 15.0 * 2.6;
    return r;
  };
  auto scaled = [&](double f) {
    return CellReach([&, f](const std::array<int, 3>& lo, const std::array<int, 3>& hi) {
      std::array<double, 3> r = reach(lo, hi);
      for (double& x : r) x *= f;
      return r;
    });
  };
  const MajorantGrid mg = build_majorant_grid(g, cell, margin, scaled(1.0));
  const MajorantGrid global = build_majorant_grid(g, cell, margin);
  const MajorantGrid short_reach = build_majorant_grid(g, cell, margin, scaled(0.85));
  ASSERT_EQ(mg.dims, global.dims);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  int outside = 0, outside_short = 0, tighter = 0, checked = 0;
  for (size_t idx = 0; idx < mg.dmax.size(); ++idx) {
    tighter += mg.dmax[idx] < global.dmax[idx];
    EXPECT_LE(mg.dmax[idx], global.dmax[idx]) << idx;
    if (global.dmax[idx] <= 0) continue;
    const std::array<int, 3> c{int(idx % size_t(mg.dims[0])), int((idx / size_t(mg.dims[0])) % size_t(mg.dims[1])),
                               int(idx / (size_t(mg.dims[0]) * size_t(mg.dims[1])))};
    std::array<int, 3> lo{}, hi{};
    for (size_t a = 0; a < 3; ++a) lo[a] = mg.origin[a] + c[a] * cell, hi[a] = lo[a] + cell;
    const std::array<double, 3> r = reach(lo, hi);
    for (int n = 0; n < 12; ++n) {
      std::array<double, 3> p{};
      for (size_t a = 0; a < 3; ++a) {
        // half of the points at a corner of the reachable box, the rest anywhere in it
        const double u = n < 6 ? double((n >> a) & 1) : U(rng);
        p[a] = lo[a] - r[a] + u * (hi[a] - lo[a] + 2 * r[a]);
      }
      const float d = sample_index_trilinear(g, p[0], p[1], p[2]);
      ++checked;
      outside += d > mg.dmax[idx] || d < mg.dmin[idx];
      outside_short += d > short_reach.dmax[idx] || d < short_reach.dmin[idx];
    }
  }
  EXPECT_GT(checked, 10000);
  EXPECT_EQ(outside, 0);
  EXPECT_GT(tighter, int(mg.dmax.size() / 20)) << "the per-cell reach must tighten cells";
  EXPECT_GT(outside_short, 10) << "cells of a shorter reach must miss the density at the full reach";
}

// A far reach (build_majorant_grid's exact_read_limit passed) bounds each cell by the 8^3 leaves
// its grown extent meets: on Blender's smoke frame with a reach of up to 6 voxels varying by cell,
// every leaf-bounded cell holds its exact bounds (which the test above checks against the density:
// a leaf bound missing a block or rounding the extent inwards would fall inside them), the
// density at random points of its reach box, and is tighter than the global margin's somewhere.
TEST(MotionBlur, FarReachBoundsByLeafHoldTheExactBounds) {
  const GridData g = load_float_grid(kShared + "/usd/smoke_000002.vdb", "density", -1, "smoke");
  const int cell = 4;
  const std::array<int, 3> margin{6, 6, 6};
  auto reach = [](const std::array<int, 3>& lo, const std::array<int, 3>&) {
    std::array<double, 3> r{};
    for (size_t a = 0; a < 3; ++a) r[a] = double((lo[a] * 5 + int(a)) & 15) / 15.0 * 6.0;
    return r;
  };
  const MajorantGrid exact = build_majorant_grid(g, cell, margin, reach, std::numeric_limits<double>::infinity());
  const MajorantGrid leaf = build_majorant_grid(g, cell, margin, reach, 0.0);
  const MajorantGrid global = build_majorant_grid(g, cell, margin, {}, std::numeric_limits<double>::infinity());
  ASSERT_EQ(leaf.dims, exact.dims);
  int looser = 0, tighter = 0, outside = 0, checked = 0;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  for (size_t idx = 0; idx < leaf.dmax.size(); ++idx) {
    EXPECT_GE(leaf.dmax[idx], exact.dmax[idx]) << idx;
    EXPECT_LE(leaf.dmin[idx], exact.dmin[idx]) << idx;
    looser += leaf.dmax[idx] > exact.dmax[idx];
    tighter += leaf.dmax[idx] < global.dmax[idx];
    if (global.dmax[idx] <= 0 || idx % 7) continue;
    const std::array<int, 3> c{int(idx % size_t(leaf.dims[0])), int((idx / size_t(leaf.dims[0])) % size_t(leaf.dims[1])),
                               int(idx / (size_t(leaf.dims[0]) * size_t(leaf.dims[1])))};
    std::array<int, 3> lo{}, hi{};
    for (size_t a = 0; a < 3; ++a) lo[a] = leaf.origin[a] + c[a] * cell, hi[a] = lo[a] + cell;
    const std::array<double, 3> r = reach(lo, hi);
    for (int n = 0; n < 8; ++n) {
      std::array<double, 3> p{};
      for (size_t a = 0; a < 3; ++a) p[a] = lo[a] - r[a] + U(rng) * (hi[a] - lo[a] + 2 * r[a]);
      const float d = sample_index_trilinear(g, p[0], p[1], p[2]);
      ++checked;
      outside += d > leaf.dmax[idx] || d < leaf.dmin[idx];
    }
  }
  EXPECT_GT(checked, 1000);
  EXPECT_EQ(outside, 0);
  EXPECT_GT(looser, 0) << "leaf bounds round the extent out: some must be wider than the exact ones";
  EXPECT_GT(tighter, int(leaf.dmax.size() / 50)) << "the per-cell reach must still tighten cells";
}

// Blender's own velocity grid (smoke frame 1: staggered, no active values) loads as staggered
// with speed 0: the medium cannot move, so the kernels and the image are a still medium's. No
// shutter: the same. Outliers above the threshold read as 0.
TEST(MotionBlur, StillVelocityKeepsTheKernelsAndTheImageAndOutliersReadZero) {
  const std::string dir = temp_dir("blur_still");
  const VelocityGrid blender = load_velocity_grid(kShared + "/usd/smoke_000001.vdb", "velocity",
                                                  std::numeric_limits<double>::infinity(), "test");
  EXPECT_TRUE(blender.staggered);
  EXPECT_EQ(blender.max_speed, 0.0);
  write_moving_box(dir + "/zero.vdb", openvdb::Vec3s(0.0f));
  write_moving_box(dir + "/box.vdb", openvdb::Vec3s(40.0f, 0, 0));
  json still = box_scene(dir + "/zero.vdb", 8);
  still["media"][0].erase("velocity");
  const RenderResult ref = render(still, dir);
  json zero = box_scene(dir + "/zero.vdb", 8);
  json no_shutter = box_scene(dir + "/box.vdb", 8);
  no_shutter["camera"].erase("shutter");
  for (const json& s : {zero, no_shutter}) {
    const RenderResult r = render(s, dir);
    EXPECT_EQ(r.features & (ST_FEATURE_VELOCITY | ST_FEATURE_TIME), 0u);
    EXPECT_EQ(r.rgb, ref.rgb);
  }
  // the outlier threshold: 40 units per second is an outlier above 39 (after scale 1)
  json outlier = box_scene(dir + "/box.vdb", 8);
  outlier["media"][0]["velocity"]["outlier_threshold"] = 39;
  const RenderResult r = render(outlier, dir);
  EXPECT_EQ(r.features & ST_FEATURE_VELOCITY, 0u);
  EXPECT_EQ(r.rgb, render(box_scene(dir + "/zero.vdb", 8), dir).rgb);
  const VelocityGrid g = load_velocity_grid(dir + "/box.vdb", "vel", 39.0, "test");
  EXPECT_EQ(g.outliers, uint64_t(kNx * 96 * kNz));
  EXPECT_EQ(g.max_speed, 0.0) << "the background is a velocity too: zeroed";
}

// Sample-range shards, pixel windows and the generic kernel add up to (or equal) the single render.
TEST(MotionBlur, ShardsTilesAndTheGenericKernelAreExact) {
  const std::string dir = temp_dir("blur_shards");
  write_moving_box(dir + "/box.vdb", openvdb::Vec3s(40.0f, 5.0f, 0), true);
  const json s = box_scene(dir + "/box.vdb", 32);
  Renderer whole(scene_from_json(s, dir), quiet_options());
  const RenderResult all = whole.render(0, 32);
  const RenderResult a = whole.render(0, 12), b = whole.render(12, 20);
  ASSERT_EQ(all.sum.size(), a.sum.size());
  for (size_t i = 0; i < all.sum.size(); ++i) EXPECT_NEAR(a.sum[i] + b.sum[i], all.sum[i], 1e-9 + 1e-6 * all.sum[i]) << i;
  RenderOptions tile = quiet_options();
  tile.pixel_bounds = std::array<int, 4>{8, 20, 4, 30};
  const RenderResult t = render(s, dir, tile);
  for (int y = 0; y < t.height; ++y)
    for (int x = 0; x < t.width; ++x)
      for (int c = 0; c < 3; ++c)
        EXPECT_EQ(t.sum[(size_t(y) * t.width + x) * 3 + c], all.sum[(size_t(y + 4) * all.width + x + 8) * 3 + c]);
  RenderOptions generic = quiet_options();
  generic.generic_kernels = true;
  EXPECT_EQ(render(s, dir, generic).rgb, all.rgb);
}

TEST(MotionBlur, BadVelocityGridsAndFieldsAreRefusedByName) {
  const std::string dir = temp_dir("blur_bad");
  write_moving_box(dir + "/box.vdb", openvdb::Vec3s(1.0f, 0, 0));
  write_moving_box(dir + "/other_xf.vdb", openvdb::Vec3s(1.0f, 0, 0), false, 2 * kVoxel);
  write_moving_box(dir + "/nan.vdb", openvdb::Vec3s(std::nanf(""), 0, 0));
  auto err = [&](const std::string& file, const std::function<void(json&)>& edit) {
    json s = box_scene(file, 1);
    edit(s);
    return error_of([&] { render(s, dir); });
  };
  auto has = [](const std::string& msg, std::initializer_list<const char*> parts) {
    for (const char* p : parts)
      if (msg.find(p) == std::string::npos) return ::testing::AssertionFailure() << msg << " lacks " << p;
    return ::testing::AssertionSuccess();
  };
  const std::string box = dir + "/box.vdb";
  EXPECT_TRUE(has(err(box, [](json& s) { s["media"][0]["velocity"]["grid"] = "density"; }),
                  {"/media/0/velocity", "box.vdb", "\"density\"", "value type float", "vec3s"}));
  EXPECT_TRUE(has(err(box, [](json& s) { s["media"][0]["velocity"]["grid"] = "v"; }),
                  {"/media/0/velocity", "no velocity grid named \"v\"", "\"vel\" (vec3s)"}));
  EXPECT_TRUE(has(err(dir + "/nan.vdb", [](json&) {}), {"/media/0/velocity", "nan.vdb", "\"vel\"", "not finite"}));
  EXPECT_TRUE(has(err(dir + "/other_xf.vdb", [](json&) {}),
                  {"/media/0/velocity/grid", "'vel'", "different index-to-world transform"}));
  EXPECT_TRUE(has(err(kShared + "/derived/smoke1.nvdb", [](json&) {}),
                  {"/media/0/velocity", "smoke1.nvdb", "OpenVDB (.vdb) files only"}));
  EXPECT_TRUE(has(err(box, [](json& s) { s["media"][0]["velocity"]["fps"] = 0; }), {"/media/0/velocity/fps", "> 0"}));
  EXPECT_TRUE(has(err(box, [](json& s) { s["media"][0]["velocity"]["outlier_threshold"] = -1; }),
                  {"/media/0/velocity/outlier_threshold"}));
  EXPECT_TRUE(has(err(box, [](json& s) { s["media"][0]["velocity"]["speed"] = 1; }), {"/media/0/velocity", "speed"}));
  EXPECT_TRUE(has(err(box, [](json& s) { s["media"][0]["velocity"] = "vel"; }), {"/media/0/velocity"}));
  EXPECT_TRUE(has(err(box, [](json& s) {
                    s["media"][0] = {{"type", "homogeneous"}, {"bounds", {{0, 0, 0}, {1, 1, 1}}}, {"velocity", {{"grid", "vel"}}}};
                  }),
                  {"/media/0", "velocity"}));
}

// `info` lists a vec3s grid's use as a velocity and its largest speed; `render` refuses a bad
// velocity grid by file and field with a non-zero exit.
TEST(MotionBlur, InfoListsVelocityGridsAndRenderRefusesBadOnes) {
  const std::string dir = temp_dir("blur_info");
  write_moving_box(dir + "/box.vdb", openvdb::Vec3s(3.0f, 4.0f, 0), true);
  const st_cli::Proc p = st_cli::run({"info", dir + "/box.vdb"});
  EXPECT_EQ(p.code, 0) << p.describe();
  EXPECT_NE(p.out.find("as velocity    yes (staggered), largest speed 5 "), std::string::npos) << p.out;
  const st_cli::Proc j = st_cli::run({"info", "--json", dir + "/box.vdb"});
  EXPECT_NE(j.out.find("\"velocity_use\""), std::string::npos) << j.out;
  json s = box_scene(dir + "/box.vdb", 1);
  s["media"][0]["velocity"]["grid"] = "density";
  write_text(dir + "/bad.json", s.dump());
  const st_cli::Proc r = st_cli::run({"render", dir + "/bad.json", "-o", dir + "/bad.exr", "--quiet"});
  EXPECT_NE(r.code, 0) << r.describe();
  EXPECT_NE(r.out.find("/media/0/velocity"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("box.vdb"), std::string::npos) << r.out;
}
