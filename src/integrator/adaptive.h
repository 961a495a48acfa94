// adaptive.h: adaptive sampling to a noise target, without bias.
//
// Design (docs/adaptive.md has the derivation). A pixel's samples come in rounds: round 0, the
// pilot, gives every pixel kNoiseMinSpp samples; round r >= 1 gives each pixel still active
// k_r = max(pilot, n_r / 2) more, rounded up to a multiple of 4 (n_r the samples before it, the same for every pixel that takes
// the round, so a round's paths are samples n_r .. n_r + k_r - 1 of each listed pixel, the very
// paths a uniform render draws), capped at the render's spp. The pixel's estimate is
// X = sum_r a_r M_r, M_r the mean of its round-r samples, with a weight a_r that is fixed before
// round r is drawn (it depends on rounds < r only) and weights that sum to 1 over the rounds the
// pixel takes: whether round r is its last is decided before round r too, and the last round
// takes the weight left, B_r = 1 - sum_{s<r} a_s. Then E[a_r M_r | rounds < r] = a_r mu, and
// E[X] = mu E[sum_r a_r] = mu: no bias from stopping. Var X = sigma^2 V, V = sum_r a_r^2 / k_r,
// which is sigma^2 / n when the weights are a_r = k_r / n (equal per sample); the rule aims
// there: before round r, the samples T still needed are predicted from the rounds so far,
// rho (V + B^2 / T) <= E^2 with rho = sigma^2 / max(m, floor)^2 the relative variance per sample
// (as noise.h measures the error), or the mean over the pixel's 3x3 neighbourhood where that is
// larger; then a_r = B k_r / T, or B when T <= k_r (the last round, which then takes T samples
// rounded up to a quarter of k_r: a round is one render of a list of entries, a pixel and the offset
// of its first sample, each of the lengths' common divisor of samples; the weight of a round that is not the last is taken from a rho with a margin,
// kAdaptiveWeightMargin). The aim is kAdaptiveAim times the target, raised towards the target as
// far as the drift of the pixels that finished allows (adaptive_aim); a pixel out of reach of its
// aim (rho V >= aim^2) aims at the target, or, out of reach of that too, takes B^2 / V samples
// more (its error then ends within sqrt(2) of the least it can reach, sqrt(rho V)), at most to
// the cap. No pixel is given more than the samples the image's 97.5th-percentile pixel needs (the
// 96.25th once the drift measured allows, chosen with the aim), nor twice what its
// 95th-percentile pixel needs (adaptive_cap): the image's error is the 95th percentile's, and the
// rest of that allowance is left to pixels that drift above their aim. The
// pilot's weight comes from the neighbours' pilots, never the pixel's own (adaptive_pilot_weights);
// k_0 / spp where nothing is known, which can only be too small (what it loses is at most its own
// samples). The floor is kNoiseFloor times the mean brightness of the pilot's noisy pixels.
// Decisions use other pixels' samples (the floor, the neighbourhood, the cap, the pilot's weight),
// which are independent of a pixel's own paths, so they bias nothing; but they tie the pixels
// together, so an adaptive film is rendered whole: no shards, tiles, devices or ranks.
#pragma once
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "integrator/multi_device.h"
#include "integrator/renderer.h"

namespace spectrack {

// Each pixel aims at kAdaptiveAim times the target: the image's error is the 95th percentile of
// the pixels' errors as measured after the render, which drift from the prediction that stopped
// them (the last round's samples change the sample variance), so pixels aimed exactly at the
// target leave more than 5% of them above it.
constexpr double kAdaptiveAim = 0.9;
// A pixel's last round takes the samples it still needs, rounded up to a multiple of
// 1 / kAdaptiveLastRoundSteps of the round.
constexpr int64_t kAdaptiveLastRoundSteps = 4;

// A round that is not the pixel's last gets its weight B k / T from rho (1 + kAdaptiveWeightMargin
// / sqrt(n)), not rho: a rho estimated too low from few samples would give the early rounds too
// much weight, and a pixel whose fixed weights already hold more variance than its aim allows
// (rho V >= aim^2) can no longer reach it, however many samples it takes; a weight too small
// costs only part of its round's samples.
constexpr double kAdaptiveWeightMargin = 4.0;

// The pilot's weight of a pixel is k_0 / N, N the samples its noisiest 3x3 neighbour (the pixel
// itself left out: its own pilot must not set its weight) needs at the aim, times
// kAdaptivePilotMargin, within [kAdaptivePilotMin k_0, spp]; spp when no neighbour is noisy (no
// information: as if the pixel took every sample). A weight near the pixel's share k_0 / n keeps
// the pilot's samples from being wasted; one far above it could leave the aim out of reach.
constexpr double kAdaptivePilotMargin = 2.0;
constexpr double kAdaptivePilotMin = 4.0;
// The per-pixel cap leaves kAdaptiveCapShare of the percentile's allowance (the 5% of counted
// pixels that may end above the target) to the pixels it stops, the rest to pixels that drift
// above their aim, until the drift is measured: then each round's share is one of
// kAdaptiveCapShares steps of kAdaptiveCapShareStep from it (0.5, 0.625, 0.75), chosen with the
// aim (adaptive_aim); but the cap is never more than kAdaptiveCapGrowth times the samples the
// image's percentile pixel needs (where the needs between the two percentiles grow steeply, a few
// pixels would otherwise take more samples than the whole image).
constexpr double kAdaptiveCapShare = 0.5;
constexpr int kAdaptiveCapShares = 3;
constexpr double kAdaptiveCapShareStep = 0.125;
constexpr double kAdaptiveCapGrowth = 2.0;

// The aim follows the drift measured so far (adaptive_aim): once kAdaptiveDriftMin counted pixels
// have finished at an aim (their predicted error at least kAdaptiveDriftFrom times the aim: not
// the pixels that finished far below it), their drifts, log(measured / predicted error) times the
// square root of the samples the prediction rested on, tell how likely each pixel still active is
// to end above the target from the error it is predicted to end at (the aim, or what the cap
// leaves it) and its samples. Of the aims in [kAdaptiveAim, 1] (steps of kAdaptiveAimStep) and the
// cap's shares, the round takes the pair that leaves the active pixels the fewest samples to take
// among those at which the expected count above the target, with kAdaptiveDriftSpread standard
// deviations, and the finished pixels above it fit in the percentile's allowance.
constexpr size_t kAdaptiveDriftMin = 32;
constexpr double kAdaptiveDriftFrom = 0.5;
constexpr double kAdaptiveAimStep = 0.01;
constexpr double kAdaptiveDriftSpread = 2.0;

struct AdaptivePlan {
  double target = 0;      // the relative error each pixel is brought to (noise.h's r_p)
  int64_t spp = 0;        // at most this many samples per pixel
  int64_t pilot = 16;     // round 0 (kNoiseMinSpp, at most spp)
  double floor = 0;       // brightness floor of r_p (radiance); 0: from the pilot
  double aim = kAdaptiveAim;  // each pixel aims at aim * target
  double cap_share = kAdaptiveCapShare;  // the share of the allowance the per-pixel cap stops (adaptive_cap)
};

// One pixel's rounds so far (RGB of its whole beauty).
struct AdaptivePixel {
  double B = 1;           // the weight the rounds to come share
  double V = 0;           // sum of a_r^2 / k_r over the rounds taken
  int64_t n = 0;          // samples taken
  double s1[3] = {}, s2[3] = {};  // sums and sums of squares of its samples (unweighted)
  double work = 0;        // its paths' work (RenderResult::pixel_work; 0 without SPECTRACK_ADAPTIVE_PIXELS)
  double predicted = 0;   // the relative error its last round was decided to bring it to (0 before)
  int64_t decided = 0;    // its samples when that round was decided
  bool done() const { return B == 0; }
  // The per-channel variance of one sample (0 below 2 samples) and the mean brightness.
  double sample_variance(int c) const;
  double brightness() const;
};

// The samples of the round that starts after n samples: the pilot's k_0, then n / 2 (at least
// k_0) rounded up to a multiple of kAdaptiveLastRoundSteps, at most spp - n.
int64_t adaptive_round_samples(int64_t n, const AdaptivePlan& plan);
// A pixel's relative variance per sample, sigma^2 / max(m, floor)^2 (0 below 2 samples), and per
// pixel the larger of its own and the mean over its 3x3 neighbourhood: a pixel whose samples
// missed a rare bright path that its neighbours drew does not stop (Cycles' adaptive sampling
// looks at neighbours too), while one noisier than its neighbours keeps its own. The window's
// pixels are row-major, width x height.
double adaptive_relative_variance(const AdaptivePixel& px, double floor);
std::vector<double> adaptive_neighbourhood(const std::vector<AdaptivePixel>& px, int width, int height, double floor);
// The samples to come that bring rho (V + B^2 / T) to the aim, or to the target where the aim is
// out of reach (rho V >= aim^2), or B^2 / V where the target is out of reach too (the samples that
// add no more variance than the rounds so far hold); 0: none needed (the next round is the last).
double adaptive_samples_needed(const AdaptivePixel& px, double rho, const AdaptivePlan& plan);
// The weight of the pixel's next round of k samples, from rounds so far only: B when it is the
// last round (the pixel reaches its aim, or `cap` samples, with it), else B k / T (above).
double adaptive_round_weight(const AdaptivePixel& px, int64_t k, int64_t cap, double rho, const AdaptivePlan& plan);
// The samples the pixel takes in that round: k, or fewer in its last round.
int64_t adaptive_round_length(const AdaptivePixel& px, int64_t k, int64_t cap, double rho, const AdaptivePlan& plan);
// The per-pixel cap: the samples the 97.5th-percentile pixel needs (plan.cap_share 0.5) over the
// counted pixels of the rounds so far (noise.h's; the taken samples of finished pixels, taken plus
// needed of the others), at most kAdaptiveCapGrowth times the 95th-percentile pixel's, within
// [2 pilot, spp].
int64_t adaptive_cap(const std::vector<AdaptivePixel>& px, const std::vector<double>& rho, const AdaptivePlan& plan);
// The relative error the pixel is predicted to end at: rho (V + B^2 / T), T the samples it is to
// take (adaptive_samples_needed, at most those left below the cap, at least 1).
double adaptive_final_error(const AdaptivePixel& px, double rho, int64_t cap, const AdaptivePlan& plan);
// The plan of the next round, its aim and the cap's share (kAdaptiveDriftMin above), from the
// rounds so far (rho: the pixels' relative variances as the rule uses them, adaptive_neighbourhood):
// `plan` until enough pixels have finished, then the pair that fits the allowance with the fewest
// samples.
AdaptivePlan adaptive_aim(const std::vector<AdaptivePixel>& px, const std::vector<double>& rho, double floor,
                          const AdaptivePlan& plan);
// The pilot's weight of every pixel (kAdaptivePilotMargin above) from the window's pilot round
// (row-major, width x height); each depends on the neighbours' pilots only.
std::vector<double> adaptive_pilot_weights(const std::vector<AdaptivePixel>& pilot, int width, int height,
                                           const AdaptivePlan& plan);
// Adds a round of k samples taken with weight a (s1, s2: 3 sums each of the round's samples).
void adaptive_add_round(AdaptivePixel& px, double a, int64_t k, const double* s1, const double* s2);

struct AdaptiveResult {
  // The window's film as a render of plan.spp samples per pixel: every sum is the weighted
  // estimate times plan.spp, the second moments hold what gives each pixel's variance layer the
  // variance of its estimate, sigma^2 V (film.h writes them); sample_begin 0, spp_done plan.spp.
  RenderResult film;
  std::vector<float> samples;  // the samples each pixel took
  double floor = 0;            // the brightness floor used
  int rounds = 0;
  double aim = 0;              // the last round's aim (adaptive_aim)
  int64_t cap = 0;             // the last round's per-pixel cap (adaptive_cap)
  int64_t round_end = 0;       // the sample count the last round ended at
  double mean_samples = 0;     // over the window's pixels
  // The pilot was drawn whole (no stop cut it short), so the film's variance layer measures its
  // noise (integrator/noise.h) as far as the pilot's samples allow; false when a stop cut it.
  bool noise_measured = false;
  // Why the rounds ended with the target missed (multi_device.h MultiDeviceResult::stop_reason):
  // "spp" when some pixel took plan.spp samples, else "pixels-finished"; "" when the target was
  // met or the render was stopped.
  std::string stop_reason;
};

// Renders the adaptive film of the renderer's window (settings().adaptive). `after_round` (may be
// empty) sees the film after each round (a preview). A stop or the deadline ends the render after
// the current round's finished samples; the pixels then average the weight they took (biased:
// film.interrupted).
AdaptiveResult render_adaptive(Renderer& r, const AdaptivePlan& plan,
                               const std::function<void(const AdaptiveResult&)>& after_round = {});

// The command line's and the Python module's adaptive render (render_multi_device with
// settings.adaptive): one Renderer on `device`, the plan from the settings (noise_target, spp),
// the film as a piece with its samples layer. base.progress, when set, is told after each round.
MultiDeviceResult render_adaptive_film(const SceneDesc& scene, const RenderOptions& base, const RenderSettings& settings,
                                       const std::string& device);

}  // namespace spectrack
