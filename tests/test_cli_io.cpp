// test_cli_io.cpp: how a command ends and what it leaves on disk, run as a real process: signals
// in every phase (SIGPIPE on stderr, SIGTERM from the first instant and during merge), the time
// limit counted from the command's start (set-up phases, a stage loop that finished no sample,
// frame sequences), and outputs that cannot be written (/dev/full, a path under a regular file, a
// write that fails midway).
//
// Design: as test_cli.cpp (cli_util.h). A write failing midway is made with a file-size limit
// (bash's `ulimit -f`; spectrack ignores SIGXFSZ, so the write fails with EFBIG), which holds for
// root too, unlike folder permissions. A signal "as early as possible" is sent as soon as
// /proc/PID/status shows the process catching SIGTERM, then again after short delays.
#include <OpenImageIO/imageio.h>

#include <cstdlib>

#include "cli_util.h"

namespace {

using namespace st_cli;

// Files a failed or interrupted write could have left in `dir`: temporary outputs (".x.tmp").
std::vector<std::string> temporary_files(const std::string& dir) {
  std::vector<std::string> left;
  for (auto& e : fs::directory_iterator(dir)) {
    const std::string n = e.path().filename().string();
    if (n.size() > 4 && n[0] == '.' && n.substr(n.size() - 4) == ".tmp") left.push_back(n);
  }
  return left;
}

std::string read_bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

// Whether process `pid` catches `sig` (SigCgt of /proc/PID/status).
// Whether the process `pid` runs spectrack and catches `sig`: a child between fork and exec still
// has the test process's handlers (a library loaded by an earlier test may have installed one), and
// the SIG_DFL it sets before exec would let the signal kill it.
bool catches(pid_t pid, int sig) {
  std::error_code ec;
  if (fs::read_symlink("/proc/" + std::to_string(pid) + "/exe", ec) != fs::canonical(kBinary, ec)) return false;
  std::ifstream f("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(f, line))
    if (line.rfind("SigCgt:", 0) == 0) return (std::strtoull(line.c_str() + 7, nullptr, 16) >> (sig - 1)) & 1;
  return false;
}

// Runs spectrack with `args` (output to a file), sends `sig` `delay_s` after the process first
// catches SIGTERM, and waits for it (killed after `timeout_s`).
Proc run_and_signal_early(const std::vector<std::string>& args, int sig, double delay_s, double timeout_s = 60) {
  Proc p;
  p.args = args;
  const std::string log = (fs::temp_directory_path() / ("spectrack_early_" + std::to_string(::getpid()) + ".log")).string();
  std::vector<std::string> full = args;
  full.insert(full.begin(), kBinary);
  std::vector<char*> argv;
  for (auto& a : full) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  const auto t0 = Clock::now();
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::signal(SIGTERM, SIG_DFL);
    ::signal(SIGINT, SIG_DFL);
    const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(fd, 1);
    ::dup2(fd, 2);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  int status = 0;
  bool ended = false, ready = false;
  Clock::time_point ready_at;
  while (since(t0) < timeout_s) {
    if (::waitpid(pid, &status, WNOHANG) == pid) {
      ended = true;
      break;
    }
    if (!ready && catches(pid, SIGTERM)) ready = true, ready_at = Clock::now();
    if (ready && !p.signal_sent && since(ready_at) >= delay_s) {
      ::kill(pid, sig);
      p.signal_sent = true;
    }
    ::usleep(200);
  }
  if (!ended) {
    ::kill(pid, SIGKILL);
    ::waitpid(pid, &status, 0);
    p.timed_out = true;
  }
  p.seconds = since(t0);
  p.exited = WIFEXITED(status);
  p.code = p.exited ? WEXITSTATUS(status) : -1;
  p.signaled = WIFSIGNALED(status);
  p.sig = p.signaled ? WTERMSIG(status) : 0;
  std::ifstream f(log);
  p.out.assign(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
  fs::remove(log);
  return p;
}

// Runs `script` with bash; $1, $2, ... are `args`.
Proc run_bash(const std::string& script, const std::vector<std::string>& args, double timeout_s = 120) {
  std::vector<std::string> a = {"/bin/bash", "-c", script, "bash"};
  a.insert(a.end(), args.begin(), args.end());
  RunOptions o;
  o.timeout_s = timeout_s;
  return run_command(a, o);
}

// Room for a cold kernel build.
RunOptions slow() {
  RunOptions o;
  o.timeout_s = 300;
  return o;
}

// A render that never finishes a batch: every path scatters for ever inside a huge box.
json endless_scene() { return homogeneous_scene(16, 16, 4, 10.0, 0.0, 1e6); }

// ---- signals -----------------------------------------------------------------------------------

TEST(CliSignals, ClosedStderrPipeStopsTheProgressNotTheRender) {
  std::string dir = test_dir();
  std::string scene = write_scene(dir, "s.json", homogeneous_scene(64, 64, 64, 2.0, 0.0));
  std::string exr = dir + "/x.exr";
  run({"render", scene, "-o", exr, "--quiet"}, slow());  // warm the kernel cache
  fs::remove(exr);
  // the reader takes one byte (of the banner) and goes away; the progress lines then meet EPIPE
  Proc p = run_bash("\"$1\" render \"$2\" -o \"$3\" 2>&1 | head -c 1 >/dev/null; echo \"status=${PIPESTATUS[0]}\"",
                    {kBinary, scene, exr});
  EXPECT_THAT(p.out, HasSubstr("status=0")) << p.describe();
  auto in = OIIO::ImageInput::open(exr);
  ASSERT_TRUE(in) << "no image\n" << p.describe();
  EXPECT_EQ(in->spec().get_int_attribute("spectrack:spp", -1), 64);
  EXPECT_EQ(in->spec().get_int_attribute("spectrack:interrupted", -1), 0);
}

TEST(CliSignals, SigtermFromTheFirstInstantExits130AndWritesNothing) {
  std::string dir = test_dir();
  std::string scene = write_scene(dir, "endless.json", endless_scene());
  std::string exr = dir + "/x.exr";
  // at the handler's installation (start-up), then in scene loading, set-up and the stage loop
  // (the endless scene never finishes a sample, so there is never anything to write)
  for (double delay : {0.0, 0.002, 0.02, 0.1, 0.3, 1.0}) {
    Proc p = run_and_signal_early({"render", scene, "-o", exr, "--stats-json", dir + "/s.json"}, SIGTERM, delay, 120);
    ASSERT_TRUE(p.signal_sent) << "delay " << delay << "\n" << p.describe();
    EXPECT_FALSE(p.signaled) << "delay " << delay << "\n" << p.describe();
    EXPECT_TRUE(p.exited && p.code == 130) << "delay " << delay << "\n" << p.describe();
    EXPECT_FALSE(fs::exists(exr)) << "delay " << delay << "\n" << p.describe();
    EXPECT_FALSE(fs::exists(dir + "/s.json")) << "delay " << delay << "\n" << p.describe();
  }
  EXPECT_EQ(temporary_files(dir), std::vector<std::string>{});
}

TEST(CliSignals, SigtermDuringMergeExits130AndWritesNothing) {
  std::string dir = test_dir();
  std::string scene = write_scene(dir, "s.json", homogeneous_scene(384, 384, 2, 2.0, 0.0));
  std::vector<std::string> parts;
  for (const char* r : {"0:1", "1:2"}) {
    parts.push_back(dir + "/part_" + std::string(1, r[0]) + ".exr");
    Proc p = run({"render", scene, "--spp-range", r, "--aov", "variance,emission,direct,indirect,albedo,depth", "-o",
                  parts.back(), "--quiet"}, slow());
    ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
  }
  std::string out = dir + "/merged.exr";
  for (double delay : {0.0, 0.01, 0.05}) {
    Proc p = run_and_signal_early({"merge", out, parts[0], parts[1], "--preview", dir + "/m.png"}, SIGTERM, delay);
    ASSERT_TRUE(p.signal_sent) << p.describe();
    if (p.exited && p.code == 0) continue;  // the merge was done before the signal came
    EXPECT_FALSE(p.signaled) << "delay " << delay << "\n" << p.describe();
    EXPECT_TRUE(p.exited && p.code == 130) << "delay " << delay << "\n" << p.describe();
    EXPECT_FALSE(fs::exists(out)) << p.describe();
  }
  EXPECT_EQ(temporary_files(dir), std::vector<std::string>{});
}

// ---- the time limit ----------------------------------------------------------------------------

// A limit that ends the command before any sample finished: exit 3, the message, nothing written.
void expect_time_limit_exit(const Proc& p, const std::string& dir, double limit) {
  EXPECT_FALSE(p.signaled) << p.describe();
  EXPECT_TRUE(p.exited && p.code == 3) << p.describe();
  EXPECT_THAT(p.out, HasSubstr(fmt::format("time limit of {:g} s reached during ", limit))) << p.describe();
  EXPECT_THAT(p.out, HasSubstr("no sample finished; nothing written")) << p.describe();
  for (const char* f : {"/x.exr", "/x.png", "/stats.json"}) EXPECT_FALSE(fs::exists(dir + f)) << f << "\n" << p.describe();
  EXPECT_EQ(temporary_files(dir), std::vector<std::string>{});
}

TEST(CliTimeLimit, LimitReachedDuringSetUpExits3AtTheDeadline) {
  std::string dir = test_dir();
  json s = homogeneous_scene(8, 8, 1, 1.0, 0.0);
  std::string scene = write_scene(dir, "s.json", s);
  std::vector<std::string> outs = {"-o", dir + "/x.exr", "--preview", dir + "/x.png", "--stats-json", dir + "/stats.json"};
  std::vector<std::string> a = {"render", scene, "--time-limit", "0.02"};
  a.insert(a.end(), outs.begin(), outs.end());
  Proc p = run(a);
  expect_time_limit_exit(p, dir, 0.02);
  EXPECT_LT(p.seconds, 0.02 + 1.5) << p.describe();
  // the scene's render.time_limit: the same once the scene is loaded
  s["render"]["time_limit"] = 0.02;
  a = {"render", write_scene(dir, "limited.json", s)};
  a.insert(a.end(), outs.begin(), outs.end());
  p = run(a);
  expect_time_limit_exit(p, dir, 0.02);
}

TEST(CliTimeLimit, LimitReachedLoadingALargeEnvironmentMapIsKept) {
  std::string dir = test_dir();
  const int w = 4096, h = 2048;
  std::vector<float> px(size_t(w) * h * 3);
  for (size_t i = 0; i < px.size(); ++i) px[i] = float((i * 2654435761u) % 1000) / 1000.0f;
  auto out = OIIO::ImageOutput::create(dir + "/env.exr");
  OIIO::ImageSpec spec(w, h, 3, OIIO::TypeDesc::FLOAT);
  spec.attribute("compression", "none");
  ASSERT_TRUE(out->open(dir + "/env.exr", spec) && out->write_image(OIIO::TypeDesc::FLOAT, px.data()) && out->close());
  json s = homogeneous_scene(8, 8, 1, 1.0, 0.0);
  s["lights"] = json::array({{{"type", "environment"}, {"map", "env.exr"}}});
  const auto t0 = Clock::now();
  Proc p = run({"render", write_scene(dir, "s.json", s), "-o", dir + "/x.exr", "--time-limit", "0.3"});
  expect_time_limit_exit(p, dir, 0.3);
  EXPECT_LT(since(t0), 0.3 + 1.5) << p.describe();
}

TEST(CliTimeLimit, StageLoopWithoutAFinishedSampleWritesNothing) {
  std::string dir = test_dir();
  std::string scene = write_scene(dir, "endless.json", endless_scene());
  run({"render", scene, "-o", dir + "/x.exr", "--spp", "1", "--time-limit", "8", "--quiet"}, slow());  // warm
  Proc p = run({"render", scene, "-o", dir + "/x.exr", "--stats-json", dir + "/stats.json", "--time-limit", "3"});
  expect_time_limit_exit(p, dir, 3);
  EXPECT_LT(p.seconds, 3 + 4.0) << p.describe();
}

TEST(CliTimeLimit, FrameWithoutASampleEndsTheSequenceNamingIt) {
  std::string dir = test_dir();
  const std::string vdb = small_vdb(dir);
  for (const char* f : {"/cloud_4.vdb", "/cloud_5.vdb"}) fs::copy_file(vdb, dir + f);
  json s = vdb_scene("cloud_#.vdb");
  s["render"]["time_limit"] = 0.02;  // spent before the first frame's set-up: frame 4 ends with nothing
  Proc p = run({"render", write_scene(dir, "seq.json", s), "--frames", "4:5", "-o", dir + "/f_#.exr"}, slow());
  EXPECT_TRUE(p.exited && p.code == 3) << p.describe();
  EXPECT_THAT(p.out, HasSubstr("frame 4: time limit of 0.02 s reached during ")) << p.describe();
  EXPECT_THAT(p.out, Not(HasSubstr("frame 5"))) << p.describe();
  EXPECT_FALSE(fs::exists(dir + "/f_4.exr")) << p.describe();
}

// ---- output files ------------------------------------------------------------------------------

TEST(CliOutputs, StatsToAFullDeviceFails) {
  std::string dir = test_dir();
  std::string scene = write_scene(dir, "s.json", homogeneous_scene(8, 8, 1, 1.0, 0.0));
  Proc p = run({"render", scene, "-o", dir + "/x.exr", "--stats-json", "/dev/full", "--quiet"}, slow());
  expect_error_exit(p, 1);
  EXPECT_THAT(p.out, HasSubstr("/dev/full: cannot write: No space left on device")) << p.describe();
}

TEST(CliOutputs, ImageToADeviceOrFolderIsRefusedByName) {
  std::string dir = test_dir();
  std::string scene = write_scene(dir, "s.json", homogeneous_scene(8, 8, 1, 1.0, 0.0));
  fs::create_directories(dir + "/folder");
  for (auto [out, why] : std::vector<std::pair<std::string, std::string>>{
           {"/dev/full", "is a character device"}, {dir + "/folder", "is a folder"}, {dir + "/noext", "has no extension"}}) {
    Proc p = run({"render", scene, "-o", out, "--quiet"});
    expect_error_exit(p, 1);
    EXPECT_THAT(p.out, HasSubstr(out + ": " + why)) << p.describe();
    EXPECT_THAT(p.out, Not(HasSubstr("unsupported output format ''"))) << p.describe();
  }
  Proc p = run({"merge", "/dev/full", dir + "/a.exr"});
  expect_error_exit(p, 1);
}

TEST(CliOutputs, OutputUnderARegularFileIsRefusedBeforeRendering) {
  std::string dir = test_dir();
  std::string scene = write_scene(dir, "s.json", homogeneous_scene(8, 8, 1, 1.0, 0.0));
  std::ofstream(dir + "/file") << "x";
  for (std::vector<std::string> extra : {std::vector<std::string>{"-o", dir + "/file/x.exr"},
                                         {"-o", dir + "/x.exr", "--preview", dir + "/file/x.png"},
                                         {"-o", dir + "/x.exr", "--stats-json", dir + "/file/s.json"}}) {
    std::vector<std::string> a = {"render", scene, "--quiet"};
    a.insert(a.end(), extra.begin(), extra.end());
    Proc p = run(a);
    expect_error_exit(p, 1);
    EXPECT_THAT(p.out, HasSubstr(dir + "/file is not a folder")) << p.describe();
    EXPECT_FALSE(fs::exists(dir + "/x.exr")) << p.describe();
  }
}

// A file-size limit makes the writes fail midway: no file under the final name (an older one
// stays as it was), no temporary file, the reason named.
TEST(CliOutputs, WriteFailingMidwayLeavesNoPartialFile) {
  std::string dir = test_dir();
  std::string scene = write_scene(dir, "s.json", homogeneous_scene(128, 128, 2, 2.0, 0.0));
  std::string a = dir + "/a.exr", b = dir + "/b.exr", merged = dir + "/m.exr";
  for (auto [out, range] : {std::pair{a, "0:1"}, std::pair{b, "1:2"}})
    ASSERT_EQ(run({"render", scene, "--spp-range", range, "-o", out, "--quiet"}, slow()).code, 0);
  ASSERT_EQ(run({"merge", merged, a, b, "--quiet"}).code, 0);
  const std::string before = read_bytes(merged);
  Proc p = run_bash("ulimit -f 8; exec \"$@\"", {kBinary, "merge", merged, a, b, "--quiet"});
  expect_error_exit(p, 1);
  EXPECT_THAT(p.out, HasSubstr(merged + ": cannot write: File too large")) << p.describe();
  EXPECT_EQ(read_bytes(merged), before) << "the older merge was touched";
  // a render's PNG; the same render first, without the limit, fills the kernel caches (PoCL aborts
  // when it cannot write its own cache), so that only the image meets the limit
  ASSERT_EQ(run({"render", scene, "-o", dir + "/x.png", "--quiet"}, slow()).code, 0);
  fs::remove(dir + "/x.png");
  p = run_bash("ulimit -f 1; exec \"$@\"", {kBinary, "render", scene, "-o", dir + "/x.png", "--quiet"});
  expect_error_exit(p, 1);
  EXPECT_THAT(p.out, HasSubstr(dir + "/x.png: cannot write: File too large")) << p.describe();
  EXPECT_FALSE(fs::exists(dir + "/x.png")) << p.describe();
  EXPECT_EQ(temporary_files(dir), std::vector<std::string>{});
}

}  // namespace
