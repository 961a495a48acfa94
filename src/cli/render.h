// render.h: `spectrack render`: its arguments, its flags and the command.
//
// Design: RenderArgs holds what CLI11 parsed (range-checked by the validators of cli/options.h);
// cmd_render turns it into RenderOptions once (render.cpp) and renders one scene or a frame
// sequence, on one or several devices, or as one MPI rank (MpiArg, started by main).
#pragma once
#include <CLI/CLI.hpp>

#include <cstdint>
#include <string>

#include "integrator/settings.h"
#ifdef SPECTRACK_HAVE_MPI
#include "cli/mpi_render.h"
#endif

namespace spectrack {

struct RenderArgs {
  std::string scene, output, stats_json, preview, device, tracker, scheme, absorption, light_sampling, transmittance,
      lookup, spp_range, pixel_bounds, frames, aov, compression, guiding, guide_splitting, shutter;
  bool alpha = false, no_alpha = false, half = false, spectral = false;
  double march_spacing = 0, pilot_spacing = 0;  // 0: not given
  int spp = -1;
  int64_t seed = -1;
  int path_slots = 0;
  int budget = 256;
  int chunk_spp = 0;
  int majorant_cell = RenderOptions().majorant_cell;
  int majorant_block = RenderOptions().majorant_block;
  double majorant_step_cost = RenderOptions().majorant_step_cost;
  int batches_in_flight = 0;
  int shadow_ring = 0;
  uint32_t feature_floor = 0;  // RenderOptions::feature_floor (frame sequences)
  std::optional<long long> frame;  // the frame a sequence renders (EXR metadata spectrack:frame)
  double time_limit = 0;
  double noise_target = 0;  // 0: not given
  double checkpoint = 0;    // seconds between checkpoints; 0: none
  bool resume = false;
  bool generic_kernels = false;
  bool quiet = false;
  bool mpi = false;
};

struct MpiArg {
  bool on = false;
  int rank = 0, size = 1;
#ifdef SPECTRACK_HAVE_MPI
  MpiWorld world;
#endif
};

// The `render` subcommand's arguments and flags (render_flags.cpp).
CLI::App* add_render_command(CLI::App& app, RenderArgs& ra);
// A render, or with --frames A:B a sequence; the exit code.
int cmd_render(const RenderArgs& a, MpiArg& mpi);

}  // namespace spectrack
