// render_stats.h: the statistics of a finished render as one JSON object: what `--stats-json`
// writes and what the Python module's Image.stats holds (the one place that lists the keys).
#pragma once
#include <nlohmann/json.hpp>

#include <string>

#include "image/image.h"
#include "integrator/multi_device.h"

namespace spectrack {

// The counters (integrator/stats_json.h) with the samples, the settings the render ran, the devices,
// the window, the timings (seconds_total and seconds_to_renderer count from the command's start),
// the guiding cache and each VDB medium's majorant structure. `meta` may hold "time_limit",
// "noise_target" and "noise_error" (floats) and "noise_pixels" (an int).
nlohmann::json render_stats_json(const MultiDeviceResult& r, double seconds_total, double seconds_to_renderer,
                                 int mpi_ranks, const Metadata& meta);

// The metadata of a finished render, as its EXR and the statistics record them (one list for the
// command line and the Python module): the time limit (0: none), the stop reason, the noise target
// and the error reached (measured from the variance layer), adaptive sampling's rounds, floor and
// mean samples, dropped non-finite samples, the spp requested, the devices, the render's seconds and
// the scene file.
Metadata render_metadata(const MultiDeviceResult& r, const std::string& scene_path, double time_limit);

// Why the render stopped: noise-target, time-limit or signal before its requested samples; with a
// noise target not met, spp or (adaptive sampling) pixels-finished (MultiDeviceResult::stop_reason);
// "" for a render without a noise target that took its samples.
std::string render_stop_reason(const MultiDeviceResult& r);

}  // namespace spectrack
