// test_opencl.cpp: the OpenCL runtime layer on the default device: a kernel that fails to build
// reports the build log and the file holding the assembled source; the binary cache serves a
// second build, and a corrupt or truncated entry is rebuilt rather than trusted.
#include <gtest/gtest.h>

#include <cstdlib>
#include <chrono>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>

#include "device/opencl.h"
#include "integrator/multi_device.h"
#include "kernels/types.h"

using namespace spectrack;

namespace {

struct CacheDir {
  std::string dir;
  CacheDir() {
    dir = (std::filesystem::temp_directory_path() / ("spectrack_cache_test_" + std::to_string(::getpid()))).string();
    std::filesystem::remove_all(dir);
    ::setenv("SPECTRACK_KERNEL_CACHE_DIR", dir.c_str(), 1);
    ::unsetenv("SPECTRACK_NO_KERNEL_CACHE");
  }
  ~CacheDir() {
    std::filesystem::remove_all(dir);
    ::unsetenv("SPECTRACK_KERNEL_CACHE_DIR");
  }
};

TEST(OpenCL, BuildFailurePrintsLogAndSavesSource) {
  CacheDir cache;
  DeviceInfo dev = select_device("");
  cl::Context ctx(dev.device);
  std::string src = "__kernel void broken(__global float* x) { x[0] = undefined_symbol_xyz; }\n";
  try {
    build_program(ctx, dev, src, "-cl-std=CL1.2", true);
    FAIL() << "a broken kernel must not build";
  } catch (const Error& e) {
    std::string msg = e.what();
    EXPECT_NE(msg.find("undefined_symbol_xyz"), std::string::npos) << "the build log must be in the message: " << msg;
    auto pos = msg.find("assembled source written to ");
    ASSERT_NE(pos, std::string::npos) << msg;
    std::string path = msg.substr(pos + std::string("assembled source written to ").size());
    while (!path.empty() && (path.back() == '\n' || path.back() == ' ')) path.pop_back();
    std::ifstream f(path);
    ASSERT_TRUE(f.good()) << path;
    std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
    EXPECT_EQ(text, src);
    std::filesystem::remove(path);
  }
}

TEST(OpenCL, CacheServesSecondBuildAndRebuildsCorruptEntries) {
  CacheDir cache;
  DeviceInfo dev = select_device("");
  cl::Context ctx(dev.device);
  std::string src = assemble_kernel_source({{"ST_KERNEL_MAX_MEDIA", "1"}});
  ProgramBuild a = build_program(ctx, dev, src, "-cl-std=CL1.2", true);
  EXPECT_FALSE(a.from_cache);
  ASSERT_FALSE(a.cache_file.empty());
  ASSERT_TRUE(std::filesystem::exists(a.cache_file));
  ProgramBuild b = build_program(ctx, dev, src, "-cl-std=CL1.2", true);
  EXPECT_TRUE(b.from_cache);
  EXPECT_EQ(a.cache_file, b.cache_file);
  // another option string is another entry
  ProgramBuild c = build_program(ctx, dev, src, "-cl-std=CL1.2 -DSPECTRACK_TEST_VARIANT=1", true);
  EXPECT_FALSE(c.from_cache);
  EXPECT_NE(c.cache_file, a.cache_file);
  // the scene-feature mask is in the source, so specialised kernels get their own entries
  std::string spec = assemble_kernel_source({{"ST_KERNEL_MAX_MEDIA", "1"}, {"ST_FEATURES", "0x80u"}});
  EXPECT_NE(spec, src);
  ProgramBuild sb = build_program(ctx, dev, spec, "-cl-std=CL1.2", true);
  EXPECT_FALSE(sb.from_cache);
  EXPECT_NE(sb.cache_file, a.cache_file);
  // flip a byte in the binary: the checksum fails, the entry is rebuilt and rewritten
  {
    std::fstream f(a.cache_file, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(-10, std::ios::end);
    char ch = 0;
    f.read(&ch, 1);
    f.seekp(-10, std::ios::end);
    ch = char(ch ^ 0x5a);
    f.write(&ch, 1);
  }
  ProgramBuild d = build_program(ctx, dev, src, "-cl-std=CL1.2", true);
  EXPECT_FALSE(d.from_cache) << "a corrupt entry must not be trusted";
  ProgramBuild e = build_program(ctx, dev, src, "-cl-std=CL1.2", true);
  EXPECT_TRUE(e.from_cache) << "the rebuilt entry is written back";
  // truncate it
  std::filesystem::resize_file(a.cache_file, 30);
  ProgramBuild f = build_program(ctx, dev, src, "-cl-std=CL1.2", true);
  EXPECT_FALSE(f.from_cache);
  // the kernels of a cached program run
  cl_int err = CL_SUCCESS;
  cl::Kernel k(e.program, "k_track", &err);
  EXPECT_EQ(err, CL_SUCCESS);
}

TEST(OpenCL, DisabledCacheWritesNothing) {
  CacheDir cache;
  ::setenv("SPECTRACK_NO_KERNEL_CACHE", "1", 1);
  EXPECT_EQ(kernel_cache_dir(), "");
  DeviceInfo dev = select_device("");
  cl::Context ctx(dev.device);
  ProgramBuild a = build_program(ctx, dev, "__kernel void k(__global int* x) { x[0] = 1; }", "", true);
  EXPECT_TRUE(a.cache_file.empty());
  EXPECT_FALSE(std::filesystem::exists(cache.dir));
  ::unsetenv("SPECTRACK_NO_KERNEL_CACHE");
}

TEST(OpenCL, DeviceSelection) {
  auto devs = enumerate_devices(false);
  ASSERT_FALSE(devs.empty());
  DeviceInfo d = select_device("0:0");
  EXPECT_EQ(d.platform_index, 0);
  EXPECT_EQ(d.device_index, 0);
  DeviceInfo byname = select_device(devs[0].name.substr(0, 5));
  EXPECT_EQ(byname.name, devs[0].name);
  EXPECT_THROW(select_device("7:7"), Error);
  EXPECT_THROW(select_device("definitely-not-a-device"), Error);
  ::setenv("SPECTRACK_DEVICE", "definitely-not-a-device", 1);
  try {
    select_device("");
    ADD_FAILURE() << "SPECTRACK_DEVICE must be honoured";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("SPECTRACK_DEVICE"), std::string::npos) << e.what();
  }
  // a render's device list leaves one device of the variable to select_device, which names it
  ::setenv("SPECTRACK_DEVICE", "9:9", 1);
  EXPECT_EQ(parse_device_list(""), std::vector<std::string>{""});
  try {
    select_device(parse_device_list("").front());
    ADD_FAILURE() << "SPECTRACK_DEVICE=9:9 was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("SPECTRACK_DEVICE"), std::string::npos) << e.what();
  }
  ::setenv("SPECTRACK_DEVICE", "0:0,0:0", 1);  // a list is the render's to split
  EXPECT_EQ(parse_device_list(""), (std::vector<std::string>{"0:0", "0:0"}));
  ::unsetenv("SPECTRACK_DEVICE");
}

// The assembler resolves the kernels' own #includes: the renderer's program holds every kernel
// file once (so the cache key, a hash of this text, changes with any of them), no #include of a
// kernel file is left for the device compiler, and a file is inlined before its first user.
TEST(OpenCL, AssemblerInlinesEachKernelFileOnce) {
  const std::string src = assemble_kernel_source({{"ST_KERNEL_MAX_MEDIA", "1"}});
  auto count = [&](const std::string& what) {
    size_t n = 0;
    for (size_t p = src.find(what); p != std::string::npos; p = src.find(what, p + 1)) ++n;
    return n;
  };
  for (const auto& e : std::filesystem::directory_iterator(std::string(SPECTRACK_SOURCE_DIR) + "/kernels")) {
    const std::string name = e.path().filename().string();
    if (name == "probe.cl") continue;  // the test probes' program only
    EXPECT_EQ(count("#line 1 \"kernels/" + name + "\""), 1u) << name;
  }
  EXPECT_EQ(count("#line 1 \"nanovdb/PNanoVDB.h\""), 1u);
  EXPECT_EQ(count("#line 1 \"<film_table.h"), 1u);
  EXPECT_EQ(count("#include \""), 0u);
  EXPECT_LT(src.find("#line 1 \"kernels/types.h\""), src.find("#line 1 \"kernels/medium.h\""));
  EXPECT_LT(src.find("#line 1 \"kernels/tracking.h\""), src.find("#line 1 \"kernels/track.cl\""));
  // probe.cl adds itself and nothing the renderer already holds
  const std::string probe = assemble_kernel_source({{"ST_KERNEL_MAX_MEDIA", "1"}}, {"probe.cl"});
  EXPECT_EQ(probe.size() > src.size(), true);
  EXPECT_EQ(probe.find("#line 1 \"kernels/types.h\""), probe.rfind("#line 1 \"kernels/types.h\""));
  EXPECT_THROW(kernel_files_source({"no_such_file.h"}), Error);
}

// An include may carry a one-line comment; any other quoted include is refused by file and line
// instead of reaching the device compiler as a file it cannot find.
TEST(KernelSource, IncludesWithTrailingCommentsAreInlined) {
  const std::map<std::string, std::string> files = {
      {"a.h", "int a;\n"},
      {"b.h", "int b;\n"},
      {"root.cl", "#include \"a.h\"  // a comment\n#include \"b.h\" /* another */\nint r;\n"},
      {"bad.cl", "int x;\n#include \"a.h\" int y;\n"}};
  const std::string src = kernel_files_source({"root.cl"}, files);
  EXPECT_NE(src.find("int a;"), std::string::npos);
  EXPECT_NE(src.find("int b;"), std::string::npos);
  EXPECT_EQ(src.find("#include"), std::string::npos) << src;
  try {
    kernel_files_source({"bad.cl"}, files);
    ADD_FAILURE() << "an unreadable include passed";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("kernels/bad.cl:2"), std::string::npos) << e.what();
  }
}

}  // namespace

namespace {

// The build log of `source` compiled fresh (a unique comment defeats the OpenCL runtime's own
// binary cache) with the renderer's options.
std::string fresh_build_log(const cl::Context& ctx, const DeviceInfo& dev, const std::string& source) {
  const auto now = std::chrono::steady_clock::now().time_since_epoch().count();
  cl::Program prog(ctx, source + "\n/* " + std::to_string(::getpid()) + " " + std::to_string(now) + " */\n");
  const cl_int err = prog.build({dev.device}, "-cl-std=CL1.2");
  std::string log;
  prog.getBuildInfo(dev.device, CL_PROGRAM_BUILD_LOG, &log);
  EXPECT_EQ(err, CL_SUCCESS) << log;
  return log;
}

}  // namespace

// The renderer's kernels build without a warning for a scene without any feature, with every one
// (the generic kernel), and with every feature but one, for each: a cold compile prints the count of
// its warnings to stderr ("3 warnings generated."), where a user and the CLI tests see it. The
// warnings the specialisation invites are those of a feature test folded to a constant on the
// right of && or ||: keep ST_HAS_X on the left.
TEST(KernelSource, RendererBuildsWithoutWarningsForEveryFeature) {
  ::setenv("POCL_KERNEL_CACHE", "0", 1);
  DeviceInfo dev = select_device("");
  cl::Context ctx(dev.device);
  // the check sees a warning where there is one
  const std::string twin = fresh_build_log(ctx, dev, "__kernel void k(__global int* x) { int c = x[0] || 5; x[1] = c; }\n");
  if (twin.find("warning") == std::string::npos) GTEST_SKIP() << "this OpenCL runtime reports no warnings in its build log";
  std::vector<uint32_t> masks = {0u, uint32_t(ST_FEATURES_ALL)};
  for (int b = 0; b < 32; ++b) {
    const uint32_t bit = 1u << b;
    if (!(uint32_t(ST_FEATURES_ALL) & bit)) continue;
    masks.push_back(uint32_t(ST_FEATURES_ALL) & ~bit);  // everything but the feature: its tests fold to 0
  }
  for (uint32_t mask : masks) {
    const std::string src = assemble_kernel_source({{"ST_KERNEL_MAX_MEDIA", "2"}, {"ST_FEATURES", fmt::format("0x{:x}u", mask)}});
    const std::string log = fresh_build_log(ctx, dev, src);
    EXPECT_EQ(log.find("warning"), std::string::npos) << "features 0x" << std::hex << mask << ":\n" << log;
  }
}
