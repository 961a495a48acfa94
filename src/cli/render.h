// render.h: `spectrack render`: its arguments, its flags and the command.
//
// Design: RenderArgs holds what CLI11 parsed, one member per row of the settings table
// (integrator/option_table.h; range-checked by the validators of cli/options.h); cmd_render turns
// it into RenderOptions once (render.cpp) and renders one scene or a frame
// sequence, on one or several devices, or as one MPI rank (MpiArg, started by main).
#pragma once
#include <CLI/CLI.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <type_traits>

#include "integrator/settings.h"
#ifdef SPECTRACK_HAVE_MPI
#include "cli/mpi_render.h"
#endif

namespace spectrack {

// What a value of `Type` in the settings table is held in: numbers as std::optional (not given:
// nullopt), flags as bool, texts as std::string (not given: empty).
template <class Type>
using ArgSlot = std::conditional_t<std::is_same_v<Type, bool> || std::is_same_v<Type, std::string>, Type,
                                   std::optional<Type>>;

struct RenderArgs {
  std::string scene;  // the positional argument
  // one member per row of the settings table (integrator/option_table.def)
#define ST_OPTION(member, Type, ...) ArgSlot<Type> member{};
#include "integrator/option_table.def"
#undef ST_OPTION
  uint32_t feature_floor = 0;  // RenderOptions::feature_floor (frame sequences)
  std::optional<long long> frame;  // the frame a sequence renders (EXR metadata spectrack:frame)
  std::string framed_camera;       // its camera framed over the sequence's frames (RenderIdentity::camera), or ""
};

// The film layers of a render of `scene` to `output` (docs/aov.md): film.aovs and --aov; alpha from
// --alpha / --no-alpha, else film.alpha, else on for an EXR output. Layers need an EXR: with a PNG
// output an Error naming the scene's /film/output when the scene asked for both, else a UsageError.
uint32_t film_layers(const RenderArgs& a, const SceneDesc& scene, const std::string& output);

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
