// main.cpp: the spectrack command line (CLI11), shaped like pbrt's and Mitsuba's:
//   spectrack render SCENE [-o FILE] [--spp N | --spp-range A:B] [--pixel-bounds x0,x1,y0,y1]
//                    [--seed S] [--tracker T] [--scheme S] [--device D|all|D1,D2] [--mpi]
//                    [--stats-json FILE] [--preview FILE.png] [--quiet]
//   spectrack merge OUT.exr IN.exr... [--preview FILE.png]   (cli/merge.cpp)
//   (tuning: [--majorant-cell N] [--majorant-block N] [--generic-kernels] [--batches-in-flight N])
//   spectrack devices   (cli/devices.cpp)
//   spectrack info FILE... [--json] [--frames A:B]   (cli/info.cpp)
// main only dispatches: each subcommand is its own file (render: cli/render.cpp and
// cli/render_flags.cpp). The values of the options are checked by the validators of
// cli/options.h (exit 2).
// A render is a FilmPiece (film/film.h): the window and sample range it holds, with exact
// per-pixel sums; shards, tiles, devices and MPI ranks all combine through merge_pieces.
// Exit codes: 0 success; 1 a user-facing error (message on stderr names file, field and reason);
// 2 bad command line; 3 the time limit came before any sample finished (nothing written);
// 130 interrupted (the image of the finished samples is still written and marked `interrupted`
// in its metadata; cli/run_control.h).
#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <iostream>
#include <string>
#include <vector>

#include "cli/devices.h"
#include "cli/info.h"
#include "cli/merge.h"
#include "cli/options.h"
#include "cli/render.h"
#include "cli/run_control.h"
#include "util/error.h"

using namespace spectrack;

// A first argument that is neither an option nor a command is named, with the commands (CLI11
// would say only "A subcommand is required").
static bool unknown_command(CLI::App& app, int argc, char** argv) {
  if (argc < 2 || argv[1][0] == '-') return false;
  std::vector<std::string> names;
  for (const CLI::App* c : app.get_subcommands({})) names.push_back(c->get_name());
  if (std::find(names.begin(), names.end(), argv[1]) != names.end()) return false;
  std::cerr << "error: unknown command '" << argv[1] << "' (the commands: " << fmt::format("{}", fmt::join(names, ", "))
            << "; spectrack --help)\n";
  return true;
}

int main(int argc, char** argv) {
  install_signal_handlers();  // first: a signal in any phase ends the command with 130, never by the signal
  CLI::App app{"spectrack: spectral and decomposition tracking for heterogeneous volumes on OpenCL"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("spectrack ") + SPECTRACK_VERSION);
  RenderArgs ra;
  add_render_command(app, ra);
  MergeArgs ma;
  add_merge_command(app, ma);
  app.add_subcommand("devices", "list OpenCL platforms and devices");
  std::vector<std::string> info_files;
  bool info_json = false;
  auto* info = app.add_subcommand("info", "print the grids of VDB/NanoVDB files and the media, lights and camera of scenes");
  info->add_option("files", info_files, "volume (.vdb, .nvdb) or scene files (.json, or any other name, as render reads them)")->required()->expected(1, -1);
  info->add_flag("--json", info_json, "one JSON document instead of tables");
  std::string info_frames;
  info->add_option("--frames", info_frames,
                   "frames A..B of frame patterns ('#' runs or $F<N>) in volume names and in scenes' media files")
      ->check(frames_check());
  if (unknown_command(app, argc, argv)) return 2;
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  MpiArg mpi;
  try {
    if (app.got_subcommand("devices")) return cmd_devices();
    if (app.got_subcommand("merge")) return cmd_merge(ma);
    if (app.got_subcommand("info")) {
      std::optional<std::array<long long, 2>> frames;
      if (!info_frames.empty()) {
        std::array<long long, 2> ab{};
        check_frames(info_frames, &ab[0], &ab[1]);  // checked by CLI11 already
        frames = ab;
      }
      return cmd_info(info_files, info_json, frames);
    }
    if (ra.mpi) {
#ifdef SPECTRACK_HAVE_MPI
      mpi.world = mpi_start(&argc, &argv);
      mpi.on = true;
      mpi.rank = mpi.world.rank;
      mpi.size = mpi.world.size;
#else
      throw Error("--mpi: this spectrack was built without MPI (install libopenmpi-dev and rebuild; CMake finds it)");
#endif
    }
    int code = cmd_render(ra, mpi);
#ifdef SPECTRACK_HAVE_MPI
    if (mpi.on) mpi_finish();
#endif
    return code;
  } catch (const TimeLimitError& e) {
    std::cerr << "error: " << e.what() << "\n";
#ifdef SPECTRACK_HAVE_MPI
    if (mpi.on) mpi_finish();
#endif
    return kExitTimeLimit;
  } catch (const UsageError& e) {
    std::cerr << "error: " << e.what() << "\n";
#ifdef SPECTRACK_HAVE_MPI
    if (mpi.on && mpi.size > 1) mpi_abort(2);
    if (mpi.on) mpi_finish();
#endif
    return 2;
  } catch (const std::exception& e) {
    std::cerr << (mpi.on && mpi.size > 1 ? fmt::format("error (MPI rank {}): ", mpi.rank) : std::string("error: "))
              << e.what() << "\n";
#ifdef SPECTRACK_HAVE_MPI
    if (mpi.on && mpi.size > 1) mpi_abort(1);  // the other ranks would wait in the reduction for ever
    if (mpi.on) mpi_finish();
#endif
    return 1;
  }
}
