// test_cli_values.cpp: the command line's values end in a clear refusal, never a wrapped or
// silently ignored value: integers that would wrap or be read as octal or hex, --pixel-bounds
// past 2^32, --frames past the frame limit, --shutter values that are not finite or close before open, an empty --device, --half with a PNG; and frame
// sequences: a homogeneous medium beside a VDB sequence, a symlink loop and a NUL in a path.
//
// Design: every case runs the real binary (cli_util.h) and checks the exit code (2 for the
// command line, 1 for the scene), that the message names the option or field and the reason,
// and that no image was written.
#include "cli_util.h"

namespace {

using namespace st_cli;

class CliValues : public testing::Test {
 protected:
  void SetUp() override {
    dir = test_dir();
    scene = write_scene(dir, "tiny.json", homogeneous_scene(8, 8, 1, 1.0, 0.0));
  }
  Proc render(std::vector<std::string> extra, const std::string& out = "") {
    std::vector<std::string> a = {"render", scene, "-o", out.empty() ? dir + "/x.exr" : out, "--quiet"};
    a.insert(a.end(), extra.begin(), extra.end());
    return run(a);
  }
  void expect_usage(const std::vector<std::string>& extra, const std::vector<std::string>& words) {
    Proc p = render(extra);
    expect_error_exit(p, 2);
    for (auto& w : words) EXPECT_THAT(p.out, HasSubstr(w)) << p.describe();
    EXPECT_FALSE(fs::exists(dir + "/x.exr")) << p.describe();
  }
  std::string dir, scene;
};

TEST_F(CliValues, PixelBoundsPast2To32AreRefusedNotWrapped) {
  expect_usage({"--pixel-bounds", "0,4294967312,0,16"}, {"--pixel-bounds", "x1", "4294967312", "65536"});
  expect_usage({"--pixel-bounds", "0,4,0,99999999999999999999999"}, {"y1", "outside"});
  expect_usage({"--pixel-bounds", "0,+4,0,4"}, {"x1", "decimal"});
  expect_usage({"--pixel-bounds", "0,4,0,4,"}, {"x0,x1,y0,y1"});
}

TEST_F(CliValues, IntegerOptionsRefuseWrapsOctalHexAndSpaces) {
  // each integer option: a value that wraps an int, one past 2^64, an octal and a hex one
  for (const std::string opt : {"--spp", "--path-slots", "--budget", "--chunk-spp", "--majorant-cell",
                                "--majorant-block", "--batches-in-flight", "--shadow-ring", "--seed"}) {
    for (const std::string bad : {"4294967297", "99999999999999999999", "010", "0x10", " 5", "+5", "-1", ""}) {
      Proc p = render({opt, bad});
      expect_error_exit(p, 2);
      EXPECT_THAT(p.out, HasSubstr(opt)) << opt << " " << bad << "\n" << p.describe();
    }
  }
  expect_usage({"--seed", "4294967296"}, {"--seed", "outside [0, 4294967295]"});
  expect_usage({"--spp", "010"}, {"--spp", "'010' has a leading zero"});
  expect_usage({"--majorant-step-cost", "nan"}, {"--majorant-step-cost", "nan"});
}

TEST_F(CliValues, SppRangeValuesAreReadStrictly) {
  expect_usage({"--spp-range", "0:4294967297"}, {"--spp-range", "B", "outside"});
  expect_usage({"--spp-range", "0:0x10"}, {"--spp-range", "decimal"});
  expect_usage({"--spp-range", "0:16777217"}, {"--spp-range", "16777217 samples"});
}

TEST_F(CliValues, ShutterValuesAreReadStrictly) {
  expect_usage({"--shutter", "0.02:0"}, {"--shutter", "CLOSE is before OPEN"});
  expect_usage({"--shutter", "0:nan"}, {"--shutter", "'nan' is not a finite number"});
  expect_usage({"--shutter", "0:1e999"}, {"--shutter", "not a finite number"});
  expect_usage({"--shutter", "0:1e300"}, {"--shutter", "'1e300' is not a finite number (as a float)"});
  expect_usage({"--shutter", "-3e38:3e38"}, {"--shutter", "CLOSE - OPEN is not finite"});
  expect_usage({"--shutter", "0"}, {"--shutter", "OPEN:CLOSE"});
  expect_usage({"--shutter", ":1"}, {"--shutter", "'' is not a finite number"});
  Proc ok = render({"--shutter", "-0.01:0.01"});
  EXPECT_TRUE(ok.exited && ok.code == 0) << ok.describe();
}

TEST_F(CliValues, FramesPastTheLimitSaySo) {
  expect_usage({"--frames", "0:1000000"}, {"--frames", "1000001 frames", "at most 1000000"});
  expect_usage({"--frames", "-9223372036854775808:9223372036854775807"}, {"--frames", "outside"});
  expect_usage({"--frames", "5:4"}, {"--frames", "B is below A"});
}

TEST_F(CliValues, EmptyDeviceIsRefused) {
  expect_usage({"--device", ""}, {"--device", "empty device"});
  expect_usage({"--device", "  "}, {"--device", "empty device"});
}

TEST_F(CliValues, HalfWithAPngIsRefused) {
  Proc p = render({"--half"}, dir + "/x.png");
  expect_error_exit(p, 2);
  EXPECT_THAT(p.out, HasSubstr("--half")) << p.describe();
  EXPECT_THAT(p.out, HasSubstr("PNG")) << p.describe();
  EXPECT_FALSE(fs::exists(dir + "/x.png")) << p.describe();
  // --compression likewise; the scene's own film.half or film.compression with its own PNG output is
  // the scene's error (exit 1), and with -o choosing the PNG a warning (the twin: an EXR renders)
  Proc c = render({"--compression", "piz"}, dir + "/c.png");
  expect_error_exit(c, 2);
  EXPECT_THAT(c.out, HasSubstr("--compression: the output")) << c.describe();
  for (const char* field : {"half", "compression"}) {
    json s = homogeneous_scene(8, 8, 2, 1.0, 0.0);
    s["film"]["output"] = "own.png";
    s["film"][field] = std::string(field) == "half" ? json(true) : json("dwaa");
    scene = write_scene(dir, std::string(field) + ".json", s);
    Proc own = run({"render", scene, "-q"});
    expect_error_exit(own, 1);
    EXPECT_THAT(own.out, HasSubstr(std::string("/film/") + field + ": film." + field + ": the output")) << own.describe();
    Proc chosen = run({"render", scene, "-o", dir + "/chosen.png"});
    EXPECT_TRUE(chosen.exited && chosen.code == 0) << chosen.describe();
    EXPECT_THAT(chosen.out, HasSubstr(std::string("/film/") + field + " is ignored for the PNG output")) << chosen.describe();
    Proc exr = run({"render", scene, "-q", "-o", dir + "/own.exr"});
    EXPECT_TRUE(exr.exited && exr.code == 0) << exr.describe();
  }
}

// A render whose path slots and shadow rays cannot fit: the refusal names the options that size
// them (4 lights x a shadow ring of 8 x 2^24 slots is far above any device's memory).
TEST_F(CliValues, DeviceMemoryRefusalNamesPathSlotsAndShadowRing) {
  json s = homogeneous_scene(64, 64, 4096, 1.0, 0.0);
  for (int i = 0; i < 3; ++i)
    s["lights"].push_back({{"type", "directional"}, {"to_light", {0, 1, 0.1 * i}}, {"irradiance", {1, 1, 1}}});
  scene = write_scene(dir, "big.json", s);
  RunOptions o;
  o.timeout_s = 300;  // may include a cold kernel build
  Proc p = run({"render", scene, "-o", dir + "/x.exr", "--quiet", "--path-slots", "16777216", "--shadow-ring", "8"}, o);
  expect_error_exit(p, 1);
  EXPECT_THAT(p.out, HasSubstr("--path-slots 16777216 x 4 light(s) x --shadow-ring 8")) << p.describe();
  EXPECT_THAT(p.out, HasSubstr("a lower --path-slots or a lower --shadow-ring")) << p.describe();
  EXPECT_FALSE(fs::exists(dir + "/x.exr"));
}

// ---- frame sequences ---------------------------------------------------------------------------

json sequence_with_box(const std::string& pattern) {
  json s = vdb_scene(pattern);
  json box = homogeneous_scene(8, 8, 1, 1.0, 0.0)["media"][0];
  box["bounds"] = {{2, 2, 2}, {3, 3, 3}};
  s["media"].push_back(box);
  return s;
}

TEST(CliSequenceFiles, HomogeneousMediumBesideAVdbSequenceRenders) {
  const std::string dir = test_dir();
  for (int f = 1; f <= 2; ++f) {
    char name[64];
    std::snprintf(name, sizeof(name), "/v_%02d.vdb", f);
    st_test::write_vdb(dir + name, "density", openvdb::Coord(-4), openvdb::Coord(4), [](int, int, int) { return 0.5f; }, 0.2);
  }
  const std::string scene = write_scene(dir, "seq.json", sequence_with_box(dir + "/v_##.vdb"));
  RunOptions o;
  o.timeout_s = 300;
  Proc p = run({"render", scene, "--frames", "1:2", "-o", dir + "/f_##.exr", "--quiet"}, o);
  ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
  EXPECT_TRUE(fs::exists(dir + "/f_01.exr") && fs::exists(dir + "/f_02.exr")) << p.describe();
}

TEST(CliSequenceFiles, SymlinkLoopIsNamedAsSuch) {
  const std::string dir = test_dir();
  st_test::write_vdb(dir + "/v_01.vdb", "density", openvdb::Coord(-4), openvdb::Coord(4),
                     [](int, int, int) { return 0.5f; }, 0.2);
  fs::create_symlink("v_02.vdb", dir + "/v_02.vdb");  // a link to itself
  const std::string scene = write_scene(dir, "seq.json", sequence_with_box(dir + "/v_##.vdb"));
  Proc p = run({"render", scene, "--frames", "1:2", "-o", dir + "/f_##.exr", "--quiet"});
  expect_error_exit(p);
  EXPECT_THAT(p.out, HasSubstr("frame 2")) << p.describe();
  EXPECT_THAT(p.out, HasSubstr("v_02.vdb: symlink loop")) << p.describe();
  EXPECT_THAT(p.out, Not(HasSubstr("no such file"))) << p.describe();
  EXPECT_FALSE(fs::exists(dir + "/f_01.exr")) << p.describe();
}

TEST(CliSequenceFiles, NulInAPathIsShownAndRefused) {
  const std::string dir = test_dir();
  small_vdb(dir);
  // "small.vdb\0_##" : the system would read small.vdb, the scene says another file
  const std::string scene = write_scene(dir, "nul.json", vdb_scene(dir + std::string("/small.vdb\0_##.vdb", 19)));
  Proc p = run({"render", scene, "--frames", "1:2", "-o", dir + "/f_##.exr", "--quiet"});
  expect_error_exit(p);
  EXPECT_THAT(p.out, HasSubstr("small.vdb\\0_##.vdb")) << p.describe();
  EXPECT_THAT(p.out, HasSubstr("/media/0/file")) << p.describe();
  EXPECT_FALSE(fs::exists(dir + "/f_01.exr")) << p.describe();
}

}  // namespace
