// test_camera.cpp: the thin lens, the shutter and camera motion (docs/scene-format.md, "Lens and
// time").
//
// The analytic scene: an opaque half plane (a thin homogeneous absorber, optical depth 100) in
// front of a uniform environment of radiance 1, seen along +z, covering the image's left half. A pixel's value is the
// fraction of its camera rays that pass beside the plane's edge:
//   - thin lens, orthographic or perspective: a ray of focal-plane point X passes the edge's depth
//     at X + c l_x (l uniform on the unit disc, c the circle of confusion measured on the focal
//     plane), so the fraction is g(X / c) = 1 - (acos(s) - s sqrt(1 - s^2)) / pi, s = X / c clamped
//     to [-1, 1]; in focus (c = 0) it is the sharp step;
//   - a camera moving sideways by 2a across the shutter: the fraction is clamp((X + a) / 2a).
// Each row is an independent estimate of the same column profile, so every column's mean over
// the rows is checked within 4 SE, and so is the row sum of |profile - step| (the light the blur
// moves across the edge: 4c / (3 pi) for the lens, a / 2 for the motion), whose twin with a 3%
// larger c or a must fail.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <string>

#include "scene/scene_pack.h"
#include "test_util.h"

using namespace spectrack;
using namespace st_test;
using json = nlohmann::json;

namespace {

constexpr int kSize = 32;              // film width and height (pixels)
constexpr double kHalf = 1.0;          // half the frame on the focal plane (world units)
constexpr double kPixel = 2 * kHalf / kSize;
constexpr double kPlaneDepth = 5.0;    // the half plane's depth in front of the camera

// The opaque half plane x > 0 at z = 0, the camera at z = -5 looking along +z with y up: its right
// is world -x, so the plane covers the image's left half.
json edge_scene(const std::string& type, int spp) {
  json cam = {{"type", type}, {"position", {0, 0, -kPlaneDepth}}, {"look_at", {0, 0, 0}}, {"up", {0, 1, 0}}};
  if (type == "orthographic") cam["height"] = 2 * kHalf;
  return json{{"format", "spectrack-scene/1"},
              {"camera", cam},
              {"film", {{"width", kSize}, {"height", kSize}, {"spp", spp}}},
              {"render", {{"tracker", "spectral"}, {"seed", 11}}},
              {"lights", {{{"type", "environment"}, {"radiance", {1, 1, 1}}}}},
              {"media",
               {{{"type", "homogeneous"}, {"bounds", {{0, -40, -0.005}, {40, 40, 0.005}}}, {"sigma_a", {1e4, 1e4, 1e4}},
                 {"sigma_s", {0, 0, 0}}}}}};
}

// A perspective camera whose frame spans [-kHalf, kHalf] on the plane at depth `focus`.
void perspective_frame(json& s, double focus) {
  s["camera"]["fov_deg"] = 2.0 * std::atan(kHalf / focus) * 180.0 / M_PI;
}

// The fraction of a uniform unit disc with x > -s.
double disc_beside(double s) {
  s = std::clamp(s, -1.0, 1.0);
  return 1.0 - (std::acos(s) - s * std::sqrt(1.0 - s * s)) / M_PI;
}

// Column x's expected value: profile(X) averaged over the pixel (X on the focal plane).
template <class F>
double pixel_mean(int x, const F& profile) {
  const int n = 64;
  double sum = 0;
  for (int k = 0; k < n; ++k) sum += profile((x + (k + 0.5) / n) * kPixel - kHalf);
  return sum / n;
}

struct EdgeCheck {
  double worst_z = 0;     // largest |column mean - expected| / SE over the columns
  Stats moved;            // per row: sum over columns of |value - step| * pixel width
};

template <class F>
EdgeCheck check_edge(const RenderResult& r, const F& profile) {
  EdgeCheck e;
  std::vector<double> moved(r.height, 0.0);
  for (int x = 0; x < r.width; ++x) {
    std::vector<double> col;
    for (int y = 0; y < r.height; ++y) {
      const double v = r.rgb[(size_t(y) * r.width + x) * 3 + 1];
      col.push_back(v);
      moved[y] += (x < r.width / 2 ? v : 1.0 - v) * kPixel;
    }
    const Stats s = mean_se(col);
    e.worst_z = std::max(e.worst_z, std::abs(s.mean - pixel_mean(x, profile)) / std::max(s.se, 1e-4));
  }
  e.moved = mean_se(moved);
  return e;
}

RenderResult render(const json& s, const std::string& dir, RenderOptions o = quiet_options()) {
  return Renderer(scene_from_json(s, dir), o).render();
}

}  // namespace

// In focus the edge stays a step: every pixel a whole pixel away from it is exactly 0 or 1 (the
// plane's thickness moves a lens ray by R 0.005 / F, far below a pixel), with either camera.
TEST(ThinLens, EdgeInTheFocalPlaneStaysSharp) {
  const std::string dir = temp_dir("lens_sharp");
  for (const char* type : {"orthographic", "perspective"}) {
    json s = edge_scene(type, 64);
    if (std::string(type) == "perspective") perspective_frame(s, kPlaneDepth);
    s["camera"]["aperture_radius"] = 0.5;
    s["camera"]["focus_distance"] = kPlaneDepth;
    const RenderResult r = render(s, dir);
    EXPECT_NE(r.features & ST_FEATURE_THIN_LENS, 0u);
    for (int y = 0; y < r.height; ++y)
      for (int x = 0; x < r.width; ++x) {
        if (x == r.width / 2 - 1 || x == r.width / 2) continue;
        const float v = r.rgb[(size_t(y) * r.width + x) * 3 + 1];
        if (x < r.width / 2) EXPECT_LT(v, 1e-20f) << type << " " << x << "," << y;
        else EXPECT_EQ(v, 1.0f) << type << " " << x << "," << y;
      }
  }
}

// Out of focus the edge spreads over the circle of confusion: c = R |1 - z / F| (orthographic) or
// R |F / z - 1| (perspective, on the focal plane); here c = 0.5 (8 pixels) with both cameras.
TEST(ThinLens, DefocusedEdgeSpreadsOverTheCircleOfConfusion) {
  const std::string dir = temp_dir("lens_blur");
  const double F = 2.5;  // the focal plane, in front of the half plane
  for (const char* type : {"orthographic", "perspective"}) {
    const bool ortho = std::string(type) == "orthographic";
    json s = edge_scene(type, 512);
    if (!ortho) perspective_frame(s, F);
    const double R = ortho ? 0.5 : 1.0;
    const double c = ortho ? R * std::abs(1 - kPlaneDepth / F) : R * std::abs(F / kPlaneDepth - 1);
    ASSERT_NEAR(c, 0.5, 1e-12);
    s["camera"]["aperture_radius"] = R;
    s["camera"]["focus_distance"] = F;
    const RenderResult r = render(s, dir);
    const EdgeCheck e = check_edge(r, [c](double X) { return disc_beside(X / c); });
    EXPECT_LT(e.worst_z, 4.0) << type;
    const double moved = 4 * c / (3 * M_PI);
    EXPECT_NEAR(e.moved.mean, moved, 4 * e.moved.se) << type;
    // the twin: a circle of confusion 3% larger is seen
    EXPECT_GT(std::abs(e.moved.mean - 1.03 * moved), 4 * e.moved.se) << type << ": a 3% error must be detectable";
  }
}

// A white furnace stays 1 through a thin lens (and a moving camera): the lens changes only
// where the rays start and go.
TEST(ThinLens, WhiteFurnaceStaysOne) {
  const std::string dir = temp_dir("lens_furnace");
  write_lumpy(dir + "/lumpy.vdb");
  for (const char* tracker : {"delta-per-channel", "spectral", "spectral-mis"}) {
    json s = {{"format", "spectrack-scene/1"},
              {"camera",
               {{"position", {0.2, 0.1, -3}}, {"look_at", {0, 0, 0}}, {"fov_deg", 30}, {"aperture_radius", 0.3},
                {"focus_distance", 2.0}, {"shutter", {0, 0.04}}, {"position_close", {0.6, 0.1, -3}}}},
              {"film", {{"width", 12}, {"height", 12}, {"spp", 48}}},
              {"render", {{"tracker", tracker}, {"seed", 3}}},
              {"lights", {{{"type", "environment"}, {"radiance", {1, 1, 1}}}}},
              {"media",
               {{{"type", "vdb"}, {"file", "lumpy.vdb"}, {"density_scale", 4.0}, {"sigma_a", {0, 0, 0}},
                 {"sigma_s", {1.0, 3.0, 9.0}}, {"phase", {{"type", "hg"}, {"g", 0.4}}}}}}};
    const RenderResult r = render(s, dir);
    EXPECT_GT(r.stats.scatter_events, 1000u);
    EXPECT_EQ(r.features & (ST_FEATURE_THIN_LENS | ST_FEATURE_TIME), uint32_t(ST_FEATURE_THIN_LENS | ST_FEATURE_TIME));
    for (int ch = 0; ch < 3; ++ch) {
      const Stats st = mean_se(channel(r, ch));
      EXPECT_NEAR(st.mean, 1.0, 4 * st.se + 1e-5) << tracker << " channel " << ch;
    }
  }
}

// Aperture 0 and a shutter without motion are the pinhole, bit for bit, with no feature compiled
// in; a lens and a moving camera render the same image with the generic kernel.
TEST(ThinLens, PinholeIsBitIdenticalAndLensMatchesTheGenericKernel) {
  const std::string dir = temp_dir("lens_identity");
  json s = edge_scene("perspective", 8);
  perspective_frame(s, kPlaneDepth);
  const RenderResult pinhole = render(s, dir);
  json zero = s;
  zero["camera"]["aperture_radius"] = 0;
  zero["camera"]["focus_distance"] = 3;
  zero["camera"]["shutter"] = {0, 0.02};
  const RenderResult same = render(zero, dir);
  EXPECT_EQ(same.features, pinhole.features);
  EXPECT_EQ(same.features & (ST_FEATURE_THIN_LENS | ST_FEATURE_TIME), 0u);
  EXPECT_EQ(same.rgb, pinhole.rgb);
  json lens = zero;
  lens["camera"]["aperture_radius"] = 0.3;
  lens["camera"]["position_close"] = {0.1, 0, -kPlaneDepth};
  lens["camera"]["look_at_close"] = {0.1, 0.05, 0};
  const RenderResult specialised = render(lens, dir);
  RenderOptions g = quiet_options();
  g.generic_kernels = true;
  const RenderResult generic = render(lens, dir, g);
  EXPECT_EQ(generic.features, uint32_t(ST_FEATURES_ALL));
  EXPECT_EQ(specialised.rgb, generic.rgb);
  EXPECT_NE(specialised.rgb, pinhole.rgb);
}

// A camera moving sideways by 2a during the shutter sees the edge's time average, a linear ramp
// over 2a (here 8 pixels); the twin with a 3% longer move must fail.
TEST(Shutter, MovingCameraAveragesTheEdgeOverTheShutter) {
  const std::string dir = temp_dir("shutter_motion");
  const double a = 0.25;
  json s = edge_scene("orthographic", 256);
  s["camera"]["position"] = {-a, 0, -kPlaneDepth};
  s["camera"]["look_at"] = {-a, 0, 0};
  s["camera"]["position_close"] = {a, 0, -kPlaneDepth};
  s["camera"]["look_at_close"] = {a, 0, 0};
  s["camera"]["shutter"] = {-0.01, 0.01};
  const RenderResult r = render(s, dir);
  EXPECT_NE(r.features & ST_FEATURE_TIME, 0u);
  const EdgeCheck e = check_edge(r, [a](double X) { return std::clamp((X + a) / (2 * a), 0.0, 1.0); });
  EXPECT_LT(e.worst_z, 4.0);
  EXPECT_NEAR(e.moved.mean, a / 2, 4 * e.moved.se);
  EXPECT_GT(std::abs(e.moved.mean - 1.03 * a / 2), 4 * e.moved.se) << "a 3% error must be detectable";
  // the times are stratified over the pixel's samples: in the ramp a pixel's value varies over
  // the rows far less than the binomial p (1 - p) / spp of independent times (only the strata
  // the pixel's jitter reaches, 1/8 of the shutter here, are random)
  double ratio = 0;
  int n = 0;
  for (int x = r.width / 2 - 3; x < r.width / 2 + 3; ++x) {
    std::vector<double> col;
    for (int y = 0; y < r.height; ++y) col.push_back(r.rgb[(size_t(y) * r.width + x) * 3]);
    const Stats st = mean_se(col);
    const double p = pixel_mean(x, [a](double X) { return std::clamp((X + a) / (2 * a), 0.0, 1.0); });
    ratio += st.se * st.se * r.height / (p * (1 - p) / r.spp_done), ++n;
  }
  EXPECT_LT(ratio / n, 0.3) << "the sample times are not stratified";
  // without a shutter the camera stays where it opens: the sharp step at X = -a
  json still = s;
  still["camera"].erase("shutter");
  const RenderResult r0 = render(still, dir);
  EXPECT_EQ(r0.features & ST_FEATURE_TIME, 0u);
  for (int x : {r0.width / 2 - 6, r0.width / 2 + 6})
    EXPECT_EQ(r0.rgb[(size_t(5) * r0.width + x) * 3], x < r0.width / 2 - 4 ? 0.0f : 1.0f) << x;
}

// A sample's time and lens point depend only on (pixel, sample): sample-range shards add up to
// the single render.
TEST(Shutter, ShardsAddUpToTheSingleRender) {
  const std::string dir = temp_dir("shutter_shards");
  json s = edge_scene("perspective", 32);
  perspective_frame(s, 2.5);
  s["camera"]["aperture_radius"] = 0.4;
  s["camera"]["focus_distance"] = 2.5;
  s["camera"]["shutter"] = {0, 0.02};
  s["camera"]["position_close"] = {0.2, 0, -kPlaneDepth};
  Renderer whole(scene_from_json(s, dir), quiet_options());
  const RenderResult all = whole.render(0, 32);
  Renderer shards(scene_from_json(s, dir), quiet_options());
  const RenderResult a = shards.render(0, 12), b = shards.render(12, 20);
  ASSERT_EQ(all.sum.size(), a.sum.size());
  for (size_t i = 0; i < all.sum.size(); ++i) EXPECT_NEAR(a.sum[i] + b.sum[i], all.sum[i], 1e-9 + 1e-6 * all.sum[i]) << i;
}

TEST(Shutter, BadLensAndShutterFieldsAreRefusedByName) {
  const std::string dir = temp_dir("shutter_bad");
  auto err = [&](const std::function<void(json&)>& edit) {
    json s = edge_scene("perspective", 4);
    edit(s);
    return error_of([&] { scene_from_json(s, dir); });
  };
  EXPECT_NE(err([](json& s) { s["camera"]["aperture_radius"] = -1; }).find("/camera/aperture_radius"), std::string::npos);
  EXPECT_NE(err([](json& s) { s["camera"]["focus_distance"] = 0; }).find("/camera/focus_distance"), std::string::npos);
  EXPECT_NE(err([](json& s) { s["camera"]["shutter"] = {0.02, 0}; }).find("/camera/shutter: close"), std::string::npos);
  EXPECT_NE(err([](json& s) { s["camera"]["shutter"] = 0.02; }).find("/camera/shutter: expected [open, close]"),
            std::string::npos);
  EXPECT_NE(err([](json& s) { s["camera"]["shutter"] = {0, "x"}; }).find("/camera/shutter/1"), std::string::npos);
  EXPECT_NE(err([](json& s) { s["camera"]["position_close"] = {0, 0, 0}; }).find("/camera/look_at_close"),
            std::string::npos);
  EXPECT_NE(err([](json& s) {
              s["camera"]["look_at"] = "media";
              s["camera"]["position_close"] = {0, 0, -3};
            }).find("/camera/position_close: camera motion needs"),
            std::string::npos);
  EXPECT_NE(err([](json& s) {  // fit frames the open position alone: the path would be another
              s["camera"]["fit"] = 1.2;
              s["camera"]["position_close"] = {0, 0, -3};
            }).find("/camera/position_close: camera motion needs a position and look_at given as points and no fit"),
            std::string::npos);
  // times the kernels cannot hold as floats
  EXPECT_NE(err([](json& s) { s["camera"]["shutter"] = {0, 1e300}; }).find("/camera/shutter/1: value 1e+300 is out of range"),
            std::string::npos);
  EXPECT_NE(err([](json& s) { s["camera"]["shutter"] = {-3e38, 3e38}; }).find("/camera/shutter: its length"),
            std::string::npos);
  json wide = edge_scene("perspective", 4);
  wide["camera"]["shutter"] = {-1e6, 1e6};
  EXPECT_NO_THROW(scene_from_json(wide, dir));
  // ray origins beyond the coordinate bound: the lens's rim, the camera at shutter close
  auto pack_err = [&](const std::function<void(json&)>& edit) {
    json s = edge_scene("perspective", 4);
    edit(s);
    SceneDesc d = scene_from_json(s, dir);
    return error_of([&] { pack_scene(d, resolve_settings(d, quiet_options()), PackOptions{}); });
  };
  EXPECT_NE(pack_err([](json& s) { s["camera"]["aperture_radius"] = 1e30; }).find("/camera/aperture_radius: 1e+30 puts the lens beyond 2^60"),
            std::string::npos);
  EXPECT_NE(pack_err([](json& s) {
              s["camera"]["shutter"] = {0, 1};
              s["camera"]["position_close"] = {0, 0, -1e30};
            }).find("/camera/position_close: (0, 0, -1e+30) is beyond 2^60"),
            std::string::npos);
  json lens = edge_scene("perspective", 4);
  lens["camera"]["aperture_radius"] = 0.5;
  SceneDesc lens_desc = scene_from_json(lens, dir);
  EXPECT_NO_THROW(pack_scene(lens_desc, resolve_settings(lens_desc, quiet_options()), PackOptions{}));
  RenderOptions o = quiet_options();
  o.shutter = std::array<double, 2>{1.0, 0.0};
  EXPECT_NE(error_of([&] { render(edge_scene("perspective", 4), dir, o); }).find("shutter 1:0"), std::string::npos);
}
