// noise.h: how noisy a film is, measured from its variance layer, and when to measure it again.
//
// Design: the noise of a render is one number, the relative error of its image (docs/cli.md,
// 'Noise target'). Per pixel p with n samples, m_p = (mean_R + mean_G + mean_B) / 3 is its
// brightness and SE_p = sqrt((v_R + v_G + v_B) / 3) the root mean square over channels of the
// standard error of its mean, v_c = (S2_c - S1_c^2 / n) / (n (n - 1)) from the per-sample sums S1
// and sums of squares S2 (the variance layer, docs/aov.md). The pixels that count are the noisy
// ones: m_p > 0 and SE_p > 0 (a background that every sample sees the same has no error to
// measure). With M the mean of m_p over them, r_p = SE_p / max(m_p, kNoiseFloor * M): a pixel
// darker than a twentieth of the average counts its error against that floor, so faint edges do
// not decide alone. The image's relative error is the 95th percentile (kNoisePercentile) of r_p
// over the counted pixels; 0 when none counts. Below kNoiseMinSpp samples the sample variances are
// too noisy themselves (a rare bright path may not have been drawn yet), so no decision is taken.
// Checks are scheduled by sample count, not by time, so a seed stops at the same sample whenever
// the batches of samples are the same (the renderer looks at the end of a batch): the error falls as 1/sqrt(n), so the next check is where the target is predicted to
// be met, at least one sample and at most twice the samples later.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace spectrack {

constexpr double kNoisePercentile = 0.95;
constexpr double kNoiseFloor = 0.05;
constexpr int64_t kNoiseMinSpp = 16;

struct NoiseEstimate {
  double error = 0;        // the 95th percentile of r_p (0: no noisy pixel)
  uint64_t pixels = 0;     // pixels counted (m_p > 0, SE_p > 0)
  int64_t samples = 0;     // n
  bool measured = false;   // n >= 2: one sample per pixel has no sample variance, hence no error
};

// npix pixels of n samples each: sum (S1) and moment2 (S2) hold 3 values per pixel at strides
// sum_stride and moment2_stride (in doubles) from one pixel to the next.
NoiseEstimate estimate_noise(const double* sum, size_t sum_stride, const double* moment2, size_t moment2_stride,
                             size_t npix, int64_t n);

// The same from a film's sums as RenderResult and FilmPiece hold them: `sum` 3 per pixel, `aov_sum`
// the channels `aov_channels` (aov_sum_channels, renderer.h), which must include the variance
// layer's "moment2.*". A transparent film's R, G, B leave out the environment layer; the second
// moments are of the whole beauty, so its S1 adds the layer back. Throws Error without the layer.
NoiseEstimate estimate_film_noise(const std::vector<double>& sum, const std::vector<double>& aov_sum,
                                  const std::vector<std::string>& aov_channels, int64_t n);

// The sample count at which to look again after an estimate of `error` at n samples, for a
// target error `target` (kNoiseMinSpp at the least).
int64_t next_noise_check(double error, int64_t n, double target);

}  // namespace spectrack
