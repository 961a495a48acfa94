// output_file.cpp: see output_file.h.
#include "util/output_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>

namespace spectrack {
namespace {

namespace fs = std::filesystem;

// The temporary files open now, for remove_temporary_outputs: state 0 free, 1 being filled, 2 set.
struct TempSlot {
  std::atomic<int> state{0};
  char path[4096];
};
TempSlot g_slots[16];
std::atomic<unsigned> g_counter{0};

int register_temp(const std::string& p) {
  if (p.size() >= sizeof(TempSlot::path)) return -1;
  for (int i = 0; i < int(sizeof(g_slots) / sizeof(g_slots[0])); ++i) {
    int expected = 0;
    if (!g_slots[i].state.compare_exchange_strong(expected, 1)) continue;
    std::memcpy(g_slots[i].path, p.c_str(), p.size() + 1);
    g_slots[i].state.store(2);
    return i;
  }
  return -1;  // more than 16 at once: not removed by a signal (never the case in the CLI)
}

void release_temp(int slot) {
  if (slot >= 0) g_slots[slot].state.store(0);
}

// The file a path names, symlinks followed (also one that points at a file not there yet).
std::string follow_symlinks(const std::string& p) {
  fs::path q = p;
  for (int hops = 0; hops < 40; ++hops) {
    struct stat st;
    if (::lstat(q.c_str(), &st) != 0 || !S_ISLNK(st.st_mode)) break;
    std::error_code ec;
    fs::path t = fs::read_symlink(q, ec);
    if (ec) break;
    q = t.is_absolute() ? t : q.parent_path() / t;
  }
  return q.string();
}

const char* kind_of(mode_t m) {
  if (S_ISCHR(m)) return "a character device";
  if (S_ISFIFO(m)) return "a FIFO (named pipe)";
  if (S_ISBLK(m)) return "a block device";
  if (S_ISSOCK(m)) return "a socket";
  return "not a regular file";
}

// Why a file cannot be created in `dir`, in words.
std::string create_failure(const fs::path& dir, int err) {
  std::error_code ec;
  if (err == ENOENT && !fs::is_directory(dir, ec)) return fmt::format("its folder {} does not exist", dir.string());
  if (err == ENOTDIR) return fmt::format("{} is not a folder (a part of the path is a file)", dir.string());
  return fmt::format("cannot create a file in its folder {}: {}", dir.string(), std::strerror(err));
}

}  // namespace

OutputFile::OutputFile(const std::string& path) : path_(path) {
  if (path.empty()) throw Error("an output file name is empty");
  struct stat st;
  if (::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode)) {  // the kernel follows /dev/stdout's links
    if (S_ISDIR(st.st_mode)) throw Error(fmt::format("{}: is a folder, not a file", path));
    if (!S_ISCHR(st.st_mode) && !S_ISFIFO(st.st_mode))
      throw Error(fmt::format("{}: is {}, not a regular file", path, kind_of(st.st_mode)));
    // a device or FIFO is written in place; O_NONBLOCK: a FIFO without a reader fails at once
    fd_ = ::open(path.c_str(), O_WRONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd_ < 0) {
      const int err = errno;
      throw Error(fmt::format("{}: cannot open {} for writing: {}", path, kind_of(st.st_mode),
                              err == ENXIO ? "no process reads it" : std::strerror(err)));
    }
    ::fcntl(fd_, F_SETFL, ::fcntl(fd_, F_GETFL) & ~O_NONBLOCK);
    in_place_ = true;
    return;
  }
  target_ = follow_symlinks(path);
  fs::path dir = fs::path(target_).parent_path();
  if (dir.empty()) dir = ".";
  std::string name = fs::path(target_).filename().string();
  if (name.empty() || name == "." || name == "..") throw Error(fmt::format("{}: names a folder, not a file", path));
  if (name.size() > 200) name.resize(200);  // room for the suffix within NAME_MAX
  for (int tries = 0;; ++tries) {
    temp_ = (dir / fmt::format(".{}.{}-{}.tmp", name, long(::getpid()), g_counter.fetch_add(1))).string();
    fd_ = ::open(temp_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd_ >= 0) break;
    const int err = errno;
    if (err == EEXIST && tries < 100) continue;
    temp_.clear();
    throw Error(fmt::format("{}: {}", path, create_failure(dir, err)));
  }
  slot_ = register_temp(temp_);
}

OutputFile::~OutputFile() { discard(); }

void OutputFile::fail(const std::string& reason) noexcept {
  try {
    if (error_.empty()) error_ = reason.empty() ? std::string("unknown failure") : reason;
  } catch (...) {
  }
}

size_t OutputFile::write_at(const void* data, size_t bytes, uint64_t offset) noexcept {
  if (failed() || fd_ < 0) return 0;
  if (in_place_ && offset != size_) {
    fail(fmt::format("{} cannot be written out of order (it is not a regular file)", path_));
    return 0;
  }
  const char* p = static_cast<const char*>(data);
  size_t done = 0;
  while (done < bytes) {
    const ssize_t n = in_place_ ? ::write(fd_, p + done, bytes - done)
                                : ::pwrite(fd_, p + done, bytes - done, off_t(offset + done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      fail(n == 0 ? std::string("the device took no bytes") : std::string(std::strerror(errno)));
      break;
    }
    done += size_t(n);
  }
  size_ = std::max<uint64_t>(size_, offset + done);
  return done;
}

void OutputFile::commit() {
  if (fd_ >= 0) {
    if (::close(fd_) != 0) fail(std::strerror(errno));  // NFS and some file systems report here
    fd_ = -1;
  }
  if (!failed() && !in_place_ && ::rename(temp_.c_str(), target_.c_str()) != 0)
    fail(fmt::format("cannot rename {} to it: {}", temp_, std::strerror(errno)));
  if (failed()) {
    discard();
    throw Error(fmt::format("{}: cannot write: {}{}", path_, error_,
                            in_place_ ? "" : " (nothing was written under this name)"));
  }
  release_temp(slot_);
  slot_ = -1;
  temp_.clear();
}

void OutputFile::discard() noexcept {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  release_temp(slot_);
  slot_ = -1;
  if (!temp_.empty()) ::unlink(temp_.c_str());
  temp_.clear();
}

void write_output_file(const std::string& path, const std::string& bytes) {
  OutputFile f(path);
  f.append(bytes.data(), bytes.size());
  f.commit();
}

void check_creatable_file(const std::string& path) { OutputFile probe(path); }

void remove_temporary_outputs() noexcept {
  for (TempSlot& s : g_slots)
    if (s.state.load() == 2) ::unlink(s.path);
}

}  // namespace spectrack
