// info.h: `spectrack info FILE... [--json]` (info.cpp).
#pragma once
#include <string>
#include <vector>

namespace spectrack {
// Prints every grid of each .vdb/.nvdb and, for a scene .json, its media's world boxes and
// optical depths, its lights and its (framed) camera; a table, or one JSON document with --json.
// Returns 0, or 1 after naming on stderr each file that could not be read and why.
int cmd_info(const std::vector<std::string>& files, bool as_json);
}  // namespace spectrack
