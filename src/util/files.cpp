// files.cpp: see files.h.
#include "util/files.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>

namespace spectrack {
namespace {

namespace fs = std::filesystem;

std::string prefix(const std::string& context, const std::string& path) {
  return (context.empty() ? "" : context + ": ") + path + ": ";
}


[[noreturn]] void refuse(const std::string& context, const std::string& path, const std::string& reason) {
  throw Error(prefix(context, path) + reason);
}

void check_stat(const struct stat& st, const std::string& path, const std::string& context, uint64_t max_bytes) {
  if (!S_ISREG(st.st_mode))
    refuse(context, path, std::string("is ") + kind_of(st.st_mode) + ", not a regular file; spectrack reads inputs "
                          "from regular files only");
  if (uint64_t(st.st_size) > max_bytes)
    refuse(context, path, "is " + std::to_string(uint64_t(st.st_size)) + " bytes, more than the " +
                              std::to_string(max_bytes) + " bytes such a file can be");
}

// What a path names, for comparisons: the file's identity where it exists, else a canonical
// path (dangling symlinks followed to the file they would create).
struct Identity {
  bool exists = false;
  dev_t dev = 0;
  ino_t ino = 0;
  std::string path;
};

Identity identify(const std::string& p) {
  Identity id;
  struct stat st;
  if (::stat(p.c_str(), &st) == 0) {
    id.exists = true;
    id.dev = st.st_dev;
    id.ino = st.st_ino;
  }
  std::error_code ec;
  fs::path q = fs::absolute(p, ec);
  // a dangling symlink writes where it points
  for (int hops = 0; hops < 40 && fs::is_symlink(fs::symlink_status(q, ec)); ++hops) {
    fs::path t = fs::read_symlink(q, ec);
    if (ec) break;
    q = t.is_absolute() ? t : q.parent_path() / t;
  }
  fs::path c = fs::weakly_canonical(q, ec);
  id.path = (ec ? q.lexically_normal() : c).string();
  return id;
}

bool same(const Identity& a, const Identity& b) {
  if (a.exists && b.exists) return a.dev == b.dev && a.ino == b.ino;
  return a.path == b.path;
}

}  // namespace

const char* kind_of(mode_t m) {
  if (S_ISDIR(m)) return "a folder";
  if (S_ISFIFO(m)) return "a FIFO (named pipe)";
  if (S_ISCHR(m)) return "a character device";
  if (S_ISBLK(m)) return "a block device";
  if (S_ISSOCK(m)) return "a socket";
  return "not a regular file";
}

uint64_t check_input_file(const std::string& path, const std::string& context, uint64_t max_bytes) {
  struct stat st;
  if (::stat(path.c_str(), &st) != 0) {
    const int err = errno;
    refuse(context, path, err == ENOENT ? std::string("no such file") : std::string("cannot stat: ") + std::strerror(err));
  }
  check_stat(st, path, context, max_bytes);
  return uint64_t(st.st_size);
}

std::string read_input_file(const std::string& path, const std::string& context, uint64_t max_bytes) {
  check_input_file(path, context, max_bytes);
  // O_NONBLOCK: should the path have become a FIFO since the stat, open must not wait for a writer
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    const int err = errno;
    refuse(context, path, std::string("cannot open: ") + std::strerror(err));
  }
  struct stat st;
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode) || uint64_t(st.st_size) > max_bytes) {
    ::close(fd);
    check_input_file(path, context, max_bytes);  // names the reason
    refuse(context, path, "changed while it was opened");
  }
  std::string text;
  char buf[65536];
  for (;;) {
    const ssize_t n = ::read(fd, buf, sizeof buf);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      const int err = errno;
      ::close(fd);
      refuse(context, path, std::string("read error: ") + std::strerror(err));
    }
    if (n == 0) break;
    text.append(buf, size_t(n));
    if (text.size() > max_bytes) {
      ::close(fd);
      refuse(context, path, "holds more than the " + std::to_string(max_bytes) + " bytes such a file can be");
    }
  }
  ::close(fd);
  return text;
}

bool same_file(const std::string& a, const std::string& b) { return same(identify(a), identify(b)); }

void check_distinct_paths(const std::vector<NamedPath>& outputs, const std::vector<NamedPath>& inputs) {
  std::vector<std::pair<const NamedPath*, Identity>> outs, ins;
  for (const NamedPath& o : outputs)
    if (!o.path.empty()) outs.push_back({&o, identify(o.path)});
  for (const NamedPath& i : inputs)
    if (!i.path.empty()) ins.push_back({&i, identify(i.path)});
  auto clash = [](const NamedPath& a, const NamedPath& b, const Identity& id, const char* how) {
    throw Error(a.what + " " + a.path + " and " + b.what + " " + b.path + " name the same file (" + id.path + "): " +
                how + "; give them different names");
  };
  for (size_t i = 0; i < outs.size(); ++i)
    for (size_t j = i + 1; j < outs.size(); ++j)
      if (same(outs[i].second, outs[j].second))
        clash(*outs[i].first, *outs[j].first, outs[i].second, "one output would overwrite the other");
  for (auto& o : outs)
    for (auto& in : ins)
      if (same(o.second, in.second)) clash(*o.first, *in.first, in.second, "it would be both an input and the output of this command");
}

}  // namespace spectrack
