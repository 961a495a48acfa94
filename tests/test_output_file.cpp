// test_output_file.cpp: OutputFile (util/output_file.h), the one way spectrack writes its
// outputs: the whole content under the final name or nothing new there, every failure an Error
// naming the file and the reason, no temporary file left behind.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>

#include "test_util.h"
#include "util/output_file.h"

namespace {

using namespace spectrack;
using testing::HasSubstr;
namespace fs = std::filesystem;

std::string slurp(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

size_t entries(const std::string& dir) {
  return size_t(std::distance(fs::directory_iterator(dir), fs::directory_iterator()));
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(OutputFile, CommitReplacesTheWholeFileAndLeavesNothingElse) {
  const std::string dir = st_test::temp_dir("output_file_commit");
  const std::string path = dir + "/a.json";
  std::ofstream(path) << "old content, longer than the new";
  write_output_file(path, "new");
  EXPECT_EQ(slurp(path), "new");
  EXPECT_EQ(entries(dir), 1u);
}

TEST(OutputFile, WithoutCommitTheOldFileStaysAndTheTemporaryGoes) {
  const std::string dir = st_test::temp_dir("output_file_abandon");
  const std::string path = dir + "/a.exr";
  std::ofstream(path) << "old";
  {
    OutputFile f(path);
    f.append("partial", 7);
    EXPECT_EQ(entries(dir), 2u);  // the old file and the temporary one
  }
  EXPECT_EQ(slurp(path), "old");
  EXPECT_EQ(entries(dir), 1u);
}

TEST(OutputFile, AFailedWriteThrowsOnCommitNamingTheFile) {
  const std::string dir = st_test::temp_dir("output_file_fail");
  const std::string path = dir + "/a.png";
  OutputFile f(path);
  f.append("abc", 3);
  f.fail("the encoder gave up");
  EXPECT_EQ(f.append("def", 3), 0u);  // nothing more after a failure
  EXPECT_THAT(error_of([&] { f.commit(); }), HasSubstr(path + ": cannot write: the encoder gave up"));
  EXPECT_FALSE(fs::exists(path));
  EXPECT_EQ(entries(dir), 0u);
}

TEST(OutputFile, AFullDeviceIsAnError) {
  EXPECT_THAT(error_of([] { write_output_file("/dev/full", std::string(100000, 'x')); }),
              HasSubstr("/dev/full: cannot write: No space left on device"));
}

TEST(OutputFile, MissingOrNonFolderParentsAreRefusedAtOnce) {
  const std::string dir = st_test::temp_dir("output_file_parent");
  std::ofstream(dir + "/file") << "x";
  EXPECT_THAT(error_of([&] { OutputFile f(dir + "/file/a.exr"); }), HasSubstr(dir + "/file is not a folder"));
  EXPECT_THAT(error_of([&] { OutputFile f(dir + "/none/a.exr"); }), HasSubstr("folder " + dir + "/none does not exist"));
  fs::create_directories(dir + "/sub");
  EXPECT_THAT(error_of([&] { OutputFile f(dir + "/sub"); }), HasSubstr("is a folder, not a file"));
}

TEST(OutputFile, ASymlinkIsFollowedToItsFile) {
  const std::string dir = st_test::temp_dir("output_file_symlink");
  fs::create_symlink("target.json", dir + "/link.json");  // dangling until written
  write_output_file(dir + "/link.json", "through");
  EXPECT_TRUE(fs::is_symlink(dir + "/link.json"));
  EXPECT_EQ(slurp(dir + "/target.json"), "through");
}

TEST(OutputFile, SignalCleanupRemovesTheTemporaryFile) {
  const std::string dir = st_test::temp_dir("output_file_signal");
  OutputFile f(dir + "/a.exr");
  f.append("x", 1);
  EXPECT_EQ(entries(dir), 1u);
  remove_temporary_outputs();
  EXPECT_EQ(entries(dir), 0u);
}

}  // namespace
