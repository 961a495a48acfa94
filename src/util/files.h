// files.h: the files a command reads and writes, checked before anything is read or rendered.
//
// Design: every input (scene JSON, VDB/NanoVDB, environment map, merge input) goes through
// check_input_file, which stats the path (following symlinks) and refuses anything that is not a
// regular file (a FIFO would block the reader for ever, /dev/zero would grow memory without
// bound, a folder is not a file) and any file larger than the caller's bound; read_input_file
// also reads it through one descriptor opened with O_NONBLOCK and re-checked with fstat, and
// stops one byte past the bound, so a file that grows (or a /proc file whose size says 0) cannot
// make it read more. Outputs are compared with inputs and with each other by what they name:
// device and inode where the file exists (hard links, symlinks), else the canonical path of the
// folder plus the name (so "./x.exr", "x.exr" and "dir/../x.exr" are one file).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "util/error.h"

#include <sys/stat.h>

namespace spectrack {

// `what` names the path in messages: "scene file", "/media/0/file", "--stats-json".
struct NamedPath {
  std::string what;
  std::string path;
};

constexpr uint64_t kMaxSceneBytes = uint64_t(64) << 20;  // a scene JSON is a few KiB; 64 MiB is absurd

// Throws Error "<context>: <path>: <reason>" (context may be empty) unless `path` is a regular
// file of at most max_bytes; returns its size.
uint64_t check_input_file(const std::string& path, const std::string& context, uint64_t max_bytes = UINT64_MAX);
// check_input_file, then the whole content (at most max_bytes; more is an error).
std::string read_input_file(const std::string& path, const std::string& context, uint64_t max_bytes);

// Throws Error unless every non-empty output names a different file from every other output and
// from every input; the message names both (their `what` and path) and the file they share.
void check_distinct_paths(const std::vector<NamedPath>& outputs, const std::vector<NamedPath>& inputs);
// Whether a and b name the same file (existing or not), as check_distinct_paths compares them.
bool same_file(const std::string& a, const std::string& b);

// What a file of mode `m` is, in words ("a folder", "a FIFO (named pipe)", ...), for messages
// that refuse it.
const char* kind_of(mode_t m);

}  // namespace spectrack
