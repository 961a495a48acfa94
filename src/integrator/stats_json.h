// stats_json.h: RenderStats as the JSON object of `--stats-json` (the counter fields and the
// per-kernel device times), and back, so statistics of MPI ranks can travel as text and be added.
#pragma once
#include <nlohmann/json.hpp>

#include "integrator/renderer.h"

namespace spectrack {

// paths, density_lookups (+ _tracking, _shadow), emission_lookups, collision counts, dda_steps,
// requeues, iterations, nonfinite_samples, scatter_events, max_throughput, occupancy_mean / _min,
// iterations_below_half_occupancy, kernels{name: {seconds, launches}}
nlohmann::json stats_to_json(const RenderStats& s);
RenderStats stats_from_json(const nlohmann::json& j);

}  // namespace spectrack
