// render_outputs.cpp: see render_outputs.h.
#include "cli/render_outputs.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <climits>
#include <iostream>

#include "cli/checks.h"
#include "cli/run_control.h"
#include "film/film.h"
#include "integrator/stats_json.h"
#include "util/output_file.h"
#include "util/strings.h"

namespace spectrack {
namespace {

void write_stats_json(const std::string& path, const MultiDeviceResult& r, double seconds_total,
                      double seconds_to_renderer, int mpi_ranks, const Metadata& meta) {
  nlohmann::json j = stats_to_json(r.stats);
  const FilmPiece& p = r.piece;
  j["spp"] = p.samples();
  j["spp_requested"] = r.spp_requested;
  j["spp_ranges"] = format_ranges(p.ranges);
  j["interrupted"] = p.interrupted;
  j["stop_reason"] = p.interrupted ? (r.time_limit_reached ? "time-limit" : "signal") : "";
  if (auto t = meta.find("time_limit"); t != meta.end()) j["time_limit"] = std::get<float>(t->second);
  j["seed"] = r.seed;
  j["tracker"] = tracker_name(r.tracker);
  j["scheme"] = scheme_name(r.scheme);
  j["absorption"] = absorption_name(r.absorption);
  j["light_sampling"] = light_sampling_name(r.light_sampling);
  j["light_sampling_used"] = light_sampling_name(r.light_sampling_used);
  j["transmittance"] = transmittance_name(r.transmittance);
  j["lookup"] = lookup_name(r.lookup);
  j["color"] = film_color_name(r.color);
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
  j["seconds_setup"] = r.seconds_setup;
  j["seconds_kernel_build"] = r.seconds_build;
  j["kernels_from_cache"] = r.kernels_from_cache;
  j["seconds_first_pass"] = r.seconds_first_pass;
  j["seconds_first_pass_from_start"] = seconds_to_renderer + r.seconds_first_pass;  // scene loading included
  j["features"] = r.features;
  j["generic_kernels"] = r.features == uint32_t(ST_FEATURES_ALL);
  j["guiding_used"] = r.guide.used;
  j["guide_cache_bytes"] = r.guide.bytes;
  j["guide_regions"] = r.guide.regions;
  j["guide_regions_guided"] = r.guide.regions_guided;
  j["guide_training_passes"] = r.guide.training_passes;
  j["guide_training_records"] = r.guide.records;
  j["seconds_guide_training"] = r.guide.seconds_training;
  // each VDB medium's majorant structure (docs/majorant-hierarchy.md)
  nlohmann::json maj = nlohmann::json::array();
  for (const MajorantInfo& m : r.majorants)
    maj.push_back({{"cell", m.cell}, {"block", m.block}, {"levels", m.levels}, {"blocks_per_level", m.blocks_per_level}, {"fine_cells", m.fine_cells},
                   {"blocks_empty", m.blocks_empty}, {"blocks_whole", m.blocks_whole},
                   {"blocks_refined", m.blocks_refined}, {"bytes", m.bytes}, {"seconds_build", m.seconds_build},
                   {"chord_lookups", m.chord_lookups}});
  j["majorant_grids"] = maj;
  j["dda_steps_per_nonempty_cell"] = r.stats.dda_nonempty > 0 ? double(r.stats.dda_steps) / double(r.stats.dda_nonempty) : 0.0;
  j["seconds_total"] = seconds_total;
  j["paths_per_second"] = r.seconds_render > 0 ? double(r.stats.paths) / r.seconds_render : 0.0;
  write_output_file(path, j.dump(2) + "\n");
}


// The image, the preview, the statistics, and the summary line.
void write_render_outputs(const RenderOutputs& o, const SceneDesc& scene, const MultiDeviceResult& r,
                          const RenderTimes& t, int mpi_ranks, double time_limit) {
  Metadata meta;
  if (time_limit > 0) meta["time_limit"] = float(time_limit);
  if (r.piece.interrupted) meta["stop_reason"] = std::string(r.time_limit_reached ? "time-limit" : "signal");
  if (r.stats.nonfinite_samples > 0) meta["nonfinite_samples"] = int(std::min<uint64_t>(r.stats.nonfinite_samples, INT32_MAX));
  meta["spp_requested"] = r.spp_requested;
  meta["device"] = join(r.devices, ", ");
  meta["render_seconds"] = float(r.seconds_render);
  meta["scene"] = scene.path;
  if (o.mpi) meta["mpi_ranks"] = mpi_ranks;
  write_piece(o.image, r.piece, meta, o.exr);
  if (!o.preview.empty()) write_piece(o.preview, r.piece, meta);
  if (!o.stats_json.empty()) write_stats_json(o.stats_json, r, t.total, t.to_renderer, mpi_ranks, meta);
  if (!o.quiet) {
    std::cerr << fmt::format("wrote {} ({} spp in {:.2f} s render, {:.2f} s total{})\n", o.image, r.piece.samples(),
                             r.seconds_render, t.total,
                             !r.piece.interrupted ? "" : r.time_limit_reached ? ", stopped at the time limit" : ", INTERRUPTED");
    if (!o.preview.empty()) std::cerr << fmt::format("wrote {} (preview)\n", o.preview);
    if (!o.stats_json.empty()) std::cerr << fmt::format("wrote {} (statistics)\n", o.stats_json);
  }
}

}  // namespace

int finish_render(const RenderOutputs& o, const SceneDesc& scene, const MultiDeviceResult& r, const RenderTimes& t,
                  int mpi_ranks, double time_limit, bool signalled) {
  if (r.piece.samples() == 0) {
    if (signalled) {
      std::cerr << fmt::format("spectrack: interrupted before any sample finished; nothing written ({} not written)\n",
                               o.image);
      return kExitInterrupted;
    }
    if (r.time_limit_reached)
      throw TimeLimitError(time_limit_message(deadline_watch().context(), time_limit,
                                              "the stage loop, before its first batch of samples finished"));
    throw Error(fmt::format("{}: internal: the render ended with no sample finished", o.image));
  }
  write_render_outputs(o, scene, r, t, mpi_ranks, time_limit);
  if (r.stats.nonfinite_samples > 0) return nonfinite_verdict(r.stats.nonfinite_samples, o.image);
  return signalled || (r.piece.interrupted && !r.time_limit_reached) ? kExitInterrupted : 0;
}

}  // namespace spectrack
