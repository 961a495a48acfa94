// error.h: the one exception type for user-facing failures (bad scene, bad file, bad flag,
// device failure). Its message is printed as is by the CLI, which then exits non-zero, so it
// must name the file, the field (JSON path) or the call, and the reason.
#pragma once
#include <stdexcept>
#include <string>

namespace spectrack {

struct Error : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// A bad command line found after parsing (a flag that contradicts the scene): the CLI exits 2.
struct UsageError : Error {
  using Error::Error;
};

}  // namespace spectrack
