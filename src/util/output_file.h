// output_file.h: writing an output file so that its name holds either the whole new content or
// nothing new, never a part (a full disk, a quota, a file-size limit, a failed close).
//
// Design: an OutputFile writes to a fresh temporary file in the folder of the final name (the
// same file system, so the closing rename is atomic), ".<name>.<pid>-<n>.tmp"; every write and the
// close are checked and the first failure is kept with its reason; commit() renames the temporary
// file over the final name. A failure, or an OutputFile destroyed without commit, removes the
// temporary file, and commit raises Error "<path>: cannot write: <reason>". A symlink at the final
// name is followed (the file it points at is replaced). An existing final name that is not a
// regular file (a character device such as /dev/stdout or /dev/full, a FIFO) cannot be replaced
// by a rename: it is written in place, sequentially, with the same checks (a FIFO is opened
// without waiting for a reader). The temporary names are registered so that a signal handler can
// remove them (remove_temporary_outputs) before it ends the process. Files are not fsynced: a
// power cut may lose a file the command reported written, as it may any other.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>

#include "util/error.h"

namespace spectrack {

class OutputFile {
 public:
  // Opens the temporary file (or the device in place); throws Error naming `path` and the reason
  // when the folder is missing, not a folder, not writable or full.
  explicit OutputFile(const std::string& path);
  ~OutputFile();  // removes the temporary file unless committed
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;

  // Writes at `offset`, or at the end of what was written; they never throw (image libraries call
  // them through C code) and return the bytes written: fewer means failed(), and commit will throw.
  size_t write_at(const void* data, size_t bytes, uint64_t offset) noexcept;
  size_t append(const void* data, size_t bytes) noexcept { return write_at(data, bytes, size_); }
  uint64_t size() const { return size_; }
  bool failed() const { return !error_.empty(); }
  // Marks the file failed with a reason found by the caller (an image library's message).
  void fail(const std::string& reason) noexcept;
  // Closes, checks, renames into place; throws Error "<path>: cannot write: <reason>" after
  // removing the temporary file when anything failed.
  void commit();

  const std::string& path() const { return path_; }
  bool in_place() const { return in_place_; }

 private:
  void discard() noexcept;
  std::string path_, target_, temp_;  // the name given, the file it names (symlinks followed), the temporary file
  int fd_ = -1, slot_ = -1;
  bool in_place_ = false;
  uint64_t size_ = 0;
  std::string error_;
};

// An OutputFile holding `bytes`, committed.
void write_output_file(const std::string& path, const std::string& bytes);

// Throws Error unless a file named `path` can be created: not a folder, its folder exists and
// takes a new file (tried by creating and removing a temporary file, which also catches a
// read-only file system or a full inode table, whoever runs the command).
void check_creatable_file(const std::string& path);

// Removes every temporary file an OutputFile holds now; async-signal-safe (unlink only).
void remove_temporary_outputs() noexcept;

}  // namespace spectrack
