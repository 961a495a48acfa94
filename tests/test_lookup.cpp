// test_lookup.cpp: stochastic one-voxel density lookups (st_lookup_mode "stochastic",
// kernels/medium.h grid_stochastic, docs/stochastic-lookup.md) on the renderer's own device
// function (the density probe):
//   - the voxel a lookup reads is one of the 8 of the trilinear support, each with a frequency
//     that a chi-square test accepts against its trilinear weight (and rejects against a wrong
//     weight: the twin), and the mean of the lookups is the trilinear value within 4 SE;
//   - every value read lies within its majorant cell's [minorant, majorant];
//   - specialised and generic kernels render the same image; the feature bit is set only where a
//     stochastic lookup can happen, so a scene without VDB media renders the same image bit for
//     bit in both modes.
// The estimators themselves are checked with stochastic lookups in test_estimators.cpp
// (StochasticLookupsAgreeWithTrilinear), test_render.cpp (free paths, furnaces, constant VDB) and
// test_transmittance.cpp (closed-form profiles).
#include <cmath>
#include <map>

#include "test_util.h"

using namespace spectrack;
using namespace st_test;
using nlohmann::json;

namespace {

constexpr double kVox = 1.0 / 16.0;

// Every 2x2x2 block of voxels holds 8 different values.
float ramp(int i, int j, int k) { return 1.0f + 0.5f * float(i) + 0.05f * float(j) + 0.005f * float(k); }

json probe_scene(const std::string& lookup) {
  return {{"format", "spectrack-scene/1"},
          {"camera", {{"type", "orthographic"}, {"position", {0.5, 0.5, -3}}, {"look_at", {0.5, 0.5, 0.5}}, {"up", {0, 1, 0}}, {"height", 1}}},
          {"film", {{"width", 4}, {"height", 4}, {"spp", 1}}},
          {"render", {{"seed", 11}, {"lookup", lookup}}},
          {"lights", json::array()},
          {"media", {{{"type", "vdb"}, {"file", "ramp.vdb"}, {"sigma_a", {1, 1, 1}}, {"sigma_s", {0, 0, 0}}}}}};
}

// Chi-square statistic of the counts of the 8 corners of index point p against weights with the
// fractions f (corner b = (bx, by, bz): weight prod_a (b_a ? f_a : 1 - f_a)).
double chi_square(const std::map<float, int>& counts, const int i0[3], const double f[3], int n) {
  double chi2 = 0;
  for (int b = 0; b < 8; ++b) {
    int bx = b & 1, by = (b >> 1) & 1, bz = (b >> 2) & 1;
    double w = (bx ? f[0] : 1 - f[0]) * (by ? f[1] : 1 - f[1]) * (bz ? f[2] : 1 - f[2]);
    auto it = counts.find(ramp(i0[0] + bx, i0[1] + by, i0[2] + bz));
    double seen = it == counts.end() ? 0.0 : double(it->second);
    chi2 += (seen - n * w) * (seen - n * w) / (n * w);
  }
  return chi2;
}

}  // namespace

TEST(StochasticLookup, VoxelFrequenciesAreTheTrilinearWeights) {
  std::string dir = temp_dir("stochastic_voxels");
  write_vdb(dir + "/ramp.vdb", "density", openvdb::Coord(0, 0, 0), openvdb::Coord(15, 15, 15), ramp, kVox);
  Renderer r(scene_from_json(probe_scene("stochastic"), dir), quiet_options());
  // index points: inside a leaf, across the leaf faces at 7|8 on every axis, elsewhere
  const double points[][3] = {{1.3, 2.6, 3.45}, {7.5, 7.25, 7.7}, {10.2, 4.8, 12.35}, {5.65, 11.4, 0.55}};
  const int n = 40000;
  std::vector<std::array<float, 3>> world;
  for (auto& p : points)
    for (int k = 0; k < n; ++k) world.push_back({float(p[0] * kVox), float(p[1] * kVox), float(p[2] * kVox)});
  Probe probe(r);
  std::vector<float> v = probe.density(0, world);
  std::vector<std::array<float, 2>> bounds = probe.majorant(0, world);
  ASSERT_EQ(v.size(), world.size());
  const double crit = 29.88;  // chi-square, 7 degrees of freedom, alpha = 1e-4
  for (size_t pi = 0; pi < std::size(points); ++pi) {
    const double* p = points[pi];
    int i0[3];
    double f[3];
    for (int a = 0; a < 3; ++a) i0[a] = int(std::floor(p[a])), f[a] = p[a] - std::floor(p[a]);
    std::map<float, int> counts;
    std::vector<double> values;
    for (int k = 0; k < n; ++k) {
      size_t idx = pi * n + k;
      counts[v[idx]] += 1;
      values.push_back(v[idx]);
      ASSERT_LE(v[idx], bounds[idx][0]) << "a voxel read above its cell's majorant at point " << pi;
      ASSERT_GE(v[idx], bounds[idx][1]) << "a voxel read below its cell's minorant at point " << pi;
    }
    // every value read is one of the 8 voxels of the support
    int corners_seen = 0;
    for (int b = 0; b < 8; ++b) corners_seen += counts.count(ramp(i0[0] + (b & 1), i0[1] + ((b >> 1) & 1), i0[2] + ((b >> 2) & 1)));
    EXPECT_EQ(corners_seen, 8) << "point " << pi;
    EXPECT_EQ(counts.size(), 8u) << "point " << pi << ": a value that is not a voxel of the trilinear support";
    double chi2 = chi_square(counts, i0, f, n);
    EXPECT_LT(chi2, crit) << "point " << pi << ": the voxel frequencies are not the trilinear weights";
    // the twin: the same statistic rejects mirrored weights (1 - f for f on the axis whose
    // fraction is farthest from 1/2)
    int axis = 0;
    for (int a = 1; a < 3; ++a)
      if (std::abs(f[a] - 0.5) > std::abs(f[axis] - 0.5)) axis = a;
    double mirrored[3] = {f[0], f[1], f[2]};
    mirrored[axis] = 1 - f[axis];
    EXPECT_GT(chi_square(counts, i0, mirrored, n), crit) << "point " << pi << ": the chi-square test cannot fail";
    // the mean is the trilinear value
    double tri = 0;
    for (int b = 0; b < 8; ++b) {
      int bx = b & 1, by = (b >> 1) & 1, bz = (b >> 2) & 1;
      tri += (bx ? f[0] : 1 - f[0]) * (by ? f[1] : 1 - f[1]) * (bz ? f[2] : 1 - f[2]) * ramp(i0[0] + bx, i0[1] + by, i0[2] + bz);
    }
    Stats s = mean_se(values);
    EXPECT_NEAR(s.mean, tri, 4 * s.se + 1e-5) << "point " << pi;
  }
  // trilinear lookups at the same points give the trilinear value (no draw, no spread)
  Renderer t(scene_from_json(probe_scene("trilinear"), dir), quiet_options());
  std::vector<float> vt = Probe(t).density(0, {world[0], world[n]});
  EXPECT_NEAR(vt[0], ramp(1, 2, 3) + 0.5 * 0.3 + 0.05 * 0.6 + 0.005 * 0.45, 1e-5);
  EXPECT_NEAR(vt[1], ramp(7, 7, 7) + 0.5 * 0.5 + 0.05 * 0.25 + 0.005 * 0.7, 1e-5);
}

// Kernels: the stochastic-lookup code is compiled in only where a VDB lookup can be stochastic;
// specialised and generic kernels render the same image; a scene of homogeneous media only has no
// lookup to randomise and renders the same image bit for bit in both modes.
TEST(StochasticLookup, KernelsAndFeatureBit) {
  std::string dir = temp_dir("stochastic_kernels");
  write_lumpy(dir + "/lumps.vdb");
  json s = {{"format", "spectrack-scene/1"},
            {"camera", {{"type", "perspective"}, {"position", {0.3, 0.2, -3}}, {"look_at", {0, 0, 0}}, {"up", {0, 1, 0}}, {"fov_deg", 32}}},
            {"film", {{"width", 12}, {"height", 12}, {"spp", 4}}},
            {"render", {{"seed", 3}}},
            {"lights", {{{"type", "environment"}, {"radiance", {0.3, 0.4, 0.6}}}}},
            {"media", {{{"type", "vdb"}, {"file", "lumps.vdb"}, {"density_scale", 6.0}, {"sigma_a", {0.2, 0.5, 1.0}},
                        {"sigma_s", {2.0, 1.0, 0.4}}}}}};
  auto render = [&](const json& scene, int lookup, bool generic) {
    RenderOptions o = quiet_options();
    o.lookup = lookup;
    o.generic_kernels = generic;
    return Renderer(scene_from_json(scene, dir), o).render();
  };
  RenderResult tri = render(s, ST_LOOKUP_TRILINEAR, false);
  RenderResult sto = render(s, ST_LOOKUP_STOCHASTIC, false);
  RenderResult sto_generic = render(s, ST_LOOKUP_STOCHASTIC, true);
  EXPECT_FALSE(tri.features & ST_FEATURE_STOCHASTIC_LOOKUP);
  EXPECT_TRUE(sto.features & ST_FEATURE_STOCHASTIC_LOOKUP);
  EXPECT_EQ(sto_generic.features, uint32_t(ST_FEATURES_ALL));
  EXPECT_EQ(sto.rgb, sto_generic.rgb) << "specialised and generic kernels must render the same image";
  EXPECT_EQ(sto.stats.lookups_track, sto_generic.stats.lookups_track);
  EXPECT_NE(sto.rgb, tri.rgb) << "stochastic lookups must change the image of a VDB (else the comparison is blind)";
  EXPECT_EQ(sto.lookup, ST_LOOKUP_STOCHASTIC);
  EXPECT_EQ(tri.lookup, ST_LOOKUP_TRILINEAR);

  json h = s;
  h["media"] = {{{"type", "homogeneous"}, {"bounds", {{-0.8, -0.3, -0.5}, {0.6, 0.2, 0.9}}}, {"sigma_a", {0.5, 0.2, 0.1}},
                 {"sigma_s", {0.5, 1.5, 2.5}}}};
  RenderResult htri = render(h, ST_LOOKUP_TRILINEAR, false);
  RenderResult hsto = render(h, ST_LOOKUP_STOCHASTIC, false);
  EXPECT_FALSE(hsto.features & ST_FEATURE_STOCHASTIC_LOOKUP) << "no VDB medium: nothing to randomise";
  EXPECT_EQ(htri.rgb, hsto.rgb);
  EXPECT_EQ(render(h, ST_LOOKUP_STOCHASTIC, true).rgb, htri.rgb) << "the generic kernel draws nothing for homogeneous media";
}
