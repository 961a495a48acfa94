// error.h: the one exception type for user-facing failures (bad scene, bad file, bad flag,
// device failure). Its message is printed as is by the CLI, which then exits non-zero, so it
// must name the file, the field (JSON path) or the call, and the reason.
#pragma once
#include <stdexcept>
#include <string>

namespace spectrack {

struct Error : std::runtime_error {
  explicit Error(const std::string& what) : std::runtime_error(visible(what)) {}
  explicit Error(const char* what) : std::runtime_error(what) {}

 private:
  // A NUL byte (a JSON string may hold one) would end the message where it is printed: shown as \0.
  static std::string visible(const std::string& what) {
    if (what.find('\0') == std::string::npos) return what;
    std::string s;
    for (char c : what) s += c == '\0' ? std::string("\\0") : std::string(1, c);
    return s;
  }
};

// A bad command line found after parsing (a flag that contradicts the scene): the CLI exits 2.
struct UsageError : Error {
  using Error::Error;
};

}  // namespace spectrack
