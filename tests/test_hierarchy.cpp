// test_hierarchy.cpp: the adaptive majorant/minorant hierarchy (kernels/majorant.h,
// build_majorant_hierarchy in src/volume/majorant_grid.cpp, docs/majorant-hierarchy.md):
//   - host: the typed block entries round-trip through the majorant buffer, and a corrupted entry
//     (a bound 3% low, a group edge that does not divide the block, groups past the pool) fails;
//   - host: every fine cell's bounds at its block's level contain the fine cell's own; an empty
//     block is walked whole at zero, a uniform one whole, a block on a sharp interface at the
//     finest level when lookups are dear and whole when they are cheap;
//   - device: density lookups (trilinear and stochastic) at random points of every shared VDB lie
//     within [minorant, majorant] of the group the walk uses there, under several cost models;
//   - transmittance against closed form for every tracker on axis rays along fine-cell, group
//     and block faces of a volume whose hierarchy mixes levels;
//   - the hierarchy and the one-level grid agree on a diagonal ray's transmittance (4 SE), and
//     the hierarchy takes fewer DDA steps and no more lookups than the one-level grid of its
//     fine cells on the shared cloud.
#include <cmath>
#include <cstring>
#include <random>
#include <tuple>

#include "device/probe.h"
#include "test_util.h"
#include "volume/volume.h"

using namespace spectrack;
using namespace st_test;
using nlohmann::json;

namespace {

const std::string kShared = SHARED_DATA_DIR;
const int kTrackers[] = {ST_TRACKER_DELTA_PER_CHANNEL, ST_TRACKER_DELTA, ST_TRACKER_SPECTRAL, ST_TRACKER_DECOMPOSITION,
                         ST_TRACKER_SPECTRAL_DECOMPOSITION, ST_TRACKER_SPECTRAL_MIS};

// Voxels [0, 127] x [0, 63]^2: 0.5 for x < 16, empty for 16 <= x < 48, 1 for 48 <= x < 88, 3 beyond.
// With 2-voxel cells and blocks of 8 cells (16 voxels from index -1), blocks x 2 (voxels 31..47) is
// empty, x 4 (63..79) uniform at 1, x 5 (79..95) holds the 1|3 interface and x 6 (95..111) is
// uniform at 3, for y and z blocks inside.
float step_density(int i, int, int) { return i < 16 ? 0.5f : (i < 48 ? 0.0f : (i < 88 ? 1.0f : 3.0f)); }
const openvdb::Coord kHi(127, 63, 63);
constexpr double kVoxel = 1.0 / 32.0;

// The bounds the walk uses at fine cell (i, j, k).
std::array<float, 2> bounds_at(const MajorantGrid&, const MajorantHierarchy& h, int i, int j, int k) {
  return majorant_hierarchy_bounds(h, i, j, k);
}

int block_level(const MajorantHierarchy& h, int bx, int by, int bz) {
  const size_t b = size_t(bx) + size_t(h.block_dims[0]) * (size_t(by) + size_t(h.block_dims[1]) * bz);
  return h.blocks[b].group;
}

json step_scene(const std::string& file) {
  return {{"format", "spectrack-scene/1"},
          {"camera", {{"type", "orthographic"}, {"position", {1, 1, -3}}, {"look_at", {1, 1, 0}}, {"up", {0, 1, 0}}, {"height", 2}}},
          {"film", {{"width", 4}, {"height", 4}, {"spp", 1}}},
          {"render", {{"seed", 3}}},
          {"lights", json::array()},
          {"media", {{{"type", "vdb"}, {"file", file}, {"sigma_a", {0.3, 0.3, 0.3}}, {"sigma_s", {0, 0, 0}}}}}};
}

}  // namespace

TEST(MajorantHierarchy, LevelsFollowTheCostModelAndBoundEveryFineCell) {
  std::string dir = temp_dir("hierarchy_host");
  write_vdb(dir + "/step.vdb", "density", openvdb::Coord(0), kHi, step_density, kVoxel);
  GridData g = load_float_grid(dir + "/step.vdb", "density", -1, "step");
  MajorantGrid fine = build_majorant_grid(g, 2);
  for (double k : {1e-4, 0.05, 10.0})
    for (bool decompose : {false, true}) {
      SCOPED_TRACE("lookups per density " + std::to_string(k) + (decompose ? ", decomposing" : ""));
      MajorantCostModel cost;
      cost.lookups_per_density = k;
      cost.decompose = decompose;
      MajorantHierarchy h = build_majorant_hierarchy(fine, 8, cost);
      ASSERT_EQ(h.levels, (std::vector<int>{1, 2, 4, 8}));
      size_t total = 0;
      for (size_t n : h.blocks_per_level) total += n;
      EXPECT_EQ(total, size_t(h.block_dims[0]) * h.block_dims[1] * h.block_dims[2]);
      for (int kz = 0; kz < fine.dims[2]; ++kz)
        for (int jy = 0; jy < fine.dims[1]; ++jy)
          for (int ix = 0; ix < fine.dims[0]; ++ix) {
            const size_t f = size_t(ix) + size_t(fine.dims[0]) * (size_t(jy) + size_t(fine.dims[1]) * kz);
            auto b = bounds_at(fine, h, ix, jy, kz);
            ASSERT_GE(b[0], fine.dmax[f]) << "cell " << ix << " " << jy << " " << kz;
            ASSERT_LE(b[1], fine.dmin[f]) << "cell " << ix << " " << jy << " " << kz;
          }
      // blocks (2, 1, 1): empty; (4, 1, 1) and (6, 1, 1): uniform; (5, 1, 1): the interface
      EXPECT_EQ(block_level(h, 2, 1, 1), 8);
      EXPECT_EQ(bounds_at(fine, h, 18, 10, 10)[0], 0.0f);
      for (auto [bx, d] : {std::pair{4, 1.0f}, std::pair{6, 3.0f}}) {
        EXPECT_EQ(block_level(h, bx, 1, 1), 8);
        EXPECT_NEAR(bounds_at(fine, h, bx * 8 + 3, 10, 10)[0], d, 1e-4);
        EXPECT_NEAR(bounds_at(fine, h, bx * 8 + 3, 10, 10)[1], d, 1e-4);
      }
      if (k == 10.0 && decompose) EXPECT_EQ(block_level(h, 5, 1, 1), 1) << "the interface is worth its fine cells";
      if (k == 1e-4) EXPECT_EQ(block_level(h, 5, 1, 1), 8) << "lookups this cheap are not worth a step";
    }
  MajorantCostModel cost;
  EXPECT_THROW(build_majorant_hierarchy(fine, 1, cost), Error);
}

namespace {

// Whether every fine cell's bounds at its block's level contain the fine cell's own.
bool bounds_hold(const MajorantGrid& fine, const MajorantHierarchy& h) {
  for (int k = 0; k < fine.dims[2]; ++k)
    for (int j = 0; j < fine.dims[1]; ++j)
      for (int i = 0; i < fine.dims[0]; ++i) {
        const size_t f = size_t(i) + size_t(fine.dims[0]) * (size_t(j) + size_t(fine.dims[1]) * k);
        const auto b = majorant_hierarchy_bounds(h, i, j, k);
        if (!(b[0] >= fine.dmax[f] && b[1] <= fine.dmin[f])) return false;
      }
  return true;
}

MajorantHierarchy mixed_hierarchy(MajorantGrid* fine) {
  std::string dir = temp_dir("hierarchy_entries");
  write_vdb(dir + "/step.vdb", "density", openvdb::Coord(0), kHi, step_density, kVoxel);
  *fine = build_majorant_grid(load_float_grid(dir + "/step.vdb", "density", -1, "step"), 2);
  MajorantCostModel cost;
  cost.lookups_per_density = 10.0;
  cost.decompose = true;
  return build_majorant_hierarchy(*fine, 8, cost);
}

}  // namespace

// The typed block entries survive the majorant buffer's packing field for field, whole and
// refined blocks alike, and the walk's bounds read through them contain every fine cell's.
TEST(MajorantHierarchy, TypedEntriesRoundTripThroughTheMajorantBuffer) {
  MajorantGrid fine;
  MajorantHierarchy h = mixed_hierarchy(&fine);
  ASSERT_GT(h.blocks_refined, 0u);
  ASSERT_GT(h.blocks_whole + h.blocks_empty, 0u);
  std::vector<float> words = {7.0f, 7.0f};  // another grid's cell before the entries
  append_majorant_blocks(words, h.blocks);
  ASSERT_EQ(words.size(), 2 + 4 * h.blocks.size());
  for (size_t b = 0; b < h.blocks.size(); ++b) {
    const st_maj_block e = packed_majorant_block(words, 1, b), &want = h.blocks[b];
    ASSERT_EQ(e.group, want.group) << "block " << b;
    ASSERT_EQ(e.pool, want.pool) << "block " << b;
    ASSERT_EQ(e.dmax, want.dmax) << "block " << b;
    ASSERT_EQ(e.dmin, want.dmin) << "block " << b;
    ASSERT_TRUE(e.group == h.block || (e.group >= 1 && h.block % e.group == 0)) << "block " << b;
  }
  EXPECT_THROW(packed_majorant_block(words, 1, h.blocks.size()), Error);
  EXPECT_TRUE(bounds_hold(fine, h));
}

// The twin: a corrupted entry is caught, by the bounds (a whole block's majorant 3% low) or by
// the entry's check (a group edge that does not divide the block, groups past the pool).
TEST(MajorantHierarchy, ACorruptedEntryFailsTheBoundsCheck) {
  MajorantGrid fine;
  const MajorantHierarchy h = mixed_hierarchy(&fine);
  size_t whole = h.blocks.size(), refined = h.blocks.size();
  for (size_t b = 0; b < h.blocks.size(); ++b) {
    if (h.blocks[b].group == h.block && h.blocks[b].dmax > 0.0f && whole == h.blocks.size()) whole = b;
    if (h.blocks[b].group < h.block && refined == h.blocks.size()) refined = b;
  }
  ASSERT_LT(whole, h.blocks.size());
  ASSERT_LT(refined, h.blocks.size());
  MajorantHierarchy low = h;
  low.blocks[whole].dmax *= 0.97f;
  EXPECT_FALSE(bounds_hold(fine, low));
  MajorantHierarchy bad_group = h;
  bad_group.blocks[refined].group = 3;
  EXPECT_THROW(bounds_hold(fine, bad_group), Error);
  MajorantHierarchy bad_pool = h;
  bad_pool.blocks[refined].pool = uint32_t(h.pool.size() / 2);
  EXPECT_THROW(bounds_hold(fine, bad_pool), Error);
}

TEST(MajorantHierarchy, SharedVolumesLookupsLieWithinTheWalksBounds) {
  const std::vector<std::pair<std::string, std::string>> files = {
      {"smoke1.vdb", "density"}, {"wdas_cloud_sixteenth.vdb", "density"}, {"usd/densityAndHeat.vdb", "density"},
      {"derived/smoke1.nvdb", "density"}, {"arnold-usd/torus01.vdb", "voxel_fog_density"}};
  if (!std::filesystem::exists(kShared + "/smoke1.vdb")) GTEST_SKIP() << "no ../shared data";
  std::string dir = temp_dir("hierarchy_shared");
  for (const auto& [name, grid] : files) {
    GridData g = load_float_grid(kShared + "/" + name, grid, -1, name);
    std::mt19937 gen(17);
    std::vector<std::array<float, 3>> world;
    for (int n = 0; n < 60000; ++n) {
      double p[3];
      for (int a = 0; a < 3; ++a) {
        std::uniform_real_distribution<double> u(g.index_min[a] - 1.0, g.index_max[a] + 1.0);
        p[a] = u(gen);
      }
      std::array<float, 3> w;
      for (int r = 0; r < 3; ++r)
        w[r] = float(g.index_to_world[r][0] * p[0] + g.index_to_world[r][1] * p[1] + g.index_to_world[r][2] * p[2] +
                     g.index_to_world[r][3]);
      world.push_back(w);
    }
    for (std::string tracker : {"delta-per-channel", "spectral-decomposition"})
      for (std::string lookup : {"trilinear", "stochastic"})
        for (auto [cell, block] : {std::pair{0, 8}, std::pair{1, 16}, std::pair{4, 4}}) {
          SCOPED_TRACE(name + ", " + tracker + ", " + lookup + ", cell " + std::to_string(cell) + " block " +
                       std::to_string(block));
          json s = step_scene(kShared + "/" + name);
          s["media"][0]["grid"] = grid;
          s["render"]["tracker"] = tracker;
          s["render"]["lookup"] = lookup;
          s["media"][0]["density_scale"] = 40.0;
          RenderOptions o = quiet_options();
          o.majorant_cell = cell;
          o.majorant_block = block;
          Renderer r(scene_from_json(s, dir), o);
          Probe probe(r);
          std::vector<float> v = probe.density(0, world);
          std::vector<std::array<float, 2>> b = probe.majorant(0, world);
          int inside = 0, positive = 0;
          for (size_t i = 0; i < world.size(); ++i) {
            if (b[i][0] < 0.0f) continue;  // outside the majorant box
            ++inside;
            positive += v[i] > 0.0f;
            ASSERT_LE(v[i], b[i][0]) << "a lookup above its group's majorant at point " << i;
            ASSERT_GE(v[i], b[i][1]) << "a lookup below its group's minorant at point " << i;
          }
          EXPECT_GT(inside, 50000);
          EXPECT_GT(positive, 100) << "the points must meet the medium";
        }
  }
}

TEST(MajorantHierarchy, TransmittanceAlongCellGroupAndBlockFacesIsExact) {
  std::string dir = temp_dir("hierarchy_faces");
  write_vdb(dir + "/step.vdb", "density", openvdb::Coord(0), kHi, step_density, kVoxel);
  // optical depth along x at integer index (y, z) inside [0, 63]^2: the density is linear between
  // integer x, so the trapezoid sum over them is exact
  double tau_x = 0;
  for (int i = -1; i <= kHi.x(); ++i) {
    auto d = [](int x) { return (x < 0 || x > kHi.x()) ? 0.0 : double(step_density(x, 0, 0)); };
    tau_x += 0.5 * (d(i) + d(i + 1));
  }
  tau_x *= 0.3 * kVoxel;
  for (int tracker : kTrackers) {
    json s = step_scene("step.vdb");
    s["render"]["tracker"] = tracker_name(tracker);
    RenderOptions o = quiet_options();
    o.majorant_cell = 2;
    o.majorant_block = 8;
    o.majorant_step_cost = 0.002;  // thin enough for exact closed forms, refined where the density changes
    Renderer r(scene_from_json(s, dir), o);
    RenderResult res = r.render();
    ASSERT_EQ(res.majorants.size(), 1u);
    int levels_used = 0;
    for (size_t n : res.majorants[0].blocks_per_level) levels_used += n > 0;
    EXPECT_GE(levels_used, 2) << tracker_name(tracker) << ": the volume must mix levels";
    Probe probe(r);
    // along x: y, z on fine-cell faces (-1 + 2k), on group faces and on block faces (-1 + 16k)
    for (double iy : {15.0, 31.0, 7.0, 21.0})
      for (double iz : {15.0, 47.0, 3.0}) {
        auto T = probe.transmittance({float(-2 * kVoxel), float(iy * kVoxel), float(iz * kVoxel)}, {1, 0, 0}, 3000);
        std::vector<double> vals;
        for (auto& x : T) vals.push_back(x[0]);
        Stats m = mean_se(vals);
        EXPECT_NEAR(m.mean, std::exp(-tau_x), 4 * m.se + 1e-5)
            << tracker_name(tracker) << " along x at index y " << iy << ", z " << iz;
      }
    // along z on a fine-cell face in the interface's block (x = 89), mid-ramp (x = 87.5) and on a
    // block face (x = 63): constant density
    for (auto [ix, dens] : {std::pair{89.0, 3.0}, std::pair{87.5, 2.0}, std::pair{63.0, 1.0}}) {
      auto T = probe.transmittance({float(ix * kVoxel), float(15.0 * kVoxel), float(-2 * kVoxel)}, {0, 0, 1}, 3000);
      std::vector<double> vals;
      for (auto& x : T) vals.push_back(x[0]);
      Stats m = mean_se(vals);
      // 63 voxels of the constant plus the two half-voxel ramps to the background
      const double tau = 0.3 * kVoxel * dens * 64.0;
      EXPECT_NEAR(m.mean, std::exp(-tau), 4 * m.se + 1e-5) << tracker_name(tracker) << " along z at index x " << ix;
    }
  }
}

TEST(MajorantHierarchy, AgreesWithTheOneLevelGridAndSavesSteps) {
  std::string dir = temp_dir("hierarchy_agree");
  write_vdb(dir + "/step.vdb", "density", openvdb::Coord(0), kHi, step_density, kVoxel);
  for (int tracker : {ST_TRACKER_DECOMPOSITION, ST_TRACKER_SPECTRAL_DECOMPOSITION, ST_TRACKER_DELTA}) {
    json s = step_scene("step.vdb");
    s["render"]["tracker"] = tracker_name(tracker);
    RenderOptions one = quiet_options(), adaptive = quiet_options();
    one.majorant_cell = adaptive.majorant_cell = 2;
    one.majorant_block = 0;
    Renderer r1(scene_from_json(s, dir), one), r2(scene_from_json(s, dir), adaptive);
    std::vector<std::array<float, 4>> st1, st2;
    // a diagonal through cell and block corners
    std::array<float, 3> o{float(-kVoxel), float(-kVoxel), float(-kVoxel)}, d{1, 1, 1};
    auto T1 = Probe(r1).transmittance(o, d, 20000, &st1), T2 = Probe(r2).transmittance(o, d, 20000, &st2);
    std::vector<double> a, b;
    double steps1 = 0, steps2 = 0;
    for (size_t i = 0; i < T1.size(); ++i) {
      a.push_back(T1[i][0]);
      b.push_back(T2[i][0]);
      steps1 += st1[i][1];
      steps2 += st2[i][1];
    }
    Stats s1 = mean_se(a), s2 = mean_se(b);
    EXPECT_NEAR(s1.mean, s2.mean, 4 * std::sqrt(s1.se * s1.se + s2.se * s2.se) + 1e-6) << tracker_name(tracker);
    EXPECT_LT(steps2, 0.8 * steps1) << tracker_name(tracker) << ": empty and uniform blocks are walked whole";
  }
}

namespace {

// Walks the DDA segments of medium 0 along (o, d) and checks, at points inside each segment, that
// the host's trilinear density lies within the segment's [dmin, dmax], and that the density is 0
// before the first segment and after the last. Returns the number of segments.
size_t check_segments(Probe& probe, const GridData& g, std::array<float, 3> o, std::array<float, 3> d,
                      const std::string& what) {
  auto segs = probe.segments(0, o, d);
  auto density = [&](double t) {
    double w[3] = {o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]}, idx[3];
    for (int a = 0; a < 3; ++a) idx[a] = (w[a] - g.index_to_world[a][3]) / g.index_to_world[a][a];
    return sample_index_trilinear(g, idx[0], idx[1], idx[2]);
  };
  float prev = -1.0f;
  for (size_t k = 0; k < segs.size(); ++k) {
    const auto& s = segs[k];
    EXPECT_GE(s[1], s[0]) << what << ": segment " << k;
    if (k > 0) EXPECT_EQ(s[0], prev) << what << ": segments must be contiguous at " << k;
    prev = s[1];
    if (!(s[1] > s[0]) || !std::isfinite(s[1])) continue;
    for (double f : {0.001, 0.1, 0.37, 0.5, 0.81, 0.999}) {
      const double t = s[0] + f * (double(s[1]) - s[0]);
      const float v = density(t);
      if (v > s[2] * (1.0f + 1e-4f) + 1e-6f || v < s[3] * (1.0f - 1e-4f) - 1e-6f) {
        ADD_FAILURE() << what << ": density " << v << " at t " << t << " outside segment " << k << " [" << s[0] << ", "
                      << s[1] << ") with bounds [" << s[3] << ", " << s[2] << "]";
        return segs.size();
      }
    }
  }
  if (!segs.empty()) {
    if (segs.front()[0] > 0.0f)  // the ray starts outside the majorant box
      for (double f : {0.0, 0.5, 0.99}) EXPECT_EQ(density(f * segs.front()[0]), 0.0f) << what << ": before the first segment";
    for (double dt : {1e-3, 0.1, 1.0, 10.0}) EXPECT_EQ(density(segs.back()[1] + dt), 0.0f) << what << ": after the last";
  }
  return segs.size();
}

}  // namespace

TEST(MajorantHierarchy, DdaSegmentsBoundTheDensityOnEveryRay) {
  std::string dir = temp_dir("hierarchy_segments");
  write_vdb(dir + "/step.vdb", "density", openvdb::Coord(0), kHi, step_density, kVoxel);
  GridData g = load_float_grid(dir + "/step.vdb", "density", -1, "step");
  const float v = float(kVoxel);
  // axis rays in both directions on fine-cell (-1 + 2k), group and block (-1 + 16k) faces, through
  // the interface's block; diagonals through cell corners in all eight octants
  std::vector<std::pair<std::array<float, 3>, std::array<float, 3>>> rays;
  for (float s : {1.0f, -1.0f}) {
    const float x0 = s > 0 ? -2 * v : 130 * v, z0 = s > 0 ? -2 * v : 66 * v;
    for (float iy : {15.0f, 31.0f, 7.0f, 21.0f, 47.0f})
      for (float iz : {15.0f, 3.0f, 31.0f}) rays.push_back({{x0, iy * v, iz * v}, {s, 0, 0}});
    for (float ix : {89.0f, 87.5f, 79.0f, 95.0f, 63.0f}) rays.push_back({{ix * v, 15 * v, z0}, {0, 0, s}});
  }
  for (int oct = 0; oct < 8; ++oct) {
    std::array<float, 3> d{oct & 1 ? -1.0f : 1.0f, oct & 2 ? -1.0f : 1.0f, oct & 4 ? -1.0f : 1.0f}, o;
    const float ext[3] = {128 * v, 64 * v, 64 * v};
    for (int a = 0; a < 3; ++a) o[a] = d[a] > 0 ? -v : ext[a] - v;
    rays.push_back({o, d});
    std::array<float, 3> o2 = o;
    o2[0] += (d[0] > 0 ? 64 : -64) * v;  // starting inside, on block corners
    rays.push_back({o2, d});
  }
  std::mt19937 gen(5);
  std::normal_distribution<float> n01;
  std::uniform_real_distribution<float> u(-0.5f, 1.5f);
  for (int k = 0; k < 300; ++k) {
    std::array<float, 3> d{n01(gen), n01(gen), n01(gen)};
    rays.push_back({{u(gen) * 128 * v, u(gen) * 64 * v, u(gen) * 64 * v}, d});
  }
  for (auto [cell, block, step_cost] : {std::tuple{2, 8, 0.002}, std::tuple{2, 8, 0.6}, std::tuple{1, 16, 0.01},
                                        std::tuple{2, 0, 0.6}, std::tuple{3, 4, 0.01}}) {
    json s = step_scene("step.vdb");
    s["render"]["tracker"] = "decomposition";
    RenderOptions o = quiet_options();
    o.majorant_cell = cell;
    o.majorant_block = block;
    o.majorant_step_cost = step_cost;
    Renderer r(scene_from_json(s, dir), o);
    Probe probe(r);
    size_t total = 0;
    for (size_t k = 0; k < rays.size(); ++k)
      total += check_segments(probe, g, rays[k].first, rays[k].second,
                              "cell " + std::to_string(cell) + " block " + std::to_string(block) + " step cost " +
                                  std::to_string(step_cost) + ", ray " + std::to_string(k));
    EXPECT_GT(total, rays.size());
  }
}
