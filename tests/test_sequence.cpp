// test_sequence.cpp: `spectrack render --frames A:B` (docs/cli.md, `--frames`): the 3-frame Blender
// smoke of ../shared/data/vdb/usd renders 3 images, later frames reuse the kernels (loaded from the
// kernel cache, not compiled again), and a missing frame is an error naming it.
#include "cli_util.h"
#include "scene/frames.h"

namespace {

using namespace st_cli;

TEST(Sequence, FramePatterns) {
  EXPECT_EQ(spectrack::expand_frame("smoke_######.vdb", 2), "smoke_000002.vdb");
  EXPECT_EQ(spectrack::expand_frame("smoke_$F6.vdb", 13), "smoke_000013.vdb");
  EXPECT_EQ(spectrack::expand_frame("out_$F.exr", 7), "out_7.exr");
  EXPECT_EQ(spectrack::expand_frame("plain.exr", 7), "plain.exr");
  EXPECT_TRUE(spectrack::has_frame_pattern("a_##.vdb"));
  EXPECT_FALSE(spectrack::has_frame_pattern("a.vdb"));
}

json smoke_sequence(const std::string& file) {
  json s = vdb_scene(file);
  s["camera"]["look_at"] = {0, 0, 5};
  s["camera"]["position"] = {0, -30, 5};
  s["camera"]["up"] = {0, 0, 1};
  return s;
}

TEST(Sequence, ThreeFramesThreeImagesOneKernelBuild) {
  const std::string dir = test_dir();
  const std::string scene = write_scene(dir, "seq.json", smoke_sequence(kShared + "/usd/smoke_######.vdb"));
  RunOptions o;
  o.timeout_s = 600;
  Proc p = run({"render", scene, "--frames", "1:3", "-o", dir + "/f_$F4.exr", "--stats-json", dir + "/s_####.json"}, o);
  ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
  for (int f = 1; f <= 3; ++f) {
    char name[64];
    std::snprintf(name, sizeof(name), "/f_%04d.exr", f);
    EXPECT_TRUE(fs::exists(dir + name)) << name << "\n" << p.out;
    EXPECT_THAT(p.out, HasSubstr("frame " + std::to_string(f) + " (" + std::to_string(f) + " of 3)"));
  }
  for (int f = 2; f <= 3; ++f) {
    char name[64];
    std::snprintf(name, sizeof(name), "/s_%04d.json", f);
    const json st = json::parse(std::ifstream(dir + name));
    EXPECT_TRUE(st["kernels_from_cache"].get<bool>()) << "frame " << f << " compiled its kernels again";
  }
}

TEST(Sequence, MissingFrameIsNamed) {
  const std::string dir = test_dir();
  const std::string scene = write_scene(dir, "seq.json", smoke_sequence(kShared + "/usd/smoke_######.vdb"));
  Proc p = run({"render", scene, "--frames", "2:5", "-o", dir + "/f_####.exr"});
  expect_error_exit(p);
  EXPECT_THAT(p.out, HasSubstr("frame 4")) << p.out;
  EXPECT_THAT(p.out, HasSubstr("smoke_000004.vdb: no such file")) << p.out;
  EXPECT_FALSE(fs::exists(dir + "/f_0002.exr")) << "rendered before checking every frame";
  Proc q = run({"render", scene, "--frames", "1:2", "-o", dir + "/plain.exr"});
  expect_error_exit(q, 2);  // usage errors
  EXPECT_THAT(q.out, HasSubstr("no frame pattern")) << q.out;
  Proc r = run({"render", scene, "-o", dir + "/plain.exr"});
  expect_error_exit(r, 2);
  EXPECT_THAT(r.out, HasSubstr("--frames")) << r.out;
  // the statistics and the preview are written per frame too: one name for all would be overwritten
  for (const char* flag : {"--stats-json", "--preview"}) {
    Proc one = run({"render", scene, "--frames", "1:2", "-o", dir + "/g_####.exr", flag,
                    dir + (flag[2] == 's' ? "/plain.json" : "/plain.png")});
    expect_error_exit(one, 2);
    EXPECT_THAT(one.out, HasSubstr(std::string(flag) + " " + dir)) << one.out;
    EXPECT_THAT(one.out, HasSubstr("no frame pattern")) << one.out;
    EXPECT_FALSE(fs::exists(dir + "/g_0001.exr"));
  }
}

}  // namespace
