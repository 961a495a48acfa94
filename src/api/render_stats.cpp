// render_stats.cpp: see render_stats.h.
#include "api/render_stats.h"

#include <algorithm>
#include <climits>
#include <optional>

#include "film/film.h"
#include "integrator/noise.h"
#include "integrator/stats_json.h"
#include "util/strings.h"

namespace spectrack {

std::string render_stop_reason(const MultiDeviceResult& r) {
  if (r.noise_target_reached) return "noise-target";
  if (!r.piece.interrupted) return r.stop_reason;
  return r.time_limit_reached ? "time-limit" : "signal";
}

namespace {

// The image's relative error (integrator/noise.h) where the film has the variance layer.
std::optional<NoiseEstimate> film_noise(const FilmPiece& p) {
  if (!(p.id.aovs & ST_AOV_BIT(VARIANCE)) || p.samples() == 0) return std::nullopt;
  // an adaptive film whose pilot a stop cut short: pixels of fewer samples have no variance to count
  if (!p.pixel_samples.empty() && *std::min_element(p.pixel_samples.begin(), p.pixel_samples.end()) < float(kNoiseMinSpp))
    return std::nullopt;
  const NoiseEstimate e = estimate_film_noise(p.sum, p.aov_sum, aov_sum_channels(p.id.aovs), p.samples());
  return e.measured ? std::optional<NoiseEstimate>(e) : std::nullopt;
}

}  // namespace

Metadata render_metadata(const MultiDeviceResult& r, const std::string& scene_path, double time_limit) {
  Metadata meta;
  if (time_limit > 0) meta["time_limit"] = float(time_limit);
  if (!render_stop_reason(r).empty()) meta["stop_reason"] = render_stop_reason(r);
  if (r.noise_target > 0) meta["noise_target"] = float(r.noise_target);
  if (const std::optional<NoiseEstimate> noise = film_noise(r.piece)) {
    meta["noise_error"] = float(noise->error);
    meta["noise_pixels"] = int(std::min<uint64_t>(noise->pixels, INT32_MAX));
  }
  if (!r.piece.pixel_samples.empty()) {  // adaptive sampling (integrator/adaptive.h)
    double total = 0;
    for (float n : r.piece.pixel_samples) total += n;
    meta["adaptive"] = 1;
    meta["adaptive_rounds"] = r.adaptive_rounds;
    meta["adaptive_floor"] = float(r.adaptive_floor);
    meta["adaptive_mean_spp"] = float(total / double(r.piece.pixel_samples.size()));
  }
  if (r.stats.nonfinite_samples > 0) meta["nonfinite_samples"] = int(std::min<uint64_t>(r.stats.nonfinite_samples, INT32_MAX));
  meta["spp_requested"] = r.spp_requested;
  meta["device"] = join(r.devices, ", ");
  meta["render_seconds"] = float(r.seconds_render);
  meta["scene"] = scene_path;
  return meta;
}

nlohmann::json render_stats_json(const MultiDeviceResult& r, double seconds_total, double seconds_to_renderer,
                                 int mpi_ranks, const Metadata& meta) {
  nlohmann::json j = stats_to_json(r.stats);
  const FilmPiece& p = r.piece;
  j["spp"] = p.samples();
  j["spp_requested"] = r.spp_requested;
  j["spp_ranges"] = format_ranges(p.ranges);
  j["interrupted"] = p.interrupted;
  j["stop_reason"] = render_stop_reason(r);
  for (const char* k : {"time_limit", "noise_target", "noise_error", "adaptive_floor", "adaptive_mean_spp", "denoise_seconds"})
    if (auto t = meta.find(k); t != meta.end()) j[k] = std::get<float>(t->second);
  if (auto t = meta.find("noise_pixels"); t != meta.end()) j["noise_pixels"] = std::get<int>(t->second);
  if (auto t = meta.find("adaptive_rounds"); t != meta.end()) j["adaptive_rounds"] = std::get<int>(t->second);
  j["seed"] = r.seed;
  for (const RecordedChoice& c : recorded_choices())  // as the EXR records them
    if (!c.only_when_set || !(p.id.*c.field).empty()) j[c.key] = p.id.*c.field;
  j["light_sampling_used"] = light_sampling_name(r.light_sampling_used);
  j["equiangular_used"] = r.equiangular_used;
  // the run's automatic choices as used (renderer.h RunChoices; the first device's)
  j["path_slots"] = r.path_slots;
  j["shadow_ring"] = r.shadow_ring;
  j["state_layout"] = r.state_layout;
  j["batches_in_flight"] = r.batches_in_flight;
  j["iteration_budget"] = r.iteration_budget;
  j["film_layers"] = nlohmann::json::array();
  for (int k = 0; k < ST_AOV_COUNT; ++k)
    if (r.aovs & (1u << k)) j["film_layers"].push_back(aov_name(k));
  j["device"] = join(r.devices, ", ");
  j["devices"] = r.devices;
  j["samples_per_device"] = r.samples_per_device;
  j["mpi_ranks"] = mpi_ranks;
  j["width"] = p.width;
  j["height"] = p.height;
  j["full_width"] = p.id.full_width;
  j["full_height"] = p.id.full_height;
  j["pixel_bounds"] = {p.x0, p.x0 + p.width, p.y0, p.y0 + p.height};
  j["scene_hash"] = p.id.scene_hash;
  j["seconds_render"] = r.seconds_render;
  j["cpu_seconds_render"] = r.cpu_seconds_render;
  j["seconds_setup"] = r.seconds_setup;
  j["seconds_kernel_build"] = r.seconds_build;
  j["kernels_from_cache"] = r.kernels_from_cache;
  j["seconds_first_pass"] = r.seconds_first_pass;
  j["seconds_first_pass_from_start"] = seconds_to_renderer + r.seconds_first_pass;  // scene loading included
  j["features"] = r.features;
  j["generic_kernels"] = r.features == uint32_t(ST_FEATURES_ALL);
  j["guiding"] = guiding_name(r.guiding_requested);  // as requested; guiding_used: whether it ran
  j["guiding_used"] = r.guide.used;
  j["guide_cache_bytes"] = r.guide.bytes;
  j["guide_regions"] = r.guide.regions;
  j["guide_regions_guided"] = r.guide.regions_guided;
  j["guide_training_passes"] = r.guide.training_passes;
  j["guide_cache_file"] = r.guide.cache_file;
  j["guide_training_records"] = r.guide.records;
  j["seconds_guide_training"] = r.guide.seconds_training;
  j["seconds_guide_training_loops"] = r.guide.seconds_training_loops;
  j["seconds_guide_drain"] = r.guide.seconds_drain;
  j["seconds_guide_fit"] = r.guide.seconds_fit;
  j["cpu_seconds_guide_training"] = r.guide.cpu_seconds_training;
  j["guide_training_iterations"] = r.guide.training_iterations;
  j["guide_drains"] = r.guide.drains;
  j["guide_training_kernels"] = nlohmann::json::object();
  for (auto& [name, t] : r.guide.training_kernels)
    j["guide_training_kernels"][name] = {{"seconds", t.seconds}, {"launches", t.launches}};
  // each VDB medium's majorant structure (docs/majorant-hierarchy.md)
  nlohmann::json maj = nlohmann::json::array();
  for (const MajorantInfo& m : r.majorants)
    maj.push_back({{"cell", m.cell}, {"block", m.block}, {"levels", m.levels}, {"blocks_per_level", m.blocks_per_level}, {"fine_cells", m.fine_cells},
                   {"blocks_empty", m.blocks_empty}, {"blocks_whole", m.blocks_whole},
                   {"blocks_refined", m.blocks_refined}, {"bytes", m.bytes}, {"step_cost", m.step_cost}, {"seconds_build", m.seconds_build},
                   {"chord_lookups", m.chord_lookups}});
  j["majorant_grids"] = maj;
  j["dda_steps_per_nonempty_cell"] = r.stats.dda_nonempty > 0 ? double(r.stats.dda_steps) / double(r.stats.dda_nonempty) : 0.0;
  j["seconds_total"] = seconds_total;
  j["paths_per_second"] = r.seconds_render > 0 ? double(r.stats.paths) / r.seconds_render : 0.0;
  return j;
}

}  // namespace spectrack
