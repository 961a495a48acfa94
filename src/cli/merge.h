// merge.h: the `merge` subcommand (src/cli/merge.cpp).
#pragma once
#include <CLI/CLI.hpp>

#include <string>
#include <vector>

namespace spectrack {

struct MergeArgs {
  std::string output, preview, compression;
  bool half = false;
  std::vector<std::string> inputs;
  bool quiet = false;
};

CLI::App* add_merge_command(CLI::App& app, MergeArgs& a);
// Exit code 0; throws Error (exit 1) for inputs it refuses.
int cmd_merge(const MergeArgs& a);

}  // namespace spectrack
