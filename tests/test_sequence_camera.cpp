// test_sequence_camera.cpp: a frame sequence keeps one camera (docs/cli.md, "Frame sequences"):
// framing from every frame's boxes, an empty frame warned by name and rendered with that camera,
// `spectrack info --frames`, and the frame number and shutter in the EXR metadata (merge refuses
// pieces of other frames).

#include "cli_util.h"
#include "image/image.h"
#include "scene/sequence_camera.h"
#include "scene/framing.h"

namespace {

using namespace st_cli;

// Three frames of a small cube of fog: at x = -1 (frame 1), x = +1 (frame 2), and empty (frame 3).
std::string write_frames(const std::string& dir) {
  for (int f = 1; f <= 3; ++f) {
    const std::string path = dir + "/cube_000" + std::to_string(f) + ".vdb";
    st_test::write_vdb(path, "density", openvdb::Coord(-2), openvdb::Coord(2),
                       [f](int, int, int) { return f == 3 ? 0.0f : 0.5f; }, 0.1,
                       openvdb::Vec3d(f == 1 ? -1.0 : 1.0, 0.0, 0.0));
  }
  return dir + "/cube_####.vdb";
}

json framed_sequence(const std::string& pattern) {
  json s = vdb_scene(pattern);
  s["camera"] = {{"type", "perspective"}, {"position", "auto"}, {"up", {0, 1, 0}}, {"fov_deg", 40}};
  return s;
}

// The sequence's camera frames both cubes (aimed at the centre of their union), and an empty
// frame does not move it.
TEST(SequenceCamera, FramesEveryFrameAndSkipsEmptyOnes) {
  const std::string dir = test_dir();
  const json s = framed_sequence(write_frames(dir));
  const spectrack::SceneDesc scene = st_test::scene_from_json(s, dir);
  const spectrack::SequenceCamera all = spectrack::sequence_camera(scene, 1, 3, true);
  EXPECT_EQ(all.empty_frames, std::vector<long long>{3});
  EXPECT_FALSE(spectrack::camera_needs_framing(all.camera));
  EXPECT_NEAR(all.camera.look_at[0], 0.0, 1e-9);  // the union's centre, not one cube's
  for (double x : {-1.0, 1.0}) {
    const spectrack::Box3 cube{{x - 0.3, -0.3, -0.3}, {x + 0.3, 0.3, 0.3}};
    EXPECT_TRUE(spectrack::box_in_view(all.camera, 8, 8, cube)) << x;
  }
  const spectrack::SequenceCamera first = spectrack::sequence_camera(scene, 1, 1, true);
  EXPECT_NEAR(first.camera.look_at[0], -1.0, 1e-9);  // a single frame frames its own cube
  EXPECT_THAT(st_test::error_of([&] { spectrack::sequence_camera(scene, 3, 3, true); }), HasSubstr("every frame 3..3 is empty"));
}

TEST(SequenceCamera, RenderWarnsOfTheEmptyFrameAndRecordsFrameAndShutter) {
  const std::string dir = test_dir();
  const std::string scene = write_scene(dir, "seq.json", framed_sequence(write_frames(dir)));
  RunOptions o;
  o.timeout_s = 600;
  Proc p = run({"render", scene, "--frames", "1:3", "--shutter", "0:0.02", "-o", dir + "/f_####.exr"}, o);
  ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
  EXPECT_THAT(p.out, HasSubstr("warning: frame 3: every medium's grid is empty")) << p.out;
  EXPECT_THAT(p.out, HasSubstr("cube_0003.vdb")) << p.out;
  for (int f = 1; f <= 3; ++f) {
    const auto img = spectrack::read_image(dir + "/f_000" + std::to_string(f) + ".exr", spectrack::ImageUse::kFilmPiece);
    EXPECT_EQ(meta_string(img, "frame"), std::to_string(f));
    EXPECT_EQ(meta_string(img, "shutter"), "0:0.02/1");
  }
  // merge refuses two frames as one render
  Proc m = run({"merge", dir + "/m.exr", dir + "/f_0001.exr", dir + "/f_0002.exr"});
  expect_error_exit(m);
  EXPECT_THAT(m.out, HasSubstr("the frame differs")) << m.out;
}

// A camera framed over the sequence depends on the frames: frame 1 of `--frames 1:1` is framed on
// its own cube, of `--frames 1:2` on both. Each piece records its camera, so merge refuses the two
// (they would average two framings), and takes two pieces of the same range (the twin).
TEST(SequenceCamera, PiecesOfAFrameFramedOverOtherRangesDoNotMerge) {
  const std::string dir = test_dir();
  const std::string scene = write_scene(dir, "seq.json", framed_sequence(write_frames(dir)));
  RunOptions o;
  o.timeout_s = 600;
  for (const auto& [frames, range, out] : {std::tuple<const char*, const char*, const char*>{"1:1", "0:1", "/a_####.exr"},
                                           {"1:2", "1:2", "/b_####.exr"}, {"1:2", "0:1", "/c_####.exr"}}) {
    Proc p = run({"render", scene, "--frames", frames, "--spp-range", range, "-q", "-o", dir + out}, o);
    ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
  }
  const auto a = spectrack::read_image(dir + "/a_0001.exr", spectrack::ImageUse::kFilmPiece);
  const auto b = spectrack::read_image(dir + "/b_0001.exr", spectrack::ImageUse::kFilmPiece);
  EXPECT_THAT(meta_string(a, "camera"), HasSubstr("position ("));
  EXPECT_NE(meta_string(a, "camera"), meta_string(b, "camera"));
  Proc m = run({"merge", dir + "/m.exr", dir + "/a_0001.exr", dir + "/b_0001.exr"});
  expect_error_exit(m);
  EXPECT_THAT(m.out, HasSubstr("the camera (framed over the sequence's frames) differs")) << m.out;
  Proc twin = run({"merge", dir + "/m.exr", dir + "/c_0001.exr", dir + "/b_0001.exr"});
  EXPECT_TRUE(twin.exited && twin.code == 0) << twin.describe();
}

TEST(SequenceCamera, InfoTakesAFramePatternAndARange) {
  const std::string dir = test_dir();
  const std::string pattern = write_frames(dir);
  const std::string scene = write_scene(dir, "seq.json", framed_sequence(pattern));
  Proc v = run({"info", pattern, "--frames", "1:2", "--json"});
  ASSERT_TRUE(v.exited && v.code == 0) << v.describe();
  EXPECT_THAT(v.out, HasSubstr("cube_0001.vdb"));
  EXPECT_THAT(v.out, HasSubstr("cube_0002.vdb"));
  Proc s = run({"info", scene, "--frames", "1:3"});
  ASSERT_TRUE(s.exited && s.code == 0) << s.describe();
  EXPECT_THAT(s.out, HasSubstr("(frame 3)"));
  // one camera line, the same for every frame
  std::vector<std::string> cams;
  std::istringstream lines(s.out);
  for (std::string l; std::getline(lines, l);)
    if (l.find("  camera ") == 0) cams.push_back(l);
  ASSERT_EQ(cams.size(), 3u) << s.out;
  EXPECT_EQ(cams[0], cams[1]);
  EXPECT_EQ(cams[0], cams[2]);
  Proc missing = run({"info", pattern});
  expect_error_exit(missing);
  EXPECT_THAT(missing.out, HasSubstr("is a frame pattern: give the frames with --frames A:B"));
}

}  // namespace
