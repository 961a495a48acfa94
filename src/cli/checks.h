// checks.h: the command line's checks around a render or merge, one call each from main.cpp.
//
// Design: header-only (the CLI is one translation unit; tests reach these through the binary).
//   - check_tracker_scheme: --scheme is refused (UsageError, exit 2) when the tracker that will
//     run (from --tracker or the scene) ignores it; a scene's render.spectral_scheme with such a
//     tracker is a warning (a scene may set both and be rendered with several trackers). Trackers
//     without a scheme then run and are recorded with max, the analog probabilities they use.
//   - render_outputs / scene_inputs / merge inputs feed check_distinct_paths (util/files.h).
//   - check_no_nul, check_frame_files, check_half: scene paths with a NUL byte, every frame's
//     volume files before a sequence renders, --half or --compression with a PNG output.
//   - check_piece_storage: a piece (--spp-range, --pixel-bounds) stored so that merge will refuse
//     it (half floats, a compression that changes floats) is a warning before it renders.
//   - nonfinite_verdict: a render that dropped non-finite samples exits 1. Its image is still
//     written, marked with spectrack:nonfinite_samples, for diagnosis; dropping samples is never a
//     success (it is a bug, or an input the float kernels cannot represent).
#pragma once
#include <fmt/format.h>

#include <sys/stat.h>

#include <cctype>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include "image/image.h"
#include "integrator/renderer.h"
#include "scene/frames.h"
#include "scene/scene.h"
#include "util/files.h"
#include "util/strings.h"
#include "util/warning.h"

namespace spectrack {

// Checks --scheme (`scheme_flag`, its text) against the tracker that will run; resolve_settings
// then records max, the analog probabilities, for a tracker without a scheme.
inline void check_tracker_scheme(const SceneDesc& scene, const RenderOptions& opt, const std::string& scheme_flag,
                                 const std::string& tracker_flag) {
  const int tracker = opt.tracker.value_or(scene.render.tracker);
  if (tracker_uses_scheme(tracker)) return;
  const std::string from = tracker_flag.empty() ? fmt::format(" (render.tracker of {})", scene.path) : "";
  if (!scheme_flag.empty())
    throw UsageError(fmt::format("--scheme {}: tracker {}{} ignores the spectral scheme; only spectral and "
                                 "spectral-decomposition use one (drop --scheme, or pick one of those with --tracker)",
                                 scheme_flag, tracker_name(tracker), from));
  if (scene.render.scheme_set && scene.render.scheme != ST_SCHEME_MAX && !opt.quiet)
    std::cerr << fmt::format("warning: {}: /render/spectral_scheme: \"{}\" is ignored by tracker {}{} (only spectral "
                             "and spectral-decomposition use a scheme); the render uses and records max\n",
                             scene.path, scheme_name(scene.render.scheme), tracker_name(tracker),
                             tracker_flag.empty() ? "" : " (--tracker)");
}

// Checks --wavelength-sampling (`flag`, its text) and render.wavelength_sampling against the colour
// mode: rgb mode draws no wavelengths, so the flag is refused and the scene's field warned of.
inline void check_wavelength_sampling(const SceneDesc& scene, const RenderOptions& opt, const std::string& flag) {
  if (opt.color.value_or(scene.render.color) == ST_FILM_COLOR_SPECTRAL) return;
  if (!flag.empty())
    throw UsageError(fmt::format("--wavelength-sampling {}: only spectral mode draws wavelengths, and {} renders in rgb "
                                 "(add --spectral, or drop --wavelength-sampling)",
                                 flag, scene.path));
  if (scene.render.wavelength_sampling && !opt.quiet)
    std::cerr << fmt::format("warning: {}: /render/wavelength_sampling: \"{}\" is ignored in rgb mode (only spectral "
                             "mode, render.color \"spectral\" or --spectral, draws wavelengths)\n",
                             scene.path, wavelength_sampling_name(*scene.render.wavelength_sampling));
}

// --chunk-spp shares samples between devices: with one device named (not "all") it means nothing.
inline void check_chunk_spp(std::optional<int> chunk_spp, const std::vector<std::string>& devices,
                            const std::string& device_flag) {
  if (!chunk_spp || devices.size() > 1 || device_flag == "all") return;
  throw UsageError(fmt::format("--chunk-spp {}: only used to share samples between several devices (--device all or "
                               "a comma-separated list); this render has one device",
                               *chunk_spp));
}

// Every file a render of `scene` reads.
inline std::vector<NamedPath> scene_inputs(const SceneDesc& scene) {
  std::vector<NamedPath> in{{"the scene file", scene.path}};
  for (const MediumDesc& m : scene.media)
    if (m.type == ST_MEDIUM_VDB) in.push_back({"the volume of " + m.json_path + "/file", m.file});
  for (const LightDesc& l : scene.lights)
    if (!l.map.empty()) in.push_back({"the environment map of " + l.json_path + "/map", l.map});
  return in;
}

// A path as a message shows it: a NUL byte (which JSON strings may hold, but no file name can) as \0.
inline std::string shown_path(const std::string& path) {
  std::string s;
  for (char c : path) s += c == '\0' ? std::string("\\0") : std::string(1, c);
  return s;
}

// The system would read a path only up to a NUL byte, so a scene path holding one names another
// file than the scene says: refused, naming the field.
inline void check_no_nul(const SceneDesc& scene, const std::string& output) {
  auto check = [&](const std::string& field, const std::string& path) {
    if (path.find('\0') != std::string::npos)
      throw Error(fmt::format("{}: {}: \"{}\" holds a NUL byte, which no file name can hold", scene.path, field,
                              shown_path(path)));
  };
  for (const MediumDesc& m : scene.media) check(m.json_path + "/file", m.file);
  for (const LightDesc& l : scene.lights) check(l.json_path + "/map", l.map);
  check("/film/output (the output)", output);
}

// Every frame's volume files exist as regular files before the first frame renders; the message
// names the frame, the field and the reason (errno's, "symlink loop" for ELOOP).
inline void check_frame_files(const SceneDesc& scene, long long first, long long last) {
  for (long long f = first; f <= last; ++f)
    for (const MediumDesc& m : scene.media) {
      if (m.type != ST_MEDIUM_VDB) continue;  // a homogeneous medium has no file
      const std::string file = expand_frame(m.file, f);
      const std::string context = fmt::format("{}: {}/file: frame {}", scene.path, m.json_path, f);
      struct stat st;
      if (::stat(file.c_str(), &st) != 0) {
        const int err = errno;
        const std::string why = err == ENOENT  ? std::string("no such file")
                                : err == ELOOP ? std::string("symlink loop (too many levels of symbolic links)")
                                               : std::string("cannot stat: ") + std::strerror(err);
        throw Error(fmt::format("{}: {}: {}", context, shown_path(file), why));
      }
      check_input_file(file, context);  // a regular file (not a FIFO, a device or a folder)
    }
}

// --half stores EXR channels as 16-bit floats and --compression chooses the EXR's compression; a
// PNG holds 8-bit values whatever is asked, so either flag with a PNG output is refused (exit 2),
// and film.half or film.compression of the scene is a warning where -o chose the PNG (a scene may
// be rendered to either format) and the scene's error (exit 1) where its own film.output is the
// PNG. The Python module's Image.write refuses the same (png_option_error).
inline std::string png_option_error(bool half, const std::string& compression, const std::string& output,
                                    const char* half_name, const char* compression_name) {
  if (lower_extension(output) != ".png") return {};
  if (half)
    return fmt::format("{}: the output {} is a PNG, which holds 8-bit values; {} applies to EXR outputs only (drop "
                       "it, or write an .exr)",
                       half_name, output, half_name);
  if (!compression.empty())
    return fmt::format("{}: the output {} is a PNG, which has its own compression; {} applies to EXR outputs only "
                       "(drop it, or write an .exr)",
                       compression_name, output, compression_name);
  return {};
}

inline void check_half(bool half_flag, const std::string& compression_flag, const SceneDesc& scene,
                       const std::string& output, bool scene_output, bool quiet) {
  if (lower_extension(output) != ".png") return;
  if (const std::string e = png_option_error(half_flag, compression_flag, output, "--half", "--compression");
      !e.empty())
    throw UsageError(e);
  const bool compressed = scene.film.compression != FilmDesc().compression;
  if (scene_output && (scene.film.half || compressed))
    throw Error(fmt::format("{}: {}: {}", scene.path, scene.film.half ? "/film/half" : "/film/compression",
                            png_option_error(scene.film.half, scene.film.compression, output, "film.half",
                                             "film.compression")));
  if (scene.film.half && !quiet)
    std::cerr << fmt::format("warning: {}: /film/half is ignored for the PNG output {} (8-bit values)\n", scene.path,
                             output);
  if (compressed && !quiet)
    std::cerr << fmt::format("warning: {}: /film/compression is ignored for the PNG output {}\n", scene.path, output);
}

// A piece of an image (a sample range or a pixel window) is rendered to be merged, and merge takes
// only files whose float sums are exact (image.cpp check_film_piece_spec): warn before the render
// rather than at the merge, hours later. A PNG piece is merge's own refusal (its message says why).
// The warning for a piece stored at `output` with `exr`, empty where merge takes it (the Python
// module's Image.write gives the same text as a UserWarning).
inline std::string piece_storage_warning(const ExrOptions& exr, const std::string& output) {
  if (lower_extension(output) != ".exr") return {};
  if (exr.half)
    return fmt::format("{} is a piece of an image (--spp-range / --pixel-bounds) stored as half floats (--half or "
                       "film.half): merge refuses it, since it needs the exact float sums",
                       output);
  if (!exr_compression_keeps_floats(exr.compression))
    return fmt::format("{} is a piece of an image (--spp-range / --pixel-bounds) compressed with {}, which changes "
                       "float pixels: merge refuses it (a lossless compression: zip, the default, zips, piz, rle or "
                       "none)",
                       output, exr.compression);
  return {};
}

inline void check_piece_storage(bool piece, const ExrOptions& exr, const std::string& output) {
  if (!piece) return;
  if (const std::string w = piece_storage_warning(exr, output); !w.empty()) warn(w);
}

inline std::vector<NamedPath> merge_inputs(const std::vector<std::string>& files) {
  std::vector<NamedPath> in;
  for (const std::string& f : files) in.push_back({"the merge input", f});
  return in;
}

// Returns the exit code for a render that wrote `output` after dropping `nonfinite` samples.
inline int nonfinite_verdict(uint64_t nonfinite, const std::string& output) {
  if (nonfinite == 0) return 0;
  std::cerr << fmt::format(
      "error: {} non-finite sample(s) (NaN or infinity) were dropped, so the image is wrong; it was written to {} "
      "for diagnosis (metadata spectrack:nonfinite_samples). This is a bug, or an input the float kernels cannot "
      "represent: please report it with the scene\n",
      nonfinite, output);
  return 1;
}

// A merge input whose render dropped samples holds wrong pixels: refused.
inline void check_merge_input(const std::string& file, const Metadata& meta) {
  auto it = meta.find("nonfinite_samples");
  if (it == meta.end()) return;
  const int* n = std::get_if<int>(&it->second);
  if (n && *n == 0) return;
  throw Error(fmt::format("{}: its render dropped non-finite samples (spectrack:nonfinite_samples): its pixels are "
                          "wrong, refusing to merge it",
                          file));
}

}  // namespace spectrack
