// render_outputs.cpp: see render_outputs.h.
#include "cli/render_outputs.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <climits>
#include <iostream>
#include <optional>

#include "cli/checks.h"
#include "cli/run_control.h"
#include "api/render_stats.h"
#include "film/film.h"
#include "integrator/noise.h"
#include "util/output_file.h"
#include "util/strings.h"

namespace spectrack {
namespace {

// The relative error of the image (integrator/noise.h) when it has the variance layer.
std::optional<NoiseEstimate> film_noise(const FilmPiece& p) {
  if (!(p.id.aovs & ST_AOV_BIT(VARIANCE)) || p.samples() == 0) return std::nullopt;
  return estimate_film_noise(p.sum, p.aov_sum, aov_sum_channels(p.id.aovs), p.samples());
}

void write_stats_json(const std::string& path, const MultiDeviceResult& r, double seconds_total,
                      double seconds_to_renderer, int mpi_ranks, const Metadata& meta) {
  write_output_file(path, render_stats_json(r, seconds_total, seconds_to_renderer, mpi_ranks, meta).dump(2) + "\n");
}


// The image, the preview, the statistics, and the summary line.
void write_render_outputs(const RenderOutputs& o, const SceneDesc& scene, const MultiDeviceResult& r,
                          const RenderTimes& t, int mpi_ranks, double time_limit) {
  Metadata meta;
  if (time_limit > 0) meta["time_limit"] = float(time_limit);
  if (!render_stop_reason(r).empty()) meta["stop_reason"] = render_stop_reason(r);
  if (o.noise_target > 0) meta["noise_target"] = float(o.noise_target);
  const std::optional<NoiseEstimate> noise = film_noise(r.piece);
  if (noise) {
    meta["noise_error"] = float(noise->error);
    meta["noise_pixels"] = int(std::min<uint64_t>(noise->pixels, INT32_MAX));
  }
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
    std::cerr << fmt::format("wrote {} ({} spp in {:.2f} s render, {:.2f} s total{}{})\n", o.image, r.piece.samples(),
                             r.seconds_render, t.total,
                             noise ? fmt::format(", noise {:.3g}%", 100.0 * noise->error) : std::string(),
                             r.noise_target_reached ? ", noise target reached"
                             : !r.piece.interrupted ? ""
                             : r.time_limit_reached ? ", stopped at the time limit"
                                                    : ", INTERRUPTED");
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
