// test_transmittance.cpp: the ray-marching transmittance estimator (kernels/tracking.h,
// docs/transmittance.md) against closed forms and against ratio tracking, on the probe of the
// renderer's own device function. Closed forms: a constant box (the estimator must be exact:
// zero variance up to float rounding), a linear ramp and an exponential profile (VDB grids whose
// trilinear interpolation along the probe ray is piecewise linear, so the optical depth is a
// finite sum). Tolerances are 4 standard errors of the estimates themselves; every comparison has
// a twin that a 3% error in the reference fails.
#include <cmath>

#include "test_util.h"

using namespace spectrack;
using namespace st_test;
using nlohmann::json;

namespace {

constexpr double kVox = 1.0 / 16.0;

// A VDB whose density depends on the x index only: v(i) for i in [0, 63], y and z in [0, 7].
// Along a ray in +x at interior y, z the trilinear density is piecewise linear between integer
// x indices and 0 at indices -1 and 64, so tau = sigma_t * voxel * sum_i v(i).
double write_profile(const std::string& path, const std::function<double(int)>& v) {
  write_vdb(path, "density", openvdb::Coord(0, 0, 0), openvdb::Coord(63, 7, 7), [&](int i, int, int) { return float(v(i)); },
            kVox);
  double sum = 0;
  for (int i = 0; i < 64; ++i) sum += double(float(v(i)));
  return sum * kVox;
}

json probe_scene() {
  return {{"format", "spectrack-scene/1"},
          {"camera", {{"type", "orthographic"}, {"position", {0, 0, -3}}, {"look_at", {0, 0, 0}}, {"up", {0, 1, 0}}, {"height", 1}}},
          {"film", {{"width", 4}, {"height", 4}, {"spp", 1}}},
          {"render", {{"seed", 5}}},
          {"lights", json::array()},
          {"media", json::array()}};
}

struct Estimate {
  Stats T[3];
  double lookups = 0;  // per estimate
};

Estimate run(const json& s, const std::string& dir, int tracker, int transmittance, std::array<float, 3> o,
             std::array<float, 3> d, int n, int budget = 256, int lookup = ST_LOOKUP_TRILINEAR,
             int majorant_cell = 0) {
  RenderOptions opt = quiet_options();
  opt.lookup = lookup;
  opt.majorant_cell = majorant_cell;
  if (majorant_cell > 0) opt.majorant_block = 0;  // one level of those cells
  opt.tracker = tracker;
  opt.transmittance = transmittance;
  opt.iteration_budget = budget;
  Renderer r(scene_from_json(s, dir), opt);
  std::vector<std::array<float, 4>> stats;
  auto T = Probe(r).transmittance(o, d, n, &stats);
  Estimate e;
  for (int c = 0; c < 3; ++c) {
    std::vector<double> v;
    for (auto& x : T) {
      EXPECT_TRUE(std::isfinite(x[c])) << tracker_name(tracker);
      v.push_back(x[c]);
    }
    e.T[c] = mean_se(v);
  }
  for (auto& x : stats) e.lookups += x[0];
  e.lookups /= double(std::max(1, n));
  return e;
}

const int kTrackers[] = {ST_TRACKER_DELTA_PER_CHANNEL, ST_TRACKER_SPECTRAL, ST_TRACKER_SPECTRAL_DECOMPOSITION,
                         ST_TRACKER_SPECTRAL_MIS};

}  // namespace

TEST(RayMarching, ConstantBoxIsExact) {
  std::string dir = temp_dir("rm_box");
  json s = probe_scene();
  s["media"].push_back({{"type", "homogeneous"}, {"bounds", {{-1, -1, -0.6}, {1, 1, 0.6}}}, {"sigma_a", {0.3, 0.6, 1.2}},
                        {"sigma_s", {0.2, 0.4, 0.3}}});
  const double st[3] = {0.5, 1.0, 1.5};
  for (int tracker : kTrackers) {
    Estimate e = run(s, dir, tracker, ST_TRANSMITTANCE_RAY_MARCHING, {0.1f, 0.2f, -2}, {0, 0, 1}, 2000);
    for (int c = 0; c < 3; ++c) {
      double exact = std::exp(-st[c] * 1.2);
      EXPECT_NEAR(e.T[c].mean, exact, 2e-5) << tracker_name(tracker) << " channel " << c;
      EXPECT_LT(e.T[c].se, 1e-6) << tracker_name(tracker) << " channel " << c << ": zero variance expected";
    }
  }
}

TEST(RayMarching, ClosedFormProfiles) {
  std::string dir = temp_dir("rm_profiles");
  struct Profile {
    const char* name;
    std::function<double(int)> v;
  };
  const Profile profiles[] = {{"linear ramp", [](int i) { return 0.05 + 0.03 * i; }},
                              {"exponential", [](int i) { return 2.0 * std::exp(-i / 12.0); }}};
  const double sig[3] = {0.4, 1.0, 2.0};
  for (const Profile& p : profiles) {
    double tau1 = write_profile(dir + "/profile.vdb", p.v);
    json s = probe_scene();
    s["media"].push_back({{"type", "vdb"}, {"file", "profile.vdb"}, {"sigma_a", {sig[0], sig[1], sig[2]}}, {"sigma_s", {0, 0, 0}}});
    // stochastic one-voxel lookups (docs/stochastic-lookup.md) for two of the trackers
    for (int tracker : kTrackers)
      for (int mode : {ST_TRANSMITTANCE_RATIO, ST_TRANSMITTANCE_RAY_MARCHING})
        for (int lookup : {ST_LOOKUP_TRILINEAR, ST_LOOKUP_STOCHASTIC}) {
          if (lookup == ST_LOOKUP_STOCHASTIC && tracker != ST_TRACKER_DELTA_PER_CHANNEL &&
              tracker != ST_TRACKER_SPECTRAL_DECOMPOSITION)
            continue;
          // one level of 8-voxel cells: the twin's power was sized on them; the default hierarchy
          // walks this thin ramp in whole 16-voxel blocks, whose looser bounds give ray marching
          // about twice the variance (docs/majorant-hierarchy.md)
          Estimate e = run(s, dir, tracker, mode, {-1.0f, 3.5f / 16.0f, 3.5f / 16.0f}, {1, 0, 0}, 20000, 256, lookup, 8);
          for (int c = 0; c < 3; ++c) {
            double exact = std::exp(-sig[c] * tau1);
            const Stats& m = e.T[c];
            EXPECT_NEAR(m.mean, exact, 4 * m.se + 1e-6) << p.name << ", " << tracker_name(tracker) << ", "
                                                        << transmittance_name(mode) << ", " << lookup_name(lookup)
                                                        << " lookups, channel " << c;
            if (mode == ST_TRANSMITTANCE_RAY_MARCHING)  // the twin: a 3% error is seen
              EXPECT_GT(std::abs(m.mean - 1.03 * exact), 4 * m.se)
                  << p.name << ", " << tracker_name(tracker) << ", " << lookup_name(lookup) << ", channel " << c
                  << ": too noisy to see a 3% error";
          }
        }
  }
}

TEST(RayMarching, AgreesWithRatioTrackingOnAHeterogeneousVolume) {
  std::string dir = temp_dir("rm_lumpy");
  write_lumpy(dir + "/lumps.vdb");
  json s = probe_scene();
  s["media"].push_back({{"type", "vdb"}, {"file", "lumps.vdb"}, {"density_scale", 1.0}, {"sigma_a", {0.2, 0.5, 1.0}},
                        {"sigma_s", {2.0, 1.0, 0.4}}});
  // a second, overlapping medium, so the residual and the control come from two media
  s["media"].push_back({{"type", "homogeneous"}, {"bounds", {{-0.8, -0.3, -0.5}, {0.6, 0.2, 0.9}}}, {"sigma_a", {0.1, 0.05, 0.02}},
                        {"sigma_s", {0.1, 0.3, 0.5}}});
  for (int tracker : kTrackers) {
    std::array<float, 3> o{-1.5f, 0.1f, 0.05f}, d{1, 0.05f, 0.1f};
    Estimate ratio = run(s, dir, tracker, ST_TRANSMITTANCE_RATIO, o, d, 40000);
    Estimate rm = run(s, dir, tracker, ST_TRANSMITTANCE_RAY_MARCHING, o, d, 20000);
    Estimate rm_resumed = run(s, dir, tracker, ST_TRANSMITTANCE_RAY_MARCHING, o, d, 20000, 3);  // tiny budget: resumed often
    for (int c = 0; c < 3; ++c) {
      double se = std::hypot(ratio.T[c].se, rm.T[c].se);
      EXPECT_NEAR(rm.T[c].mean, ratio.T[c].mean, 4 * se) << tracker_name(tracker) << " channel " << c;
      EXPECT_GT(std::abs(rm.T[c].mean - 1.03 * ratio.T[c].mean), 4 * se)
          << tracker_name(tracker) << " channel " << c << ": the comparison cannot see a 3% error";
      EXPECT_NEAR(rm_resumed.T[c].mean, ratio.T[c].mean, 4 * std::hypot(ratio.T[c].se, rm_resumed.T[c].se))
          << tracker_name(tracker) << " channel " << c << " (budget 3)";
      // the point of the estimator: far less variance per lookup
      double eff_ratio = 1.0 / (ratio.T[c].se * ratio.T[c].se * 40000 * ratio.lookups);
      double eff_rm = 1.0 / (rm.T[c].se * rm.T[c].se * 20000 * rm.lookups);
      EXPECT_GT(eff_rm, eff_ratio) << tracker_name(tracker) << " channel " << c << ": variance x lookups, ratio "
                                   << 1 / eff_ratio << " vs ray marching " << 1 / eff_rm;
    }
  }
}

TEST(RayMarching, DenseRaysStayCheapAndFinite) {
  // optical depth 60 in the blue channel: the pilot's roulette ends most estimates early
  std::string dir = temp_dir("rm_dense");
  json s = probe_scene();
  s["media"].push_back({{"type", "vdb"}, {"file", "lumps.vdb"}, {"density_scale", 60.0}, {"sigma_a", {0.02, 0.3, 1.0}},
                        {"sigma_s", {0.1, 0.5, 1.0}}});
  write_lumpy(dir + "/lumps.vdb");
  for (int tracker : kTrackers) {
    std::array<float, 3> o{-1.5f, 0.0f, 0.02f}, d{1, 0, 0};
    Estimate ratio = run(s, dir, tracker, ST_TRANSMITTANCE_RATIO, o, d, 20000);
    Estimate rm = run(s, dir, tracker, ST_TRANSMITTANCE_RAY_MARCHING, o, d, 20000);
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(rm.T[c].mean, ratio.T[c].mean, 4 * std::hypot(ratio.T[c].se, rm.T[c].se) + 1e-9)
          << tracker_name(tracker) << " channel " << c;
    EXPECT_LT(rm.lookups, 3.0 * ratio.lookups + 20) << tracker_name(tracker);
  }
  // bounds that do not hold: a minorant scaled far above the data makes the residual negative
  // (exp(-tau_c) alone would overflow), a majorant scaled below it makes f > 1; still finite and
  // the same mean as ratio tracking
  s["media"][0]["minorant_scale"] = 4.0;
  s["media"][0]["majorant_scale"] = 0.5;
  for (int tracker : {ST_TRACKER_DECOMPOSITION, ST_TRACKER_SPECTRAL_DECOMPOSITION}) {
    std::array<float, 3> o{-1.5f, 0.0f, 0.02f}, d{1, 0, 0};
    Estimate ratio = run(s, dir, tracker, ST_TRANSMITTANCE_RATIO, o, d, 20000);
    Estimate rm = run(s, dir, tracker, ST_TRANSMITTANCE_RAY_MARCHING, o, d, 20000);
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(rm.T[c].mean, ratio.T[c].mean, 4 * std::hypot(ratio.T[c].se, rm.T[c].se) + 1e-9)
          << "non-bounding, " << tracker_name(tracker) << " channel " << c;
  }
}

TEST(RayMarching, OptionsAreChecked) {
  std::string dir = temp_dir("rm_options");
  json s = probe_scene();
  s["render"]["transmittance"] = "ray-marching";
  EXPECT_EQ(resolve_settings(scene_from_json(s, dir), quiet_options()).transmittance, ST_TRANSMITTANCE_RAY_MARCHING);
  s["render"]["transmittance"] = "marching";
  try {
    scene_from_json(s, dir);
    ADD_FAILURE() << "unknown estimator accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("/render/transmittance"), std::string::npos) << e.what();
  }
  s["render"].erase("transmittance");
  RenderOptions o = quiet_options();
  o.march_spacing = 0.0;
  EXPECT_THROW(resolve_settings(scene_from_json(s, dir), o), Error);
  o.march_spacing = 1.0;
  o.pilot_spacing = std::nan("");
  EXPECT_THROW(resolve_settings(scene_from_json(s, dir), o), Error);
}
