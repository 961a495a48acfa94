// test_framing.cpp: the camera framing of docs/scene-format.md (scene/framing.h):
// "look_at": "media", "position": "auto" and "fit" put every medium's world box inside the
// frustum, on the shipped scenes, on a translated smoke and through pack_scene; the parser's
// refusals; the fixed bench/scenes/smoke1.json shows its whole smoke.
#include <gtest/gtest.h>

#include <cmath>
#include <algorithm>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "scene/media_bounds.h"
#include "scene/scene_pack.h"
#include "integrator/settings.h"
#include "scene/framing.h"
#include "scene/scene.h"
#include "test_util.h"
#include "volume/volume.h"

namespace {

using namespace spectrack;
namespace fs = std::filesystem;
const std::string kSrc = SPECTRACK_SOURCE_DIR;
const std::string kSharedVdb = SHARED_DATA_DIR;

std::vector<std::string> shipped_scenes() {
  std::vector<std::string> out;
  for (const char* d : {"data/scenes", "bench/scenes"})
    for (auto& e : fs::directory_iterator(kSrc + "/" + d))
      if (e.path().extension() == ".json") out.push_back(e.path().string());
  std::sort(out.begin(), out.end());
  return out;
}

bool all_in_view(const CameraDesc& c, const FilmDesc& f, const std::vector<Box3>& boxes) {
  for (const Box3& b : boxes)
    if (!box_in_view(c, f.width, f.height, b, 1e-6)) return false;
  return true;
}

// The fit is tight: the boxes fill the frame up to the margin (a narrower view cuts them).
void expect_tight(CameraDesc c, const FilmDesc& f, const std::vector<Box3>& boxes, double fit) {
  if (c.type == ST_CAMERA_ORTHOGRAPHIC) {
    c.height /= fit * 1.01;
  } else {
    c.fov_deg = 2.0 * std::atan(std::tan(0.5 * c.fov_deg * M_PI / 180.0) / (fit * 1.01)) * 180.0 / M_PI;
  }
  EXPECT_FALSE(all_in_view(c, f, boxes)) << "the framing leaves more than the margin free";
}

TEST(Framing, UnitBoxesPerspectiveAndOrthographic) {
  const std::vector<Box3> boxes = {Box3{{-1, -2, -1}, {3, 1, 0.5}}, Box3{{10, 0, 0}, {11, 1, 1}}};
  for (int type : {ST_CAMERA_PERSPECTIVE, ST_CAMERA_ORTHOGRAPHIC})
    for (auto [w, h] : {std::pair{64, 64}, std::pair{200, 50}, std::pair{30, 120}}) {
      CameraDesc c;
      c.type = type;
      c.look_at_media = c.position_auto = true;
      c.fit = 1.1;
      FilmDesc f;
      f.width = w, f.height = h;
      CameraDesc r = frame_camera(c, w, h, boxes, "t");
      EXPECT_FALSE(camera_needs_framing(r));
      EXPECT_NEAR(r.look_at[0], 5.0, 1e-12);
      EXPECT_NEAR(r.look_at[1], -0.5, 1e-12);
      EXPECT_NEAR(r.look_at[2], 0.0, 1e-12);
      EXPECT_LT(r.position[2], r.look_at[2]);  // looks along +z
      EXPECT_TRUE(all_in_view(r, f, boxes)) << type << " " << w << "x" << h;
      expect_tight(r, f, boxes, 1.1);
      // from a given position: the direction is kept
      c.position_auto = false;
      c.position = {20, 5, 20};
      r = frame_camera(c, w, h, boxes, "t");
      EXPECT_TRUE(all_in_view(r, f, boxes));
      const Vec3 d0{20 - 5.0, 5 + 0.5, 20 - 0.0}, d1{r.position[0] - 5.0, r.position[1] + 0.5, r.position[2] - 0.0};
      const double l0 = std::sqrt(d0[0] * d0[0] + d0[1] * d0[1] + d0[2] * d0[2]);
      const double l1 = std::sqrt(d1[0] * d1[0] + d1[1] * d1[1] + d1[2] * d1[2]);
      for (int a = 0; a < 3; ++a) EXPECT_NEAR(d0[a] / l0, d1[a] / l1, 1e-9);
    }
}

TEST(Framing, NothingAskedChangesNothingAndErrorsAreNamed) {
  CameraDesc c;
  CameraDesc r = frame_camera(c, 8, 8, {}, "s.json: /camera");
  EXPECT_EQ(r.position, c.position);
  c.look_at_media = true;
  try {
    frame_camera(c, 8, 8, {}, "s.json: /camera");
    FAIL() << "framing without media was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("s.json: /camera"), std::string::npos) << e.what();
  }
  // "auto" with a z-up camera looks along +y
  CameraDesc z = c;
  z.position_auto = true;
  z.up = {0, 0, 1};
  CameraDesc rz = frame_camera(z, 8, 8, {Box3{{-1, -1, -1}, {1, 1, 1}}}, "s");
  EXPECT_LT(rz.position[1], -1.0);
  EXPECT_NEAR(rz.position[0], 0.0, 1e-12);
  // position straight above the media with up (0, 1, 0): parallel
  c.position = {0, 10, 0};
  EXPECT_THROW(frame_camera(c, 8, 8, {Box3{{-1, -1, -1}, {1, 1, 1}}}, "s"), Error);
  // media that are all empty grids (degenerate boxes): nothing to fit to, refused by name; the
  // twin: one medium with content frames as before
  CameraDesc fit = z;
  fit.fit = 1.0;
  const std::vector<Box3> empty{Box3{{2, 3, 4}, {2, 3, 4}}, Box3{{0, 0, 0}, {0, 0, 0}}};
  try {
    frame_camera(fit, 8, 8, empty, "s.json: /camera");
    FAIL() << "framing empty media was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("every medium is empty"), std::string::npos) << e.what();
  }
  std::vector<Box3> one = empty;
  one.push_back(Box3{{-1, -1, -1}, {1, 1, 1}});
  EXPECT_NO_THROW(frame_camera(fit, 8, 8, one, "s"));
}

TEST(Framing, ParserAcceptsMediaAutoAndFit) {
  auto parse = [](const std::string& cam) {
    return parse_scene(R"({"format": "spectrack-scene/1", "camera": )" + cam + "}", "s.json", "/tmp");
  };
  SceneDesc s = parse(R"({"position": "auto"})");
  EXPECT_TRUE(s.camera.position_auto);
  EXPECT_TRUE(s.camera.look_at_media);
  EXPECT_DOUBLE_EQ(s.camera.fit, 1.1);
  s = parse(R"({"position": [1, 2, 3], "look_at": "media"})");
  EXPECT_TRUE(s.camera.look_at_media);
  EXPECT_EQ(s.camera.fit, 0);
  s = parse(R"({"type": "orthographic", "look_at": "media", "fit": 2})");
  EXPECT_DOUBLE_EQ(s.camera.fit, 2.0);
  for (const char* bad : {R"({"look_at": "middle"})", R"({"position": "far"})", R"({"fit": 0})", R"({"fit": -1})",
                          R"({"fit": "yes"})", R"({"look_at": "media", "up": [0, 0, 0]})"}) {
    EXPECT_THROW(parse(bad), Error) << bad;
  }
}

// Every shipped scene, framed from its own position with fit 1.1 (and from "auto"): every
// medium's box in the frustum.
TEST(Framing, ShippedScenesFramed) {
  for (const std::string& f : shipped_scenes()) {
    SCOPED_TRACE(f);
    SceneDesc s;
    try {
      s = load_scene(f);
    } catch (const Error& e) {  // a scene on ../shared data that is absent here
      ASSERT_FALSE(fs::exists(kSharedVdb)) << e.what();
      continue;
    }
    const std::vector<Box3> boxes = media_world_boxes(s);
    ASSERT_FALSE(boxes.empty());
    for (bool auto_pos : {false, true}) {
      CameraDesc c = s.camera;
      c.look_at_media = true;
      c.position_auto = auto_pos;
      c.fit = 1.1;
      // the scene's own is "auto": a far point along -z, or -y for a z-up camera (as frame_camera's auto)
      if (!auto_pos && camera_needs_framing(s.camera))
        c.position = std::abs(c.up[2]) > 0.999 * std::hypot(c.up[0], c.up[1], c.up[2]) ? Vec3{0, -1e4, 0} : Vec3{0, 0, -1e4};
      const CameraDesc r = frame_camera(c, s.film.width, s.film.height, boxes, f);
      EXPECT_TRUE(all_in_view(r, s.film, boxes)) << auto_pos;
    }
  }
}

// bench/scenes/smoke1.json (a framing that cuts its smoke off at the right edge fails): every box is in view,
// also through pack_scene's camera (the one the kernels get).
TEST(Framing, BenchSmoke1ShowsAllItsSmoke) {
  const std::string f = kSrc + "/bench/scenes/smoke1.json";
  if (!fs::exists(kSharedVdb + "/smoke1.vdb")) GTEST_SKIP() << "no ../shared data";
  SceneDesc s = load_scene(f);
  const std::vector<Box3> boxes = media_world_boxes(s);
  const CameraDesc r = frame_camera(s.camera, s.film.width, s.film.height, boxes, f);
  EXPECT_TRUE(all_in_view(r, s.film, boxes));
  // smoke1 is centred near (-7.1, 40.7, 0.7)
  EXPECT_NEAR(r.look_at[0], -7.1, 1.0);
  EXPECT_NEAR(r.look_at[1], 40.7, 1.0);
  EXPECT_NEAR(r.look_at[2], 0.7, 1.0);
  RenderOptions o;
  o.quiet = true;
  PackedScene p = pack_scene(s, resolve_settings(s, o), PackOptions{});
  EXPECT_NEAR(p.st.camera.position.x, r.position[0], 1e-3 * (1 + std::abs(r.position[0])));
  EXPECT_NEAR(p.st.camera.position.y, r.position[1], 1e-3 * (1 + std::abs(r.position[1])));
  EXPECT_NEAR(p.st.camera.position.z, r.position[2], 1e-3 * (1 + std::abs(r.position[2])));
}

// A translated (and rotated, scaled) smoke far from the origin, framed by "auto".
TEST(Framing, TranslatedSmoke) {
  if (!fs::exists(kSharedVdb + "/smoke1.vdb")) GTEST_SKIP() << "no ../shared data";
  nlohmann::json j = {
      {"format", "spectrack-scene/1"},
      {"camera", {{"position", "auto"}, {"fov_deg", 25}}},
      {"film", {{"width", 96}, {"height", 48}, {"spp", 1}}},
      {"media", nlohmann::json::array()}};
  nlohmann::json m = {{"type", "vdb"}, {"file", kSharedVdb + "/smoke1.vdb"},
                      {"transform", {{"scale", 0.5}, {"rotate_deg", {0, 35, 10}}, {"translate", {300, -120, 55}}}}};
  j["media"].push_back(m);
  SceneDesc s = parse_scene(j.dump(), "translated.json", "/tmp");
  const std::vector<Box3> boxes = media_world_boxes(s);
  const CameraDesc r = frame_camera(s.camera, 96, 48, boxes, "translated.json");
  EXPECT_TRUE(all_in_view(r, s.film, boxes));
  expect_tight(r, s.film, boxes, 1.1);
  // the box follows the transform: smoke1's centre (-7.1, 40.7, 0.7) scaled, rotated, translated
  EXPECT_GT(r.look_at[0], 250);
  EXPECT_LT(r.look_at[1], -80);
  // the box's transform is the one the kernels get: world_to_index maps its corners back
  RenderOptions o;
  o.quiet = true;
  PackedScene p = pack_scene(s, resolve_settings(s, o), PackOptions{});
  GridData g = load_float_grid(s.media[0].file, "density", -1, "t");
  for (int c = 0; c < 8; ++c) {
    const Vec3 idx{double((c & 1) ? g.index_max[0] + 1 : g.index_min[0] - 1), double((c & 2) ? g.index_max[1] + 1 : g.index_min[1] - 1),
                   double((c & 4) ? g.index_max[2] + 1 : g.index_min[2] - 1)};
    const Vec3 w = medium_index_to_world(s.media[0], g, idx);
    const st_float4* m = p.st.media[0].world_to_index;
    for (int r = 0; r < 3; ++r) {
      const double back = m[r].x * w[0] + m[r].y * w[1] + m[r].z * w[2] + m[r].w;
      EXPECT_NEAR(back, idx[r], 1e-2) << "corner " << c << " axis " << r;
    }
  }
  // the unframed default camera at (0, 0, -4) would not see it
  CameraDesc plain;
  EXPECT_FALSE(all_in_view(plain, s.film, boxes));
}

}  // namespace
