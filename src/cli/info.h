// info.h: `spectrack info FILE... [--json] [--frames A:B]` (info.cpp).
#pragma once
#include <array>
#include <optional>
#include <string>
#include <vector>

namespace spectrack {
// Prints every grid of each .vdb/.nvdb and, for a scene .json, its media's world boxes and
// optical depths, its lights and its (framed) camera; a table, or one JSON document with --json.
// Returns 0, or 1 after naming on stderr each file that could not be read and why.
// With `frames` [A, B], a frame pattern (scene/frames.h) in a volume's name, or in a scene's media
// files, stands for frames A..B (a scene's frames share the sequence's framed camera).
int cmd_info(const std::vector<std::string>& files, bool as_json,
             const std::optional<std::array<long long, 2>>& frames = std::nullopt);
}  // namespace spectrack
