// render_watch.h: the watch on a render of the command line (integrator/film_watch.h): the noise target,
// the progressive preview, checkpoints and resumption.
//
// Design: one RenderWatch per render (per frame). A noise target looks at the film at the sample
// counts integrator/noise.h schedules and stops the render once the estimate is at or below the target
// (from kNoiseMinSpp samples on); the preview PNG is rewritten every kPreviewSeconds of rendering;
// with --checkpoint the output image and the film state (<output>.resume) are written every so many
// seconds and when the render ends early, and the state is removed when it completes; --resume
// continues from that state. Every file goes through util/output_file.h, so a viewer never reads a
// half-written preview. The progress line shows the last noise estimate (note()).
#pragma once
#include <chrono>
#include <mutex>
#include <optional>
#include <string>

#include "image/image.h"
#include "integrator/film_watch.h"
#include "integrator/noise.h"

namespace spectrack {

constexpr double kPreviewSeconds = 4.0;  // the preview is rewritten this often during a render

struct WatchConfig {
  double noise_target = 0;          // 0: none
  std::string preview;              // "" : none
  std::string image;                // the output (checkpoints rewrite it)
  double checkpoint_seconds = 0;    // 0: no checkpoint
  std::string state_path;           // the film state: <image>.resume
  std::string state_key;            // film_state_key of this render
  RenderIdentity id;                // with the scene hash: checkpoint images are pieces
  ExrOptions exr;
  Metadata meta;                    // the checkpoint images' metadata besides the piece's
  int64_t spp = 0;                  // samples requested
};

// Where the film state of a render to `image` goes.
std::string film_state_path(const std::string& image);

class RenderWatch : public FilmWatch {
 public:
  explicit RenderWatch(WatchConfig c);
  int wants(int64_t samples_done) override;
  bool see(const RenderResult& film, const FilmState* state) override;
  // checkpoints write the last state; a resumed render removes the state it completes
  bool wants_final_state() const override { return c_.checkpoint_seconds > 0 || resumed_.has_value(); }
  void final_state(const FilmState& state) override;
  int64_t samples_needed() const override { return c_.noise_target > 0 ? next_check_ : INT64_MAX; }
  const FilmState* resume() const override { return resumed_ ? &*resumed_ : nullptr; }
  // Loads the film state to continue from; false when there is none (the render starts at 0).
  bool load_resume();
  std::string note() const;  // "noise 3.1% (target 2%)", "" before the first estimate
  std::optional<NoiseEstimate> last_estimate() const;

 private:
  using Clock = std::chrono::steady_clock;
  WatchConfig c_;
  Clock::time_point last_preview_, last_checkpoint_;
  int64_t next_check_ = kNoiseMinSpp;
  bool reached_ = false;
  std::optional<FilmState> resumed_;
  mutable std::mutex mu_;  // the estimate, read by the progress callback
  std::optional<NoiseEstimate> estimate_;
};

}  // namespace spectrack
