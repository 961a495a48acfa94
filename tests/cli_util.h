// cli_util.h: running the `spectrack` binary (SPECTRACK_BINARY) as a real process for the CLI
// tests: fork+exec with stdout and stderr merged into one pipe, stdin from /dev/null, a wall-clock
// limit after which the child is killed, and an optional signal sent once given text appeared;
// plus small scenes and a per-test folder that is removed when the test passes.
#pragma once
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <variant>
#include <vector>

#include <OpenImageIO/imageio.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "image/image.h"
#include "test_util.h"

#ifndef SPECTRACK_BINARY
#error "SPECTRACK_BINARY must be defined (the path of the spectrack executable)"
#endif
#ifndef SHARED_DATA_DIR
#error "SHARED_DATA_DIR must be defined (../shared/data/vdb)"
#endif

namespace st_cli {

using testing::HasSubstr;
using testing::Not;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using json = nlohmann::json;

inline const std::string kBinary = SPECTRACK_BINARY;
inline const std::string kShared = SHARED_DATA_DIR;

inline double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// ---- running the binary ------------------------------------------------------------------------

struct RunOptions {
  double timeout_s = 60.0;  // the child is killed (SIGKILL) after this long
  std::string binary;       // the executable run() starts; empty = SPECTRACK_BINARY
  // Optional: send `signal` `signal_delay_s` seconds after `signal_after_text` first appears in
  // the output (immediately counted from the start when the text is empty).
  int signal = 0;
  std::string signal_after_text;
  double signal_delay_s = 0.0;
  // ... and only once this text followed by a digit 1-9 has appeared (e.g. "progress: " for a
  // progress line of at least 10%).
  std::string signal_also_needs;
};

// Whether `text` holds `prefix` followed by a digit 1-9.
inline bool has_nonzero_after(const std::string& text, const std::string& prefix) {
  for (size_t at = text.find(prefix); at != std::string::npos; at = text.find(prefix, at + 1)) {
    size_t d = at + prefix.size();
    if (d < text.size() && text[d] >= '1' && text[d] <= '9') return true;
  }
  return false;
}

struct Proc {
  std::vector<std::string> args;
  std::string out;  // stdout and stderr, interleaved as written
  bool exited = false, signaled = false, timed_out = false, signal_sent = false;
  int code = -1, sig = 0;
  double seconds = 0.0;              // from fork to exit
  double seconds_after_signal = -1;  // from our signal to exit

  // For failure messages: the command, how it ended and what it printed.
  std::string describe() const {
    std::ostringstream s;
    s << "command:";
    for (auto& a : args) s << " '" << a << "'";
    s << "\nended: ";
    if (timed_out) s << "TIMED OUT (killed) ";
    if (exited) s << "exit code " << code;
    if (signaled) s << "killed by signal " << sig << " (" << strsignal(sig) << ")";
    s << " after " << seconds << " s\noutput:\n" << out;
    return s.str();
  }
};

// Runs argv[0] (a path) with the arguments that follow.
inline Proc run_command(std::vector<std::string> args, const RunOptions& o = {}) {
  Proc p;
  p.args = args;
  int fd[2];
  if (::pipe2(fd, O_CLOEXEC) != 0) {
    ADD_FAILURE() << "pipe2: " << std::strerror(errno);
    return p;
  }
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  const auto t0 = Clock::now();
  pid_t pid = ::fork();
  if (pid < 0) {
    ADD_FAILURE() << "fork: " << std::strerror(errno);
    ::close(fd[0]);
    ::close(fd[1]);
    return p;
  }
  if (pid == 0) {
    // Child: a clean signal state (the test runner may ignore or block SIGINT), output to the pipe.
    ::signal(SIGINT, SIG_DFL);
    ::signal(SIGTERM, SIG_DFL);
    ::signal(SIGPIPE, SIG_DFL);
    sigset_t none;
    sigemptyset(&none);
    ::sigprocmask(SIG_SETMASK, &none, nullptr);
    int devnull = ::open("/dev/null", O_RDONLY);
    if (devnull >= 0) ::dup2(devnull, 0);
    ::dup2(fd[1], 1);
    ::dup2(fd[1], 2);
    ::execv(argv[0], argv.data());
    const char msg[] = "test_cli: execv failed\n";
    (void)!::write(2, msg, sizeof(msg) - 1);
    ::_exit(127);
  }
  ::close(fd[1]);
  bool eof = false;
  double text_seen_at = o.signal_after_text.empty() ? 0.0 : -1.0;
  Clock::time_point signal_time;
  int status = 0;
  for (;;) {
    if (!eof) {
      pollfd pfd{fd[0], POLLIN, 0};
      int n = ::poll(&pfd, 1, 20);
      if (n > 0) {
        char buf[4096];
        ssize_t got = ::read(fd[0], buf, sizeof(buf));
        if (got > 0) p.out.append(buf, size_t(got));
        else if (got == 0 || (errno != EINTR && errno != EAGAIN)) eof = true;
      }
    } else {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    pid_t w = ::waitpid(pid, &status, WNOHANG);
    if (w == pid) break;
    const double t = since(t0);
    if (o.signal && !p.signal_sent) {
      if (text_seen_at < 0 && p.out.find(o.signal_after_text) != std::string::npos) text_seen_at = t;
      const bool also = o.signal_also_needs.empty() || has_nonzero_after(p.out, o.signal_also_needs);
      if (text_seen_at >= 0 && t >= text_seen_at + o.signal_delay_s && also) {
        ::kill(pid, o.signal);
        p.signal_sent = true;
        signal_time = Clock::now();
      }
    }
    if (t > o.timeout_s) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, &status, 0);
      p.timed_out = true;
      break;
    }
  }
  p.seconds = since(t0);
  if (p.signal_sent) p.seconds_after_signal = since(signal_time);
  // Whatever is still in the pipe (the child has exited, so this ends).
  for (;;) {
    char buf[4096];
    ssize_t got = ::read(fd[0], buf, sizeof(buf));
    if (got > 0) p.out.append(buf, size_t(got));
    else if (got < 0 && errno == EINTR) continue;
    else break;
  }
  ::close(fd[0]);
  p.exited = WIFEXITED(status);
  p.code = p.exited ? WEXITSTATUS(status) : -1;
  p.signaled = WIFSIGNALED(status);
  p.sig = p.signaled ? WTERMSIG(status) : 0;
  return p;
}

// Runs the spectrack binary with `args`.
inline Proc run(std::vector<std::string> args, const RunOptions& o = {}) {
  args.insert(args.begin(), o.binary.empty() ? kBinary : o.binary);
  return run_command(args, o);
}

// ---- scenes ------------------------------------------------------------------------------------

// A box of homogeneous medium lit by a white environment, seen by the default camera.
inline json homogeneous_scene(int width, int height, int spp, double sigma_s, double sigma_a, double half = 1.0) {
  return json{
      {"format", "spectrack-scene/1"},
      {"camera", {{"type", "perspective"}, {"position", {0, 0, -4}}, {"look_at", {0, 0, 0}}, {"up", {0, 1, 0}},
                  {"fov_deg", 40}}},
      {"film", {{"width", width}, {"height", height}, {"spp", spp}, {"output", "out.exr"}}},
      {"render", {{"tracker", "spectral"}, {"spectral_scheme", "history-average"}, {"seed", 7}}},
      {"lights", json::array({{{"type", "environment"}, {"radiance", {1.0, 1.0, 1.0}}}})},
      {"media", json::array({{{"name", "box"},
                              {"type", "homogeneous"},
                              {"bounds", {{-half, -half, -half}, {half, half, half}}},
                              {"sigma_s", {sigma_s, sigma_s, sigma_s}},
                              {"sigma_a", {sigma_a, sigma_a, sigma_a}},
                              {"phase", {{"type", "isotropic"}}}}})}};
}

// The same frame around one VDB medium (`file` absolute or relative to the scene folder).
inline json vdb_scene(const std::string& file, const std::string& grid = "") {
  json s = homogeneous_scene(8, 8, 1, 1.0, 0.0);
  json m = {{"name", "cloud"}, {"type", "vdb"}, {"file", file}, {"sigma_s", {1.0, 1.0, 1.0}},
            {"sigma_a", {0.0, 0.0, 0.0}}, {"phase", {{"type", "hg"}, {"g", 0.3}}}};
  if (!grid.empty()) m["grid"] = grid;
  s["media"] = json::array({m});
  return s;
}

// The lumpy test volume `vdb` (st_test::write_lumpy), chromatic, under a blue environment and a sun:
// every path type contributes.
inline json lumpy_sky_scene(const std::string& vdb) {
  json s = vdb_scene(vdb);
  s["camera"]["fov_deg"] = 35;
  s["media"][0]["density_scale"] = 6.0;
  s["media"][0]["sigma_s"] = {1.0, 0.6, 0.3};
  s["media"][0]["sigma_a"] = {0.05, 0.1, 0.2};
  s["lights"] = json::array({{{"type", "environment"}, {"radiance", {0.3, 0.4, 0.6}}},
                             {{"type", "directional"}, {"to_light", {-0.5, 1.0, -0.3}}, {"irradiance", {3, 3, 3}}}});
  return s;
}

// lumpy_sky_scene on a small film (24x16 unless given), the lumpy volume written into `dir` once:
// a chromatic, heterogeneous scene for renders to a noise target, uniform or adaptive, denoised.
inline json small_noise_scene(const std::string& dir, int width = 24, int height = 16) {
  const std::string vdb = dir + "/lumpy.vdb";
  if (!fs::exists(vdb)) st_test::write_lumpy(vdb);
  json s = lumpy_sky_scene(vdb);
  s["film"]["width"] = width;
  s["film"]["height"] = height;
  return s;
}

// Every channel of every pixel of an image file as floats, pixel-major (empty, and a test
// failure, when it cannot be read); `channels` gets the channel count.
inline std::vector<float> image_pixels(const std::string& path, int* channels = nullptr) {
  auto in = OIIO::ImageInput::open(path);
  EXPECT_TRUE(in) << path;
  if (!in) return {};
  const auto& spec = in->spec();
  if (channels) *channels = spec.nchannels;
  std::vector<float> px(size_t(spec.width) * spec.height * spec.nchannels);
  in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, px.data());
  return px;
}

inline std::string write_scene(const std::string& dir, const std::string& name, const json& scene) {
  std::string path = dir + "/" + name;
  std::ofstream(path) << scene.dump(2);
  return path;
}

// A per-test folder (the test's name and the process id keep parallel runs apart), removed when
// the test passes (st_test::temp_dir).
inline std::string test_dir() {
  const auto* info = testing::UnitTest::GetInstance()->current_test_info();
  std::string d = st_test::temp_dir(std::string("cli_") + info->test_suite_name() + "_" + info->name());
  // Start empty: a left-over image would hide a missing one.
  for (auto& e : fs::directory_iterator(d)) fs::remove_all(e.path());
  return d;
}

// A small valid fog volume ("density" grid) to point scenes at.
inline std::string small_vdb(const std::string& dir) {
  std::string path = dir + "/small.vdb";
  st_test::write_vdb(path, "density", openvdb::Coord(-4), openvdb::Coord(4), [](int, int, int) { return 0.5f; }, 0.2);
  return path;
}

// A spectrack:* metadata value of an EXR read back, as text ("<missing>" when absent).
inline std::string meta_string(const spectrack::RgbImage& img, const std::string& key) {
  auto it = img.meta.find(key);
  if (it == img.meta.end()) return "<missing>";
  if (auto s = std::get_if<std::string>(&it->second)) return *s;
  if (auto i = std::get_if<int>(&it->second)) return std::to_string(*i);
  return std::to_string(std::get<float>(it->second));
}

// Checks that `p` failed as a user-facing error: exit code 1, no signal, in time.
inline void expect_error_exit(const Proc& p, int code = 1) {
  EXPECT_FALSE(p.timed_out) << p.describe();
  EXPECT_FALSE(p.signaled) << p.describe();
  EXPECT_TRUE(p.exited) << p.describe();
  EXPECT_EQ(p.code, code) << p.describe();
}

// Runs `spectrack render <scene> -o <dir>/out.exr --quiet` and expects a scene error naming the
// scene file and `json_path` with every one of `words`.
inline void expect_scene_error(const std::string& dir, const json& scene, const std::string& json_path,
                        const std::vector<std::string>& words) {
  std::string path = write_scene(dir, "scene_under_test.json", scene);
  Proc p = run({"render", path, "-o", dir + "/out.exr", "--quiet"});
  expect_error_exit(p);
  EXPECT_THAT(p.out, HasSubstr("error:")) << p.describe();
  EXPECT_THAT(p.out, HasSubstr("scene_under_test.json")) << p.describe();
  EXPECT_THAT(p.out, HasSubstr(json_path)) << p.describe();
  for (auto& w : words) EXPECT_THAT(p.out, HasSubstr(w)) << p.describe();
  EXPECT_FALSE(fs::exists(dir + "/out.exr")) << "an image was written despite the error\n" << p.describe();
}

}  // namespace st_cli
