// render_watch.cpp: see render_watch.h.
#include "integrator/render_watch.h"

#include <fmt/format.h>

#include <filesystem>
#include <iostream>

namespace spectrack {

std::string film_state_path(const std::string& image) { return image + ".resume"; }

RenderWatch::RenderWatch(WatchConfig c) : c_(std::move(c)) {
  last_preview_ = last_checkpoint_ = Clock::now();
}

int RenderWatch::wants(int64_t n) {
  const Clock::time_point now = Clock::now();
  int want = kNothing;
  if (c_.noise_target > 0 && n >= next_check_) want |= kFilm;
  if (!c_.preview.empty() && std::chrono::duration<double>(now - last_preview_).count() >= kPreviewSeconds) want |= kFilm;
  if (c_.checkpoint_seconds > 0 && std::chrono::duration<double>(now - last_checkpoint_).count() >= c_.checkpoint_seconds)
    want |= kFilm | kState;
  return want;
}

bool RenderWatch::see(const RenderResult& film, const FilmState* state) {
  const int64_t n = film.spp_done;
  if (c_.noise_target > 0 && (n >= next_check_ || n >= c_.spp)) {  // n = spp: an adaptive film so far
    const NoiseEstimate e = estimate_film_noise(film.sum, film.aov_sum, film.aov_channels, n);
    if (e.measured) {
      std::lock_guard<std::mutex> lock(mu_);
      estimate_ = e;
    }
    reached_ = n >= kNoiseMinSpp && e.error <= c_.noise_target;
    next_check_ = next_noise_check(e.error, n, c_.noise_target);
  }
  const Clock::time_point now = Clock::now();
  if (!c_.preview.empty() && std::chrono::duration<double>(now - last_preview_).count() >= kPreviewSeconds) {
    write_piece(c_.preview, piece_from_result(film, c_.id, "render"), c_.meta);
    last_preview_ = now;
  }
  if (state) {
    write_film_state(c_.state_path, *state, c_.state_key);
    FilmPiece p = piece_from_result(film, c_.id, "render");
    p.interrupted = true;  // a render in progress
    Metadata meta = c_.meta;
    meta["stop_reason"] = std::string("checkpoint");
    write_piece(c_.image, p, meta, c_.exr);
    last_checkpoint_ = now;
  }
  return reached_;
}

void RenderWatch::final_state(const FilmState& state) {
  if (reached_ || state.samples_done >= c_.spp) {  // complete: nothing to resume
    std::error_code ec;
    std::filesystem::remove(c_.state_path, ec);
    return;
  }
  if (c_.checkpoint_seconds > 0) write_film_state(c_.state_path, state, c_.state_key);
}

bool RenderWatch::load_resume() {
  std::error_code ec;
  if (!std::filesystem::exists(c_.state_path, ec)) return false;
  resumed_ = read_film_state(c_.state_path, c_.state_key);
  if (resumed_->samples_done >= c_.spp)
    throw Error(fmt::format("{}: the film state already holds all {} samples; nothing to resume (remove it to render "
                            "again)", c_.state_path, c_.spp));
  return true;
}

std::string RenderWatch::note() const {
  std::lock_guard<std::mutex> lock(mu_);
  if (!estimate_) return "";
  return fmt::format("noise {:.3g}% (target {:.3g}%)", 100.0 * estimate_->error, 100.0 * c_.noise_target);
}

std::optional<NoiseEstimate> RenderWatch::last_estimate() const {
  std::lock_guard<std::mutex> lock(mu_);
  return estimate_;
}

}  // namespace spectrack
