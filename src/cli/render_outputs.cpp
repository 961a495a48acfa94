// render_outputs.cpp: see render_outputs.h.
#include "cli/render_outputs.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <climits>
#include <iostream>

#include "cli/checks.h"
#include "cli/run_control.h"
#include "api/render_stats.h"
#include "film/film.h"
#include "image/denoise.h"
#include "util/output_file.h"
#include "util/strings.h"

namespace spectrack {
namespace {

// The beauty of `p` denoised (image/denoise.h) with its albedo layer as auxiliary input: per pixel the
// mean albedo of the samples whose camera ray collided, and 1 for the fraction that did not (a
// background takes the light it shows as its own colour).
std::vector<float> denoised_beauty(const FilmPiece& p) {
  const std::vector<std::string> sums = aov_sum_channels(p.id.aovs);
  const size_t na = sums.size(), npix = size_t(p.width) * size_t(p.height);
  const size_t a = size_t(std::find(sums.begin(), sums.end(), "albedo.R") - sums.begin());
  const size_t h = size_t(std::find(sums.begin(), sums.end(), "collision.fraction") - sums.begin());
  if (a >= na || h >= na) throw Error("internal: --denoise without the albedo layer");
  std::vector<float> albedo(npix * 3);
  const double n = double(p.samples());
  for (size_t i = 0; i < npix; ++i) {
    const double hits = p.aov_sum[i * na + h], f = n > 0 ? std::clamp(hits / n, 0.0, 1.0) : 0.0;
    for (size_t c = 0; c < 3; ++c)
      albedo[i * 3 + c] = float((hits != 0 ? p.aov_sum[i * na + a + c] / hits : 0.0) * f + (1.0 - f));
  }
  return denoise(piece_beauty(p), albedo, p.width, p.height);
}

void write_stats_json(const std::string& path, const MultiDeviceResult& r, double seconds_total,
                      double seconds_to_renderer, int mpi_ranks, const Metadata& meta) {
  write_output_file(path, render_stats_json(r, seconds_total, seconds_to_renderer, mpi_ranks, meta).dump(2) + "\n");
}


// The image, the preview, the statistics, and the summary line.
void write_render_outputs(const RenderOutputs& o, const SceneDesc& scene, const MultiDeviceResult& r,
                          const RenderTimes& t, int mpi_ranks, double time_limit) {
  Metadata meta = render_metadata(r, scene.path, time_limit);
  const auto noise = meta.find("noise_error");  // measured once, by render_metadata
  if (o.mpi) meta["mpi_ranks"] = mpi_ranks;
  if (o.denoise) {
    FilmPiece d = r.piece;
    const auto t0 = std::chrono::steady_clock::now();
    d.denoised = denoised_beauty(d);
    meta["denoised"] = std::string("oidn RT, albedo");
    meta["denoise_seconds"] = float(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    write_piece(o.image, d, meta, o.exr);
  } else {
    write_piece(o.image, r.piece, meta, o.exr);
  }
  if (!o.preview.empty()) write_piece(o.preview, r.piece, meta);
  if (!o.stats_json.empty()) write_stats_json(o.stats_json, r, t.total, t.to_renderer, mpi_ranks, meta);
  if (!o.quiet) {
    std::cerr << fmt::format("wrote {} ({} in {:.2f} s render, {:.2f} s total{}{})\n", o.image,
                             r.piece.pixel_samples.empty()
                                 ? fmt::format("{} spp", r.piece.samples())
                                 : fmt::format("adaptive, {:.1f} spp on average, {} in a pixel at most (--spp {})",
                                               std::get<float>(meta["adaptive_mean_spp"]),
                                               *std::max_element(r.piece.pixel_samples.begin(), r.piece.pixel_samples.end()),
                                               r.piece.samples()),
                             r.seconds_render, t.total,
                             noise != meta.end() ? fmt::format(", noise {:.3g}%", 100.0 * std::get<float>(noise->second))
                                                 : std::string(),
                             r.noise_target_reached         ? ", noise target reached"
                             : r.stop_reason == "spp"         ? ", noise target missed at --spp"
                             : r.stop_reason == "pixels-finished"
                                 ? ", noise target missed: every pixel took the samples predicted for its aim or "
                                   "the per-pixel cap, or, where the target was out of its reach, those that bring it "
                                   "near the least error its weights allow (docs/adaptive.md)"
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
