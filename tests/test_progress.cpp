// test_progress.cpp: what `spectrack render` tells while and after it renders (docs/cli.md): in a
// non-TTY run progress lines come at 0%, every 5 s and at 100% with samples done, samples/s and
// an ETA, the fraction advances within a batch, and the last lines name every file written.
#include <regex>

#include "cli_util.h"

namespace {

using namespace st_cli;

std::vector<std::string> progress_lines(const std::string& out) {
  std::vector<std::string> v;
  std::istringstream s(out);
  std::string line;
  while (std::getline(s, line))
    if (line.rfind("progress: ", 0) == 0) v.push_back(line);
  return v;
}

int percent(const std::string& line) { return std::atoi(line.c_str() + std::strlen("progress: ")); }

// A render cut by --time-limit after ~15 s of many small batches: about one line per 5 s of the
// stage loop (generous tolerance for a loaded machine), each with spp, spp/s and ETA.
TEST(CliProgress, LogLinesComeEveryFiveSeconds) {
  const std::string dir = test_dir();
  const std::string scene = write_scene(dir, "slow.json", homogeneous_scene(64, 64, 4096, 2.0, 0.0));
  RunOptions o;
  o.timeout_s = 600;
  Proc p = run({"render", scene, "-o", dir + "/x.exr", "--stats-json", dir + "/s.json", "--path-slots", "4096",
                "--time-limit", "20"}, o);
  ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
  const json stats = json::parse(std::ifstream(dir + "/s.json"));
  const double loop = stats["seconds_render"].get<double>();
  const auto lines = progress_lines(p.out);
  ASSERT_FALSE(lines.empty()) << p.out;
  EXPECT_EQ(percent(lines[0]), 0) << lines[0];
  const std::regex form(R"(progress: \d+% \([0-9.]+/4096 spp, ([0-9.e+]+|-) spp/s, (ETA [0-9:]+( s)?|ETA \?|took [0-9:]+( s)?)\))");
  for (const auto& l : lines) EXPECT_TRUE(std::regex_match(l, form)) << l;
  // 0%, then one line per 5 s: never more than that, and not far fewer (an iteration may run long)
  const double expected = 1 + loop / 5.0;
  EXPECT_LE(double(lines.size()), expected + 1.0) << p.out << "loop " << loop << " s";
  if (loop > 10) EXPECT_GE(double(lines.size()), 0.5 * expected) << p.out << "loop " << loop << " s";
  for (size_t i = 1; i < lines.size(); ++i) EXPECT_GE(percent(lines[i]), percent(lines[i - 1]));
}

// One batch only (every path in flight at once): the fraction still moves before it ends.
TEST(CliProgress, AdvancesWithinABatch) {
  const std::string dir = test_dir();
  // thick, white medium: long random walks, so the single batch takes several seconds
  const std::string scene = write_scene(dir, "thick.json", homogeneous_scene(32, 32, 64, 30.0, 0.0));
  RunOptions o;
  o.timeout_s = 600;
  Proc p = run({"render", scene, "-o", dir + "/x.exr", "--path-slots", "65536", "--batches-in-flight", "1",
                "--stats-json", dir + "/s.json"}, o);
  ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
  const auto lines = progress_lines(p.out);
  ASSERT_GE(lines.size(), 2u) << p.out;
  EXPECT_EQ(percent(lines.front()), 0);
  EXPECT_EQ(percent(lines.back()), 100) << p.out;
  const json stats = json::parse(std::ifstream(dir + "/s.json"));
  const double loop = stats["seconds_render"].get<double>();
  bool between = false;
  for (const auto& l : lines) between = between || (percent(l) > 0 && percent(l) < 100);
  // the batch is accumulated only at its end: a line in between shows the paths finished so far
  if (loop > 6.0) EXPECT_TRUE(between) << p.out << "loop " << loop << " s";
}

// The summary names the image, the preview and the statistics.
TEST(CliProgress, SummaryNamesEveryOutput) {
  const std::string dir = test_dir();
  const std::string scene = write_scene(dir, "s.json", homogeneous_scene(16, 16, 4, 1.0, 0.0));
  Proc p = run({"render", scene, "-o", dir + "/img.exr", "--preview", dir + "/img.png", "--stats-json", dir + "/st.json"},
               RunOptions{300.0});
  ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
  EXPECT_THAT(p.out, HasSubstr("wrote " + dir + "/img.exr (4 spp")) << p.out;
  EXPECT_THAT(p.out, HasSubstr("wrote " + dir + "/img.png (preview)")) << p.out;
  EXPECT_THAT(p.out, HasSubstr("wrote " + dir + "/st.json (statistics)")) << p.out;
  const auto lines = progress_lines(p.out);
  ASSERT_GE(lines.size(), 2u) << p.out;
  EXPECT_EQ(percent(lines.front()), 0);
  EXPECT_THAT(lines.back(), HasSubstr("progress: 100% (4/4 spp")) << p.out;
  EXPECT_THAT(lines.back(), HasSubstr("took")) << p.out;
}

// `devices` lines up its columns (the header's "type" column starts where every row's does).
TEST(CliProgress, DevicesTableIsAligned) {
  Proc p = run({"devices"}, RunOptions{120.0});
  ASSERT_TRUE(p.exited) << p.describe();
  if (p.code != 0) GTEST_SKIP() << "no OpenCL device";
  std::istringstream s(p.out);
  std::string header, row;
  std::getline(s, header);
  const size_t col = header.find("type");
  ASSERT_NE(col, std::string::npos) << p.out;
  while (std::getline(s, row)) {
    if (row.empty()) continue;
    EXPECT_GE(row.size(), col);
    EXPECT_EQ(row[col - 1], ' ') << p.out;
    EXPECT_NE(row[col], ' ') << p.out;
  }
}

}  // namespace
