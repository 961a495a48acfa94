// test_sphere_light.cpp: sphere lights (kernels/light.h, track.cl): seen directly (its radiance,
// opaque for alpha), through an absorbing slab (radiance x exp(-sigma_a d)), single scattering in a
// homogeneous medium against a numerical integral of the light it receives (cone sampling and phase
// sampling combined by MIS), in several trackers and in spectral mode; refusals; the feature mask.
//
// Design: as test_local_lights.cpp: an orthographic camera of tiny extent, so that every pixel is
// one independent estimate of the same value; 4 standard errors, and a twin check that a 3% error
// is seen. Exact estimates (a sphere seen through vacuum) use a small relative tolerance instead.
#include <cmath>
#include <functional>

#include "scene/scene_pack.h"
#include "test_util.h"

using namespace spectrack;
using namespace st_test;
using nlohmann::json;

namespace {

const double kC[3] = {0.5, 0.2, 0.1}, kR = 0.2;  // the sphere inside the box [-1, 1]^3
const double kSigmaA[3] = {0.3, 0.2, 0.1}, kSigmaS[3] = {0.5, 1.0, 2.0};
const double kL[3] = {2.0, 3.0, 4.0};

json sphere_light(const double L[3] = kL) {
  return {{"type", "sphere"}, {"position", {kC[0], kC[1], kC[2]}}, {"radius", kR}, {"radiance", {L[0], L[1], L[2]}}};
}

json scene_with(const json& light, const json& camera, int spp) {
  return {{"format", "spectrack-scene/1"},
          {"camera", camera},
          {"film", {{"width", 16}, {"height", 16}, {"spp", spp}}},
          {"render", {{"seed", 5}}},
          {"lights", {light}}};
}

json ortho(const std::array<double, 3>& from, const std::array<double, 3>& at) {
  return {{"type", "orthographic"}, {"position", {from[0], from[1], from[2]}}, {"look_at", {at[0], at[1], at[2]}},
          {"up", {0, 1, 0}}, {"height", 1e-3}};
}

void expect_values(const RenderResult& r, const double expected[3], bool twin, const std::string& what, double rel) {
  EXPECT_EQ(r.stats.nonfinite_samples, 0u) << what;
  for (int c = 0; c < 3; ++c) {
    Stats m = mean_se(channel(r, c));
    const double tol = 4 * m.se + rel * expected[c];
    EXPECT_NEAR(m.mean, expected[c], tol) << what << ", channel " << c << " (SE " << m.se << ")";
    if (twin) EXPECT_GT(std::abs(m.mean - 1.03 * expected[c]), tol) << what << ": must detect a 3% error, channel " << c;
  }
}

// The single-scattering line integral along x = y = 0, z in [-1, 1] of an isotropic homogeneous
// medium lit by the sphere: at distance D from the centre the sphere fills the cone theta <
// asin(r / D), and a direction at theta reaches its surface after s = D cos theta -
// sqrt(r^2 - D^2 sin^2 theta), so the in-scattered radiance is sigma_s / (4 pi) L 2 pi
// int exp(-sigma_t s) sin theta dtheta. Simpson's rule in both variables.
double single_scattering(double sa, double ss, double L) {
  const double st = sa + ss;
  auto simpson = [](const std::function<double(double)>& f, double a, double b, int n) {
    const double h = (b - a) / n;
    double sum = f(a) + f(b);
    for (int i = 1; i < n; ++i) sum += f(a + i * h) * (i % 2 ? 4 : 2);
    return sum * h / 3;
  };
  auto in_scattered = [&](double z) {
    const double dz = kC[2] - z, D = std::sqrt(kC[0] * kC[0] + kC[1] * kC[1] + dz * dz);
    const double theta_max = std::asin(kR / D);
    const double cone = simpson(
        [&](double th) {
          const double s = D * std::cos(th) - std::sqrt(std::max(0.0, kR * kR - D * D * std::sin(th) * std::sin(th)));
          return std::exp(-st * s) * std::sin(th);
        },
        0, theta_max, 400);
    return ss / (4 * M_PI) * L * 2 * M_PI * cone;
  };
  return simpson([&](double z) { return std::exp(-st * (z + 1)) * in_scattered(z); }, -1, 1, 2000);
}

// Seen straight from the camera: its radiance, exactly, opaque for alpha; in spectral mode a gray
// radiance (the film colour of L D65 is L).
TEST(SphereLight, SeenDirectlyIsItsRadiance) {
  const std::string dir = temp_dir("sphere_direct");
  for (const char* tracker : {"spectral-decomposition", "delta-per-channel", "spectral-mis"}) {
    json s = scene_with(sphere_light(), ortho({kC[0], kC[1], -3}, {kC[0], kC[1], 0}), 2);
    s["render"]["tracker"] = tracker;
    RenderOptions o = quiet_options();
    o.aovs = ST_AOV_BIT(ALPHA) | ST_AOV_BIT(ENVIRONMENT) | ST_AOV_BIT(EMISSION);
    RenderResult r = Renderer(scene_from_json(s, dir), o).render();
    EXPECT_TRUE(r.features & ST_FEATURE_SPHERE_LIGHT);
    EXPECT_FALSE(r.features & ST_FEATURE_ESCAPE) << "no escaping ray sees a sphere light";
    expect_values(r, kL, true, tracker, 1e-5);
    const size_t na = r.aov_channels.size();
    for (size_t i = 0; i < r.sum.size() / 3; ++i) {
      EXPECT_EQ(r.aov_sum[i * na + 0], double(r.spp_done)) << "opaque: alpha 1";
      EXPECT_NEAR(r.aov_sum[i * na + 6], r.sum[i * 3], 1e-5 * r.sum[i * 3]) << "the emission pass";
    }
  }
  const double gray[3] = {3, 3, 3};
  json s = scene_with(sphere_light(gray), ortho({kC[0], kC[1], -3}, {kC[0], kC[1], 0}), 2);
  s["render"]["color"] = "spectral";
  expect_values(Renderer(scene_from_json(s, dir), quiet_options()).render(), gray, false, "spectral", 1e-4);
}

// Through a slab of absorbing medium of thickness d: L exp(-sigma_a d) per channel.
TEST(SphereLight, ThroughAnAbsorbingSlabIsAttenuated) {
  const std::string dir = temp_dir("sphere_slab");
  const double d = 0.6;
  for (const char* tracker : {"spectral", "delta-per-channel"}) {
    json s = scene_with(sphere_light(), ortho({kC[0], kC[1], -3}, {kC[0], kC[1], 0}), 256);
    s["render"]["tracker"] = tracker;
    s["media"] = {{{"type", "homogeneous"}, {"bounds", {{-2, -2, -2}, {2, 2, -2 + d}}},
                   {"sigma_a", {kSigmaA[0] * 4, kSigmaA[1] * 4, kSigmaA[2] * 4}}, {"sigma_s", {0, 0, 0}}}};
    RenderResult r = Renderer(scene_from_json(s, dir), quiet_options()).render();
    double expected[3];
    for (int c = 0; c < 3; ++c) expected[c] = kL[c] * std::exp(-4 * kSigmaA[c] * d);
    expect_values(r, expected, true, tracker, 1e-6);
  }
}

// Single scattering (max_depth 1) from the sphere inside a homogeneous box: light sampling in the
// cone and phase sampling, combined by MIS, against the integral; several trackers, transmittance
// estimators and light-sampling modes (with a second light, so one-light sampling chooses), and
// with equi-angular sampling towards the sphere's centre (kernels/equiangular.h; its twin too).
TEST(SphereLight, SingleScatteringMatchesTheIntegral) {
  const std::string dir = temp_dir("sphere_single");
  struct Case {
    int tracker, transmittance, light_sampling, equiangular;
  } cases[] = {{ST_TRACKER_SPECTRAL_DECOMPOSITION, ST_TRANSMITTANCE_RATIO, ST_LIGHT_SAMPLING_ALL, kEquiangularOff},
               {ST_TRACKER_DELTA_PER_CHANNEL, ST_TRANSMITTANCE_RAY_MARCHING, ST_LIGHT_SAMPLING_POWER, kEquiangularOff},
               {ST_TRACKER_SPECTRAL_MIS, ST_TRANSMITTANCE_RATIO, ST_LIGHT_SAMPLING_CONTRIBUTION, kEquiangularOff},
               {ST_TRACKER_SPECTRAL_DECOMPOSITION, ST_TRANSMITTANCE_RATIO, ST_LIGHT_SAMPLING_ALL, kEquiangularOn},
               {ST_TRACKER_DELTA_PER_CHANNEL, ST_TRANSMITTANCE_RAY_MARCHING, ST_LIGHT_SAMPLING_POWER, kEquiangularOn}};
  for (const Case& c : cases) {
    const bool twin = &c == &cases[0] || &c == &cases[3];
    json s = scene_with(sphere_light(), ortho({0, 0, -3}, {0, 0, 0}), twin ? 2048 : 512);
    s["render"]["max_depth"] = 1;
    s["media"] = {{{"type", "homogeneous"}, {"bounds", {{-1, -1, -1}, {1, 1, 1}}},
                   {"sigma_a", {kSigmaA[0], kSigmaA[1], kSigmaA[2]}}, {"sigma_s", {kSigmaS[0], kSigmaS[1], kSigmaS[2]}}}};
    if (c.light_sampling != ST_LIGHT_SAMPLING_ALL)  // a dark second light: one-light sampling must pick
      s["lights"].push_back({{"type", "point"}, {"position", {-3, 0, 0}}, {"intensity", {0, 0, 0}}});
    RenderOptions o = quiet_options();
    o.tracker = c.tracker;
    o.transmittance = c.transmittance;
    o.light_sampling = c.light_sampling;
    o.equiangular = c.equiangular;
    RenderResult r = Renderer(scene_from_json(s, dir), o).render();
    EXPECT_EQ(bool(r.features & ST_FEATURE_EQUIANGULAR), c.equiangular == kEquiangularOn);
    double expected[3];
    for (int ch = 0; ch < 3; ++ch) expected[ch] = single_scattering(kSigmaA[ch], kSigmaS[ch], kL[ch]);
    expect_values(r, expected, twin, std::string(tracker_name(c.tracker)) + (c.equiangular ? ", equi-angular" : ""), 1e-4);
  }
}

// Bad fields are refused by path; a scene without a sphere compiles no sphere code, and the
// generic kernel renders a sphere scene's bits.
TEST(SphereLight, RefusalsFeatureMaskAndGenericKernels) {
  const std::string dir = temp_dir("sphere_bad");
  auto error = [&](const json& light) { return error_of([&] { scene_from_json(scene_with(light, ortho({0, 0, -3}, {0, 0, 0}), 1), dir); }); };
  EXPECT_NE(error({{"type", "sphere"}, {"position", {0, 0, 0}}}).find("/lights/0/radius: missing required field"),
            std::string::npos);
  EXPECT_NE(error({{"type", "sphere"}, {"position", {0, 0, 0}}, {"radius", 0}}).find("/lights/0/radius: value 0 is out of range"),
            std::string::npos);
  EXPECT_NE(error({{"type", "sphere"}, {"position", {0, 0, 0}}, {"radius", 1}, {"intensity", {1, 1, 1}}})
                .find("/lights/0/intensity: field not allowed for a sphere light"),
            std::string::npos);
  EXPECT_NE(error({{"type", "sphere"}, {"radius", 1}}).find("/lights/0/position: missing required field"), std::string::npos);
  json s = scene_with(sphere_light(), {{"type", "perspective"}, {"position", {0, 0.5, -3}}, {"look_at", {0, 0, 0}}, {"up", {0, 1, 0}}}, 4);
  s["media"] = {{{"type", "homogeneous"}, {"bounds", {{-1, -1, -1}, {1, 1, 1}}}, {"sigma_a", {0.1, 0.1, 0.1}},
                 {"sigma_s", {1, 1, 1}}, {"phase", {{"type", "hg"}, {"g", 0.3}}}}};
  s["lights"].push_back({{"type", "directional"}, {"to_light", {0, 1, 0}}, {"irradiance", {1, 1, 1}}});
  RenderOptions a = quiet_options();
  a.light_sampling = ST_LIGHT_SAMPLING_CONTRIBUTION;
  RenderOptions b = a;
  b.generic_kernels = true;
  RenderResult ra = Renderer(scene_from_json(s, dir), a).render();
  RenderResult rb = Renderer(scene_from_json(s, dir), b).render();
  EXPECT_EQ(ra.rgb, rb.rgb);
  json none = s;
  none["lights"] = {s["lights"][1]};
  SceneDesc d = scene_from_json(none, dir);
  EXPECT_FALSE(pack_scene(d, resolve_settings(d, quiet_options()), PackOptions{}).features & ST_FEATURE_SPHERE_LIGHT);
}

}  // namespace
