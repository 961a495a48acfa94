// strings.h: the small string helpers every folder uses: lower case, a file's lower-case
// extension (how every reader and writer tells formats apart: ".EXR" is ".exr") and joining
// a list of names for a message.
#pragma once
#include <string>
#include <vector>

namespace spectrack {

// s in lower case (ASCII letters only; other bytes stay as they are).
std::string to_lower(std::string s);
// The extension of path's file name, dot included, in lower case ("" without one).
std::string lower_extension(const std::string& path);
// The items separated by sep: join({"a", "b"}, ", ") is "a, b".
std::string join(const std::vector<std::string>& items, const char* sep);

}  // namespace spectrack
