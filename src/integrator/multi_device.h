// multi_device.h: one film rendered by several OpenCL devices in one process.
//
// Design: every device gets its own Renderer (context, kernels, uploaded volumes) on its own host
// thread. The sample range of the render is cut into chunks of whole samples per pixel; devices
// take the next chunk from a shared counter when they finish one (so a fast GPU takes more chunks
// than a slow CPU, and nobody waits for a fixed split), and each device adds its chunks' exact
// sums into its own FilmPiece. The pieces are then merged (film.h), which adds the sums of
// disjoint sample ranges: the image is the single-device image to float rounding. With one device
// the whole range is one chunk, which is exactly Renderer::render().
#pragma once
#include <string>
#include <vector>

#include "film/film.h"
#include "integrator/renderer.h"

namespace spectrack {

// "all" (every device of every platform), or a comma-separated list of specs as --device takes
// them ("P:D" or a name substring); "" is the one default device. Throws Error for an empty item.
std::vector<std::string> parse_device_list(const std::string& spec);

struct MultiDeviceResult : RenderChoices, RunChoices {
  FilmPiece piece;          // the merged film of every device
  RenderStats stats;        // summed over devices and chunks
  std::vector<std::string> devices;  // device names, in list order
  std::vector<int64_t> samples_per_device;
  double seconds_setup = 0, seconds_build = 0;  // the slowest device's
  double seconds_render = 0;                    // stage loops alone: the device with the longest sum
  double cpu_seconds_render = 0;  // the process's CPU time over the render (one device: RenderResult's)
  bool kernels_from_cache = true;
  double seconds_first_pass = 0;  // the first device to put a batch on its film: construction to then
  int spp_requested = 0;
  bool time_limit_reached = false;  // some device stopped at RenderOptions::deadline
  bool noise_target_reached = false;  // the watch stopped the render at its noise target (not interrupted)
  // Why a render with a noise target that was neither met nor interrupted ended (api/render_stats.h
  // render_stop_reason): "spp" (--spp reached; adaptive: a pixel took every sample), or, adaptive,
  // "pixels-finished" (every pixel took the samples predicted to bring it to its aim, or the
  // per-pixel cap, and the error measured after is above the target); "" otherwise.
  std::string stop_reason;
  // adaptive sampling (integrator/adaptive.h; piece.pixel_samples): its rounds and brightness floor
  int adaptive_rounds = 0;
  double adaptive_floor = 0;
};

// What one device's render says about its run, as a MultiDeviceResult of that device alone: the
// timings, the kernel cache, what it ran with (RunChoices), the statistics and the stop flags (the
// film, the device list and the settings are the caller's).
MultiDeviceResult device_result(const RenderResult& res);

// Renders samples [sample_begin, sample_begin + spp) of the settings' window (resolved from
// `base`; base.device and base.progress are replaced per device, base.stop is honoured) on each
// device of `devices`. chunk_spp <= 0 picks the chunk size (the whole range for one device).
// Errors from any device are rethrown naming it.
MultiDeviceResult render_multi_device(const SceneDesc& scene, const RenderOptions& base, const RenderSettings& settings,
                                      const std::vector<std::string>& devices, int64_t sample_begin, int spp,
                                      int chunk_spp = 0);

}  // namespace spectrack
